// Color Ramp (Cycles 3.4 RGBRampNode, svm_node_rgb_ramp): a table of RGBA entries
// sampled evenly over fac in [0, 1] (Blender bakes its stops and interpolation mode,
// ease / cardinal / B-spline included, into 256 entries); entries are linearly
// interpolated, or with interpolate="false" the entry at or below fac is taken.
#include "render/nodes/families.h"
#include "render/nodes/math_util.h"

namespace glimmer::render::nodes {

void configure_color_ramp(const SettingsReader &r, NodeSettings &s) {
  const std::vector<float> rgb = r.floats("ramp");
  std::vector<float> alpha = r.floats("ramp_alpha");
  if (rgb.empty()) r.fail("<rgb_ramp> needs a 'ramp' attribute (RGB triples, one per table entry)");
  if (rgb.size() % 3 != 0) r.fail("<rgb_ramp> ramp: expected RGB triples, got " + std::to_string(rgb.size()) + " numbers");
  const size_t n = rgb.size() / 3;
  if (!alpha.empty() && alpha.size() != n)
    r.fail("<rgb_ramp> ramp_alpha: expected " + std::to_string(n) + " values (one per ramp entry), got " +
           std::to_string(alpha.size()));
  alpha.resize(n, 1.0f);
  s.table.resize(4 * n);
  for (size_t i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) s.table[4 * i + k] = rgb[3 * i + k];
    s.table[4 * i + 3] = alpha[i];
  }
  s.flag = r.boolean("interpolate", true);
}

// in: fac; out: color, alpha.
void eval_color_ramp(const NodeSettings &s, const ShadingPoint &, const Vec3 *in, Vec3 *out) {
  const int n = static_cast<int>(s.table.size() / 4);
  const float f = saturate(finite_or_zero(in[0].x)) * static_cast<float>(n - 1);
  const int i = clamp(static_cast<int>(f), 0, n - 1);
  const float t = f - static_cast<float>(i);
  const float *a = &s.table[4 * i];
  float rgba[4] = {a[0], a[1], a[2], a[3]};
  if (s.flag && t > 0.0f && i + 1 < n) {
    const float *b = a + 4;
    for (int k = 0; k < 4; ++k) rgba[k] = (1.0f - t) * a[k] + t * b[k];
  }
  out[0] = Vec3(rgba[0], rgba[1], rgba[2]);
  out[1] = Vec3(rgba[3]);
}

}  // namespace glimmer::render::nodes
