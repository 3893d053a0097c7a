#include "render/light_area.h"

#include <algorithm>
#include <cmath>

#include "glimmer/sampling.h"

namespace glimmer::render {

AreaLight::AreaLight(const scene::Light &light, const Spectrum &strength)
    : strength_(strength),
      co_(light.co),
      U_(light.axisu * light.sizeu),
      V_(light.axisv * light.sizev),
      u_length2_(length_squared(U_)),
      v_length2_(length_squared(V_)),
      area_(length(cross(U_, V_)) * (light.round ? kPi * 0.25f : 1.0f)),
      round_(light.round) {
  // The emitting plane is spanned by axisu/axisv; `dir` only picks its emitting side.
  Vec3 n = normalize(cross(U_, V_));
  if (dot(n, normalize(light.dir)) < 0.0f) n = -n;
  dir_ = n;
  // Cycles 3.4 spread: a soft-box grid of slats; attenuation (1 - tan(spread_angle) tan(a)) normalised by
  // 2 / (2 + (2 spread_angle - pi) tan(spread_angle)), spread_angle = (pi - max(spread, 1 deg)) / 2.
  const float spread_angle = 0.5f * (kPi - std::max(light.spread, kPi / 180.0f));
  tan_spread_ = std::tan(spread_angle);
  normalize_spread_ = 2.0f / (2.0f + (2.0f * spread_angle - kPi) * tan_spread_);
}

float AreaLight::power(float) const {
  float p = luminance(strength_);
  p *= kPi * 0.25f;
  return p;
}

bool AreaLight::sample(float u, float v, const Vec3 &P, float pick, LightSample &out) const {
  Vec3 offset;
  if (round_) {
    float x, y;
    sample_uniform_disk_concentric(u, v, x, y);
    offset = U_ * (0.5f * x) + V_ * (0.5f * y);
  } else {
    offset = U_ * (u - 0.5f) + V_ * (v - 0.5f);
  }
  const Vec3 to = co_ + offset - P;
  const float d2 = length_squared(to), d = std::sqrt(d2);
  if (!(d > 0.0f)) return false;
  out.wi = to / d;
  const float cos_l = -dot(out.wi, dir_);  // emits toward dir
  if (cos_l <= 0.0f) return false;
  out.dist = d;
  out.pdf = pdf(pick, d2, cos_l);
  out.radiance = radiance(cos_l);
  out.delta = false;
  return !is_zero(out.radiance);
}

}  // namespace glimmer::render
