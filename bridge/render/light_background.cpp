#include "render/light_background.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "glimmer/sampling.h"

namespace glimmer::render {

namespace {
// Angle between unit vectors, accurate near 0 (a sun disc is a quarter of a degree wide).
float angle_between(const Vec3 &a, const Vec3 &b) { return 2.0f * std::atan2(length(a - b), length(a + b)); }
}  // namespace

BackgroundLight::BackgroundLight(const ShaderSystem &shaders) : shaders_(&shaders) {
  const std::vector<nodes::SunDisc> suns = shaders.background_suns();
  if (suns.size() == 1) set_up_sun(suns[0]);  // several suns: the map alone, as Cycles
  if (!shaders.background_is_constant()) build_map();
  if (sun_half_angle_ > 0.0f) {
    const float map_power = width_ > 0 ? map_.marginal.total * 2.0f * kPi * kPi / float(width_ * height_)
                                       : 4.0f * kPi * luminance(shaders_->background(Vec3(0, 0, 1)));
    sun_pick_ = std::clamp(sun_power_ / (sun_power_ + map_power), 0.1f, 0.9f);
  }
}

// The cone's luminance integral by a stratified 16 x 16 quadrature over its solid angle.
void BackgroundLight::set_up_sun(const nodes::SunDisc &sun) {
  sun_frame_ = Frame::from_normal(normalize(sun.direction));
  sun_half_angle_ = sun.half_angle;
  sun_one_minus_cos_ = 2.0 * std::pow(std::sin(0.5 * double(sun.half_angle)), 2.0);
  constexpr int n = 16;
  double sum = 0.0;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const double omc = (i + 0.5) / n * sun_one_minus_cos_, sin_t = std::sqrt(omc * (2.0 - omc));
      const double phi = 2.0 * M_PI * (j + 0.5) / n;
      const Vec3 local(float(sin_t * std::cos(phi)), float(sin_t * std::sin(phi)), float(1.0 - omc));
      sum += luminance(shaders_->background(sun_frame_.to_world(local)));
    }
  sun_power_ = float(sum / (n * n) * 2.0 * M_PI * sun_one_minus_cos_);
}

bool BackgroundLight::in_sun(const Vec3 &d) const {
  // A relative margin of 1e-4 keeps sampled directions at the rim inside despite rounding.
  return sun_half_angle_ > 0.0f && angle_between(d, sun_frame_.n) <= sun_half_angle_ * (1.0f + 1e-4f);
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
        const Vec3 d = equirectangular_to_direction(u, v);
        if (!in_sun(d)) acc += luminance(shaders_->background(d));  // the sun's cone is sampled on its own
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
  // The map's cells hold L sin(theta): their mean is the integral of L over the sphere / (2 pi^2).
  return kPi * (avg + sun_power_ / (2.0f * kPi * kPi)) * disk_area;
}

float BackgroundLight::map_pdf(const Vec3 &d) const {
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

float BackgroundLight::pdf(const Vec3 &d) const {
  const float map = map_pdf(d);
  if (sun_pick_ == 0.0f) return map;
  const float cone = in_sun(d) ? float(1.0 / (2.0 * M_PI * sun_one_minus_cos_)) : 0.0f;
  return (1.0f - sun_pick_) * map + sun_pick_ * cone;
}

bool BackgroundLight::sample(float u, float v, const Vec3 &, float pick, LightSample &out) const {
  out.dist = std::numeric_limits<float>::infinity();
  if (sun_pick_ > 0.0f && choose_and_rescale(sun_pick_, u)) {
    // Uniform in the cone, 1 - cos(theta) drawn directly (cos(theta) itself has too few floats there).
    const double omc = u * sun_one_minus_cos_, sin_t = std::sqrt(omc * (2.0 - omc));
    const float phi = kTwoPi * v;
    out.wi = normalize(sun_frame_.to_world(
        Vec3(float(sin_t) * std::cos(phi), float(sin_t) * std::sin(phi), float(1.0 - omc))));
  } else if (width_ == 0) {
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
  out.world = true;
  return out.pdf > 0.0f;
}

}  // namespace glimmer::render
