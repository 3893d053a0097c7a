// One row per node type evaluated per shading point: XML name, input sockets with
// Cycles 3.4's defaults, output sockets, settings reader and eval function. The
// support table in docs/scene-format.md lists the same rows (`glimmer describe
// --nodes` prints them from here).
#include <algorithm>
#include <cstdio>

#include "render/nodes/families.h"

namespace glimmer::render::nodes {

namespace {
std::string format_float(float v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", static_cast<double>(v));
  return buf;
}
constexpr SocketType F = SocketType::Float, C = SocketType::Color, V = SocketType::Vector;
const SocketDecl kTextureVector{"vector", V, Vec3(0.0f), Implicit::Generated};
const SocketDecl kNormalInput{"normal", V, Vec3(0.0f), Implicit::Normal};

// Procedural textures, the colour ramp, math, mixing and mapping.
void add_texture_and_math_rows(std::vector<NodeDef> &t) {
  const std::vector<NodeDef> rows = {
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
  };
  t.insert(t.end(), rows.begin(), rows.end());
}

// Input nodes (texture coordinate, geometry, fresnel, light path) and two more textures.
void add_input_rows(std::vector<NodeDef> &t) {
  const std::vector<NodeDef> rows = {
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
      {"geometry",
       {},
       {{"position", V},
        {"normal", V},
        {"tangent", V},
        {"true_normal", V},
        {"incoming", V},
        {"parametric", V, Vec3(0.0f), Implicit::None, "not supported: reads 0"},
        {"backfacing", F},
        {"pointiness", F, Vec3(0.0f), Implicit::None, "not supported (no pointiness attribute): reads 0"},
        {"random_per_island", F, Vec3(0.0f), Implicit::None, "not supported (no island attribute): reads 0"}},
       nullptr, eval_geometry,
       "supported: position, normal, tangent (radial about object z, as Cycles with generated coordinates), "
       "true_normal, incoming, backfacing; parametric, pointiness and random_per_island read 0 (warned)"},
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
      {"gradient_texture",
       {kTextureVector},
       {{"color", C}, {"fac", F}},
       configure_gradient, eval_gradient, "supported: all 7 gradient types"},
      {"white_noise_texture",
       {kTextureVector, {"w", F}},
       {{"value", F}, {"color", C}},
       configure_white_noise, eval_white_noise, "supported: 1D-4D"},
  };
  t.insert(t.end(), rows.begin(), rows.end());
}

// Converters, the shading normal / tangent nodes and the sky texture.
void add_converter_normal_and_sky_rows(std::vector<NodeDef> &t) {
  const std::vector<NodeDef> rows = {
      {"value", {}, {{"value", F}}, configure_value, eval_value, "supported (`value` attribute)"},
      {"color", {}, {{"color", C}}, configure_value, eval_value, "supported (`value` attribute, RGB)"},
      {"invert", {{"fac", F, Vec3(1.0f)}, {"color", C}}, {{"color", C}}, nullptr, eval_invert, "supported"},
      {"gamma", {{"color", C}, {"gamma", F, Vec3(1.0f)}}, {{"color", C}}, nullptr, eval_gamma, "supported"},
      {"brightness_contrast",
       {{"color", C}, {"bright", F}, {"contrast", F}},
       {{"color", C}},
       nullptr, eval_brightness_contrast, "supported"},
      {"clamp",
       {{"value", F, Vec3(1.0f)}, {"min", F}, {"max", F, Vec3(1.0f)}},
       {{"result", F}},
       configure_clamp, eval_clamp, "supported: minmax, range"},
      {"map_range",
       {{"value", F, Vec3(1.0f)}, {"from_min", F}, {"from_max", F, Vec3(1.0f)}, {"to_min", F},
        {"to_max", F, Vec3(1.0f)}, {"steps", F, Vec3(4.0f)}},
       {{"result", F}},
       configure_map_range, eval_map_range, "supported: float; linear, stepped, smoothstep, smootherstep; clamp"},
      {"separate_xyz", {{"vector", V}}, {{"x", F}, {"y", F}, {"z", F}}, nullptr, eval_separate, "supported"},
      {"combine_xyz", {{"x", F}, {"y", F}, {"z", F}}, {{"vector", V}}, nullptr, eval_combine, "supported"},
      {"separate_rgb", {{"color", C}}, {{"r", F}, {"g", F}, {"b", F}}, nullptr, eval_separate, "supported"},
      {"combine_rgb", {{"r", F}, {"g", F}, {"b", F}}, {{"image", C}}, nullptr, eval_combine, "supported"},
      {"rgb_to_bw", {{"color", C}}, {{"val", F}}, nullptr, eval_rgb_to_bw, "supported: Rec.709 luminance"},
      // Shading normal and tangent nodes (render/nodes/normal_nodes.cpp), feeding closures' normal/tangent sockets.
      {"bump",
       {{"strength", F, Vec3(1.0f)}, {"distance", F, Vec3(1.0f)}, {"height", F}, kNormalInput},
       {{"normal", V}},
       configure_bump, eval_bump,
       "supported: the height also at P + dPdx and P + dPdy (the ray footprint, as Cycles' bump copies of the "
       "height graph), Mikkelsen's surface gradient, strength, distance, invert, terminator fix; "
       "use_object_space measures in world space",
       2},
      {"displacement",
       {{"height", F}, {"midlevel", F, Vec3(0.5f)}, {"scale", F, Vec3(1.0f)}, kNormalInput},
       {{"displacement", V}},
       configure_displacement, eval_displacement,
       "supported: (height - midlevel) scale N, for the shader's displacement output (rendered as bump); object "
       "space measured in world space (meshes are stored in world space)"},
      {"normal_map",
       {{"strength", F, Vec3(1.0f)}, {"color", C, Vec3(0.5f, 0.5f, 1.0f)}},
       {{"normal", V}},
       configure_normal_map, eval_normal_map,
       "approximated: tangent space with the UV map's per-vertex tangents and sign (MikkTSpace-like, "
       "scene/uv_tangents.h; no UV map: the unperturbed normal, as Cycles); object, world and Blender's "
       "object/world spaces as Cycles; strength, terminator fix"},
      {"tangent",
       {},
       {{"tangent", V}},
       configure_tangent, eval_tangent,
       "supported: uv_map (the UV map's per-vertex tangent; dP/du without UVs) or radial X/Y/Z about "
       "generated coordinates turned with the object, in the normal's plane"},
      // Sky texture (render/nodes/sky.cpp, sky_model.cpp).
      {"sky_texture",
       {kTextureVector},
       {{"color", C}},
       configure_sky, eval_sky,
       "supported: nishita (single scattering precomputed per node into a 512 x 128 table, sun disc analytic "
       "and importance-sampled by the world light when the vector is unlinked), preetham; hosek_wilkie "
       "approximated by preetham (warned); texture mapping attributes unsupported"},
  };
  t.insert(t.end(), rows.begin(), rows.end());
}

}  // namespace

const std::vector<NodeDef> &node_table() {
  static const std::vector<NodeDef> table = [] {
    std::vector<NodeDef> t;
    add_texture_and_math_rows(t);
    add_input_rows(t);
    add_converter_normal_and_sky_rows(t);
    return t;
  }();
  return table;
}

const std::vector<UnsupportedNode> &unsupported_nodes() {
  static const std::vector<UnsupportedNode> list = {
      {"brick_texture", "the input keeps its constant (warned)"},
      {"magic_texture", "the input keeps its constant (warned)"},
      {"ies_texture", "the input keeps its constant (warned)"},
      {"point_density_texture", "the input keeps its constant (warned)"},
      {"normal", "the input keeps its constant (warned)"},
      {"uvmap", "the input keeps its constant (warned); use texture_coordinate uv"},
      {"attribute", "the input keeps its constant (warned)"},
      {"object_info", "the input keeps its constant (warned)"},
      {"vertex_color", "the input keeps its constant (warned)"},
      {"rgb_curves", "the input keeps its constant (warned)"},
      {"vector_curves", "the input keeps its constant (warned)"},
      {"float_curve", "the input keeps its constant (warned)"},
      {"vector_rotate", "the input keeps its constant (warned)"},
      {"vector_transform", "the input keeps its constant (warned)"},
      {"mix_color", "the input keeps its constant (warned); `mix` (MixRGB) is supported"},
      {"mix_float", "the input keeps its constant (warned)"},
      {"mix_vector", "the input keeps its constant (warned)"},
      {"separate_color", "the input keeps its constant (warned); separate_rgb is supported"},
      {"combine_color", "the input keeps its constant (warned); combine_rgb is supported"},
      {"separate_hsv", "the input keeps its constant (warned)"},
      {"combine_hsv", "the input keeps its constant (warned)"},
      {"blackbody", "the input keeps its constant (warned)"},
      {"wavelength", "the input keeps its constant (warned)"},
      {"wireframe", "the input keeps its constant (warned)"},
      {"bevel", "the input keeps its constant (warned)"},
      {"ambient_occlusion", "the input keeps its constant (warned)"},
      {"camera_info", "the input keeps its constant (warned)"},
      {"light_falloff", "the input keeps its constant (warned)"},
      {"particle_info", "the input keeps its constant (warned)"},
      {"hair_info", "the input keeps its constant (warned)"},
      {"vector_displacement", "ignored (warned)"},
  };
  return list;
}

std::string support_table_markdown() {
  std::string out = "| Node | Inputs (default) | Outputs | Support |\n|---|---|---|---|\n";
  auto sockets = [](const std::vector<SocketDecl> &list, bool defaults) {
    std::string s;
    for (const SocketDecl &d : list) {
      s += (s.empty() ? "" : ", ") + std::string("`") + d.name + "`";
      if (!defaults) continue;
      if (d.implicit == Implicit::Generated) s += " (generated)";
      else if (d.implicit == Implicit::Normal) s += " (N)";
      else if (d.type == SocketType::Float) s += " (" + format_float(d.default_value.x) + ")";
      else s += " (" + format_float(d.default_value.x) + " " + format_float(d.default_value.y) + " " +
                format_float(d.default_value.z) + ")";
    }
    return s.empty() ? std::string("-") : s;
  };
  for (const NodeDef &d : node_table())
    out += std::string("| `") + d.xml_name + "` | " + sockets(d.inputs, true) + " | " + sockets(d.outputs, false) +
           " | " + d.support + " |\n";
  for (const UnsupportedNode &u : unsupported_nodes())
    out += std::string("| `") + u.xml_name + "` | | | unsupported: " + u.fallback + " |\n";
  return out;
}

const NodeDef *find_node(const std::string &xml_name) {
  const auto &t = node_table();
  auto it = std::find_if(t.begin(), t.end(), [&](const NodeDef &d) { return xml_name == d.xml_name; });
  return it == t.end() ? nullptr : &*it;
}

}  // namespace glimmer::render::nodes
