// Nodes that read the shading point itself: Texture Coordinate (Cycles 3.4
// svm_node_tex_coord), Fresnel and Layer Weight (svm_node_fresnel /
// svm_node_layer_weight, Fresnel of a dielectric from cos = I.N) and Light Path
// (svm_node_light_path: the kind of ray that reached the point, its length, depths).
#include "render/nodes/families.h"
#include "render/nodes/math_util.h"

namespace glimmer::render::nodes {

namespace {

// Unpolarised Fresnel reflectance of a dielectric with relative IOR eta (Cycles'
// fresnel_dielectric_cos); 1 under total internal reflection.
float fresnel_dielectric_cos(float cos_i, float eta) {
  const float c = std::fabs(cos_i);
  float g = eta * eta - 1.0f + c * c;
  if (g <= 0.0f) return 1.0f;
  g = std::sqrt(g);
  const float a = (g - c) / (g + c);
  const float b = (c * (g + c) - 1.0f) / (c * (g - c) + 1.0f);
  return 0.5f * a * a * (1.0f + b * b);
}

Vec3 transform_point(const float *m, const Vec3 &p) {
  return {m[0] * p.x + m[1] * p.y + m[2] * p.z + m[3], m[4] * p.x + m[5] * p.y + m[6] * p.z + m[7],
          m[8] * p.x + m[9] * p.y + m[10] * p.z + m[11]};
}

}  // namespace

// out: generated, normal, uv, object, camera, window, reflection.
void eval_texture_coordinate(const NodeSettings &, const ShadingPoint &sp, const Vec3 *, Vec3 *out) {
  out[0] = sp.generated;
  out[1] = sp.N;
  out[2] = Vec3(sp.uv[0], sp.uv[1], 0.0f);
  out[3] = sp.P;
  out[4] = sp.world_to_camera ? transform_point(sp.world_to_camera, sp.P) : sp.P;
  out[5] = Vec3(0.0f);
  out[6] = 2.0f * dot(sp.N, sp.I()) * sp.N - sp.I();
}

// in: ior, normal; out: fac.
void eval_fresnel(const NodeSettings &, const ShadingPoint &sp, const Vec3 *in, Vec3 *out) {
  float eta = std::fmax(in[0].x, 1e-5f);
  eta = sp.backfacing ? 1.0f / eta : eta;
  out[0] = Vec3(fresnel_dielectric_cos(dot(sp.I(), in[1]), eta));
}

// in: blend, normal; out: fresnel, facing.
void eval_layer_weight(const NodeSettings &, const ShadingPoint &sp, const Vec3 *in, Vec3 *out) {
  const float blend = in[0].x;
  const float cos_i = dot(sp.I(), in[1]);
  float eta = std::fmax(1.0f - blend, 1e-5f);
  eta = sp.backfacing ? eta : 1.0f / eta;
  out[0] = Vec3(fresnel_dielectric_cos(cos_i, eta));
  const float b = clamp(blend, 0.0f, 0.99999f);
  float facing = std::fabs(cos_i);
  if (b != 0.5f) facing = std::pow(facing, b < 0.5f ? 2.0f * b : 0.5f / (1.0f - b));
  out[1] = Vec3(1.0f - facing);
}

// out: is_camera_ray, is_shadow_ray, is_diffuse_ray, is_glossy_ray, is_singular_ray, is_reflection_ray,
// is_transmission_ray, is_volume_scatter_ray, ray_length, ray_depth, diffuse_depth, glossy_depth,
// transparent_depth, transmission_depth.
void eval_light_path(const NodeSettings &, const ShadingPoint &sp, const Vec3 *, Vec3 *out) {
  const PathInfo &p = sp.path;
  auto flag = [](bool b) { return Vec3(b ? 1.0f : 0.0f); };
  out[0] = flag(p.camera);
  out[1] = flag(p.shadow);
  out[2] = flag(p.diffuse);
  out[3] = flag(p.glossy);
  out[4] = flag(p.singular);
  out[5] = flag(p.reflection);
  out[6] = flag(p.transmission);
  out[7] = flag(false);
  out[8] = Vec3(p.ray_length);
  out[9] = Vec3(static_cast<float>(p.depth));
  out[10] = Vec3(static_cast<float>(p.diffuse_depth));
  out[11] = Vec3(static_cast<float>(p.glossy_depth));
  out[12] = Vec3(static_cast<float>(p.transparent_depth));
  out[13] = Vec3(static_cast<float>(p.transmission_depth));
}

}  // namespace glimmer::render::nodes
