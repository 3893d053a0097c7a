// Deterministic low-discrepancy sampling from (seed, pixel, sample, dimension set):
// Owen-scrambled Sobol points with a per-set shuffled index (Burley 2020,
// "Practical Hash-based Owen Scrambling", JCGT 9(4)). A set is 2, 4 or 6 jointly
// stratified dimensions (the first Sobol dimensions); sets are decorrelated
// from each other by their own index shuffle and scrambles ("padding").
// Every value is a pure function of its arguments, so images do not depend on
// thread count or tile size.
//
// Cost: the Sobol generator matrices of the six dimensions are precomputed (compile time) as byte tables
// of the bit-reversed columns, two dimensions per 64-bit entry, so a pair of dimensions is four table
// look-ups and two Laine-Karras permutations; each scrambled (still bit-reversed) value becomes its float by
// three byte look-ups and two exact additions, no bit reversal; a set costs one seed hash and one index
// shuffle for all its dimensions. On CPUs with AVX2, get_vertex and get_path_start compute the same values
// with the six (seven) scrambles and floats in the lanes of one vector register (sampler_draw.h/.cpp). The
// render loop draws path starts eight at a time (draw_path_starts) and each vertex's set start one vertex ahead
// (get_vertex with NextVertex), so the draws' dependent chains overlap with other work instead of stalling the
// path that waits on them (docs/architecture.md "Draws ahead of the chain that waits on them").
#pragma once

#include <array>
#include <cstdint>

#include "glimmer/rng.h"

