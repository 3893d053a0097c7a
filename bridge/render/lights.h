// The scene's lights, one type per kind with Cycles 3.4 strength conventions
// (render/light_point.h, light_spot.h, light_distant.h, light_area.h,
// light_triangle.h, light_background.h); each kind's sample() and intersect() /
// pdf() share one radiance and one pdf formula. Lights are chosen by a CDF over
// estimated power.
#pragma once

#include <string>
#include <type_traits>
#include <variant>
#include <vector>

#include "glimmer/math.h"
#include "render/distribution.h"
#include "render/lamp_through_lobe.h"
#include "render/light_area.h"
#include "render/light_background.h"
#include "render/light_common.h"
#include "render/light_distant.h"
#include "render/light_point.h"
#include "render/light_spot.h"
#include "render/light_triangle.h"
#include "render/shader_system.h"
#include "scene/scene.h"

namespace glimmer::render {

// How a constant-colour world is sampled: as a light (uniform directions, MIS with the BSDF ray) or by BSDF
// rays only (MIS weight 1, no NEE). Cycles' automatic world sampling always takes the second (scene/light.cpp,
// test_enabled_lights: the background light is kept only when the world shader varies spatially or portals
// exist). Measured on a white-world sphere (docs/architecture.md, "Constant-colour world"): right for
// closures whose BSDF sample weight eval / pdf is the same for every sample (diffuse: cosine sampling
// integrates a constant world almost exactly, the uniform light only adds noise, 11x lower RMSE at 16 spp;
// the isotropic multi_ggx conductor sampled exactly, which it does where no light is MIS-combined with its
// samples, docs/microfacet.md), wrong for rough GGX (1.8x higher RMSE at 256 spp) and for the rarely sampled
// Fresnel reflection of glass, where MIS with the uniform light is better.
enum class ConstantWorld { BsdfOnly, AsLight };
// BsdfOnly when the world is constant, sampling is not light-only and every closure instance samples with a
// constant weight (samples_with_constant_weight), probed with GLIMMER_SAMPLING_UNCOMBINED when the world would
// then be the only light source BSDF rays find (no lamps, no emissive triangles: `other_lights` false), i.e.
// when the renderer will set that flag; else AsLight.
ConstantWorld constant_world_sampling(const ShaderSystem &shaders, bool light_only, bool other_lights);
// Probe of one closure instance in contexts with the given sampling_flags: the per-sample relative standard
// deviation of its sample weight at a few incidence angles (64 samples each, both sides for transmissive
// closures) is below 2 % and no sample is absorbed. Diffuse and emission are known constant; closures with a
// stochastic eval, references and those that trace rays or read the environment are not probed (false).
bool samples_with_constant_weight(const host::ClosureInstance &closure, uint32_t sampling_flags);
// Name of the choice for reports (`glimmer render --stats`): "light" or "bsdf_only".
const char *constant_world_name(ConstantWorld choice);

class LightSet {
 public:
  LightSet(const scene::Scene &scene, ShaderSystem &shaders, const std::vector<int> &mesh_shader, Vec3 center,
           float radius, bool light_only, FeatureSet &features, std::vector<std::string> &warnings);

