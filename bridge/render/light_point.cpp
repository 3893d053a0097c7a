#include "render/light_point.h"

#include <cmath>

#include "glimmer/sampling.h"

namespace glimmer::render {

PointLight::PointLight(const scene::Light &light, const Spectrum &strength)
    : strength_(strength), co_(light.co), radius_(light.radius), disk_area_(kPi * light.radius * light.radius) {}

bool PointLight::sample(float u, float v, const Vec3 &P, float pick, LightSample &out) const {
  const Vec3 to_center = co_ - P;
  const float d_center = length(to_center);
  if (!(d_center > 0.0f)) return false;
  if (!(radius_ > 0.0f)) {
    out.wi = to_center / d_center;
    out.dist = d_center;
    out.pdf = pick;
    out.radiance = strength_ * (kInv4Pi / (d_center * d_center));
    out.delta = true;
    return !is_zero(out.radiance);
  }
  const Vec3 lightN = -to_center / d_center;  // disk normal, toward P
  const Frame f = Frame::from_normal(lightN);
  float x, y;
  sample_uniform_disk_concentric(u, v, x, y);
  const Vec3 Pl = co_ + (f.s * x + f.t * y) * radius_;
  const Vec3 to = Pl - P;
  const float d2 = length_squared(to), d = std::sqrt(d2);
  if (!(d > 0.0f)) return false;
  out.wi = to / d;
  const float cos_l = -dot(lightN, out.wi);
  if (cos_l <= 0.0f) return false;
  out.dist = d;
  out.pdf = disk_pdf(pick, d2, cos_l);
  out.radiance = disk_radiance();
  out.delta = false;
  return !is_zero(out.radiance);
}

}  // namespace glimmer::render
