// The Owen-scrambled Sobol sampler (bridge/render/sampler.h) per path vertex: one 4D BSDF set and one 2D
// light set, against the sampler before the precomputed tables (kept here as the reference: per 2D pair a
// hash, three nested uniform scrambles and the second dimension bit by bit), which drew the same eight
// numbers per vertex as four 2D pairs. Compare the two figures of one run (the machine may be shared).
#include <benchmark/benchmark.h>

#include "render/sampler.h"

namespace {

using namespace glimmer;
using namespace glimmer::render;

// ---- The previous sampler (reference for the speed ratio) ----
uint32_t nested_uniform_scramble_bitwise(uint32_t x, uint32_t seed) {
  return reverse_bits(laine_karras_permutation(reverse_bits(x), seed));
}
uint32_t sobol_dim1_bitwise(uint32_t i) {
  uint32_t r = 0u;
  for (uint32_t v = 1u << 31; i != 0u; i >>= 1, v ^= v >> 1)
    if (i & 1u) r ^= v;
  return r;
}
struct BitwisePairSampler {
  uint32_t pixel_seed, sample;
  void get2(uint32_t pair, float &u, float &v) const {
    const uint32_t pair_seed = hash_u32x2(pixel_seed, pair);
    const uint32_t index = nested_uniform_scramble_bitwise(sample, pair_seed);
    u = uint_to_unit_float(nested_uniform_scramble_bitwise(reverse_bits(index), hash_u32(pair_seed ^ 0xa511e9b3u)));
    v = uint_to_unit_float(nested_uniform_scramble_bitwise(sobol_dim1_bitwise(index), hash_u32(pair_seed ^ 0x63d83595u)));
  }
};

constexpr int kBounces = 4;

void BM_SamplerPathVertices(benchmark::State &state) {
  uint32_t sample = 0;
  float acc = 0.0f;
  for (auto _ : state) {
    const PixelSampler sampler(1u, sample & 0xffffu, sample >> 16);
    for (int b = 0; b < kBounces; ++b) {
      float bsdf[4], u, v;
      sampler.get_bsdf(b, bsdf);
      sampler.get_light(b, u, v);
      acc += bsdf[0] + bsdf[1] + bsdf[2] + bsdf[3] + u + v;
    }
    ++sample;
  }
  benchmark::DoNotOptimize(acc);
  state.SetItemsProcessed(state.iterations() * kBounces);
}
BENCHMARK(BM_SamplerPathVertices);

void BM_SamplerPathVerticesBitwiseReference(benchmark::State &state) {
  uint32_t sample = 0;
  float acc = 0.0f;
  for (auto _ : state) {
    const BitwisePairSampler sampler{hash_u32x2(1u, sample & 0xffffu), sample >> 16};
    for (int b = 0; b < kBounces; ++b) {
      float r[8];
      for (uint32_t p = 0; p < 4; ++p) sampler.get2(1u + 4u * b + p, r[2 * p], r[2 * p + 1]);
      acc += r[0] + r[1] + r[2] + r[3] + r[4] + r[5] + r[6] + r[7];
    }
    ++sample;
  }
  benchmark::DoNotOptimize(acc);
  state.SetItemsProcessed(state.iterations() * kBounces);
}
BENCHMARK(BM_SamplerPathVerticesBitwiseReference);

}  // namespace
