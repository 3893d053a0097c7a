#include "render/light_spot.h"

#include <cmath>

namespace glimmer::render {

SpotLight::SpotLight(const scene::Light &light, const Spectrum &strength)
    : lamp_(light, strength),
      dir_(normalize(light.dir)),
      cos_half_spot_(std::cos(0.5f * light.spot_angle)),
      spot_smooth_((1.0f - cos_half_spot_) * light.spot_smooth) {}

float SpotLight::attenuation(const Vec3 &dir_from_light) const {
  float attenuation = dot(dir_from_light, dir_);
  if (attenuation <= cos_half_spot_) return 0.0f;
  const float t = attenuation - cos_half_spot_;
  if (t < spot_smooth_ && spot_smooth_ != 0.0f) {
    const float s = t / spot_smooth_;
    attenuation *= s * s * (3.0f - 2.0f * s);
  }
  return attenuation;
}

bool SpotLight::sample(float u, float v, const Vec3 &P, float pick, LightSample &out) const {
  if (!lamp_.sample(u, v, P, pick, out)) return false;
  out.radiance *= attenuation(-out.wi);
  return !is_zero(out.radiance);
}

}  // namespace glimmer::render
