// Cycles 3.4 spot lamp (kernel/light/spot.h): the point lamp (render/light_point.h)
// times spot_attenuation, evaluated with the direction from the lamp point to the
// shading point (or along the ray): the cosine to the spot axis, zero outside the
// cone of half-angle spot_angle / 2, smoothstep edge of width spot_smooth.
#pragma once

#include "render/light_point.h"

namespace glimmer::render {

class SpotLight {
 public:
  SpotLight(const scene::Light &light, const Spectrum &strength);
  float power(float scene_disk_area) const { return lamp_.power(scene_disk_area); }
  bool sample(float u, float v, const Vec3 &P, float pick, LightSample &out) const;
  bool intersect(const Vec3 &o, const Vec3 &d, float t_max, float pick, LightHit &out) const;
  float attenuation(const Vec3 &dir_from_light) const;

 private:
  PointLight lamp_;
  Vec3 dir_;  // spot axis (unit)
  float cos_half_spot_, spot_smooth_;
};

// Inline (header): LightSet::intersect calls it on every ray segment of every path.
inline bool SpotLight::intersect(const Vec3 &o, const Vec3 &d, float t_max, float pick, LightHit &out) const {
  if (!lamp_.intersect(o, d, t_max, pick, out)) return false;
  out.radiance *= attenuation(-d);
  return !is_zero(out.radiance);
}

}  // namespace glimmer::render
