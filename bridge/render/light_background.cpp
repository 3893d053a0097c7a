#include "render/light_background.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "glimmer/sampling.h"

namespace glimmer::render {

BackgroundLight::BackgroundLight(const ShaderSystem &shaders) : shaders_(&shaders) {
  if (!shaders.background_is_constant()) build_map();
}

void BackgroundLight::build_map() {
  width_ = 512;
  height_ = 256;
  std::vector<std::vector<float>> weights(height_, std::vector<float>(width_));
  double sum = 0.0;
  for (int y = 0; y < height_; ++y) {
    for (int x = 0; x < width_; ++x) {
      float acc = 0.0f;
      for (int s = 0; s < 4; ++s) {  // 2x2 supersampling within the cell
        const float u = (x + 0.25f + 0.5f * (s & 1)) / width_, v = (y + 0.25f + 0.5f * (s >> 1)) / height_;
        acc += luminance(shaders_->background(equirectangular_to_direction(u, v)));
      }
      const float sin_theta = std::sin(kPi * (1.0f - (y + 0.5f) / height_));
      weights[y][x] = acc * 0.25f * sin_theta;
      sum += weights[y][x];
    }
  }
  // Floor: every direction keeps a non-zero density (unbiasedness for features finer than a cell).
  const float floor = static_cast<float>(sum / (width_ * height_)) * 0.01f + 1e-12f;
  for (int y = 0; y < height_; ++y) {
    const float sin_theta = std::sin(kPi * (1.0f - (y + 0.5f) / height_));
    for (auto &w : weights[y]) w += floor * sin_theta;
  }
  map_ = Distribution2D(weights);
}

float BackgroundLight::power(float disk_area) const {
  const float avg = width_ > 0 ? map_.marginal.total / static_cast<float>(width_ * height_)
                               : luminance(shaders_->background(Vec3(0, 0, 1)));
  return kPi * avg * disk_area;
}

float BackgroundLight::pdf(const Vec3 &d) const {
  if (width_ == 0) return kInv4Pi;
  float u, v;
  direction_to_equirectangular(d, u, v);
  const int x = std::clamp(static_cast<int>((u - std::floor(u)) * width_), 0, width_ - 1);
  const int y = std::clamp(static_cast<int>(v * height_), 0, height_ - 1);
  const float p_uv = map_.probability(x, y) * width_ * height_;
  const float sin_theta = std::sin(kPi * (1.0f - v));
  if (!(sin_theta > 1e-6f)) return 0.0f;
  return p_uv / (2.0f * kPi * kPi * sin_theta);
}

bool BackgroundLight::sample(float u, float v, const Vec3 &, float pick, LightSample &out) const {
  out.dist = std::numeric_limits<float>::infinity();
  if (width_ == 0) {
    out.wi = sample_uniform_sphere(u, v);
  } else {
    int x, y;
    float ur, vr;
    map_.sample(u, v, x, y, ur, vr);
    out.wi = equirectangular_to_direction((x + ur) / width_, (y + vr) / height_);
  }
  out.pdf = pick * pdf(out.wi);
  out.radiance = shaders_->background(out.wi);
  out.delta = false;
  return out.pdf > 0.0f;
}

}  // namespace glimmer::render
