#include "render/light_distant.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "glimmer/sampling.h"

namespace glimmer::render {

DistantLight::DistantLight(const scene::Light &light, const Spectrum &strength)
    : strength_(strength), dir_(normalize(light.dir)) {
  const float half = 0.5f * std::min(light.angle, 0.999f * kPi);
  cos_half_angle_ = std::cos(half);
  tan_radius_ = std::tan(half);
  inv_area_ = tan_radius_ > 0.0f ? 1.0f / (kPi * tan_radius_ * tan_radius_) : 1.0f;
}

float DistantLight::power(float disk_area) const {
  float p = luminance(strength_);
  p *= disk_area;
  return p;
}

bool DistantLight::sample(float u, float v, const Vec3 &, float pick, LightSample &out) const {
  out.dist = std::numeric_limits<float>::infinity();
  if (!(tan_radius_ > 0.0f)) {
    out.wi = -dir_;
    out.pdf = pick;
    out.radiance = strength_;
    out.delta = true;
    return true;
  }
  const Frame f = Frame::from_normal(-dir_);
  float x, y;
  sample_uniform_disk_concentric(u, v, x, y);
  out.wi = normalize(f.n + (f.s * x + f.t * y) * tan_radius_);
  const float cos_theta = dot(out.wi, f.n);
  const float dens = density(cos_theta);
  out.pdf = pick * dens;
  out.radiance = strength_ * dens;
  out.delta = false;
  return true;
}

}  // namespace glimmer::render
