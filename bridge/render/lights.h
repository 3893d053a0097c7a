// Lights with Cycles 3.4 strength conventions:
//  - point/spot (strength S in W): radiant intensity S / (4 pi); with radius r
//    a sphere of radiance S / (4 pi * pi r^2). Spot: times Cycles'
//    spot_attenuation (includes the cosine to the spot axis, smoothstep edge).
//  - sun (S in W/m^2): irradiance S at normal incidence; with angle a a cone
//    of half-angle a/2 and radiance S / (pi sin^2(a/2)).
//  - area (quad sizeu x sizev along axisu/axisv, or disk/ellipse with round):
//    radiance S / (4 A) (Cycles' eval_fac = 0.25 * invarea), emitting toward `dir`.
//  - background: radiance color * strength; equirectangular maps are importance sampled.
//  - mesh emission: radiance color * strength (emission closure), sampled by area.
// Lights are chosen by a CDF over estimated power.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "glimmer/math.h"
#include "render/shader_system.h"
#include "scene/scene.h"

namespace glimmer::render {

struct LightSample {
  Vec3 wi;            // toward the light
  float dist = 0.0f;  // to the light point (infinite for distant lights)
  Spectrum radiance{0.0f};  // incident radiance (delta lights: irradiance-like term, pdf = pick probability)
  float pdf = 0.0f;   // solid angle density including the pick probability
  bool delta = false;
};

struct LightHit {
  Spectrum radiance{0.0f};
  float pdf = 0.0f;  // what sample() would give for this direction
  float t = 0.0f;
  bool delta = false;
};

// Every lamp a ray segment passes through: Cycles' lamps do not block rays
// (shade_light adds the emission and the ray continues past the lamp).
struct LightHits {
  static constexpr int kMax = 16;
  LightHit hits[kMax];
  int count = 0;
  void add(const LightHit &h) {
    if (count < kMax) hits[count++] = h;
  }
};

// Piecewise-constant 1D distribution.
struct Distribution1D {
  std::vector<float> cdf;  // size n + 1
  float total = 0.0f;
  explicit Distribution1D(const std::vector<float> &weights = {});
  int count() const { return static_cast<int>(cdf.size()) - 1; }
  // Returns the bin and rescales u to [0, 1) within it.
  int sample(float u, float &u_remapped) const;
  float probability(int i) const { return total > 0.0f ? (cdf[i + 1] - cdf[i]) : 0.0f; }
};

// Film reconstruction filter by importance sampling (Cycles' filter table idea).
class FilmFilter {
 public:
  FilmFilter() = default;
  FilmFilter(scene::FilterType type, float width);
  float offset(float u) const;  // pixel offset from the centre

 private:
  scene::FilterType type_ = scene::FilterType::Box;
  float width_ = 1.0f;
  std::vector<float> inverse_cdf_;
};

// How a constant-colour world is sampled: as a light (uniform directions, MIS with the BSDF ray) or by BSDF
// rays only (MIS weight 1, no NEE). Cycles' automatic world sampling always takes the second (scene/light.cpp,
// test_enabled_lights: the background light is kept only when the world shader varies spatially or portals
// exist). Measured on a white-world sphere (docs/architecture.md, "Constant-colour world"): right for
// diffuse closures, whose cosine sampling integrates a constant world almost exactly (the uniform light only
// adds noise: 11x lower RMSE at 16 spp), wrong for rough GGX (1.8x higher RMSE at 256 spp) and for the rarely
// sampled Fresnel reflection of glass, where MIS with the uniform light is better.
enum class ConstantWorld { BsdfOnly, AsLight };
// BsdfOnly when every closure present is diffuse (and not light-only sampling), else AsLight.
ConstantWorld constant_world_sampling(const FeatureSet &features, bool light_only);

class LightSet {
 public:
  LightSet(const scene::Scene &scene, ShaderSystem &shaders, const std::vector<int> &mesh_shader, Vec3 center,
           float radius, ConstantWorld constant_world, FeatureSet &features, std::vector<std::string> &warnings);

  int count() const { return static_cast<int>(lights_.size()); }
  // u picks the light (power CDF) and, rescaled within the light's share, with v places the point on it.
  bool sample(float u, float v, const Vec3 &P, LightSample &out) const;
  // Lamps hit by a ray before t_max, and the sun disk when the ray escapes.
  // Lamps hit by the ray (o, d) before t_max; camera_ray: the ray comes from the camera (through transparent
  // surfaces only), so lamps with use_camera = false are skipped as in Cycles' lights_intersect.
  void intersect(const Vec3 &o, const Vec3 &d, float t_max, bool hit_surface, bool camera_ray, LightHits &out) const;
  float background_pdf(const Vec3 &d) const;
  // Light-sampling pdf for a BSDF ray from `from` hitting emissive triangle (mesh, prim) at P.
  float triangle_pdf(int mesh, int prim, const Vec3 &from, const Vec3 &P, const Vec3 &Ng, const Vec3 &d) const;

 private:
  enum class Kind { Point, Sun, Spot, Area, Background, Triangle };
  struct Entry {
    Kind kind;
    Spectrum strength{0.0f};
    Vec3 co{0.0f}, dir{0.0f, 0.0f, -1.0f};
    float radius = 0.0f;
    float cos_half_angle = 1.0f;  // sun
    float sun_tan_radius = 0.0f;  // tan(angle / 2): the sun disk's radius at unit distance
    float sun_inv_area = 1.0f;
    float cos_half_spot = 0.0f, spot_smooth = 0.0f;
    Vec3 U{0.0f}, V{0.0f};  // area extents
    float area = 0.0f;
    bool round = false;
    bool use_camera = true;
    float tan_spread = 0.0f, normalize_spread = 1.0f;  // area light spread (Cycles 3.4 scene/light.cpp)
    int mesh = -1, prim = -1;
  };
  const scene::Scene &scene_;
  const ShaderSystem &shaders_;
  const std::vector<int> &mesh_shader_;
  std::vector<Entry> lights_;
  Distribution1D pick_;
  std::vector<std::vector<int>> triangle_light_;  // per mesh, per triangle: light index or -1
  int background_light_ = -1;
  // Environment importance map.
  int env_w_ = 0, env_h_ = 0;
  std::vector<Distribution1D> env_rows_;
  Distribution1D env_marginal_;

  float pick_probability(int i) const { return pick_.probability(i); }
  float spot_attenuation(const Entry &l, const Vec3 &dir_from_light) const;
  static float spread_attenuation(const Entry &l, float cos_to_normal);
  Spectrum triangle_emission(const Entry &l, const scene::SurfacePoint &s, const Vec3 &wi_toward_viewer) const;
  void build_environment_map();
  float environment_pdf(const Vec3 &d) const;
};

}  // namespace glimmer::render
