// Cycles texture and utility nodes evaluated per shading point (docs/scene-format.md,
// "Texture and utility nodes"). One table row per node type (node_table.cpp): its XML
// name, input and output sockets with their Cycles 3.4 defaults, a configure function
// that reads the node's settings (enums, ramps) and an eval function. The shader
// system compiles the nodes feeding a closure input into a NodeProgram
// (node_program.h) and runs it at every shading point.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "glimmer/closure_abi.h"
#include "glimmer/math.h"
#include "scene/transform.h"

namespace glimmer::render::nodes {

// Cycles' socket types as far as values go: a float, or three floats (colour,
// vector, point, normal). A float socket's value is held in .x.
enum class SocketType : uint8_t { Float, Color, Vector };

// What an unlinked input reads when the file gives no value: its constant, or a
// coordinate of the shading point (Cycles' texture nodes default to generated
// coordinates, the Fresnel/Layer Weight normal to the shading normal).
enum class Implicit : uint8_t { None, Generated, Normal };

struct SocketDecl {
  const char *name;  // Cycles' socket name, lower case as in the XML
  SocketType type;
  Vec3 default_value{0.0f};
  Implicit implicit = Implicit::None;
  const char *caveat = nullptr;  // an output that only approximates Cycles: warned when linked
};

// The path through the shading point (Light Path node).
struct PathInfo {
  bool camera = true, shadow = false, diffuse = false, glossy = false, singular = false, reflection = false,
       transmission = false;
  float ray_length = 0.0f;
  int depth = 0, diffuse_depth = 0, glossy_depth = 0, transparent_depth = 0, transmission_depth = 0;
};

// The Light Path node's view of a path: `label` is the last scatter's GLIMMER_LABEL_* bits
// (GLIMMER_LABEL_NONE for a camera ray, transparent passes keep it), depths as Cycles counts them.
inline PathInfo path_info(uint32_t label, float ray_length, int depth, int diffuse_depth, int glossy_depth,
                          int transparent_depth, int transmission_depth) {
  PathInfo p;
  p.camera = label == GLIMMER_LABEL_NONE;
  p.diffuse = (label & GLIMMER_LABEL_DIFFUSE) != 0;
  p.glossy = (label & GLIMMER_LABEL_GLOSSY) != 0;
  p.singular = (label & GLIMMER_LABEL_SINGULAR) != 0;
  p.reflection = (label & GLIMMER_LABEL_REFLECT) != 0;
  p.transmission = (label & GLIMMER_LABEL_TRANSMIT) != 0;
  p.ray_length = ray_length;
  p.depth = depth;
  p.diffuse_depth = diffuse_depth;
  p.glossy_depth = glossy_depth;
  p.transparent_depth = transparent_depth;
  p.transmission_depth = transmission_depth;
  return p;
}

// Everything a node may read at a shading point (the renderer's TexCoords).
struct ShadingPoint {
  Vec3 P{0.0f};                      // world position
  Vec3 N{0.0f, 0.0f, 1.0f};          // shading normal (facing the incoming ray)
  Vec3 generated{0.0f};              // object bounding box, 0..1 (the direction for the world)
  float uv[2] = {0.0f, 0.0f};
  Vec3 direction{0.0f, 0.0f, 1.0f};  // ray direction (toward the point; Cycles' sd->I is its negation)
  bool backfacing = false;
  // The footprint of one pixel step in x and y (ray differentials on the surface; zero: unknown,
  // the finest detail): position, generated and uv derivatives, for filtered image lookups.
  Vec3 dPdx{0.0f}, dPdy{0.0f}, dgenerated_dx{0.0f}, dgenerated_dy{0.0f};
  float duv_dx[2] = {0.0f, 0.0f}, duv_dy[2] = {0.0f, 0.0f};
  PathInfo path;
  const float *world_to_camera = nullptr;  // 3x4 row-major (set by the node program; null: identity)
  // The surface around the point (Bump, Normal Map, Tangent): the geometric normal on N's side, the UV
  // map's dP/du and dP/dv, and one pixel step of the ray footprint (ray differentials) in P, uv and
  // generated coordinates (zero where the ray carries no differentials, e.g. shadow rays).
  Vec3 Ng{0.0f, 0.0f, 1.0f};
  Vec3 dPdu{1.0f, 0.0f, 0.0f}, dPdv{0.0f, 1.0f, 0.0f};
  Vec3 tangent{0.0f};       // the UV map's per-vertex tangent, interpolated (scene/uv_tangents.h); 0 without UVs
  float tangent_sign = 1.0f;  // its handedness
  const scene::Transform *object = nullptr;  // the object's transform (null: identity)
  Vec3 object_normal_to_world(const Vec3 &n) const { return object ? object->normal(n) : n; }
  // The Bump node's two offsets (Cycles' placement: make_orthonormals(Ng) scaled by the footprint width), in
  // P, uv and generated coordinates; the footprint above is the image filters', these are the bump's.
  Vec3 bump_dPdx{0.0f}, bump_dPdy{0.0f};
  float bump_duv_dx[2] = {0.0f, 0.0f}, bump_duv_dy[2] = {0.0f, 0.0f};
  Vec3 bump_dgenerated_dx{0.0f}, bump_dgenerated_dy{0.0f};
  Vec3 I() const { return -direction; }
  // The point one footprint step away along x (axis 1) or y (axis 2), where Cycles' Bump node evaluates
  // its height input a second and third time (its SHADER_BUMP_DX / _DY copies of the height graph).
  ShadingPoint offset(int axis) const {
    ShadingPoint s = *this;
    const bool x = axis == 1;
    s.P = P + (x ? bump_dPdx : bump_dPdy);
    s.uv[0] = uv[0] + (x ? bump_duv_dx[0] : bump_duv_dy[0]);
    s.uv[1] = uv[1] + (x ? bump_duv_dx[1] : bump_duv_dy[1]);
    s.generated = generated + (x ? bump_dgenerated_dx : bump_dgenerated_dy);
    return s;
  }
};

class SkyModel;  // sky_model.h

// A node's settings (enums and tables), read once by its configure function.
struct NodeSettings {
  int mode[4] = {0, 0, 0, 0};  // enum settings, per node type (e.g. dimensions, metric, feature)
  bool flag = false;           // use_clamp / interpolate
  std::vector<float> table;    // colour ramp: RGBA per entry
  std::shared_ptr<const SkyModel> sky;  // sky texture: the model precomputed for this node
};

// Reads a node's settings from its XML attributes; errors and warnings name the
// node's file:line.
class SettingsReader {
 public:
  virtual ~SettingsReader() = default;
  // The index of the attribute's value among `choices` (case-insensitive), or
  // `fallback` when the attribute is absent; an unknown value is an error.
  virtual int choice(const char *attribute, std::initializer_list<const char *> choices, int fallback) const = 0;
  virtual bool boolean(const char *attribute, bool fallback) const = 0;
  virtual std::vector<float> floats(const char *attribute) const = 0;  // empty when absent
  virtual std::string text(const char *attribute) const = 0;          // empty when absent
  virtual void warn(const std::string &message) const = 0;
  [[noreturn]] virtual void fail(const std::string &message) const = 0;
};

using ConfigureFn = void (*)(const SettingsReader &, NodeSettings &);
// in[i] holds input i (declared order), out[j] receives output j.
using EvalFn = void (*)(const NodeSettings &, const ShadingPoint &, const Vec3 *in, Vec3 *out);

struct NodeDef {
  const char *xml_name;
  std::vector<SocketDecl> inputs;
  std::vector<SocketDecl> outputs;
  ConfigureFn configure;  // may be null
  EvalFn eval;
  const char *support;    // one line for the support table: how it maps onto Cycles
  // An input also read one footprint step away along x and y (Bump's height): its two extra values
  // follow the declared inputs in `in`.
  int offset_input = -1;
};

// Every node type evaluated per shading point (node_table.cpp).
const std::vector<NodeDef> &node_table();
const NodeDef *find_node(const std::string &xml_name);

// Cycles value nodes the renderer does not evaluate, with their fallback.
struct UnsupportedNode {
  const char *xml_name;
  const char *fallback;
};
const std::vector<UnsupportedNode> &unsupported_nodes();

// The support table of docs/scene-format.md (`glimmer describe --nodes`), from the two lists above.
std::string support_table_markdown();

}  // namespace glimmer::render::nodes
