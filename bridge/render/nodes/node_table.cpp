// One row per node type evaluated per shading point: XML name, input sockets with
// Cycles 3.4's defaults, output sockets, settings reader and eval function. The
// support table in docs/scene-format.md lists the same rows (`glimmer describe
// --nodes` prints them from here).
#include <algorithm>

#include "render/nodes/families.h"

namespace glimmer::render::nodes {

namespace {
constexpr SocketType F = SocketType::Float, C = SocketType::Color, V = SocketType::Vector;
const SocketDecl kTextureVector{"vector", V, Vec3(0.0f), Implicit::Generated};
const SocketDecl kNormalInput{"normal", V, Vec3(0.0f), Implicit::Normal};
}  // namespace

const std::vector<NodeDef> &node_table() {
  static const std::vector<NodeDef> table = {
      {"noise_texture",
       {kTextureVector, {"w", F}, {"scale", F, Vec3(5.0f)}, {"detail", F, Vec3(2.0f)}, {"roughness", F, Vec3(0.5f)},
        {"distortion", F}},
       {{"fac", F}, {"color", C}},
       configure_noise, eval_noise,
       "supported: Perlin fBM as Cycles 3.4 (lookup3 hash, gradients, scales), 1D-4D, detail/roughness/distortion"},
      {"voronoi_texture",
       {kTextureVector, {"w", F}, {"scale", F, Vec3(5.0f)}, {"smoothness", F, Vec3(1.0f)},
        {"exponent", F, Vec3(0.5f)}, {"randomness", F, Vec3(1.0f)}},
       {{"distance", F}, {"color", C}, {"position", V}, {"w", F}, {"radius", F}},
       configure_voronoi, eval_voronoi,
       "supported: 1D-4D; f1, f2, smooth_f1, distance_to_edge, n_sphere_radius; euclidean, manhattan, chebychev, "
       "minkowski"},
      {"musgrave_texture",
       {kTextureVector, {"w", F}, {"scale", F, Vec3(5.0f)}, {"detail", F, Vec3(2.0f)}, {"dimension", F, Vec3(2.0f)},
        {"lacunarity", F, Vec3(2.0f)}, {"offset", F}, {"gain", F, Vec3(1.0f)}},
       {{"fac", F}},
       configure_musgrave, eval_musgrave,
       "supported: fBM, multifractal, hybrid/ridged multifractal, hetero terrain, 1D-4D"},
      {"wave_texture",
       {kTextureVector, {"scale", F, Vec3(5.0f)}, {"distortion", F}, {"detail", F, Vec3(2.0f)},
        {"detail_scale", F, Vec3(1.0f)}, {"detail_roughness", F, Vec3(0.5f)}, {"phase_offset", F}},
       {{"color", C}, {"fac", F}},
       configure_wave, eval_wave, "supported: bands/rings, all directions, sine/saw/tri profiles, noise distortion"},
      {"rgb_ramp",
       {{"fac", F}},
       {{"color", C}, {"alpha", F}},
       configure_color_ramp, eval_color_ramp,
       "supported: Cycles' table form (`ramp` RGB triples, `ramp_alpha`, `interpolate`); Blender bakes its stops "
       "and interpolation mode into that table"},
      {"math",
       {{"value1", F, Vec3(0.5f)}, {"value2", F, Vec3(0.5f)}, {"value3", F}},
       {{"value", F}},
       configure_math, eval_math,
       "supported: all 40 operations of Cycles 3.4 with its safe conventions, use_clamp; Inf/NaN results are 0"},
      {"vector_math",
       {{"vector1", V}, {"vector2", V}, {"vector3", V}, {"scale", F, Vec3(1.0f)}},
       {{"vector", V}, {"value", F}},
       configure_vector_math, eval_vector_math,
       "supported: all 27 operations; reflect/refract/normalize of a zero vector give 0 (Cycles: NaN)"},
      {"mix",
       {{"fac", F, Vec3(0.5f)}, {"color1", C}, {"color2", C}},
       {{"color", C}},
       configure_mix_rgb, eval_mix_rgb, "supported: all 18 blend modes of MixRGB, use_clamp"},
      {"hsv",
       {{"hue", F, Vec3(0.5f)}, {"saturation", F, Vec3(1.0f)}, {"value", F, Vec3(1.0f)}, {"fac", F, Vec3(1.0f)},
        {"color", C}},
       {{"color", C}},
       nullptr, eval_hsv, "supported"},
      {"mapping",
       {{"vector", V}, {"location", V}, {"rotation", V}, {"scale", V, Vec3(1.0f)}},
       {{"vector", V}},
       configure_mapping, eval_mapping, "supported: point, texture, vector, normal; XYZ Euler rotation"},
      {"texture_coordinate",
       {},
       {{"generated", V},
        {"normal", V, Vec3(0.0f), Implicit::None, "the world-space shading normal (Cycles: object space)"},
        {"uv", V},
        {"object", V, Vec3(0.0f), Implicit::None, "the world-space position (Cycles: object space)"},
        {"camera", V},
        {"window", V, Vec3(0.0f), Implicit::None, "not supported: reads 0"},
        {"reflection", V}},
       nullptr, eval_texture_coordinate,
       "approximated: generated, uv, camera, reflection as Cycles; normal and object in world space (meshes are "
       "stored in world space); window unsupported (0, warned)"},
      {"fresnel", {{"ior", F, Vec3(1.45f)}, kNormalInput}, {{"fac", F}}, nullptr, eval_fresnel, "supported"},
      {"layer_weight",
       {{"blend", F, Vec3(0.5f)}, kNormalInput},
       {{"fresnel", F}, {"facing", F}},
       nullptr, eval_layer_weight, "supported"},
      {"light_path",
       {},
       {{"is_camera_ray", F}, {"is_shadow_ray", F}, {"is_diffuse_ray", F}, {"is_glossy_ray", F},
        {"is_singular_ray", F}, {"is_reflection_ray", F}, {"is_transmission_ray", F},
        {"is_volume_scatter_ray", F, Vec3(0.0f), Implicit::None, "always 0 (no volumes)"}, {"ray_length", F},
        {"ray_depth", F}, {"diffuse_depth", F}, {"glossy_depth", F}, {"transparent_depth", F},
        {"transmission_depth", F}},
       nullptr, eval_light_path,
       "supported at shading points of camera and scattered rays (shadow rays evaluate only transparency)"},
  };
  return table;
}

const NodeDef *find_node(const std::string &xml_name) {
  const auto &t = node_table();
  auto it = std::find_if(t.begin(), t.end(), [&](const NodeDef &d) { return xml_name == d.xml_name; });
  return it == t.end() ? nullptr : &*it;
}

}  // namespace glimmer::render::nodes
