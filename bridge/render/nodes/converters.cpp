// Converter and colour nodes of Cycles 3.4 (svm_node_value, svm_node_invert, svm_node_gamma,
// svm_node_brightness, svm_node_clamp, svm_node_map_range, separate/combine XYZ and RGB,
// rgb_to_bw).
#include "render/nodes/families.h"
#include "render/nodes/math_util.h"

namespace glimmer::render::nodes {

namespace {
enum RangeType { kLinear, kStepped, kSmoothstep, kSmootherstep };

float smoothstep(float edge0, float edge1, float x) {
  if (x < edge0) return 0.0f;
  if (x >= edge1) return 1.0f;
  const float t = (x - edge0) / (edge1 - edge0);
  return (3.0f - 2.0f * t) * t * t;
}
float smootherstep(float edge0, float edge1, float x) {
  const float t = clamp(safe::divide(x - edge0, edge1 - edge0), 0.0f, 1.0f);
  return t * t * t * (t * (t * 6.0f - 15.0f) + 10.0f);
}
// clamp to [a, b] or [b, a], whichever is ordered
float clamp_either(float v, float a, float b) { return a > b ? clamp(v, b, a) : clamp(v, a, b); }
}  // namespace

void configure_value(const SettingsReader &r, NodeSettings &s) {
  const std::vector<float> v = r.floats("value");
  if (v.size() != 1 && v.size() != 3 && !v.empty()) r.fail("value: expected 1 or 3 numbers");
  s.table = v.empty() ? std::vector<float>{0.0f} : v;
}
// out: value (value node) or color (color node).
void eval_value(const NodeSettings &s, const ShadingPoint &, const Vec3 *, Vec3 *out) {
  out[0] = s.table.size() == 3 ? Vec3(s.table[0], s.table[1], s.table[2]) : Vec3(s.table[0]);
}

// in: fac, color; out: color.
void eval_invert(const NodeSettings &, const ShadingPoint &, const Vec3 *in, Vec3 *out) {
  const float fac = in[0].x;
  out[0] = (1.0f - fac) * in[1] + fac * (Vec3(1.0f) - in[1]);
}

// in: color, gamma; out: color.
void eval_gamma(const NodeSettings &, const ShadingPoint &, const Vec3 *in, Vec3 *out) {
  Vec3 c = in[0];
  for (int i = 0; i < 3; ++i)
    if (c[i] > 0.0f) c[i] = std::pow(c[i], in[1].x);
  out[0] = finite_or_zero(c);
}

// in: color, bright, contrast; out: color.
void eval_brightness_contrast(const NodeSettings &, const ShadingPoint &, const Vec3 *in, Vec3 *out) {
  const float a = 1.0f + in[2].x, b = in[1].x - in[2].x * 0.5f;
  out[0] = max(in[0] * a + Vec3(b), Vec3(0.0f));
}

void configure_clamp(const SettingsReader &r, NodeSettings &s) { s.mode[0] = r.choice("clamp_type", {"minmax", "range"}, 0); }
// in: value, min, max; out: result.
void eval_clamp(const NodeSettings &s, const ShadingPoint &, const Vec3 *in, Vec3 *out) {
  const float v = in[0].x, lo = in[1].x, hi = in[2].x;
  out[0] = Vec3(s.mode[0] == 1 ? clamp_either(v, lo, hi) : std::fmin(std::fmax(v, lo), hi));
}

void configure_map_range(const SettingsReader &r, NodeSettings &s) {
  s.mode[0] = r.choice("range_type", {"linear", "stepped", "smoothstep", "smootherstep"}, kLinear);
  s.flag = r.boolean("clamp", true);
}
// in: value, from_min, from_max, to_min, to_max, steps; out: result.
void eval_map_range(const NodeSettings &s, const ShadingPoint &, const Vec3 *in, Vec3 *out) {
  const float v = in[0].x, from_min = in[1].x, from_max = in[2].x, to_min = in[3].x, to_max = in[4].x;
  const float steps = in[5].x;
  float factor;
  switch (s.mode[0]) {
    case kLinear: factor = safe::divide(v - from_min, from_max - from_min); break;
    case kStepped:
      factor = safe::divide(v - from_min, from_max - from_min);
      factor = steps > 0.0f ? std::floor(factor * (steps + 1.0f)) / steps : 0.0f;
      break;
    case kSmoothstep:
      factor = from_min > from_max ? 1.0f - smoothstep(from_max, from_min, v) : smoothstep(from_min, from_max, v);
      break;
    default:
      factor = from_min > from_max ? 1.0f - smootherstep(from_max, from_min, v) : smootherstep(from_min, from_max, v);
      break;
  }
  float result = to_min + factor * (to_max - to_min);
  if (s.flag && (s.mode[0] == kLinear || s.mode[0] == kStepped)) result = clamp_either(result, to_min, to_max);
  out[0] = Vec3(finite_or_zero(result));
}

// in: vector (or color); out: x, y, z (or r, g, b).
void eval_separate(const NodeSettings &, const ShadingPoint &, const Vec3 *in, Vec3 *out) {
  for (int i = 0; i < 3; ++i) out[i] = Vec3(in[0][i]);
}
// in: x, y, z (or r, g, b); out: vector (or image).
void eval_combine(const NodeSettings &, const ShadingPoint &, const Vec3 *in, Vec3 *out) {
  out[0] = Vec3(in[0].x, in[1].x, in[2].x);
}

// in: color; out: val (the luminance).
void eval_rgb_to_bw(const NodeSettings &, const ShadingPoint &, const Vec3 *in, Vec3 *out) { out[0] = Vec3(luminance(in[0])); }

}  // namespace glimmer::render::nodes
