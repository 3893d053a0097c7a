// Gradient Texture (Cycles 3.4 svm_gradient: linear, quadratic, easing, diagonal, radial,
// quadratic sphere, spherical ramps, clamped to [0, 1]) and White Noise Texture
// (svm_node_tex_white_noise: the lookup3 hash of the 1-4D coordinates' bits).
#include "render/nodes/families.h"
#include "render/nodes/perlin.h"

namespace glimmer::render::nodes {

void configure_gradient(const SettingsReader &r, NodeSettings &s) {
  s.mode[0] = r.choice("gradient_type",
                       {"linear", "quadratic", "easing", "diagonal", "radial", "quadratic_sphere", "spherical"}, 0);
}

// in: vector; out: color, fac.
void eval_gradient(const NodeSettings &s, const ShadingPoint &, const Vec3 *in, Vec3 *out) {
  const Vec3 &p = in[0];
  float f;
  switch (s.mode[0]) {
    case 0: f = p.x; break;
    case 1: f = std::fmax(p.x, 0.0f) * std::fmax(p.x, 0.0f); break;
    case 2: {
      const float r = clamp(p.x, 0.0f, 1.0f), t = r * r;
      f = 3.0f * t - 2.0f * t * r;
      break;
    }
    case 3: f = (p.x + p.y) * 0.5f; break;
    case 4: f = std::atan2(p.y, p.x) * kInv2Pi + 0.5f; break;
    default: {
      const float r = std::fmax(0.999999f - length(p), 0.0f);
      f = s.mode[0] == 5 ? r * r : r;
      break;
    }
  }
  f = saturate(f);
  out[0] = Vec3(f);
  out[1] = Vec3(f);
}

void configure_white_noise(const SettingsReader &r, NodeSettings &s) {
  s.mode[0] = 1 + r.choice("dimensions", {"1d", "2d", "3d", "4d"}, 2);
}

// in: vector, w; out: value, color.
void eval_white_noise(const NodeSettings &s, const ShadingPoint &, const Vec3 *in, Vec3 *out) {
  const Vec3 &v = in[0];
  const float w = in[1].x;
  Vec3 color;
  switch (s.mode[0]) {
    case 1: color = perlin::cell_color<1>({w}); break;
    case 2: color = perlin::cell_color<2>({v.x, v.y}); break;
    case 3: color = perlin::cell_color<3>({v.x, v.y, v.z}); break;
    default: color = perlin::cell_color<4>({v.x, v.y, v.z, w}); break;
  }
  out[0] = Vec3(color.x);  // the value is the colour's first hash
  out[1] = color;
}

}  // namespace glimmer::render::nodes
