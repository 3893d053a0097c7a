// Hue/Saturation/Value node (Cycles 3.4 svm_node_hsv) and the RGB <-> HSV conversions
// (Cycles' rgb_to_hsv / hsv_to_rgb, hue in [0, 1)) the Mix node's hue, saturation,
// value and color modes share.
#include "render/nodes/families.h"
#include "render/nodes/math_util.h"

namespace glimmer::render::nodes {

Vec3 rgb_to_hsv(const Vec3 &rgb) {
  const float cmax = max_component(rgb), cmin = min_component(rgb), delta = cmax - cmin;
  const float s = cmax != 0.0f ? delta / cmax : 0.0f;
  float h = 0.0f;
  if (s != 0.0f) {
    const Vec3 c = (Vec3(cmax) - rgb) / delta;
    if (rgb.x == cmax) h = c.z - c.y;
    else if (rgb.y == cmax) h = 2.0f + c.x - c.z;
    else h = 4.0f + c.y - c.x;
    h /= 6.0f;
    if (h < 0.0f) h += 1.0f;
  }
  return {h, s, cmax};
}

Vec3 hsv_to_rgb(const Vec3 &hsv) {
  float h = hsv.x;
  const float s = hsv.y, v = hsv.z;
  if (s == 0.0f) return Vec3(v);
  if (h == 1.0f) h = 0.0f;
  h *= 6.0f;
  const float i = std::floor(h), f = h - i;
  const float p = v * (1.0f - s), q = v * (1.0f - s * f), t = v * (1.0f - s * (1.0f - f));
  switch (static_cast<int>(i)) {
    case 0: return {v, t, p};
    case 1: return {q, v, p};
    case 2: return {p, v, t};
    case 3: return {p, q, v};
    case 4: return {t, p, v};
    default: return {v, p, q};
  }
}

// in: hue, saturation, value, fac, color; out: color.
void eval_hsv(const NodeSettings &, const ShadingPoint &, const Vec3 *in, Vec3 *out) {
  const float hue = in[0].x, saturation = in[1].x, value = in[2].x, fac = in[3].x;
  const Vec3 &color = in[4];
  Vec3 hsv = rgb_to_hsv(color);
  const float h = hsv.x + hue + 0.5f;  // hue 0.5 leaves it unchanged
  hsv.x = h - std::floor(h);
  hsv.y = saturate(hsv.y * saturation);
  hsv.z *= value;
  const Vec3 shifted = hsv_to_rgb(hsv);
  out[0] = finite_or_zero(max(fac * shifted + (1.0f - fac) * color, Vec3(0.0f)));
}

}  // namespace glimmer::render::nodes
