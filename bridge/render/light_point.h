// Cycles 3.4 point lamp (kernel/light/point.h; strength S in W). Without a radius
// a point of intensity S / (4 pi); with radius r a disk of that radius centred on
// co and facing the shading point (or the ray origin), sampled uniformly by area:
// radiance S / (4 pi) / (pi r^2) (eval_fac = 1/(4 pi) * invarea), pdf = t^2 / (cos * pi r^2).
#pragma once

#include "render/light_common.h"
#include "scene/scene.h"

namespace glimmer::render {

class PointLight {
 public:
  PointLight(const scene::Light &light, const Spectrum &strength);
  // Estimated power for the light pick (every kind takes the scene's bounding-disk area; lamps ignore it).
  float power(float /*scene_disk_area*/) const { return luminance(strength_); }
  const Vec3 &position() const { return co_; }
  // A point on the lamp seen from P (u, v on the disk); pdf includes `pick`.
  bool sample(float u, float v, const Vec3 &P, float pick, LightSample &out) const;
  // The disk (facing o) crossed by (o, d) before t_max; never for a point lamp (radius 0).
  bool intersect(const Vec3 &o, const Vec3 &d, float t_max, float pick, LightHit &out) const;

 private:
  // The radiance of the disk and the solid-angle density of a point on it at squared distance dist2 and
  // cosine cos_l to the disk normal: one formula for sample() and intersect().
  Spectrum disk_radiance() const { return strength_ * (kInv4Pi / disk_area_); }
  float disk_pdf(float pick, float dist2, float cos_l) const {
    return area_to_solid_angle_pdf(pick, dist2, cos_l, disk_area_);
  }

  Spectrum strength_;
  Vec3 co_;
  float radius_;
  float disk_area_;  // pi r^2
};

// Inline (header): LightSet::intersect calls it on every ray segment of every path.
inline bool PointLight::intersect(const Vec3 &o, const Vec3 &d, float t_max, float pick, LightHit &out) const {
  if (!(radius_ > 0.0f)) return false;
  // The disk of radius r at co facing the ray origin (Cycles' ray_disk_intersect with lightN = o - co).
  const Vec3 oc = o - co_;
  const float dist_origin = length(oc);
  if (!(dist_origin > 0.0f)) return false;
  const Vec3 lightN = oc / dist_origin;
  const float cos_l = -dot(d, lightN);
  if (cos_l <= 0.0f) return false;
  const float t = dist_origin / cos_l;  // plane through co with normal lightN
  if (!(t > 0.0f && t < t_max)) return false;
  const Vec3 q = o + d * t - co_;
  if (length_squared(q) > radius_ * radius_) return false;
  out.radiance = disk_radiance();
  out.pdf = disk_pdf(pick, t * t, cos_l);
  out.t = t;
  return !is_zero(out.radiance);
}

}  // namespace glimmer::render
