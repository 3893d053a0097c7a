// Mix (colour) node (Cycles 3.4 MixNode, svm_mix in kernel/svm/color_util.h): every
// blend mode, factor clamped to [0, 1], optional clamp of the result.
#include "render/nodes/families.h"
#include "render/nodes/math_util.h"

namespace glimmer::render::nodes {

namespace {

enum Mode {
  kMix, kAdd, kMultiply, kScreen, kOverlay, kSubtract, kDivide, kDifference, kDarken, kLighten, kDodge, kBurn, kHue,
  kSaturation, kValue, kColor, kSoftLight, kLinearLight
};

Vec3 lerp(const Vec3 &a, const Vec3 &b, float t) { return (1.0f - t) * a + t * b; }

template <typename F>
Vec3 per_channel(const Vec3 &a, const Vec3 &b, F &&f) { return {f(a.x, b.x), f(a.y, b.y), f(a.z, b.z)}; }

}  // namespace

Vec3 mix_colors(int mode, float t, const Vec3 &c1, const Vec3 &c2) {
  const float tm = 1.0f - t;
  switch (mode) {
    case kMix: return lerp(c1, c2, t);
    case kAdd: return lerp(c1, c1 + c2, t);
    case kMultiply: return lerp(c1, c1 * c2, t);
    case kScreen: return Vec3(1.0f) - (Vec3(tm) + t * (Vec3(1.0f) - c2)) * (Vec3(1.0f) - c1);
    case kOverlay:
      return per_channel(c1, c2, [&](float a, float b) {
        return a < 0.5f ? a * (tm + 2.0f * t * b) : 1.0f - (tm + 2.0f * t * (1.0f - b)) * (1.0f - a);
      });
    case kSubtract: return lerp(c1, c1 - c2, t);
    case kDivide:
      return per_channel(c1, c2, [&](float a, float b) { return b != 0.0f ? tm * a + t * a / b : a; });
    case kDifference: return lerp(c1, abs(c1 - c2), t);
    case kDarken: return lerp(c1, min(c1, c2), t);
    case kLighten: return lerp(c1, max(c1, c2), t);
    case kDodge:
      return per_channel(c1, c2, [&](float a, float b) {
        if (a == 0.0f) return a;
        const float d = 1.0f - t * b;
        return d <= 0.0f ? 1.0f : std::fmin(a / d, 1.0f);
      });
    case kBurn:
      return per_channel(c1, c2, [&](float a, float b) {
        const float d = tm + t * b;
        return d <= 0.0f ? 0.0f : clamp(1.0f - (1.0f - a) / d, 0.0f, 1.0f);
      });
    case kHue: {
      const Vec3 hsv2 = rgb_to_hsv(c2);
      if (hsv2.y == 0.0f) return c1;
      Vec3 hsv = rgb_to_hsv(c1);
      hsv.x = hsv2.x;
      return lerp(c1, hsv_to_rgb(hsv), t);
    }
    case kSaturation: {
      Vec3 hsv = rgb_to_hsv(c1);
      if (hsv.y == 0.0f) return c1;
      hsv.y = tm * hsv.y + t * rgb_to_hsv(c2).y;
      return hsv_to_rgb(hsv);
    }
    case kValue: {
      Vec3 hsv = rgb_to_hsv(c1);
      hsv.z = tm * hsv.z + t * rgb_to_hsv(c2).z;
      return hsv_to_rgb(hsv);
    }
    case kColor: {
      const Vec3 hsv2 = rgb_to_hsv(c2);
      if (hsv2.y == 0.0f) return c1;
      Vec3 hsv = rgb_to_hsv(c1);
      hsv.x = hsv2.x;
      hsv.y = hsv2.y;
      return lerp(c1, hsv_to_rgb(hsv), t);
    }
    case kSoftLight: {
      const Vec3 screen = Vec3(1.0f) - (Vec3(1.0f) - c2) * (Vec3(1.0f) - c1);
      return tm * c1 + t * ((Vec3(1.0f) - c1) * c2 * c1 + c1 * screen);
    }
    default: return c1 + t * (2.0f * c2 - Vec3(1.0f));  // linear light
  }
}

void configure_mix_rgb(const SettingsReader &r, NodeSettings &s) {
  s.mode[0] = r.choice("mix_type",
                       {"mix", "add", "multiply", "screen", "overlay", "subtract", "divide", "difference", "darken",
                        "lighten", "dodge", "burn", "hue", "saturation", "value", "color", "soft_light",
                        "linear_light"},
                       kMix);
  s.flag = r.boolean("use_clamp", false);
}

// in: fac, color1, color2; out: color.
void eval_mix_rgb(const NodeSettings &s, const ShadingPoint &, const Vec3 *in, Vec3 *out) {
  Vec3 c = mix_colors(s.mode[0], saturate(in[0].x), in[1], in[2]);
  if (s.flag) c = {saturate(c.x), saturate(c.y), saturate(c.z)};
  out[0] = finite_or_zero(c);
}

}  // namespace glimmer::render::nodes
