// Cycles 3.4 sun lamp (kernel/light/distant.h, scene/light.cpp; strength S in W/m^2).
// With angle a, a disk of radius tan(a/2) at unit distance along -dir, sampled
// uniformly by area: radiance = pdf = S / (pi tan^2(a/2) cos^3 theta) (theta from the
// sun axis), i.e. irradiance slightly below S. With angle 0, a delta direction of
// irradiance S. Only rays that escape the scene see the disk.
#pragma once

#include <limits>

#include "render/light_common.h"
#include "scene/scene.h"

namespace glimmer::render {

class DistantLight {
 public:
  DistantLight(const scene::Light &light, const Spectrum &strength);
  // Power through the scene's bounding disk of area `disk_area`.
  float power(float disk_area) const;
  bool sample(float u, float v, const Vec3 &P, float pick, LightSample &out) const;
  // The sun disk in direction d of a ray that escaped the scene (hit_surface false).
  bool intersect(const Vec3 &o, const Vec3 &d, float t_max, bool hit_surface, float pick, LightHit &out) const;

 private:
  // Radiance = density over the disk (solid angle) at cosine cos_theta to the axis: one formula for
  // sample() and intersect().
  float density(float cos_theta) const { return inv_area_ / (cos_theta * cos_theta * cos_theta); }

  Spectrum strength_;
  Vec3 dir_;                 // direction the light travels (unit)
  float cos_half_angle_;     // cos(a / 2)
  float tan_radius_;         // tan(a / 2): the disk's radius at unit distance
  float inv_area_;           // 1 / (pi tan^2(a / 2))
};

// Inline (header): LightSet::intersect calls it on every ray segment of every path.
inline bool DistantLight::intersect(const Vec3 &, const Vec3 &d, float, bool hit_surface, float pick, LightHit &out) const {
  if (hit_surface || !(tan_radius_ > 0.0f)) return false;
  const float cos_theta = dot(d, -dir_);
  if (cos_theta < cos_half_angle_) return false;
  const float dens = density(cos_theta);
  out.radiance = strength_ * dens;
  out.pdf = pick * dens;
  out.t = std::numeric_limits<float>::infinity();
  return true;
}

}  // namespace glimmer::render
