// The texture/utility nodes feeding one closure input, compiled into a flat program:
// one step per node (shared nodes once), in dependency order, each reading its inputs
// from constants, earlier steps' outputs (registers), the shading point's implicit
// coordinates, or "external" inputs (nodes outside the table, such as image and
// checker textures, which the shader system evaluates). Run per shading point.
#pragma once

#include <array>
#include <cmath>
#include <functional>
#include <string>
#include <vector>

#include "render/nodes/node.h"
#include "render/nodes/sky_model.h"
#include "scene/scene.h"

namespace glimmer::render::nodes {

struct Operand {
  enum class Kind : uint8_t { Constant, Register, Implicit, External } kind = Kind::Constant;
  SocketType from = SocketType::Float, to = SocketType::Float;
  Implicit implicit = Implicit::None;
  int index = 0;  // register or external input
  Vec3 value{0.0f};
};

// Cycles' implicit conversions between socket types: colour -> float is the
// luminance, vector -> float the average, float -> colour/vector all three
// channels; colour <-> vector keep the values.
inline Vec3 convert(const Vec3 &v, SocketType from, SocketType to) {
  if (to != SocketType::Float || from == SocketType::Float) return v;
  return Vec3(from == SocketType::Color ? luminance(v) : average(v));
}

class NodeProgram {
 public:
  static constexpr int kMaxRegisters = 256;
  static constexpr int kMaxInputs = 16;

  // The value of the linked output at `sp` (a float output in all three channels).
  // `external(id, sp)` evaluates an external input.
  template <typename External>
  Vec3 eval(const ShadingPoint &sp, External &&external) const;

  int step_count() const { return static_cast<int>(steps_.size()); }
  // The sun discs of the sky textures that read the shading point's own direction (vector input
  // unlinked): for the world, directions the background light samples explicitly.
  std::vector<SunDisc> sun_discs() const;

 private:
  friend class ProgramBuilder;
  struct Step {
    const NodeDef *def = nullptr;
    NodeSettings settings;
    std::vector<Operand> inputs;
    int out_base = 0;
    uint8_t at = 0;  // evaluated at the point (0) or one footprint step along x (1) / y (2): Bump's height
  };
  std::vector<Step> steps_;
  Operand result_;
  int registers_ = 0;
  bool reads_camera_ = false;
  bool offsets_ = false;  // some step runs at an offset point (a Bump node's height)
  std::array<float, 12> world_to_camera_{};

  template <typename External>
  Vec3 run(const ShadingPoint *const at[3], External &external) const;

  template <typename External>
  static Vec3 read(const Operand &o, const Vec3 *regs, const ShadingPoint &sp, External &external) {
    Vec3 v;
    switch (o.kind) {
      case Operand::Kind::Constant: return o.value;
      case Operand::Kind::Register: v = regs[o.index]; break;
      case Operand::Kind::Implicit: v = o.implicit == Implicit::Normal ? sp.N : sp.generated; break;
      case Operand::Kind::External: v = external(o.index, sp); break;
    }
    return convert(v, o.from, o.to);
  }
};

template <typename External>
Vec3 NodeProgram::eval(const ShadingPoint &point, External &&external) const {
  ShadingPoint with_camera;
  const ShadingPoint *sp = &point;
  if (reads_camera_) {
    with_camera = point;
    with_camera.world_to_camera = world_to_camera_.data();
    sp = &with_camera;
  }
  if (!offsets_) {
    const ShadingPoint *const at[3] = {sp, sp, sp};
    return run(at, external);
  }
  const ShadingPoint dx = sp->offset(1), dy = sp->offset(2);
  const ShadingPoint *const at[3] = {sp, &dx, &dy};
  return run(at, external);
}

template <typename External>
Vec3 NodeProgram::run(const ShadingPoint *const at[3], External &external) const {
  // Registers are written before they are read (steps in dependency order): raw storage, not 256
  // zero-initialised Vec3 per evaluation (that zeroing cost as much as a cheap node).
  alignas(Vec3) unsigned char storage[sizeof(Vec3) * kMaxRegisters];
  Vec3 *regs = reinterpret_cast<Vec3 *>(storage);
  Vec3 in[kMaxInputs];
  for (const Step &s : steps_) {
    const ShadingPoint &p = *at[s.at];
    for (size_t i = 0; i < s.inputs.size(); ++i) in[i] = read(s.inputs[i], regs, p, external);
    s.def->eval(s.settings, p, in, regs + s.out_base);
  }
  // Huge or non-finite inputs (a scale of 1e30, an Inf from a division the node does not guard) end as 0 here.
  const Vec3 r = read(result_, regs, *at[0], external);
  return {std::isfinite(r.x) ? r.x : 0.0f, std::isfinite(r.y) ? r.y : 0.0f, std::isfinite(r.z) ? r.z : 0.0f};
}

// What the shader system provides while compiling.
struct BuildHooks {
  // A link from a node the table does not hold: the id of an external input (and its
  // output type), or -1 when that node is not supported either (already warned).
  std::function<int(const scene::ShaderLink &, SocketType &type)> external;
  std::function<void(const scene::SourceLocation &, const std::string &)> warn;
  std::array<float, 12> camera_to_world{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};  // 3x4 row-major
};

// Compiles the table nodes behind `link` (whose from_node is a table node). Throws
// scene::SceneError (file:line) for unknown sockets, bad values or settings.
NodeProgram compile_program(const scene::ShaderGraph &g, const scene::ShaderLink &link, const BuildHooks &hooks);

// Socket names compare as Cycles' XML reader does: case-insensitive, ignoring
// spaces (and underscores, so `detail_scale` and `DetailScale` both match).
std::string socket_key(const std::string &name);

}  // namespace glimmer::render::nodes
