// Cycles 3.4 area lamp (kernel/light/area.h; strength S in W): a quad sizeu x sizev
// along axisu / axisv, or a disk / ellipse (round), emitting on the side `dir` picks;
// radiance S / (4 A) (eval_fac = 0.25 * invarea) times the spread attenuation, the
// point sampled uniformly by area: pdf = t^2 / (cos A).
#pragma once

#include <algorithm>
#include <cmath>

#include "render/light_common.h"
#include "scene/scene.h"

namespace glimmer::render {

class AreaLight {
 public:
  AreaLight(const scene::Light &light, const Spectrum &strength);
  float power(float scene_disk_area) const;  // the area is not in it (radiance S / (4 A))
  bool sample(float u, float v, const Vec3 &P, float pick, LightSample &out) const;
  bool intersect(const Vec3 &o, const Vec3 &d, float t_max, float pick, LightHit &out) const;
  // Whether the whole lamp lies below the plane through P with unit normal n, with a margin that rounding cannot
  // cross: every point that sample() or intersect() can give makes a direction from P with n . w < 0 (the host's
  // lamps through an exit lobe, render/lamp_through_lobe.h, skip such a lamp).
  bool wholly_below(const Vec3 &P, const Vec3 &n) const;
  // A lower bound of sample()'s solid-angle density (pick 1) over the lamp seen from P: t^2 / (A cos_l) >= h^2 / A,
  // h the distance from P to the lamp's plane (render/lamp_through_lobe.h's lobe-set skip; session 32).
  float min_pdf(const Vec3 &P) const {
    const float h = dot(P - co_, dir_);
    return h * h / area_;
  }

 private:
  // Radiance leaving at cosine cos_l to the normal, and the solid-angle density of a point at squared
  // distance dist2: one formula each for sample() and intersect().
  Spectrum radiance(float cos_l) const { return strength_ * (0.25f / area_ * spread_attenuation(cos_l)); }
  float pdf(float pick, float dist2, float cos_l) const { return area_to_solid_angle_pdf(pick, dist2, cos_l, area_); }
  float spread_attenuation(float cos_to_normal) const;
  bool inside(const Vec3 &q) const;  // q relative to the centre, in the light's plane

  Spectrum strength_;
  Vec3 co_, dir_;  // centre; emitting normal (unit)
  Vec3 U_, V_;     // full extents along axisu, axisv
  float u_length2_, v_length2_;  // length_squared(U_), length_squared(V_): inside() per ray, made once
  float area_;
  bool round_;
  float tan_spread_ = 0.0f, normalize_spread_ = 1.0f;  // Cycles 3.4 spread (scene/light.cpp)
};

// Inline (header): LightSet::intersect calls it on every ray segment of every path.
inline float AreaLight::spread_attenuation(float cos_to_normal) const {
  // Cycles 3.4 light_spread_attenuation (kernel/light/light.h): the share of a soft-box grid cell not hidden by
  // its slats at angle a from the normal.
  if (tan_spread_ <= 0.0f) return 1.0f;
  const float sin_a = std::sqrt(std::max(0.0f, 1.0f - cos_to_normal * cos_to_normal));
  const float tan_a = sin_a / cos_to_normal;
  return std::max((1.0f - tan_spread_ * tan_a) * normalize_spread_, 0.0f);
}

// The quad's corners (a round lamp's bounding quad): every lamp point x is a convex combination of them, so
// n . (x - P) < -1e-4 |x - P| - 1e-5 s when each corner's is (the triangle inequality); s bounds the coordinates, and
// 1e-5 s covers the rounding of a sampled or hit point (~1e-6 s) and of x - P, 1e-4 |x - P| that of the hit's
// distance along the ray, of the unit direction and of its dot with n.
inline bool AreaLight::wholly_below(const Vec3 &P, const Vec3 &n) const {
  const auto extent = [](const Vec3 &v) { return std::max(std::fabs(v.x), std::max(std::fabs(v.y), std::fabs(v.z))); };
  const float slack = 1e-5f * (1.0f + extent(P) + extent(co_) + extent(U_) + extent(V_));
  for (const float su : {-0.5f, 0.5f})
    for (const float sv : {-0.5f, 0.5f}) {
      const Vec3 d = co_ + U_ * su + V_ * sv - P;
      if (!(dot(d, n) < -1e-4f * length(d) - slack)) return false;
    }
  return true;
}

inline bool AreaLight::inside(const Vec3 &q) const {
  const float su = dot(q, U_) / u_length2_, sv = dot(q, V_) / v_length2_;
  return round_ ? (4.0f * (su * su + sv * sv) <= 1.0f) : (std::fabs(su) <= 0.5f && std::fabs(sv) <= 0.5f);
}

inline bool AreaLight::intersect(const Vec3 &o, const Vec3 &d, float t_max, float pick, LightHit &out) const {
  const float denom = dot(d, dir_);
  if (std::fabs(denom) < 1e-9f) return false;
  const float t = dot(co_ - o, dir_) / denom;
  if (!(t > 0.0f && t < t_max)) return false;
  if (!inside(o + d * t - co_)) return false;
  const float cos_l = -denom;
  if (cos_l <= 0.0f) return false;  // back side: no emission
  out.radiance = radiance(cos_l);
  if (is_zero(out.radiance)) return false;
  out.pdf = pdf(pick, t * t, cos_l);
  out.t = t;
  return true;
}

}  // namespace glimmer::render
