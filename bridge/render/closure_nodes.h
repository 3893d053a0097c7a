// Cycles closure nodes -> DSO closures, as data: one row per Cycles node
// (closure, socket -> parameter, default, clamp, weight socket). The shader
// system builds every closure leaf from these rows in one loop
// (ShaderSystem::make_leaf); `glimmer describe --json` prints them (key
// "nodes") and docs/scene-format.md's node table is generated from that
// (tools/scene_format_tables.py, checked by the docs.scene_format_tables test).
#pragma once

#include <limits>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "glimmer/closure_abi.h"

namespace glimmer::host {
class PluginLibrary;
}

namespace glimmer::render {

enum class SocketRole {
  Weight,         // the closure weight: Cycles' colour input (may be textured)
  Strength,       // a constant scalar on the weight (emission strength)
  Param,          // a DSO parameter: the constant clamped to [min, max]; a link is evaluated per shading
                  // point when the closure declares the parameter varying (else it warns)
  SchemaParam,    // a DSO parameter given as text and validated by its schema (absent: the closure's default)
  ParamOrWeight,  // a DSO colour parameter, not varying: a link becomes the weight (the parameter is then 1)
  Normal,         // the closure's shading normal: a link (Bump, Normal Map, any vector) is evaluated per
                  // shading point; unlinked, the interpolated normal
  Tangent,        // the closure's tangent: a link (Tangent node, any vector) per shading point; unlinked, the
                  // UV map's dP/du, or for Cycles' anisotropic glossy the radial Z tangent (`radial_default`)
  Rotation,       // turns the tangent about the normal by value * 2 pi (constant or per shading point)
  Ignored,        // accepted without effect (a link warns)
  Unsupported,    // accepted; a value other than the default warns with `note` (a link warns)
};

struct SocketRow {
  const char *socket;
  SocketRole role;
  const char *param = nullptr;  // Param/SchemaParam/ParamOrWeight: the DSO parameter
  float default_value = 0.0f;   // Weight/Strength/Param/Unsupported: Cycles' socket default
  float min = -std::numeric_limits<float>::infinity(), max = std::numeric_limits<float>::infinity();  // Param clamp
  const char *alias = nullptr;  // another spelling read when `socket` is absent (glass `ior` for `IOR`)
  const char *note = nullptr;   // Unsupported: the warning (after "<node type>: ")
  bool radial_default = false;  // Tangent: unlinked, Cycles' default tangent (radial about generated Z)
};

enum class NodeKind {
  Closure,      // a DSO closure
  Transparent,  // host-side pass-through (transparent_bsdf)
  Fallback,     // not supported: grey (0.8) diffuse with a warning
  Holdout,      // no closure (black) with a warning
  Composite,    // expanded by the host into closure nodes of this table (principled_bsdf: render/principled.cpp)
};

struct ClosureNodeRow {
  const char *node;     // XML element (Cycles node name)
  NodeKind kind = NodeKind::Closure;
  const char *closure = nullptr;  // DSO closure
  const char *output = "bsdf";    // the node's output socket
  std::vector<SocketRow> sockets = {};  // empty with `schema`: the DSO closure's parameters are the sockets
  std::vector<std::pair<const char *, const char *>> fixed = {};  // {parameter, value} when the closure has it
  bool distribution = false;      // `distribution` attribute -> ggx|beckmann|multi_ggx|sharp; an unlinked
                                  // roughness of 0 selects sharp (Cycles' simplify_settings)
  bool bounce_tint = false;       // multi_ggx: a constant colour is also the closure's bounce_tint
  bool filter_glossy = false;     // blurred variants of `roughness` for filter_glossy
  bool fallback_diffuse = false;  // the DSO lacks the closure: diffuse with a warning (else an error)
  bool schema = false;            // sockets from the closure's schema (SchemaParam; a ParamOrWeight colour)
  const char *doc = "";
  const SocketRow *find(const std::string &socket) const;  // by name or alias
};

// The rows for the Cycles nodes the host maps itself.
const std::vector<ClosureNodeRow> &closure_node_rows();
const ClosureNodeRow *find_closure_node(const std::string &node);
const char *socket_role_name(SocketRole role);

// The row of a DSO closure used under its own name (`glint` or `glint_bsdf`): its
// schema parameters are the sockets; a linked colour becomes the weight.
ClosureNodeRow schema_row(const GlimmerClosureType &type, const char *node);

// The rows as JSON (`glimmer describe --json`, key "nodes"), schema rows with the plugin's
// parameters, every parameter socket with the closure's varying flag.
nlohmann::json describe_closure_nodes(const host::PluginLibrary &plugin);

}  // namespace glimmer::render
