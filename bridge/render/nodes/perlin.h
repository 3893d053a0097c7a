// Cycles 3.4's procedural-noise building blocks (kernel/svm/noise.h, util/hash.h), as
// facts: Bob Jenkins' lookup3 final mix hashing the integer lattice coordinates,
// Perlin's improved gradient noise (quintic fade 6t^5 - 15t^4 + 10t^3, Cycles'
// gradient sets per dimension and its output scales 0.2500 / 0.6616 / 0.9820 /
// 0.8344 for 1D..4D), and the fBM sum of octaves the Noise and Wave textures use.
// Shared by noise.cpp, wave.cpp, musgrave.cpp and voronoi.cpp.
#pragma once

#include <array>
#include <bit>
#include <cmath>
#include <cstdint>

#include "glimmer/math.h"

namespace glimmer::render::nodes::perlin {

// ---- Jenkins lookup3 (hashlittle's final() and mix()) on 1-4 32-bit words ----
constexpr uint32_t rot(uint32_t x, int k) { return (x << k) | (x >> (32 - k)); }

constexpr void final_mix(uint32_t &a, uint32_t &b, uint32_t &c) {
  c ^= b; c -= rot(b, 14);
  a ^= c; a -= rot(c, 11);
  b ^= a; b -= rot(a, 25);
  c ^= b; c -= rot(b, 16);
  a ^= c; a -= rot(c, 4);
  b ^= a; b -= rot(a, 14);
  c ^= b; c -= rot(b, 24);
}

constexpr void mix(uint32_t &a, uint32_t &b, uint32_t &c) {
  a -= c; a ^= rot(c, 4); c += b;
  b -= a; b ^= rot(a, 6); a += c;
  c -= b; c ^= rot(b, 8); b += a;
  a -= c; a ^= rot(c, 16); c += b;
  b -= a; b ^= rot(a, 19); a += c;
  c -= b; c ^= rot(b, 4); b += a;
}

// Initial state of lookup3 for n words: 0xdeadbeef + (n << 2) + 13.
constexpr uint32_t seed_for(uint32_t words) { return 0xdeadbeefu + (words << 2) + 13u; }

constexpr uint32_t hash(uint32_t kx) {
  uint32_t a = seed_for(1), b = a, c = a;
  a += kx;
  final_mix(a, b, c);
  return c;
}
constexpr uint32_t hash(uint32_t kx, uint32_t ky) {
  uint32_t a = seed_for(2), b = a, c = a;
  b += ky;
  a += kx;
  final_mix(a, b, c);
  return c;
}
constexpr uint32_t hash(uint32_t kx, uint32_t ky, uint32_t kz) {
  uint32_t a = seed_for(3), b = a, c = a;
  c += kz;
  b += ky;
  a += kx;
  final_mix(a, b, c);
  return c;
}
constexpr uint32_t hash(uint32_t kx, uint32_t ky, uint32_t kz, uint32_t kw) {
  uint32_t a = seed_for(4), b = a, c = a;
  a += kx;
  b += ky;
  c += kz;
  mix(a, b, c);
  a += kw;
  final_mix(a, b, c);
  return c;
}

// Hashes of float coordinates (their bit patterns) to [0, 1], inclusive: n / 0xffffffff.
inline float unit(uint32_t n) { return static_cast<float>(n) * (1.0f / static_cast<float>(0xffffffffu)); }
inline uint32_t bits(float f) { return std::bit_cast<uint32_t>(f); }
inline float hash_to_float(float x) { return unit(hash(bits(x))); }
inline float hash_to_float(float x, float y) { return unit(hash(bits(x), bits(y))); }
inline float hash_to_float(float x, float y, float z) { return unit(hash(bits(x), bits(y), bits(z))); }
inline float hash_to_float(float x, float y, float z, float w) {
  return unit(hash(bits(x), bits(y), bits(z), bits(w)));
}

// ---- Gradient noise ----
inline float fade(float t) { return t * t * t * (t * (t * 6.0f - 15.0f) + 10.0f); }
inline float lerp(float a, float b, float t) { return (1.0f - t) * a + t * b; }

// Integer cell and fraction of x (cells beyond the int range, and non-finite x, are clamped to it: the
// conversion would be undefined there; the fraction of a non-finite x is NaN and the noise 0).
inline int cell_of(float x, float &fraction) {
  const float f = std::floor(x);
  fraction = x - f;
  return static_cast<int>(std::fmin(std::fmax(f, -2147483520.0f), 2147483520.0f));
}
inline uint32_t u32(int i) { return static_cast<uint32_t>(i); }

// Gradients dotted with the offset from the lattice point (Cycles' grad1..grad4).
inline float gradient(uint32_t h, float x) {
  const uint32_t k = h & 15u;
  float g = 1.0f + static_cast<float>(k & 7u);
  if (k & 8u) g = -g;
  return g * x;
}
inline float gradient(uint32_t h, float x, float y) {
  const uint32_t k = h & 7u;
  const float u = k < 4u ? x : y;
  const float v = 2.0f * (k < 4u ? y : x);
  return ((k & 1u) ? -u : u) + ((k & 2u) ? -v : v);
}
inline float gradient(uint32_t h, float x, float y, float z) {
  const uint32_t k = h & 15u;
  const float u = k < 8u ? x : y;
  const float v = k < 4u ? y : ((k == 12u || k == 14u) ? x : z);
  return ((k & 1u) ? -u : u) + ((k & 2u) ? -v : v);
}
inline float gradient(uint32_t h, float x, float y, float z, float w) {
  const uint32_t k = h & 31u;
  const float u = k < 24u ? x : y;
  const float v = k < 16u ? y : z;
  const float s = k < 8u ? z : w;
  return ((k & 1u) ? -u : u) + ((k & 2u) ? -v : v) + ((k & 4u) ? -s : s);
}

// Signed Perlin noise, scaled to about [-1, 1] as Cycles' snoise_Nd; non-finite -> 0.
inline float finite_or_zero(float v) { return std::isfinite(v) ? v : 0.0f; }

inline float signed_noise(float x) {
  float fx;
  const int X = cell_of(x, fx);
  const float a = gradient(hash(u32(X)), fx), b = gradient(hash(u32(X + 1)), fx - 1.0f);
  const float n = a + fade(fx) * (b - a);  // Cycles' mix() form in 1D
  return 0.2500f * finite_or_zero(n);
}

inline float signed_noise(float x, float y) {
  float fx, fy;
  const int X = cell_of(x, fx), Y = cell_of(y, fy);
  const float u = fade(fx), v = fade(fy);
  auto g = [&](int i, int j) { return gradient(hash(u32(X + i), u32(Y + j)), fx - i, fy - j); };
  const float n = lerp(lerp(g(0, 0), g(1, 0), u), lerp(g(0, 1), g(1, 1), u), v);
  return 0.6616f * finite_or_zero(n);
}

inline float signed_noise(float x, float y, float z) {
  float fx, fy, fz;
  const int X = cell_of(x, fx), Y = cell_of(y, fy), Z = cell_of(z, fz);
  const float u = fade(fx), v = fade(fy), w = fade(fz);
  auto g = [&](int i, int j, int k) {
    return gradient(hash(u32(X + i), u32(Y + j), u32(Z + k)), fx - i, fy - j, fz - k);
  };
  auto layer = [&](int k) { return lerp(lerp(g(0, 0, k), g(1, 0, k), u), lerp(g(0, 1, k), g(1, 1, k), u), v); };
  return 0.9820f * finite_or_zero(lerp(layer(0), layer(1), w));
}

inline float signed_noise(float x, float y, float z, float w) {
  float fx, fy, fz, fw;
  const int X = cell_of(x, fx), Y = cell_of(y, fy), Z = cell_of(z, fz), W = cell_of(w, fw);
  const float u = fade(fx), v = fade(fy), t = fade(fz), s = fade(fw);
  auto g = [&](int i, int j, int k, int l) {
    return gradient(hash(u32(X + i), u32(Y + j), u32(Z + k), u32(W + l)), fx - i, fy - j, fz - k, fw - l);
  };
  auto layer = [&](int k, int l) {
    return lerp(lerp(g(0, 0, k, l), g(1, 0, k, l), u), lerp(g(0, 1, k, l), g(1, 1, k, l), u), v);
  };
  const float n = lerp(lerp(layer(0, 0), layer(1, 0), t), lerp(layer(0, 1), layer(1, 1), t), s);
  return 0.8344f * finite_or_zero(n);
}

// A point of 1-4 dimensions; signed_noise(p) dispatches on N.
template <int N>
using Point = std::array<float, N>;

template <int N>
float signed_noise(const Point<N> &p) {
  if constexpr (N == 1) return signed_noise(p[0]);
  else if constexpr (N == 2) return signed_noise(p[0], p[1]);
  else if constexpr (N == 3) return signed_noise(p[0], p[1], p[2]);
  else return signed_noise(p[0], p[1], p[2], p[3]);
}

template <int N>
Point<N> scaled(Point<N> p, float s) {
  for (float &c : p) c *= s;
  return p;
}

// Cycles' fractal_noise_Nd: fBM of floor(octaves) + 1 octaves (octaves clamped to
// [0, 15]), amplitude times roughness per octave, frequency doubling; a fractional
// octave count blends in one more octave. Result in about [0, 1].
template <int N>
float fractal_noise(const Point<N> &p, float octaves, float roughness) {
  float frequency = 1.0f, amplitude = 1.0f, max_amplitude = 0.0f, sum = 0.0f;
  octaves = std::fmin(std::fmax(octaves, 0.0f), 15.0f);
  const float r = std::fmin(std::fmax(roughness, 0.0f), 1.0f);
  const int n = static_cast<int>(octaves);
  for (int i = 0; i <= n; ++i) {
    sum += signed_noise<N>(scaled<N>(p, frequency)) * amplitude;
    max_amplitude += amplitude;
    amplitude *= r;
    frequency *= 2.0f;
  }
  const float remainder = octaves - std::floor(octaves);
  if (remainder == 0.0f) return 0.5f * sum / max_amplitude + 0.5f;
  const float sum_more = sum + signed_noise<N>(scaled<N>(p, frequency)) * amplitude;
  const float a = 0.5f * sum / max_amplitude + 0.5f;
  const float b = 0.5f * sum_more / (max_amplitude + amplitude) + 0.5f;
  return (1.0f - remainder) * a + remainder * b;
}

// Cycles' random_floatN_offset(seed): per-axis offsets in [100, 200] that decorrelate
// the distortion and colour channels of the Noise texture.
template <int N>
Point<N> random_offset(float seed) {
  Point<N> o{};
  if constexpr (N == 1) {
    o[0] = 100.0f + hash_to_float(seed) * 100.0f;
  } else {
    for (int i = 0; i < N; ++i) o[i] = 100.0f + hash_to_float(seed, static_cast<float>(i)) * 100.0f;
  }
  return o;
}

// Three hashes of a lattice cell in [0, 1] (Cycles' hash_floatN_to_float3): the Voronoi cell colour and
// the White Noise colour.
template <int N>
Vec3 cell_color(const Point<N> &c) {
  if constexpr (N == 1) return {hash_to_float(c[0]), hash_to_float(c[0], 1.0f), hash_to_float(c[0], 2.0f)};
  else if constexpr (N == 2)
    return {hash_to_float(c[0], c[1]), hash_to_float(c[0], c[1], 1.0f), hash_to_float(c[0], c[1], 2.0f)};
  else if constexpr (N == 3)
    return {hash_to_float(c[0], c[1], c[2]), hash_to_float(c[0], c[1], c[2], 1.0f),
            hash_to_float(c[0], c[1], c[2], 2.0f)};
  else
    return {hash_to_float(c[0], c[1], c[2], c[3]), hash_to_float(c[2], c[0], c[3], c[1]),
            hash_to_float(c[3], c[2], c[1], c[0])};
}

template <int N>
Point<N> plus(Point<N> a, const Point<N> &b) {
  for (int i = 0; i < N; ++i) a[i] += b[i];
  return a;
}

}  // namespace glimmer::render::nodes::perlin
