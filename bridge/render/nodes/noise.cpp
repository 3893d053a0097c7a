// Noise Texture (Cycles 3.4 svm_node_tex_noise / noise_texture_Nd): fBM Perlin noise
// of 1-4 dimensions with detail (octaves), roughness and distortion; the colour's
// green and blue channels are the same fBM at offset positions.
#include "render/nodes/families.h"
#include "render/nodes/perlin.h"

namespace glimmer::render::nodes {

namespace {

using perlin::Point;

// Cycles' noise_texture_Nd on an already scaled point.
template <int N>
void noise_texture(Point<N> p, float detail, float roughness, float distortion, Vec3 &fac, Vec3 &color) {
  if (distortion != 0.0f) {
    Point<N> warp{};
    for (int i = 0; i < N; ++i)
      warp[i] = perlin::signed_noise<N>(perlin::plus<N>(p, perlin::random_offset<N>(static_cast<float>(i)))) * distortion;
    p = perlin::plus<N>(p, warp);
  }
  const float value = perlin::fractal_noise<N>(p, detail, roughness);
  fac = Vec3(value);
  // Colour offsets: seeds N and N + 1 (after the N distortion seeds).
  color = Vec3(value,
               perlin::fractal_noise<N>(perlin::plus<N>(p, perlin::random_offset<N>(static_cast<float>(N))), detail,
                                        roughness),
               perlin::fractal_noise<N>(perlin::plus<N>(p, perlin::random_offset<N>(static_cast<float>(N + 1))),
                                        detail, roughness));
}

}  // namespace

void configure_noise(const SettingsReader &r, NodeSettings &s) {
  s.mode[0] = 1 + r.choice("dimensions", {"1d", "2d", "3d", "4d"}, 2);
}

// in: vector, w, scale, detail, roughness, distortion; out: fac, color.
void eval_noise(const NodeSettings &s, const ShadingPoint &, const Vec3 *in, Vec3 *out) {
  const float scale = in[2].x;
  const Vec3 v = in[0] * scale;
  const float w = in[1].x * scale;
  const float detail = in[3].x, roughness = in[4].x, distortion = in[5].x;
  switch (s.mode[0]) {
    case 1: noise_texture<1>({w}, detail, roughness, distortion, out[0], out[1]); break;
    case 2: noise_texture<2>({v.x, v.y}, detail, roughness, distortion, out[0], out[1]); break;
    case 3: noise_texture<3>({v.x, v.y, v.z}, detail, roughness, distortion, out[0], out[1]); break;
    default: noise_texture<4>({v.x, v.y, v.z, w}, detail, roughness, distortion, out[0], out[1]); break;
  }
}

}  // namespace glimmer::render::nodes
