// Sky Texture node (Cycles 3.4 SkyTextureNode): reads the node's settings and builds its
// SkyModel (render/nodes/sky_model.h) once, when a used shader compiles the node; the
// model is per node (nothing cached globally). Evaluated at the vector input (the ray
// direction for the world).
#include <cmath>
#include <string>

#include "render/nodes/families.h"
#include "render/nodes/sky_model.h"

namespace glimmer::render::nodes {

namespace {

float read_float(const SettingsReader &r, const char *name, float fallback) {
  const std::vector<float> v = r.floats(name);
  if (v.empty()) return fallback;
  if (v.size() != 1 || !std::isfinite(v[0])) r.fail(std::string(name) + ": expected one finite number");
  return v[0];
}

Vec3 read_direction(const SettingsReader &r, const char *name, const Vec3 &fallback) {
  const std::vector<float> v = r.floats(name);
  if (v.empty()) return fallback;
  if (v.size() != 3 || !std::isfinite(v[0] + v[1] + v[2]) || v[0] * v[0] + v[1] * v[1] + v[2] * v[2] <= 0.0f)
    r.fail(std::string(name) + ": expected a non-zero direction (3 finite numbers)");
  return {v[0], v[1], v[2]};
}

float read_non_negative(const SettingsReader &r, const char *name, float fallback) {
  const float v = read_float(r, name, fallback);
  if (v < 0.0f) r.fail(std::string(name) + " " + std::to_string(v) + " is negative");
  return v;
}

}  // namespace

void configure_sky(const SettingsReader &r, NodeSettings &settings) {
  SkyModel::Settings s;
  s.type = static_cast<SkyModel::Type>(r.choice("sky_type", {"preetham", "hosek_wilkie", "nishita"}, 2));
  s.sun_direction = read_direction(r, "sun_direction", s.sun_direction);
  s.turbidity = read_float(r, "turbidity", s.turbidity);
  s.ground_albedo = read_float(r, "ground_albedo", s.ground_albedo);
  s.sun_disc = r.boolean("sun_disc", s.sun_disc);
  s.sun_size = read_non_negative(r, "sun_size", s.sun_size);
  s.sun_intensity = read_non_negative(r, "sun_intensity", s.sun_intensity);
  s.sun_elevation = read_float(r, "sun_elevation", s.sun_elevation);
  s.sun_rotation = read_float(r, "sun_rotation", s.sun_rotation);
  s.atmosphere.altitude = read_float(r, "altitude", s.atmosphere.altitude);
  s.atmosphere.air_density = read_non_negative(r, "air_density", s.atmosphere.air_density);
  s.atmosphere.dust_density = read_non_negative(r, "dust_density", s.atmosphere.dust_density);
  s.atmosphere.ozone_density = read_non_negative(r, "ozone_density", s.atmosphere.ozone_density);
  if (s.type == SkyModel::Type::HosekWilkie)
    r.warn("sky_type 'hosek_wilkie' is approximated by the Preetham model (same sun_direction and turbidity; "
           "ground_albedo ignored): the Hosek-Wilkie coefficient dataset is not included");
  settings.sky = std::make_shared<const SkyModel>(s);
}

// in: vector; out: color.
void eval_sky(const NodeSettings &s, const ShadingPoint &, const Vec3 *in, Vec3 *out) {
  out[0] = s.sky->radiance(in[0]);
}

}  // namespace glimmer::render::nodes
