// An emissive mesh triangle (Cycles' kernel/light/triangle.h): radiance from the
// mesh's emission closures (color * strength) evaluated at the sampled point, the
// point sampled uniformly by area: pdf = t^2 / (|cos| A). A BSDF ray finds the
// triangle through the BVH; the path loop asks pdf() for its MIS weight.
#pragma once

#include <optional>

#include "render/light_common.h"
#include "render/shader_system.h"
#include "scene/scene.h"

namespace glimmer::render {

class TriangleLight {
 public:
  // Triangle `prim` of `mesh`, shaded by compiled shader `shader`.
  TriangleLight(const scene::Mesh &mesh, int prim, float area, const ShaderSystem &shaders, int shader);
  // Power of the radiance at the centroid over the triangle's area; none when it emits nothing there.
  std::optional<float> power() const;
  bool sample(float u, float v, const Vec3 &P, float pick, LightSample &out) const;
  // Solid-angle density of point P (geometric normal Ng) reached from `from` along d: the pdf sample() gives.
  float pdf(float pick, const Vec3 &from, const Vec3 &P, const Vec3 &Ng, const Vec3 &d) const;
  // Radiance of the emission closures at surface point s toward wi_toward_viewer.
  Spectrum emission(const scene::SurfacePoint &s, const Vec3 &wi_toward_viewer) const;

 private:
  static constexpr float kMinCos = 1e-7f;  // grazing: no density
  float solid_angle_pdf(float pick, float dist2, float cos_l) const {
    return area_to_solid_angle_pdf(pick, dist2, cos_l, area_);
  }

  const scene::Mesh *mesh_;
  int prim_;
  float area_;
  const ShaderSystem *shaders_;
  int shader_;
};

}  // namespace glimmer::render
