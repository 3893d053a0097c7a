// Mapping node (Cycles 3.4 svm_mapping): point / texture / vector / normal mappings
// with location, XYZ Euler rotation (R = Rz Ry Rx, Cycles' euler_to_transform) and scale.
#include "render/nodes/families.h"
#include "render/nodes/math_util.h"

namespace glimmer::render::nodes {

namespace {

enum Type { kPoint, kTexture, kVector, kNormal };

struct Rotation {
  Vec3 row[3];
  Vec3 apply(const Vec3 &v) const { return {dot(row[0], v), dot(row[1], v), dot(row[2], v)}; }
  Vec3 apply_transposed(const Vec3 &v) const { return row[0] * v.x + row[1] * v.y + row[2] * v.z; }
};

Rotation euler_rotation(const Vec3 &e) {
  const float cx = std::cos(e.x), cy = std::cos(e.y), cz = std::cos(e.z);
  const float sx = std::sin(e.x), sy = std::sin(e.y), sz = std::sin(e.z);
  return {{Vec3(cy * cz, sy * sx * cz - cx * sz, sy * cx * cz + sx * sz),
           Vec3(cy * sz, sy * sx * sz + cx * cz, sy * cx * sz - sx * cz), Vec3(-sy, cy * sx, cy * cx)}};
}

}  // namespace

void configure_mapping(const SettingsReader &r, NodeSettings &s) {
  s.mode[0] = r.choice("mapping_type", {"point", "texture", "vector", "normal"}, kPoint);
}

// in: vector, location, rotation, scale; out: vector.
void eval_mapping(const NodeSettings &s, const ShadingPoint &, const Vec3 *in, Vec3 *out) {
  const Vec3 &v = in[0], &location = in[1], &scale = in[3];
  const Rotation r = euler_rotation(in[2]);
  Vec3 result;
  switch (s.mode[0]) {
    case kPoint: result = r.apply(v * scale) + location; break;
    case kTexture: result = safe::divide(r.apply_transposed(v - location), scale); break;
    case kVector: result = r.apply(v * scale); break;
    default: result = safe::normalize(r.apply(safe::divide(v, scale))); break;
  }
  out[0] = finite_or_zero(result);
}

}  // namespace glimmer::render::nodes