namespace glimmer::render {

constexpr uint32_t reverse_bits(uint32_t x) {
  x = ((x >> 1) & 0x55555555u) | ((x & 0x55555555u) << 1);
  x = ((x >> 2) & 0x33333333u) | ((x & 0x33333333u) << 2);
  x = ((x >> 4) & 0x0f0f0f0fu) | ((x & 0x0f0f0f0fu) << 4);
  return __builtin_bswap32(x);  // the byte swap does the last two steps in one instruction
}

// Laine-Karras style hash permutation of the reversed bits (Burley 2020, sec. 3): bit k of the result
// depends only on bits <= k of x, so applied to reversed bits it is a nested uniform (Owen) scramble.
inline constexpr uint32_t kLaineKarrasRounds[4] = {0x6c50b47cu, 0xb82f1e52u, 0xc7afe638u, 0x8d22f6e6u};
constexpr uint32_t laine_karras_permutation(uint32_t x, uint32_t seed) {
  x += seed;
  x ^= x * kLaineKarrasRounds[0];
  x ^= x * kLaineKarrasRounds[1];
  x ^= x * kLaineKarrasRounds[2];
  x ^= x * kLaineKarrasRounds[3];
  return x;
}

// Sobol direction numbers v_k = m_k 2^(32-k) of the first six dimensions (Joe & Kuo 2008,
// new-joe-kuo-6.21201: degree s, inner coefficients a, initial m; dimension 0 is van der Corput), by the
// recurrence m_k = 2 a_1 m_{k-1} ^ 4 a_2 m_{k-2} ^ ... ^ 2^(s-1) a_(s-1) m_(k-s+1) ^ 2^s m_{k-s} ^ m_{k-s}.
constexpr int kSobolDimensions = 6;
struct SobolPolynomial {
  int degree;
  uint32_t a;  // a_1 .. a_{s-1}, a_1 most significant
  uint32_t m[4];
};
inline constexpr SobolPolynomial kSobolPolynomials[kSobolDimensions] = {
    {0, 0, {0}}, {1, 0, {1}}, {2, 1, {1, 3}}, {3, 1, {1, 3, 1}}, {3, 2, {1, 1, 1}}, {4, 1, {1, 1, 3, 3}},
};
constexpr std::array<uint32_t, 32> sobol_direction_numbers(int dim) {
  std::array<uint32_t, 32> v{};
  if (dim == 0) {
    for (int k = 0; k < 32; ++k) v[k] = 1u << (31 - k);
    return v;
  }
  const SobolPolynomial &p = kSobolPolynomials[dim];
  const int s = p.degree;
  std::array<uint32_t, 32> m{};
  for (int k = 0; k < 32; ++k) {
    if (k < s) {
      m[k] = p.m[k];
    } else {
      uint32_t mk = m[k - s] ^ (m[k - s] << s);
      for (int j = 1; j < s; ++j)
        if ((p.a >> (s - 1 - j)) & 1u) mk ^= m[k - j] << j;
      m[k] = mk;
    }
    v[k] = m[k] << (31 - k);
  }
  return v;
}

// Sobol value of dimension `dim` at index i by the generator matrix (XOR of v_k over the set bits k of i).
constexpr uint32_t sobol_by_matrix(int dim, uint32_t i) {
  const std::array<uint32_t, 32> v = sobol_direction_numbers(dim);
  uint32_t r = 0u;
  for (int k = 0; i != 0u; i >>= 1, ++k)
    if (i & 1u) r ^= v[k];
  return r;
}

// Byte tables of the generator matrices for an index given in bit-reversed order r = reverse_bits(i), with
// bit-reversed columns, two dimensions per entry: dimension 2p in the low word of table[p], 2p + 1 in the
// high word. reverse_bits(sobol(dim, i)) is the XOR of the entries for the four bytes of r (bit j of r is bit
// 31 - j of i, whose column is v_{31-j}), so one set of four 64-bit look-ups gives a pair of dimensions. The
// shuffled index comes out of the Laine-Karras permutation in that order, and the scramble that follows
// works on reversed bits too, so neither needs a reversal.
constexpr int kSobolPairs = kSobolDimensions / 2;
struct SobolPairTables {
  uint64_t reversed[kSobolPairs][4][256];
};
constexpr SobolPairTables make_sobol_pair_tables() {
  SobolPairTables t{};
  for (int d = 0; d < kSobolDimensions; ++d) {
    const std::array<uint32_t, 32> v = sobol_direction_numbers(d);
    for (int b = 0; b < 4; ++b)
      for (uint32_t byte = 0; byte < 256u; ++byte) {
        uint32_t r = 0u;
        for (int bit = 0; bit < 8; ++bit)
          if ((byte >> bit) & 1u) r ^= reverse_bits(v[31 - (8 * b + bit)]);
        t.reversed[d / 2][b][byte] |= static_cast<uint64_t>(r) << (32 * (d % 2));
      }
  }
  return t;
}
inline constexpr SobolPairTables kSobolPairTables = make_sobol_pair_tables();

// reverse_bits(sobol(2p, i)) | reverse_bits(sobol(2p + 1, i)) << 32 for i = reverse_bits(index_reversed).
inline uint64_t sobol_pair_reversed(int pair, uint32_t index_reversed) {
  const auto &t = kSobolPairTables.reversed[pair];
  const uint32_t r = index_reversed;
  return t[0][r & 0xffu] ^ t[1][(r >> 8) & 0xffu] ^ t[2][(r >> 16) & 0xffu] ^ t[3][r >> 24];
}
// reverse_bits(sobol(dim, reverse_bits(index_reversed))).
inline uint32_t sobol_reversed(int dim, uint32_t index_reversed) {
  return static_cast<uint32_t>(sobol_pair_reversed(dim / 2, index_reversed) >> (32 * (dim % 2)));
}

// The float of a scrambled reversed value y: uint_to_unit_float(reverse_bits(y)) keeps the top 24 bits of
// reverse_bits(y), i.e. bytes 0-2 of y, each reversed: rev(y & 0xff) / 2^8 + rev(y >> 8 & 0xff) / 2^16 +
// rev(y >> 16 & 0xff) / 2^24. Each term has at most 8 significant bits and every partial sum is a multiple of
// 2^-24 below 1, so the float sums are exact: the same float as the reversal and conversion, without either
// (three look-ups in 3 KB and two additions instead of a bit reversal, a shift, a conversion and a multiply).
struct ReversedByteFloats {
  float value[3][256];
};
constexpr ReversedByteFloats make_reversed_byte_floats() {
  ReversedByteFloats t{};
  for (int j = 0; j < 3; ++j)
    for (uint32_t b = 0; b < 256u; ++b)
      t.value[j][b] = static_cast<float>(reverse_bits(b) >> 24) / static_cast<float>(1u << (8 * (j + 1)));
  return t;
}
inline constexpr ReversedByteFloats kReversedByteFloats = make_reversed_byte_floats();
// uint_to_unit_float(reverse_bits(y)), bit for bit.
inline float reversed_to_unit_float(uint32_t y) {
  const auto &t = kReversedByteFloats.value;
  return (t[0][y & 0xffu] + t[1][(y >> 8) & 0xffu]) + t[2][(y >> 16) & 0xffu];
}

// Scramble seed of dimension d of a set: the (already hashed) set seed times a per-dimension odd constant,
// a bijection, so every dimension's seed is as uniform as the set seed.
inline constexpr uint32_t kDimensionSeedOdd[kSobolDimensions] = {0x9e3779b9u, 0x85ebca6bu, 0xc2b2ae35u,
                                                                  0x27d4eb2fu, 0x165667b1u, 0xd3a2646du};
constexpr uint32_t dimension_seed(uint32_t set_seed, int d) { return set_seed * kDimensionSeedOdd[d]; }

// Dimension sets (Cycles' PRNG_* layout in spirit; docs/architecture.md "Sample dimensions"). A set is
// one shuffled index and the first 2, 4 or 6 Sobol dimensions, jointly stratified.
//   camera (vertex 0): 6D, the film position (u, v) and vertex 0's BSDF numbers (x, y, z, rr) under one
//     index, so the 4D point (film u, film v, x, y) is jointly stratified: at a highlight (a curved mirror
//     whose reflected lobe moves with the film position across the pixel) film and lobe samples do not
//     clump together as two independently scrambled 2D sets can. Film = Sobol dimensions 0-1 (a (0, 2)
//     sequence, the best anti-aliasing of edges), x, y = 2-3, z, rr = 4-5 (dimensions 0-3 form the
//     best-stratified 4D projection).
//   lens: 2D (its own set far from the others).
//   vertex 0's light: 2D (u, v): u picks the light (rescaled) and with v the point on it.
//   vertex b >= 1: one 6D set (since issue 13, session 9): light (u, v) = Sobol dimensions 0-1, BSDF x, y =
//     2-3, z = 4, rr = 5. x picks the closure of the mixture (rescaled), then the closure's own lobe choice
//     (rescaled again) and with y the direction; z is the closure's third number (dielectric
//     reflect/refract, decided on the sampled microfacet: jointly stratified with x, y); rr is Russian
//     roulette. Each vertex has its own set (padding).
//   Values nobody reads are not drawn: vertex 0's rr (Russian roulette never applies at vertices 0 and 1),
//   rr wherever bounce <= min_bounce, the light numbers where no light sample is taken. The others are the
//   same either way (every value is a pure function of seed, pixel, sample, set and dimension).
//   b counts transparent pass-throughs too (PathState::sample_vertex), so every surface a path meets
//   has its own sets.
enum SampleSet : uint32_t {
  kSetsPerBounce = 2,
  kSetBsdf = 0,   // within a bounce
  kSetLight = 1,  // within a bounce
};
constexpr uint32_t kSetLens = 0xfffffff0u;
inline uint32_t bounce_set(int bounce, uint32_t which) { return 1u + static_cast<uint32_t>(bounce) * kSetsPerBounce + which; }
// The camera set is vertex 0's BSDF set; its dimension pairs: film (u, v), BSDF (x, y), BSDF (z, rr).
constexpr uint32_t kSetCamera = 1u;  // bounce_set(0, kSetBsdf)
constexpr int kCameraFilmPair = 0, kCameraBsdfXyPair = 1, kCameraBsdfZrrPair = 2;
// The set of vertex b >= 1 is bounce_set(b, kSetBsdf); its pairs: light (u, v), BSDF (x, y), BSDF (z, rr).
constexpr int kVertexLightPair = 0, kVertexBsdfXyPair = 1, kVertexBsdfZrrPair = 2;
// What an undrawn number reads: rr = 1 ends a path that would wrongly read it (rr >= q for every q <= 1);
// light numbers are not read where they are not drawn.
constexpr float kUndrawnRr = 1.0f, kUndrawnLight = 0.5f;

// A set's seed and its shuffled index (Burley 2020, sec. 4: a nested uniform scramble of the sample index,
// kept reversed): PixelSampler::start_set.
struct SobolSetStart {
  uint32_t seed, index_reversed;
};
namespace sampler_draw {
// A vertex set's start drawn ahead (PixelSampler::get_vertex with `next`): set = start_set(bounce_set(vertex,
// kSetBsdf)) when vertex > 0; vertex 0 holds nothing.
struct NextVertex {
  alignas(32) uint32_t words[8] = {};  // lanes 0-5: sobol_reversed(d, set.index_reversed), lanes 6-7 zero
  int vertex = 0;
  SobolSetStart set{0u, 0u};
};
}  // namespace sampler_draw

// What a path starts with, drawn ahead for several paths at once (draw_path_starts):
//   value: PixelSampler::get_path_start's numbers in one 32-byte row: film u, v; vertex 0's BSDF x, y, z and
//     rr (kUndrawnRr: never read); vertex 0's light u, v (kUndrawnLight when not drawn);
//   vertex1: vertex 1's set start (PixelSampler::start_set(bounce_set(1, kSetBsdf))) and its six Sobol words,
//     the `next` of the path's first get_vertex;
//   pixel_seed, sample_reversed: the path's PixelSampler; path_seed = hash_u32x3(seed, pixel, sample).
struct alignas(32) PathStart {
  float value[8];
  sampler_draw::NextVertex vertex1;
  uint32_t pixel_seed, sample_reversed, path_seed;
  const float *film() const { return value; }
  const float *bsdf() const { return value + 2; }
  const float *light() const { return value + 6; }
};
// Path starts drawn together by draw_path_starts (at most this many per call).
constexpr int kPathStartBatch = 8;
// out[i] = the path start of (seed, pixels[i], samples[i]) for i < n <= kPathStartBatch, the same floats bit for
// bit as PixelSampler(seed, pixels[i], samples[i]).get_path_start(..., need_light), and the members above. The
// draws are independent, so their dependent chains (seed hashes, index shuffle, table rows, scrambles) overlap
// instead of each waiting at the start of its path; with AVX2 the hashes and shuffles of all n run in the lanes
// of a vector.
void draw_path_starts(uint32_t seed, const uint32_t *pixels, const uint32_t *samples, int n, bool need_light,
                      PathStart *out);

struct PixelSampler;
// Which code computes get_vertex's and get_path_start's values (bridge/render/sampler_draw.h): the scalar
// code below, or the same values with AVX2 (sampler_draw.cpp), chosen once at start-up from the CPU (and
// GLIMMER_SAMPLER_DRAW=scalar). Both give the same floats bit for bit (Sampler.VectorDrawEqualsScalarDraw).
namespace sampler_draw {
enum class Variant : uint8_t { kScalar = 0, kAvx2 = 1 };
extern Variant g_active;  // scalar until the start-up choice
void vertex_avx2(const PixelSampler &sampler, int vertex, float (&bsdf)[4], float (&light)[2], bool need_light,
                 bool need_rr);
void vertex_next_avx2(const PixelSampler &sampler, int vertex, NextVertex &next, float (&bsdf)[4],
                      float (&light)[2], bool need_light, bool need_rr);
void path_start_avx2(const PixelSampler &sampler, float (&film)[2], float (&bsdf)[4], float (&light)[2],
                     bool need_light);
void path_starts_avx2(uint32_t seed, const uint32_t *pixels, const uint32_t *samples, int n, bool need_light,
                      PathStart *out);
}  // namespace sampler_draw

struct PixelSampler {
  uint32_t pixel_seed;        // hash of (seed, pixel)
  uint32_t sample_reversed;   // reverse_bits(sample index)

