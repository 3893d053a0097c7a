// Deterministic low-discrepancy sampling from (seed, pixel, sample, dimension):
// 2D Owen-scrambled Sobol points with a per-dimension-pair shuffled index
// (Burley 2020, "Practical Hash-based Owen Scrambling", JCGT 9(4)). Every value
// is a pure function of its arguments, so images do not depend on thread count
// or tile size.
#pragma once

#include <cstdint>

#include "glimmer/rng.h"

namespace glimmer::render {

inline uint32_t reverse_bits(uint32_t x) {
  x = ((x >> 1) & 0x55555555u) | ((x & 0x55555555u) << 1);
  x = ((x >> 2) & 0x33333333u) | ((x & 0x33333333u) << 2);
  x = ((x >> 4) & 0x0f0f0f0fu) | ((x & 0x0f0f0f0fu) << 4);
  x = ((x >> 8) & 0x00ff00ffu) | ((x & 0x00ff00ffu) << 8);
  return (x >> 16) | (x << 16);
}

// Laine-Karras style hash permutation of the reversed bits (Burley 2020, sec. 3).
inline uint32_t laine_karras_permutation(uint32_t x, uint32_t seed) {
  x += seed;
  x ^= x * 0x6c50b47cu;
  x ^= x * 0xb82f1e52u;
  x ^= x * 0xc7afe638u;
  x ^= x * 0x8d22f6e6u;
  return x;
}
inline uint32_t nested_uniform_scramble(uint32_t x, uint32_t seed) {
  return reverse_bits(laine_karras_permutation(reverse_bits(x), seed));
}

// The first two Sobol dimensions: van der Corput (bit reversal) and the
// second dimension's generator matrix (v_k = v_{k-1} ^ v_{k-1} >> 1).
inline uint32_t sobol_dim0(uint32_t i) { return reverse_bits(i); }
inline uint32_t sobol_dim1(uint32_t i) {
  uint32_t r = 0u;
  for (uint32_t v = 1u << 31; i != 0u; i >>= 1, v ^= v >> 1)
    if (i & 1u) r ^= v;
  return r;
}

// Sample dimensions come in pairs; one pair = one 2D Owen-scrambled Sobol set.
struct PixelSampler {
  uint32_t pixel_seed;  // hash of (seed, pixel)
  uint32_t sample;

  PixelSampler(uint32_t seed, uint32_t pixel_index, uint32_t sample_index)
      : pixel_seed(hash_u32x2(seed, pixel_index)), sample(sample_index) {}

  void get2(uint32_t pair, float &u, float &v) const {
    const uint32_t pair_seed = hash_u32x2(pixel_seed, pair);
    const uint32_t index = nested_uniform_scramble(sample, pair_seed);
    const uint32_t x = nested_uniform_scramble(sobol_dim0(index), hash_u32(pair_seed ^ 0xa511e9b3u));
    const uint32_t y = nested_uniform_scramble(sobol_dim1(index), hash_u32(pair_seed ^ 0x63d83595u));
    u = uint_to_unit_float(x);
    v = uint_to_unit_float(y);
  }
};

// Dimension pairs per bounce (Cycles' PRNG_* layout in spirit).
enum SamplePair : uint32_t {
  kPairFilm = 0,
  kPairsPerBounce = 4,
  kPairLight = 0,        // point on the light
  kPairSelect = 1,       // (light choice, closure choice)
  kPairBsdf = 2,         // rand3[0], rand3[1]
  kPairBsdfTerminate = 3 // rand3[2], Russian roulette
};
// The thin-lens aperture sample: its own pair far from the per-bounce ones, so images without depth of field are
// unchanged.
constexpr uint32_t kPairLens = 0xfffffff0u;
inline uint32_t bounce_pair(int bounce, uint32_t which) { return 1u + static_cast<uint32_t>(bounce) * kPairsPerBounce + which; }

}  // namespace glimmer::render
