// The Owen-scrambled Sobol sampler (bridge/render/sampler.h) per path vertex: one 4D BSDF set and one 2D
// light set (also with each vertex waiting on the previous one, the two sets apart and together), against two earlier samplers kept here as references: the per-dimension tables (one 32-bit
// table per dimension, one bit reversal per dimension; the same points as today's pair tables), and the
// sampler before the precomputed tables (per 2D pair a hash, three nested uniform scrambles and the second
// dimension bit by bit), which drew the same eight numbers per vertex as four 2D pairs. Compare the
// figures of one run (the machine may be shared).
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

// ---- The per-dimension-table sampler (same points as PixelSampler; reference for the speed ratio) ----
struct PerDimensionTables {
  uint32_t reversed[kSobolDimensions][4][256];
};
constexpr PerDimensionTables make_per_dimension_tables() {
  PerDimensionTables t{};
  for (int d = 0; d < kSobolDimensions; ++d)
    for (int b = 0; b < 4; ++b)
      for (uint32_t byte = 0; byte < 256u; ++byte)
        t.reversed[d][b][byte] = static_cast<uint32_t>(kSobolPairTables.reversed[d / 2][b][byte] >> (32 * (d % 2)));
  return t;
}
constexpr PerDimensionTables kPerDimensionTables = make_per_dimension_tables();
struct PerDimensionTableSampler {
  uint32_t pixel_seed, sample_reversed;
  template <int N>
  void get(uint32_t set, float (&out)[N]) const {
    const uint32_t set_seed = hash_combine(pixel_seed, set);
    const uint32_t r = laine_karras_permutation(sample_reversed, set_seed);
    for (int d = 0; d < N; ++d) {
      const auto &t = kPerDimensionTables.reversed[d];
      const uint32_t sobol = t[0][r & 0xffu] ^ t[1][(r >> 8) & 0xffu] ^ t[2][(r >> 16) & 0xffu] ^ t[3][r >> 24];
      out[d] = uint_to_unit_float(reverse_bits(laine_karras_permutation(sobol, dimension_seed(set_seed, d))));
    }
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

// A path waits on its numbers: here each vertex's set index depends on the previous vertex's values (through a
// zero the compiler cannot see), so the chains of consecutive vertices cannot overlap, as in a render. Apart:
// get_bsdf, then get_light (one chain after the other; since issue 13, session 9, both read the vertex's one 6D
// set, so apart starts it twice); together: get_vertex (one set start, every number drawn).
template <bool kTogether>
void sampler_dependent_path(benchmark::State &state) {
  uint32_t sample = 0, zero = 0;
  benchmark::DoNotOptimize(zero);
  float acc = 0.0f;
  for (auto _ : state) {
    const PixelSampler sampler(1u, sample & 0xffffu, sample >> 16);
    uint32_t carry = 0u;
    for (int b = 0; b < kBounces; ++b) {
      const int vertex = b + static_cast<int>(carry & zero);
      float bsdf[4], light[2];
      if constexpr (kTogether) {
        sampler.get_vertex(vertex, bsdf, light);
      } else {
        sampler.get_bsdf(vertex, bsdf);
        sampler.get_light(vertex, light[0], light[1]);
      }
      carry = static_cast<uint32_t>((bsdf[3] + light[1]) * 16777216.0f);
      acc += bsdf[0] + bsdf[1] + bsdf[2] + bsdf[3] + light[0] + light[1];
    }
    ++sample;
  }
  benchmark::DoNotOptimize(acc);
  state.SetItemsProcessed(state.iterations() * kBounces);
}
void BM_SamplerDependentPathVerticesApart(benchmark::State &state) { sampler_dependent_path<false>(state); }
void BM_SamplerDependentPathVerticesTogether(benchmark::State &state) { sampler_dependent_path<true>(state); }
BENCHMARK(BM_SamplerDependentPathVerticesApart);
BENCHMARK(BM_SamplerDependentPathVerticesTogether);

// The start of a path: the film position and vertex 0's BSDF and light numbers. Today one 6D camera set and the
// light set (get_path_start: two chains side by side); the padded layout before issue 13, session 6 drew a film
// set, a 4D BSDF set and the light set (three chains, the same number of dimension pairs), kept here as the
// reference for the ratio.
template <typename Draw>
void sampler_path_start(benchmark::State &state, Draw draw) {
  uint32_t sample = 0;
  float acc = 0.0f;
  for (auto _ : state) {
    const PixelSampler sampler(1u, sample & 0xffffu, sample >> 16);
    float film[2], bsdf[4], light[2];
    draw(sampler, film, bsdf, light);
    acc += film[0] + film[1] + bsdf[0] + bsdf[1] + bsdf[2] + bsdf[3] + light[0] + light[1];
    ++sample;
  }
  benchmark::DoNotOptimize(acc);
  state.SetItemsProcessed(state.iterations());
}
void BM_SamplerPathStart(benchmark::State &state) {
  sampler_path_start(state, [](const PixelSampler &s, float (&film)[2], float (&bsdf)[4], float (&light)[2]) {
    s.get_path_start(film, bsdf, light);
  });
}
void BM_SamplerPathStartPaddedReference(benchmark::State &state) {
  sampler_path_start(state, [](const PixelSampler &s, float (&film)[2], float (&bsdf)[4], float (&light)[2]) {
    s.get(0u, film);
    s.get(kSetCamera, bsdf);
    s.get(bounce_set(0, kSetLight), light);
  });
}
BENCHMARK(BM_SamplerPathStart);
BENCHMARK(BM_SamplerPathStartPaddedReference);
// The render loop's path starts (issue 13, session 11): draw_path_starts, eight paths per call (their set
// starts in vector lanes, the eight draws independent), also giving each path's sampler, path seed and vertex 1's
// set start; per path.
void BM_SamplerPathStartsBatched(benchmark::State &state) {
  uint32_t sample = 0;
  float acc = 0.0f;
  for (auto _ : state) {
    uint32_t pixels[kPathStartBatch], samples[kPathStartBatch];
    for (int i = 0; i < kPathStartBatch; ++i) {
      pixels[i] = (sample + static_cast<uint32_t>(i)) & 0xffffu;
      samples[i] = (sample + static_cast<uint32_t>(i)) >> 16;
    }
    PathStart out[kPathStartBatch];
    draw_path_starts(1u, pixels, samples, kPathStartBatch, true, out);
    for (const PathStart &p : out)
      for (float v : p.value) acc += v;
    sample += kPathStartBatch;
  }
  benchmark::DoNotOptimize(acc);
  state.SetItemsProcessed(state.iterations() * kPathStartBatch);
}
BENCHMARK(BM_SamplerPathStartsBatched);

// Eight paths of a start and kBounces vertices each, every draw waiting on the one before it (through a zero
// the compiler cannot see), as in a render where a path waits on its numbers and the next path starts after it.
// Path by path (main before session 11): get_path_start, then get_vertex for vertices 1..kBounces. Batched (the
// render loop since session 11): the eight path starts drawn first by draw_path_starts (as trace_row does, before
// its paths), then per path get_vertex with `next` (each vertex's set start and Sobol words drawn one vertex
// ahead). Per path.
template <bool kBatched>
void sampler_dependent_paths(benchmark::State &state) {
  uint32_t sample = 0, zero = 0;
  benchmark::DoNotOptimize(zero);
  float acc = 0.0f;
  uint32_t carry = 0u;
  for (auto _ : state) {
    uint32_t pixels[kPathStartBatch], samples[kPathStartBatch];
    for (int i = 0; i < kPathStartBatch; ++i) {
      pixels[i] = (sample + static_cast<uint32_t>(i)) & 0xffffu;
      samples[i] = (sample + static_cast<uint32_t>(i)) >> 16;
    }
    PathStart starts[kPathStartBatch];
    if constexpr (kBatched) draw_path_starts(1u, pixels, samples, kPathStartBatch, true, starts);
    for (int i = 0; i < kPathStartBatch; ++i) {
      float bsdf[4], light[2];
      if constexpr (kBatched) {
        const PixelSampler sampler(starts[i]);
        sampler_draw::NextVertex next = starts[i].vertex1;
        acc += starts[i].value[static_cast<int>(carry & zero)];  // the path begins after the one before
        for (int b = 1; b <= kBounces; ++b) {
          sampler.get_vertex(b + static_cast<int>(carry & zero), next, bsdf, light, true, true);
          carry = static_cast<uint32_t>((bsdf[3] + light[1]) * 16777216.0f);
          acc += bsdf[0] + light[0];
        }
      } else {
        const PixelSampler sampler(1u, pixels[i] + (carry & zero), samples[i]);
        float film[2];
        sampler.get_path_start(film, bsdf, light);
        acc += film[0];
        for (int b = 1; b <= kBounces; ++b) {
          sampler.get_vertex(b + static_cast<int>(carry & zero), bsdf, light, true, true);
          carry = static_cast<uint32_t>((bsdf[3] + light[1]) * 16777216.0f);
          acc += bsdf[0] + light[0];
        }
      }
    }
    sample += kPathStartBatch;
  }
  benchmark::DoNotOptimize(acc);
  state.SetItemsProcessed(state.iterations() * kPathStartBatch);
}
void BM_SamplerDependentPathsPathByPath(benchmark::State &state) { sampler_dependent_paths<false>(state); }
void BM_SamplerDependentPathsBatched(benchmark::State &state) { sampler_dependent_paths<true>(state); }
BENCHMARK(BM_SamplerDependentPathsPathByPath);
BENCHMARK(BM_SamplerDependentPathsBatched);

void BM_SamplerPathVerticesPerDimensionTablesReference(benchmark::State &state) {
  uint32_t sample = 0;
  float acc = 0.0f;
  for (auto _ : state) {
    const PerDimensionTableSampler sampler{hash_u32x2(1u, sample & 0xffffu), reverse_bits(sample >> 16)};
    for (int b = 0; b < kBounces; ++b) {
      float bsdf[4], light[2];
      sampler.get(bounce_set(b, kSetBsdf), bsdf);
      sampler.get(bounce_set(b, kSetLight), light);
      acc += bsdf[0] + bsdf[1] + bsdf[2] + bsdf[3] + light[0] + light[1];
    }
    ++sample;
  }
  benchmark::DoNotOptimize(acc);
  state.SetItemsProcessed(state.iterations() * kBounces);
}
BENCHMARK(BM_SamplerPathVerticesPerDimensionTablesReference);

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