  int count() const { return static_cast<int>(lights_.size()); }
  // How a constant world is sampled (constant_world_sampling; AsLight when the world is not constant).
  ConstantWorld constant_world() const { return constant_world_; }
  // u picks the light (power CDF) and, rescaled within the light's share, with v places the point on it.
  bool sample(float u, float v, const Vec3 &P, LightSample &out) const;
  // Lamps hit by the ray (o, d) before t_max, and the sun disk when the ray escapes (hit_surface false);
  // camera_ray: the ray comes from the camera (through transparent surfaces only), so lamps with
  // use_camera = false are skipped as in Cycles' lights_intersect.
  void intersect(const Vec3 &o, const Vec3 &d, float t_max, bool hit_surface, bool camera_ray, LightHits &out) const;
  // Lamp k (0 <= k < lamp_count(): point, spot, area, sun; not emissive triangles, not the world) seen from P
  // through an exit lobe (docs/frosted_glass.md, "Lamps through the exit lobe"): Int p(w) L(w) dw, p the lobe's
  // density (ExitLobe::pdf), estimated by kLampStrata^2 points of the lamp's own sampling and kLampStrata^2
  // directions of the lobe's vMF, each set stratified with the offset (u, v), combined by the balance heuristic
  // (multi-sample MIS); `pick` chooses one of those points with probability proportional to its share, and the
  // estimate is scaled so that value x V(point) is unbiased for Int p L V: one shadow ray per lamp (the caller's).
  // False: no light of the lamp reaches P through the lobe.
  int lamp_count() const { return static_cast<int>(lamps_.size()); }
  bool lamp_through_lobe(int k, const Vec3 &P, const ExitLobe &lobe, float u, float v, float pick,
                         LampEstimate &out) const;
  // The same through a whole exit lobe mixture (ABI 2.7): p its density, the lobe's directions from its vMFs.
  bool lamp_through_lobe(int k, const Vec3 &P, const ExitLobeMixture &lobe, float u, float v, float pick,
                         LampEstimate &out) const;
  // The same with the lobe's value given apart from its proposal (ValuedExitLobe: the exact exit of a pane).
  bool lamp_through_lobe(int k, const Vec3 &P, const ValuedExitLobe &lobe, float u, float v, float pick,
                         LampEstimate &out) const;
  // Light-sampling pdf of an escaping ray in direction d (0 when the world is not a light).
  float background_pdf(const Vec3 &d) const;
  // Light-sampling pdf for a BSDF ray from `from` hitting emissive triangle (mesh, prim) at P.
  float triangle_pdf(int mesh, int prim, const Vec3 &from, const Vec3 &P, const Vec3 &Ng, const Vec3 &d) const;

 private:
  struct Light {
    std::variant<PointLight, SpotLight, DistantLight, AreaLight, TriangleLight, BackgroundLight> kind;
    bool use_camera = true;
  };
  std::vector<Light> lights_;
  // The lights intersect() can hit (point, spot, area, sun), in lights_ order: emissive triangles (found by
  // the BVH) and the world (when the ray escapes) are never visited on a ray segment.
  std::vector<int> lamps_;
  std::vector<float> power_;  // estimated power per light (the pick CDF's weights)
  Distribution1D pick_;
  std::vector<std::vector<int>> triangle_light_;  // per mesh, per triangle: light index or -1
  int background_light_ = -1;
  ConstantWorld constant_world_ = ConstantWorld::AsLight;

  float pick_probability(int i) const { return pick_.probability(i); }
  void add_lamp(const scene::Light &light, const Spectrum &strength, float disk_area, FeatureSet &features);
  template <typename Kind>
  void add_light(Kind light, float disk_area, bool use_camera) {
    if constexpr (!std::is_same_v<Kind, BackgroundLight>) lamps_.push_back(static_cast<int>(lights_.size()));
    power_.push_back(light.power(disk_area));
    lights_.push_back({std::move(light), use_camera});
  }
  void add_emissive_triangles(const scene::Scene &scene, const ShaderSystem &shaders,
                              const std::vector<int> &mesh_shader, FeatureSet &features);
};

// Inline: called on every ray segment of every path.
inline void LightSet::intersect(const Vec3 &o, const Vec3 &d, float t_max, bool hit_surface, bool camera_ray,
                                LightHits &out) const {
  out.count = 0;
  for (const int i : lamps_) {
    if (camera_ray && !lights_[i].use_camera) continue;
    const float pick = pick_probability(i);
    LightHit h;
    const bool hit = std::visit(
        [&](const auto &light) {
          using Kind = std::decay_t<decltype(light)>;
          if constexpr (std::is_same_v<Kind, DistantLight>)
            return light.intersect(o, d, t_max, hit_surface, pick, h);
          else if constexpr (std::is_same_v<Kind, TriangleLight> || std::is_same_v<Kind, BackgroundLight>)
            return false;  // not in lamps_: triangles are found by the BVH, the world when the ray escapes
          else
            return light.intersect(o, d, t_max, pick, h);
        },
        lights_[i].kind);
    if (hit) out.add(h);
  }
}

}  // namespace glimmer::render
