#include "render/lights.h"

#include "render/lamp_through_lobe.h"

#include "lab/closure_lab.h"

#include <algorithm>
#include <cmath>
#include <type_traits>

namespace glimmer::render {

bool samples_with_constant_weight(const host::ClosureInstance &closure, uint32_t sampling_flags) {
  const std::string name = closure.type().name;
  if (name == "diffuse" || name == "emission") return true;
  // Closures that trace rays or read the environment are not probed in the closure lab's empty context.
  if (closure.type().flags & (GLIMMER_CLOSURE_STOCHASTIC_EVAL | GLIMMER_CLOSURE_REFERENCE | GLIMMER_CLOSURE_NEEDS_TRACE |
                              GLIMMER_CLOSURE_NEEDS_ENVIRONMENT))
    return false;
  constexpr uint64_t kSamples = 64;
  constexpr float kMaxRelativeStd = 0.02f;
  const bool transmissive = closure.type().flags & GLIMMER_CLOSURE_TRANSMISSIVE;
  for (const float mu : {1.0f, 0.5f, 0.1f, -0.5f}) {
    if (mu < 0.0f && !transmissive) continue;
    GlimmerShadingContext ctx = host::make_local_context(Vec3(std::sqrt(1.0f - mu * mu), 0.0f, mu));
    ctx.sampling_flags = sampling_flags;
    const lab::FurnaceResult r = lab::furnace(closure, ctx, kSamples, 1);
    if (r.invalid_count > 0 || r.absorbed_count > 0) return false;
    for (int c = 0; c < 3; ++c)
      if (!(r.standard_error[c] * std::sqrt(static_cast<float>(kSamples)) <= kMaxRelativeStd * r.albedo[c]))
        return false;
  }
  return true;
}

ConstantWorld constant_world_sampling(const ShaderSystem &shaders, bool light_only, bool other_lights) {
  // Only a constant world asks (the probe is not run for other scenes).
  if (light_only || !shaders.has_background() || !shaders.background_is_constant()) return ConstantWorld::AsLight;
  const uint32_t flags = other_lights ? 0u : static_cast<uint32_t>(GLIMMER_SAMPLING_UNCOMBINED);
  for (const auto &closure : shaders.instances())
    if (!samples_with_constant_weight(*closure, flags)) return ConstantWorld::AsLight;
  return ConstantWorld::BsdfOnly;
}

const char *constant_world_name(ConstantWorld choice) {
  return choice == ConstantWorld::BsdfOnly ? "bsdf_only" : "light";
}

LightSet::LightSet(const scene::Scene &scene, ShaderSystem &shaders, const std::vector<int> &mesh_shader, Vec3 center,
                   float radius, bool light_only, FeatureSet &features, std::vector<std::string> &warnings) {
  (void)center;
  (void)warnings;
  const float disk_area = kPi * radius * radius;
  for (const auto &l : scene.lights) {
    const Spectrum strength = l.strength * shaders.light_emission(l.shader, l.where);
    if (is_zero(strength) || l.type == scene::LightType::Background) continue;  // the world: added below
    add_lamp(l, strength, disk_area, features);
  }
  add_emissive_triangles(scene, shaders, mesh_shader, features);
  // Background (a constant one only where that helps, see ConstantWorld; decided once the other lights are known).
  constant_world_ = constant_world_sampling(shaders, light_only, !lights_.empty());
  features.world_sampling = shaders.has_background() ? constant_world_name(constant_world_) : "none";
  if (shaders.has_background() && constant_world_ == ConstantWorld::AsLight) {
    background_light_ = static_cast<int>(lights_.size());
    add_light(BackgroundLight(shaders), disk_area, true);
  }
  // Every light keeps at least a small share so that none is starved.
  float total = 0.0f;
  for (float p : power_) total += p;
  for (float &p : power_) p = std::max(p, 0.01f * total / std::max<size_t>(power_.size(), 1));
  pick_ = Distribution1D(power_);
}

void LightSet::add_lamp(const scene::Light &l, const Spectrum &strength, float disk_area, FeatureSet &features) {
  using Type = scene::LightType;
  switch (l.type) {
    case Type::Point: add_light(PointLight(l, strength), disk_area, l.use_camera); break;
    case Type::Spot: add_light(SpotLight(l, strength), disk_area, l.use_camera); break;
    case Type::Sun: add_light(DistantLight(l, strength), disk_area, l.use_camera); break;
    case Type::Area: add_light(AreaLight(l, strength), disk_area, l.use_camera); break;
    case Type::Background: return;
  }
  const char *name = l.type == Type::Point ? "point" : l.type == Type::Spot ? "spot" : l.type == Type::Sun ? "sun"
                     : l.round ? "area_disk" : "area_quad";
  features.light_types.insert(name);
}

void LightSet::add_emissive_triangles(const scene::Scene &scene, const ShaderSystem &shaders,
                                      const std::vector<int> &mesh_shader, FeatureSet &features) {
  triangle_light_.resize(scene.meshes.size());
  for (size_t m = 0; m < scene.meshes.size(); ++m) {
    if (!shaders.shader(mesh_shader[m]).has_emission) continue;
    const auto &mesh = scene.meshes[m];
    triangle_light_[m].assign(mesh.triangles.size(), -1);
    for (size_t t = 0; t < mesh.triangles.size(); ++t) {
      const auto &tri = mesh.triangles[t];
      const float area = 0.5f * length(cross(mesh.P[tri[1]] - mesh.P[tri[0]], mesh.P[tri[2]] - mesh.P[tri[0]]));
      if (!(area > 0.0f)) continue;
      const TriangleLight light(mesh, static_cast<int>(t), area, shaders, mesh_shader[m]);
      const std::optional<float> power = light.power();
      if (!power) continue;
      triangle_light_[m][t] = static_cast<int>(lights_.size());
      lights_.push_back({light, true});
      power_.push_back(*power);
      features.emissive_triangles++;
    }
  }
}

float LightSet::background_pdf(const Vec3 &d) const {
  if (background_light_ < 0) return 0.0f;
  return pick_probability(background_light_) * std::get<BackgroundLight>(lights_[background_light_].kind).pdf(d);
}

bool LightSet::sample(float u, float v, const Vec3 &P, LightSample &out) const {
  if (lights_.empty()) return false;
  // u picks the light and is rescaled within its bin for the point on it (stratification kept).
  const int index = pick_.sample(u, u);
  const float pick = pick_probability(index);
  const auto &kind = lights_[index].kind;
  const bool ok = std::visit([&](const auto &light) { return light.sample(u, v, P, pick, out); }, kind);
  out.lamp = !std::holds_alternative<TriangleLight>(kind) && !std::holds_alternative<BackgroundLight>(kind);
  return ok;
}

namespace {
template <class Kind, class Lobe>
bool lamp_kind_through_lobe(const Kind &kind, const Vec3 &P, const Lobe &lobe, float u, float v, float pick,
                            LampEstimate &out) {
  return std::visit(
      [&](const auto &light) {
        using Light = std::decay_t<decltype(light)>;
        if constexpr (std::is_same_v<Light, TriangleLight> || std::is_same_v<Light, BackgroundLight>)
          return false;
        else
          return render::lamp_through_lobe(light, P, lobe, u, v, pick, out);
      },
      kind);
}
}  // namespace

bool LightSet::lamp_through_lobe(int k, const Vec3 &P, const ExitLobe &lobe, float u, float v, float pick,
                                 LampEstimate &out) const {
  if (k < 0 || k >= lamp_count()) return false;
  return lamp_kind_through_lobe(lights_[lamps_[k]].kind, P, lobe, u, v, pick, out);
}
bool LightSet::lamp_through_lobe(int k, const Vec3 &P, const ExitLobeMixture &lobe, float u, float v, float pick,
                                 LampEstimate &out) const {
  if (k < 0 || k >= lamp_count()) return false;
  return lamp_kind_through_lobe(lights_[lamps_[k]].kind, P, lobe, u, v, pick, out);
}
bool LightSet::lamp_through_lobe(int k, const Vec3 &P, const ValuedExitLobe &lobe, float u, float v, float pick,
                                 LampEstimate &out) const {
  if (k < 0 || k >= lamp_count() || lobe.proposal == nullptr || lobe.value == nullptr) return false;
  return lamp_kind_through_lobe(lights_[lamps_[k]].kind, P, lobe, u, v, pick, out);
}

float LightSet::triangle_pdf(int mesh, int prim, const Vec3 &from, const Vec3 &P, const Vec3 &Ng, const Vec3 &d) const {
  if (mesh < 0 || triangle_light_[mesh].empty()) return 0.0f;
  const int index = triangle_light_[mesh][prim];
  if (index < 0) return 0.0f;
  return std::get<TriangleLight>(lights_[index].kind).pdf(pick_probability(index), from, P, Ng, d);
}

}  // namespace glimmer::render