  PixelSampler(uint32_t seed, uint32_t pixel_index, uint32_t sample_index)
      : pixel_seed(hash_u32x2(seed, pixel_index)), sample_reversed(reverse_bits(sample_index)) {}
  // The sampler of a path whose start was drawn by draw_path_starts (the same members).
  explicit PixelSampler(const PathStart &start) : pixel_seed(start.pixel_seed), sample_reversed(start.sample_reversed) {}

  // The first N Sobol dimensions of set `set` at this sample, each in [0, 1). Dimensions go by pairs: one
  // table look-up per index byte for both, one scramble each, one 64-bit reversal for both.
  template <int N>
  void get(uint32_t set, float (&out)[N]) const {
    const Set s = start_set(set);
    for (int p = 0; 2 * p < N; ++p) pair_values(s, p, out, 2 * p);
  }
  // The camera set: the film position (u, v) and vertex 0's BSDF numbers (x, y, z, rr).
  void get_camera(float (&film)[2], float (&bsdf)[4]) const {
    const Set c = start_set(kSetCamera);
    pair_values(c, kCameraFilmPair, film, 0);
    pair_values(c, kCameraBsdfXyPair, bsdf, 0);
    pair_values(c, kCameraBsdfZrrPair, bsdf, 2);
  }
  // The BSDF numbers (x, y, z, rr) and light numbers (u, v) of path vertex >= 1, from the vertex's one 6D set
  // (one seed hash and one index shuffle). need_light: a light sample will be taken here; need_rr: Russian
  // roulette can fire here (bounce > min_bounce). Numbers not needed are not drawn (kUndrawnLight, kUndrawnRr);
  // the others do not depend on which are drawn. Vertex 0's numbers are those of get_path_start.
  void get_vertex(int vertex, float (&bsdf)[4], float (&light)[2], bool need_light = true, bool need_rr = true) const {
    if (vertex == 0) {
      float film[2];
      get_path_start(film, bsdf, light, need_light);
      return;
    }
    if (sampler_draw::g_active == sampler_draw::Variant::kAvx2) {
      sampler_draw::vertex_avx2(*this, vertex, bsdf, light, need_light, need_rr);
      return;
    }
    get_vertex_scalar(vertex, bsdf, light, need_light, need_rr);
  }
  // get_vertex's values along a path (vertex >= 1), with `next` carried from one vertex to the next: when it holds
  // this vertex's set start (drawn ahead) the draw begins at its table rows; then it starts vertex + 1's set into
  // `next`, beside this draw's chain instead of at the head of the next one. The same values as get_vertex
  // whatever `next` holds (Sampler.VertexDrawnAheadEqualsScalarDraw).
  void get_vertex(int vertex, sampler_draw::NextVertex &next, float (&bsdf)[4], float (&light)[2], bool need_light,
                  bool need_rr) const {
    if (sampler_draw::g_active == sampler_draw::Variant::kAvx2) {
      sampler_draw::vertex_next_avx2(*this, vertex, next, bsdf, light, need_light, need_rr);
      return;
    }
    get_vertex_scalar(vertex, bsdf, light, need_light, need_rr);
  }
  // get_vertex's values by the scalar code (vertex >= 1), whatever the active variant.
  void get_vertex_scalar(int vertex, float (&bsdf)[4], float (&light)[2], bool need_light, bool need_rr) const {
    const Set v = start_set(bounce_set(vertex, kSetBsdf));
    pair_values(v, kVertexBsdfXyPair, bsdf, 0);
    const uint64_t zrr = sobol_pair_reversed(kVertexBsdfZrrPair, v.index_reversed);
    bsdf[2] = value(v, zrr, 2 * kVertexBsdfZrrPair);
    bsdf[3] = need_rr ? value(v, zrr, 2 * kVertexBsdfZrrPair + 1) : kUndrawnRr;
    if (need_light) {
      pair_values(v, kVertexLightPair, light, 0);
    } else {
      light[0] = light[1] = kUndrawnLight;
    }
  }
  // The camera set (film position and vertex 0's BSDF numbers x, y, z; its rr is never read: Russian roulette
  // needs bounce > min_bounce >= 1) with vertex 0's light set when need_light: two independent chains side
  // by side at the start of a path (the same values as get_camera and get_light(0, ...)).
  void get_path_start(float (&film)[2], float (&bsdf)[4], float (&light)[2], bool need_light = true) const {
    if (sampler_draw::g_active == sampler_draw::Variant::kAvx2) {
      sampler_draw::path_start_avx2(*this, film, bsdf, light, need_light);
      return;
    }
    get_path_start_scalar(film, bsdf, light, need_light);
  }
  // get_path_start's values by the scalar code, whatever the active variant.
  void get_path_start_scalar(float (&film)[2], float (&bsdf)[4], float (&light)[2], bool need_light) const {
    const Set c = start_set(kSetCamera);
    if (need_light) {
      const Set l = start_set(bounce_set(0, kSetLight));
      pair_values(c, kCameraFilmPair, film, 0);
      pair_values(l, 0, light, 0);
    } else {
      pair_values(c, kCameraFilmPair, film, 0);
      light[0] = light[1] = kUndrawnLight;
    }
    pair_values(c, kCameraBsdfXyPair, bsdf, 0);
    bsdf[2] = value(c, sobol_pair_reversed(kCameraBsdfZrrPair, c.index_reversed), 2 * kCameraBsdfZrrPair);
    bsdf[3] = kUndrawnRr;
  }
  void get2(uint32_t set, float &u, float &v) const {
    float uv[2];
    get(set, uv);
    u = uv[0];
    v = uv[1];
  }
  // The BSDF dimensions (x, y, z, rr) of a vertex (vertex 0: from the camera set), every one drawn.
  void get_bsdf(int vertex, float (&out)[4]) const {
    if (vertex == 0) {
      float film[2];
      get_camera(film, out);
      return;
    }
    float six[6];
    get(bounce_set(vertex, kSetBsdf), six);
    for (int d = 0; d < 2; ++d) {
      out[d] = six[2 * kVertexBsdfXyPair + d];
      out[2 + d] = six[2 * kVertexBsdfZrrPair + d];
    }
  }
  // The light numbers of a vertex (vertex 0: its own 2D set).
  void get_light(int vertex, float &u, float &v) const {
    if (vertex == 0) {
      get2(bounce_set(0, kSetLight), u, v);
      return;
    }
    float six[6];
    get(bounce_set(vertex, kSetBsdf), six);
    u = six[2 * kVertexLightPair];
    v = six[2 * kVertexLightPair + 1];
  }

