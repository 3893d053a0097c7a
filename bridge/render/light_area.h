// Cycles 3.4 area lamp (kernel/light/area.h; strength S in W): a quad sizeu x sizev
// along axisu / axisv, or a disk / ellipse (round), emitting on the side `dir` picks;
// radiance S / (4 A) (eval_fac = 0.25 * invarea) times the spread attenuation, the
// point sampled uniformly by area: pdf = t^2 / (cos A).
#pragma once

#include "render/light_common.h"
#include "scene/scene.h"

namespace glimmer::render {

class AreaLight {
 public:
  AreaLight(const scene::Light &light, const Spectrum &strength);
  float power(float scene_disk_area) const;  // the area is not in it (radiance S / (4 A))
  bool sample(float u, float v, const Vec3 &P, float pick, LightSample &out) const;
  bool intersect(const Vec3 &o, const Vec3 &d, float t_max, float pick, LightHit &out) const;

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
  float area_;
  bool round_;
  float tan_spread_ = 0.0f, normalize_spread_ = 1.0f;  // Cycles 3.4 spread (scene/light.cpp)
};

}  // namespace glimmer::render
