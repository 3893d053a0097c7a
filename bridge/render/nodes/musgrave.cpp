// Musgrave Texture (Cycles 3.4 svm_node_tex_musgrave, F. K. Musgrave's fractals in
// "Texturing and Modeling: A Procedural Approach"): fBM, multifractal, hybrid and
// ridged multifractal and heterogeneous terrain over signed Perlin noise, with
// H = dimension, lacunarity, octaves = detail, offset and gain.
#include "render/nodes/families.h"
#include "render/nodes/perlin.h"

namespace glimmer::render::nodes {

namespace {

using perlin::Point;
enum Type { kMultifractal, kFbm, kHybrid, kRidged, kHeteroTerrain };

struct Fractal {
  float H, lacunarity, octaves, offset, gain;
};

template <int N>
float fbm(Point<N> p, const Fractal &f) {
  const float step = std::pow(f.lacunarity, -f.H);
  float value = 0.0f, power = 1.0f;
  for (int i = 0; i < static_cast<int>(f.octaves); ++i) {
    value += perlin::signed_noise<N>(p) * power;
    power *= step;
    p = perlin::scaled<N>(p, f.lacunarity);
  }
  const float remainder = f.octaves - std::floor(f.octaves);
  if (remainder != 0.0f) value += remainder * perlin::signed_noise<N>(p) * power;
  return value;
}

template <int N>
float multifractal(Point<N> p, const Fractal &f) {
  const float step = std::pow(f.lacunarity, -f.H);
  float value = 1.0f, power = 1.0f;
  for (int i = 0; i < static_cast<int>(f.octaves); ++i) {
    value *= power * perlin::signed_noise<N>(p) + 1.0f;
    power *= step;
    p = perlin::scaled<N>(p, f.lacunarity);
  }
  const float remainder = f.octaves - std::floor(f.octaves);
  if (remainder != 0.0f) value *= remainder * power * perlin::signed_noise<N>(p) + 1.0f;
  return value;
}

template <int N>
float hetero_terrain(Point<N> p, const Fractal &f) {
  const float step = std::pow(f.lacunarity, -f.H);
  float power = step;
  float value = f.offset + perlin::signed_noise<N>(p);
  p = perlin::scaled<N>(p, f.lacunarity);
  for (int i = 1; i < static_cast<int>(f.octaves); ++i) {
    value += (perlin::signed_noise<N>(p) + f.offset) * power * value;
    power *= step;
    p = perlin::scaled<N>(p, f.lacunarity);
  }
  const float remainder = f.octaves - std::floor(f.octaves);
  if (remainder != 0.0f) value += remainder * (perlin::signed_noise<N>(p) + f.offset) * power * value;
  return value;
}

template <int N>
float hybrid_multifractal(Point<N> p, const Fractal &f) {
  const float step = std::pow(f.lacunarity, -f.H);
  float power = step;
  float value = perlin::signed_noise<N>(p) + f.offset;
  float weight = f.gain * value;
  p = perlin::scaled<N>(p, f.lacunarity);
  for (int i = 1; weight > 0.001f && i < static_cast<int>(f.octaves); ++i) {
    weight = std::fmin(weight, 1.0f);
    const float signal = (perlin::signed_noise<N>(p) + f.offset) * power;
    power *= step;
    value += weight * signal;
    weight *= f.gain * signal;
    p = perlin::scaled<N>(p, f.lacunarity);
  }
  const float remainder = f.octaves - std::floor(f.octaves);
  if (remainder != 0.0f && weight > 0.001f) {
    weight = std::fmin(weight, 1.0f);
    value += remainder * weight * (perlin::signed_noise<N>(p) + f.offset) * power;
  }
  return value;
}

template <int N>
float ridged_multifractal(Point<N> p, const Fractal &f) {
  const float step = std::pow(f.lacunarity, -f.H);
  float power = step;
  float signal = f.offset - std::fabs(perlin::signed_noise<N>(p));
  signal *= signal;
  float value = signal;
  for (int i = 1; i < static_cast<int>(f.octaves); ++i) {
    p = perlin::scaled<N>(p, f.lacunarity);
    const float weight = saturate(signal * f.gain);
    signal = f.offset - std::fabs(perlin::signed_noise<N>(p));
    signal *= signal;
    signal *= weight;
    value += signal * power;
    power *= step;
  }
  return value;
}

template <int N>
float musgrave(int type, const Point<N> &p, const Fractal &f) {
  switch (type) {
    case kMultifractal: return multifractal<N>(p, f);
    case kFbm: return fbm<N>(p, f);
    case kHybrid: return hybrid_multifractal<N>(p, f);
    case kRidged: return ridged_multifractal<N>(p, f);
    default: return hetero_terrain<N>(p, f);
  }
}

}  // namespace

void configure_musgrave(const SettingsReader &r, NodeSettings &s) {
  s.mode[0] = r.choice("musgrave_type",
                       {"multifractal", "fbm", "hybrid_multifractal", "ridged_multifractal", "hetero_terrain"}, kFbm);
  s.mode[1] = 1 + r.choice("dimensions", {"1d", "2d", "3d", "4d"}, 2);
}

// in: vector, w, scale, detail, dimension, lacunarity, offset, gain; out: fac.
void eval_musgrave(const NodeSettings &s, const ShadingPoint &, const Vec3 *in, Vec3 *out) {
  const float scale = in[2].x;
  const Vec3 v = in[0] * scale;
  const float w = in[1].x * scale;
  const Fractal f{std::fmax(in[4].x, 1e-5f), std::fmax(in[5].x, 1e-5f), clamp(in[3].x, 0.0f, 15.0f), in[6].x,
                  in[7].x};
  float value;
  switch (s.mode[1]) {
    case 1: value = musgrave<1>(s.mode[0], {w}, f); break;
    case 2: value = musgrave<2>(s.mode[0], {v.x, v.y}, f); break;
    case 3: value = musgrave<3>(s.mode[0], {v.x, v.y, v.z}, f); break;
    default: value = musgrave<4>(s.mode[0], {v.x, v.y, v.z, w}, f); break;
  }
  out[0] = Vec3(value);
}

}  // namespace glimmer::render::nodes
