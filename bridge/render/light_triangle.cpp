#include "render/light_triangle.h"

#include <cmath>

namespace glimmer::render {

TriangleLight::TriangleLight(const scene::Mesh &mesh, int prim, float area, const ShaderSystem &shaders, int shader)
    : mesh_(&mesh), prim_(prim), area_(area), shaders_(&shaders), shader_(shader) {}

std::optional<float> TriangleLight::power() const {
  const Spectrum L = emission(mesh_->surface_at(prim_, 1.0f / 3.0f, 1.0f / 3.0f), Vec3(0, 0, 1));
  if (is_zero(L)) return std::nullopt;
  return kPi * area_ * luminance(L);
}

Spectrum TriangleLight::emission(const scene::SurfacePoint &s, const Vec3 &wi_toward_viewer) const {
  TexCoords tc;
  tc.P = s.P;
  tc.generated = s.generated;
  const Vec3 Ng = s.Ng;
  tc.N = Ng;
  tc.uv[0] = s.uv[0];
  tc.uv[1] = s.uv[1];
  tc.direction = -wi_toward_viewer;
  tc.path.camera = false;  // Light Path node: Cycles evaluates sampled emission with PATH_RAY_EMISSION only
  ClosureSet cs;
  shaders_->evaluate(shader_, tc, cs);
  GlimmerShadingContext ctx{};
  ctx.struct_size = sizeof(GlimmerShadingContext);
  ctx.wi = wi_toward_viewer;
  ctx.P = tc.P;
  ctx.N = dot(Ng, wi_toward_viewer) >= 0.0f ? Ng : -Ng;
  ctx.Ng = ctx.N;
  ctx.T = Frame::from_normal(Vec3(ctx.N)).s;
  ctx.uv[0] = tc.uv[0];
  ctx.uv[1] = tc.uv[1];
  Spectrum L(0.0f);
  for (int i = 0; i < cs.count; ++i)
    if (cs.closures[i].leaf->emissive) L += cs.closures[i].leaf->instance->emit(ctx) * cs.closures[i].weight;
  return L;
}

bool TriangleLight::sample(float u, float v, const Vec3 &P, float pick, LightSample &out) const {
  float b1 = u, b2 = v;
  if (b1 + b2 > 1.0f) { b1 = 1.0f - b1; b2 = 1.0f - b2; }
  const scene::SurfacePoint surface = mesh_->surface_at(prim_, b1, b2);
  const Vec3 to = surface.P - P;
  const float d2 = length_squared(to), d = std::sqrt(d2);
  if (!(d > 0.0f)) return false;
  out.wi = to / d;
  const float cos_l = std::fabs(dot(out.wi, surface.Ng));
  if (cos_l <= kMinCos) return false;
  out.dist = d;
  out.pdf = solid_angle_pdf(pick, d2, cos_l);
  out.radiance = emission(surface, -out.wi);
  out.delta = false;
  return !is_zero(out.radiance);
}

float TriangleLight::pdf(float pick, const Vec3 &from, const Vec3 &P, const Vec3 &Ng, const Vec3 &d) const {
  const float d2 = length_squared(P - from);
  const float cos_l = std::fabs(dot(d, Ng));
  if (cos_l <= kMinCos) return 0.0f;
  return solid_angle_pdf(pick, d2, cos_l);
}

}  // namespace glimmer::render