  // A set's start (SobolSetStart). Public for the vector draws (sampler_draw.cpp), which share this scalar start.
  using Set = SobolSetStart;
  [[gnu::always_inline]] Set start_set(uint32_t set) const {
    const uint32_t set_seed = hash_combine(pixel_seed, set);
    return {set_seed, laine_karras_permutation(sample_reversed, set_seed)};
  }

 private:
  // Dimension d of set s from its pair's table word `sobol` (sobol_pair_reversed(d / 2, ...)): its scramble and
  // the float of the reversed bits.
  [[gnu::always_inline]] static float value(const Set &s, uint64_t sobol, int d) {
    const uint32_t word = static_cast<uint32_t>(sobol >> (32 * (d % 2)));
    return reversed_to_unit_float(laine_karras_permutation(word, dimension_seed(s.seed, d)));
  }
  // Dimensions 2p and 2p + 1 of set s into out[first] and out[first + 1] (the second only if N has it): one
  // table look-up per index byte for both, then per dimension its scramble and the float of the reversed bits.
  template <int N>
  [[gnu::always_inline]] static void pair_values(const Set &s, int p, float (&out)[N], int first) {
    static_assert(N >= 1 && N <= kSobolDimensions);
    const uint64_t sobol = sobol_pair_reversed(p, s.index_reversed);
    out[first] = reversed_to_unit_float(laine_karras_permutation(static_cast<uint32_t>(sobol), dimension_seed(s.seed, 2 * p)));
    if (first + 1 < N)
      out[first + 1] =
          reversed_to_unit_float(laine_karras_permutation(static_cast<uint32_t>(sobol >> 32), dimension_seed(s.seed, 2 * p + 1)));
  }
};

}  // namespace glimmer::render
