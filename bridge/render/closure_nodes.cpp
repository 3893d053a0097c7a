#include "render/closure_nodes.h"

#include <cmath>

#include "cli/json_number.h"  // floats in their shortest decimal form
#include "host/closure_instance.h"
#include "host/plugin_library.h"
#include "render/principled.h"

namespace glimmer::render {

namespace {

using R = SocketRole;

// Sockets shared by Cycles' glossy/anisotropic, glass and refraction nodes.
std::vector<SocketRow> microfacet_sockets(float color, float roughness, std::vector<SocketRow> own) {
  std::vector<SocketRow> rows = {
      {.socket = "color", .role = R::Weight, .default_value = color},
      {.socket = "roughness", .role = R::Param, .param = "roughness", .default_value = roughness, .min = 0, .max = 1},
  };
  rows.insert(rows.end(), own.begin(), own.end());
  // Glimmer's extension: the Smith G model (`separable` as Cycles 3.4, which the Blender addon exports from 3.x).
  rows.push_back({.socket = "shadowing", .role = R::SchemaParam, .param = "shadowing"});
  rows.push_back({.socket = "normal", .role = R::Normal});
  rows.push_back({.socket = "surface_mix_weight", .role = R::Ignored});
  return rows;
}

const char *kConductorDoc =
    "the colour is the weight; multi_ggx: a constant colour is also bounce_tint (Cycles tints every "
    "bounce of its walk; a textured colour tints once and warns)";

// Cycles' glossy and anisotropic nodes (they differ in the anisotropy default).
ClosureNodeRow conductor_row(const char *node, float anisotropy) {
  return {.node = node,
          .closure = "microfacet_conductor",
          .sockets = microfacet_sockets(
              0.8f, 0.5f,
              {{.socket = "anisotropy", .role = R::Param, .param = "anisotropy", .default_value = anisotropy,
                .min = -1, .max = 1},
               {.socket = "rotation", .role = R::Rotation, .default_value = 0.0f},
               {.socket = "tangent", .role = R::Tangent, .radial_default = true}}),
          .fixed = {{"f0", "1"}},
          .distribution = true,
          .bounce_tint = true,
          .filter_glossy = true,
          .fallback_diffuse = true,
          .doc = kConductorDoc};
}

// Cycles' glass and refraction nodes (the refraction node has a tangent input, glass none).
ClosureNodeRow dielectric_row(const char *node, const char *mode, bool tangent, const char *doc) {
  std::vector<SocketRow> own = {
      {.socket = "IOR", .role = R::Param, .param = "ior", .default_value = 1.45f, .alias = "ior"}};
  if (tangent) own.push_back({.socket = "tangent", .role = R::Tangent});
  return {.node = node,
          .closure = "microfacet_dielectric",
          .sockets = microfacet_sockets(1.0f, 0.0f, own),
          .fixed = {{"mode", mode}},
          .distribution = true,
          .filter_glossy = true,
          .fallback_diffuse = true,
          .doc = doc};
}

}  // namespace

const SocketRow *ClosureNodeRow::find(const std::string &socket) const {
  for (const auto &s : sockets)
    if (socket == s.socket || (s.alias && socket == s.alias)) return &s;
  return nullptr;
}

const std::vector<ClosureNodeRow> &closure_node_rows() {
  static const std::vector<ClosureNodeRow> rows = {
      {.node = "diffuse_bsdf",
       .closure = "diffuse",
       .sockets = {{.socket = "color", .role = R::Weight, .default_value = 0.8f},
                   {.socket = "roughness",
                    .role = R::Unsupported,
                    .default_value = 0.0f,
                    .note = "Oren-Nayar roughness is not supported; Lambertian is used"},
                   {.socket = "normal", .role = R::Normal},
                   {.socket = "surface_mix_weight", .role = R::Ignored}},
       .fixed = {{"color", "1"}},
       .doc = "Lambertian; the colour is the weight"},
      conductor_row("glossy_bsdf", 0.0f),
      conductor_row("anisotropic_bsdf", 0.5f),
      dielectric_row("glass_bsdf", "glass", false, "reflection and refraction; the colour is the weight"),
      dielectric_row("refraction_bsdf", "refraction", true, "refraction only; the colour is the weight"),
      {.node = "transparent_bsdf",
       .kind = NodeKind::Transparent,
       .sockets = {{.socket = "color", .role = R::Weight, .default_value = 1.0f},
                   {.socket = "surface_mix_weight", .role = R::Ignored}},
       .doc = "host pass-through with weight colour; shadow rays pass through it too"},
      {.node = "emission",
       .closure = "emission",
       .output = "emission",
       .sockets = {{.socket = "color", .role = R::Weight, .default_value = 0.8f},
                   {.socket = "strength", .role = R::Strength, .default_value = 10.0f},
                   {.socket = "surface_mix_weight", .role = R::Ignored}},
       .fixed = {{"color", "1"}, {"strength", "1"}},
       .doc = "radiance colour * strength"},
      {.node = "glint_bsdf",
       .closure = "glint",
       .schema = true,
       .doc = "sockets are the closure's parameters (glimmer describe); a textured colour is the weight"},
      {.node = "frosted_glass_bsdf",
       .closure = "frosted_glass",
       .schema = true,
       .doc = "sockets are the closure's parameters (glimmer describe); a textured colour is the tint per interface "
              "crossing at each shading point, clamped to [0, 1] as a typed one"},
      {.node = "clearcoat_bsdf",
       .closure = "clearcoat",
       .sockets =
           {{.socket = "color", .role = R::Weight, .default_value = 1.0f},
            {.socket = "roughness", .role = R::Param, .param = "roughness", .default_value = 0.03f, .min = 0, .max = 1},
            {.socket = "normal", .role = R::Normal},
            {.socket = "surface_mix_weight", .role = R::Ignored}},
       .doc = "Cycles 3.4's Principled clearcoat lobe (GTR1, Fresnel 1.5 at the microfacet); the colour is the "
              "weight (principled_bsdf: 0.25 * clearcoat)"},
      {.node = "principled_diffuse_bsdf",
       .closure = "principled_diffuse",
       .schema = true,
       .doc = "Cycles 3.4's Principled diffuse (Burley, retro-reflection); a textured colour is the base colour at "
              "each shading point, clamped to [0, 1] as a typed one"},
      {.node = "principled_specular_bsdf",
       .closure = "principled_specular",
       .schema = true,
       .doc = "Cycles 3.4's Principled specular (GGX, Fresnel interpolated from cspec0 toward 1); sockets are the "
              "closure's parameters"},
      {.node = "principled_sheen_bsdf",
       .closure = "principled_sheen",
       .schema = true,
       .doc = "Cycles 3.4's Principled sheen (Burley 2012, Schlick weight at the half vector); sockets are the "
              "closure's parameters"},
      principled_row(),
      {.node = "holdout", .kind = NodeKind::Holdout, .output = "holdout", .doc = "not supported: no closure (black)"},
  };
  return rows;
}

// The row of a DSO closure used under its own name (`glint` or `glint_bsdf`): its
// schema parameters are the sockets. A linked `color` is the closure's own parameter, per shading point, where the
// closure declares it varying (frosted_glass: a tint per interface crossing, the same meaning as a typed colour;
// session 40: it had become the closure's weight, so a typed 0.5 and the same 0.5 from an RGB node rendered 0.311 vs
// 0.266 through a frosted sphere); else (glint's F0 colour, fixed per closure) the link becomes the weight.
ClosureNodeRow schema_row(const GlimmerClosureType &type, const char *node) {
  ClosureNodeRow row;
  row.node = node;
  row.closure = type.name;
  row.schema = true;
  for (uint32_t i = 0; i < type.param_count; ++i) {
    const GlimmerParamSpec &spec = host::param_at(type, i);
    const bool weight = std::string(spec.name) == "color" && spec.type == GLIMMER_PARAM_COLOR &&
                        !(host::param_flags(type, spec) & GLIMMER_PARAM_VARYING);
    row.sockets.push_back({.socket = spec.name,
                           .role = weight ? SocketRole::ParamOrWeight : SocketRole::SchemaParam,
                           .param = spec.name,
                           .default_value = 1.0f});
  }
  // Every DSO closure takes the shading frame from the host: normal and tangent sockets as Cycles' BSDFs.
  if (!row.find("normal")) row.sockets.push_back({.socket = "normal", .role = SocketRole::Normal});
  if (!row.find("tangent")) row.sockets.push_back({.socket = "tangent", .role = SocketRole::Tangent});
  return row;
}

const ClosureNodeRow *find_closure_node(const std::string &node) {
  for (const auto &row : closure_node_rows())
    if (node == row.node) return &row;
  return nullptr;
}

const char *socket_role_name(SocketRole role) {
  switch (role) {
    case R::Weight: return "weight";
    case R::Strength: return "strength";
    case R::Param: return "param";
    case R::SchemaParam: return "schema_param";
    case R::ParamOrWeight: return "param_or_weight";
    case R::Normal: return "normal";
    case R::Tangent: return "tangent";
    case R::Rotation: return "rotation";
    case R::Ignored: return "ignored";
    case R::Unsupported: return "unsupported";
  }
  return "?";
}

nlohmann::json describe_closure_nodes(const host::PluginLibrary &plugin) {
  nlohmann::json out = nlohmann::json::array();
  const char *kinds[] = {"closure", "transparent", "fallback", "holdout", "composite"};
  for (const ClosureNodeRow &table_row : closure_node_rows()) {
    const GlimmerClosureType *type = table_row.closure ? plugin.find(table_row.closure) : nullptr;
    ClosureNodeRow row = table_row.schema && type ? schema_row(*type, table_row.node) : table_row;
    row.doc = table_row.doc;
    nlohmann::json j;
    j["node"] = row.node;
    j["kind"] = kinds[static_cast<int>(row.kind)];
    j["closure"] = row.closure ? nlohmann::json(row.closure) : nlohmann::json(nullptr);
    j["in_plugin"] = type != nullptr;
    j["schema"] = row.schema;
    j["distribution"] = row.distribution;
    j["filter_glossy"] = row.filter_glossy;
    j["doc"] = row.doc;
    nlohmann::json fixed = nlohmann::json::object();
    for (const auto &[param, value] : row.fixed) fixed[param] = value;
    j["fixed"] = fixed;
    j["sockets"] = nlohmann::json::array();
    for (const SocketRow &s : row.sockets) {
      nlohmann::json sj;
      sj["socket"] = s.socket;
      sj["role"] = socket_role_name(s.role);
      if (s.alias) sj["alias"] = s.alias;
      if (s.param) {
        sj["param"] = s.param;
        const GlimmerParamSpec *spec = type ? host::find_param(*type, s.param) : nullptr;
        sj["varying"] = spec && (host::param_flags(*type, *spec) & GLIMMER_PARAM_VARYING) != 0;
      }
      if (s.radial_default) sj["radial_default"] = true;
      if (s.role == SocketRole::Weight || s.role == SocketRole::Strength || s.role == SocketRole::Param ||
          s.role == SocketRole::Unsupported || s.role == SocketRole::Rotation)
        sj["default"] = cli::json_float(s.default_value);
      if (s.role == SocketRole::Param) {
        sj["min"] = cli::json_float(s.min);  // null when unbounded
        sj["max"] = cli::json_float(s.max);
      }
      if (s.note) sj["note"] = s.note;
      j["sockets"].push_back(sj);
    }
    out.push_back(j);
  }
  return out;
}

}  // namespace glimmer::render
