// The sampler's vector draws (sampler_draw.h): AVX2 code behind a runtime check, with the scalar code of
// sampler.h as the fallback.
#include "render/sampler_draw.h"

#include <immintrin.h>

#include <array>
#include <cstdlib>
#include <cstring>

#include "glimmer/lane_constants.h"
#include "glimmer/rng.h"

namespace glimmer::render::sampler_draw {

namespace {
Variant choose_at_startup() {
  const char *forced = std::getenv("GLIMMER_SAMPLER_DRAW");
  if (forced != nullptr && std::strcmp(forced, "scalar") == 0) return Variant::kScalar;
  return supported(Variant::kAvx2) ? Variant::kAvx2 : Variant::kScalar;
}
const Variant g_startup_choice = choose_at_startup();
}  // namespace

// Zero-initialised (scalar) before the dynamic initialisation below, so a draw before it is still correct.
Variant g_active = g_startup_choice;

bool supported(Variant variant) {
  if (variant == Variant::kScalar) return true;
  __builtin_cpu_init();  // needed before __builtin_cpu_supports in code that may run before main
  return __builtin_cpu_supports("avx2") != 0;
}
Variant startup_choice() { return g_startup_choice; }
Variant set_active(Variant variant) {
  const Variant before = g_active;
  g_active = supported(variant) ? variant : Variant::kScalar;
  return before;
}
const char *name(Variant variant) { return variant == Variant::kAvx2 ? "avx2" : "scalar"; }

// Everything from here on is compiled for AVX2 and only called when supported(Variant::kAvx2). The inline
// functions of sampler.h (included above) keep the baseline target and are inlined into these. Clang ignores GCC's
// target pragma (`make fuzz` builds with clang), so there every function below takes the target attribute instead.
#if defined(__clang__)
#pragma clang attribute push(__attribute__((target("avx2"))), apply_to = function)
#else
#pragma GCC push_options
#pragma GCC target("avx2")
#endif

namespace {

// Four Laine-Karras rounds on eight 32-bit lanes (sampler.h laine_karras_permutation): x += seed, then
// x ^= x * c for each round constant c. vpmulld keeps the low 32 bits of each product, as the scalar multiply.
// The four constants are arguments so a test can pass wrong ones (production: laine_karras8 below).
inline __m256i laine_karras8_with(__m256i x, __m256i seed, __m256i c0, __m256i c1, __m256i c2, __m256i c3) {
  x = _mm256_add_epi32(x, seed);
  x = _mm256_xor_si256(x, _mm256_mullo_epi32(x, c0));
  x = _mm256_xor_si256(x, _mm256_mullo_epi32(x, c1));
  x = _mm256_xor_si256(x, _mm256_mullo_epi32(x, c2));
  x = _mm256_xor_si256(x, _mm256_mullo_epi32(x, c3));
  return x;
}
inline __m256i broadcast(uint32_t c) { return _mm256_set1_epi32(static_cast<int>(c)); }
// Eight copies of each production round constant, read from memory by the multiplies (vpmulld's memory
// operand), which GCC does not do for _mm256_set1_epi32 of a constant (glimmer/lane_constants.h).
alignas(32) constexpr Lanes8 kRounds8[4] = {lanes8(kLaineKarrasRounds[0]), lanes8(kLaineKarrasRounds[1]),
                                            lanes8(kLaineKarrasRounds[2]), lanes8(kLaineKarrasRounds[3])};
inline __m256i load(const Lanes8 &l) { return _mm256_load_si256(reinterpret_cast<const __m256i *>(l.lane)); }
inline __m256i laine_karras8(__m256i x, __m256i seed) {
  const Lanes8 *r = opaque(kRounds8);
  return laine_karras8_with(x, seed, load(r[0]), load(r[1]), load(r[2]), load(r[3]));
}

alignas(32) constexpr Lanes8 kNibbleMask = lanes8(0x0f0f0f0fu);
// rev4(n) << 4 (a low nibble reversed into the high one) and rev4(n) (a high nibble into the low one).
#define GLIMMER_REV4_HIGH 0x00, 0x80, 0x40, 0xc0, 0x20, 0xa0, 0x60, 0xe0, 0x10, 0x90, 0x50, 0xd0, 0x30, 0xb0, 0x70, 0xf0
#define GLIMMER_REV4_LOW 0x0, 0x8, 0x4, 0xc, 0x2, 0xa, 0x6, 0xe, 0x1, 0x9, 0x5, 0xd, 0x3, 0xb, 0x7, 0xf
alignas(32) constexpr uint8_t kLowToHigh[32] = {GLIMMER_REV4_HIGH, GLIMMER_REV4_HIGH};
alignas(32) constexpr uint8_t kHighToLow[32] = {GLIMMER_REV4_LOW, GLIMMER_REV4_LOW};
#undef GLIMMER_REV4_HIGH
#undef GLIMMER_REV4_LOW
// The bits of every byte reversed (rev8 of each byte): two vpshufb of 16-entry tables reverse and swap its nibbles.
inline __m256i reverse_byte_bits8(__m256i z) {
  const __m256i low_to_high = _mm256_load_si256(reinterpret_cast<const __m256i *>(kLowToHigh));
  const __m256i high_to_low = _mm256_load_si256(reinterpret_cast<const __m256i *>(kHighToLow));
  const __m256i nibble = load(*opaque(&kNibbleMask));
  const __m256i lo = _mm256_and_si256(z, nibble);
  const __m256i hi = _mm256_and_si256(_mm256_srli_epi16(z, 4), nibble);
  return _mm256_or_si256(_mm256_shuffle_epi8(low_to_high, lo), _mm256_shuffle_epi8(high_to_low, hi));
}
// uint_to_unit_float(reverse_bits(y)) in each lane, bit for bit as reversed_to_unit_float: the float keeps
// reverse_bits(y) >> 8 = rev8(y0) << 16 | rev8(y1) << 8 | rev8(y2) (yk: byte k of y, rev8: its bits
// reversed). One vpshufb moves bytes 0, 1, 2 to 2, 1, 0 and clears byte 3; two vpshufb of 16-entry tables
// reverse the two nibbles of every byte and swap them. The 24-bit integer converts exactly and the scale by
// 2^-24 is exact.
inline __m256 reversed_to_unit_float8(__m256i y) {
  const __m256i byte_order = _mm256_setr_epi8(2, 1, 0, -128, 6, 5, 4, -128, 10, 9, 8, -128, 14, 13, 12, -128,  //
                                              2, 1, 0, -128, 6, 5, 4, -128, 10, 9, 8, -128, 14, 13, 12, -128);
  const __m256i r = reverse_byte_bits8(_mm256_shuffle_epi8(y, byte_order));
  return _mm256_mul_ps(_mm256_cvtepi32_ps(r), _mm256_set1_ps(1.0f / 16777216.0f));
}

// The Sobol generator matrices of dimensions 0-5 for the vector draw, by index nibble: row [n][v] holds in lane d
// the XOR of the bit-reversed columns for the set bits of v at nibble n (bits 4n..4n+3) of the bit-reversed
// index, i.e. sobol_reversed(d, v << 4n) (the same matrices as kSobolPairTables, cut by nibble instead of
// byte). A set's six Sobol words are then the XOR of eight 32-byte rows: 4 KB of table, which stays in the L1
// cache where the pair tables take 24 KB, and the rows are loaded straight into a vector register.
struct SobolNibbleRows {
  Lanes8 row[8][16];
};
constexpr SobolNibbleRows make_sobol_nibble_rows() {
  SobolNibbleRows t{};
  for (int d = 0; d < kSobolDimensions; ++d) {
    const std::array<uint32_t, 32> v = sobol_direction_numbers(d);
    for (int n = 0; n < 8; ++n)
      for (uint32_t nib = 0; nib < 16u; ++nib) {
        uint32_t r = 0u;
        for (int bit = 0; bit < 4; ++bit)
          if ((nib >> bit) & 1u) r ^= reverse_bits(v[31 - (4 * n + bit)]);
        t.row[n][nib].lane[d] = r;
      }
  }
  return t;
}
alignas(32) constexpr SobolNibbleRows kSobolNibbleRows = make_sobol_nibble_rows();

// Lane d (0-5) = sobol_reversed(d, index_reversed); lanes 6-7 zero.
// The row of nibble n is at byte offset 512 n + 32 v: v * 32 = (r >> (4 n - 5)) & 0x1e0, one shift and one mask.
template <int N>
inline __m256i nibble_row(const char *rows, uint32_t r) {
  constexpr int kShift = 4 * N - 5;
  const uint32_t offset = (kShift >= 0 ? r >> (kShift < 0 ? 0 : kShift) : r << (kShift < 0 ? -kShift : 0)) & 0x1e0u;
  return _mm256_load_si256(reinterpret_cast<const __m256i *>(rows + 512 * N + offset));
}
inline __m256i sobol_words8(uint32_t index_reversed) {
  static_assert(sizeof(Lanes8) == 32 && sizeof(SobolNibbleRows) == 8 * 16 * 32);
  const char *rows = reinterpret_cast<const char *>(opaque(&kSobolNibbleRows));
  const uint32_t r = index_reversed;
  const __m256i a = _mm256_xor_si256(nibble_row<0>(rows, r), nibble_row<1>(rows, r));
  const __m256i b = _mm256_xor_si256(nibble_row<2>(rows, r), nibble_row<3>(rows, r));
  const __m256i c = _mm256_xor_si256(nibble_row<4>(rows, r), nibble_row<5>(rows, r));
  const __m256i d = _mm256_xor_si256(nibble_row<6>(rows, r), nibble_row<7>(rows, r));
  return _mm256_xor_si256(_mm256_xor_si256(a, b), _mm256_xor_si256(c, d));
}

// Two floats to out[0], out[1]: lanes 0-1 (store_low) or 2-3 (store_high) of `lanes`.
inline void store_low(float *out, __m128 lanes) { _mm_storel_pi(reinterpret_cast<__m64 *>(out), lanes); }
inline void store_high(float *out, __m128 lanes) { _mm_storeh_pi(reinterpret_cast<__m64 *>(out), lanes); }

}  // namespace

namespace {
// Per-lane dimension seeds: lanes 0-5 take dimensions 0-5 of the set whose seed is in lanes 0-5 of
// set_seeds, lanes 6-7 dimensions 0-1 of the set in lanes 6-7 (get_path_start's light set).
inline __m256i lane_seeds(__m256i set_seeds) {
  alignas(32) static constexpr Lanes8 kOdd = {{kDimensionSeedOdd[0], kDimensionSeedOdd[1], kDimensionSeedOdd[2],
                                               kDimensionSeedOdd[3], kDimensionSeedOdd[4], kDimensionSeedOdd[5],
                                               kDimensionSeedOdd[0], kDimensionSeedOdd[1]}};
  return _mm256_mullo_epi32(set_seeds, load(*opaque(&kOdd)));
}
inline __m256i set1(uint32_t x) { return _mm256_set1_epi32(static_cast<int>(x)); }
}  // namespace

// get_vertex_scalar's values (vertex >= 1): one 6D set, lanes 0-5 = Sobol dimensions 0-5 = light (u, v),
// BSDF (x, y), (z, rr). All six are scrambled (the lanes cost the same); the numbers not needed are then
// overwritten with the undrawn constants, as the scalar code never draws them.
namespace {
inline void vertex_draw_words(__m256i words, uint32_t seed, float (&bsdf)[4], float (&light)[2], bool need_light,
                              bool need_rr) {
  static_assert(kVertexLightPair == 0 && kVertexBsdfXyPair == 1 && kVertexBsdfZrrPair == 2);
  const __m256 f = reversed_to_unit_float8(laine_karras8(words, lane_seeds(set1(seed))));
  const __m128 lo = _mm256_castps256_ps128(f), hi = _mm256_extractf128_ps(f, 1);
  store_high(bsdf, lo);
  store_low(bsdf + 2, hi);
  if (!need_rr) bsdf[3] = kUndrawnRr;
  if (need_light) {
    store_low(light, lo);
  } else {
    light[0] = light[1] = kUndrawnLight;
  }
}
inline void vertex_draw(const PixelSampler::Set &v, float (&bsdf)[4], float (&light)[2], bool need_light,
                        bool need_rr) {
  vertex_draw_words(sobol_words8(v.index_reversed), v.seed, bsdf, light, need_light, need_rr);
}
}  // namespace

void vertex_avx2(const PixelSampler &sampler, int vertex, float (&bsdf)[4], float (&light)[2], bool need_light,
                 bool need_rr) {
  vertex_draw(sampler.start_set(bounce_set(vertex, kSetBsdf)), bsdf, light, need_light, need_rr);
}

// vertex_avx2 with the set's start and Sobol words from `next` when they were drawn ahead for this vertex;
// vertex + 1's (seed hash and index shuffle, scalar; its eight table rows) then go into `next`, independent of
// this draw's chain.
void vertex_next_avx2(const PixelSampler &sampler, int vertex, NextVertex &next, float (&bsdf)[4],
                      float (&light)[2], bool need_light, bool need_rr) {
  const bool ahead = next.vertex == vertex;
  const PixelSampler::Set v = ahead ? next.set : sampler.start_set(bounce_set(vertex, kSetBsdf));
  const __m256i words = ahead ? _mm256_load_si256(reinterpret_cast<const __m256i *>(next.words))
                              : sobol_words8(v.index_reversed);
  next.vertex = vertex + 1;
  next.set = sampler.start_set(bounce_set(vertex + 1, kSetBsdf));
  _mm256_store_si256(reinterpret_cast<__m256i *>(next.words), sobol_words8(next.set.index_reversed));
  vertex_draw_words(words, v.seed, bsdf, light, need_light, need_rr);
}

// get_path_start_scalar's values in one vector: the camera set's Sobol dimensions 0-5 in lanes 0-5 (film u,
// v; BSDF x, y; z and the undrawn rr), vertex 0's light set's pair 0 (its pair-table word) in lanes 6-7.
void path_start_avx2(const PixelSampler &sampler, float (&film)[2], float (&bsdf)[4], float (&light)[2],
                     bool need_light) {
  static_assert(kCameraFilmPair == 0 && kCameraBsdfXyPair == 1 && kCameraBsdfZrrPair == 2);
  const PixelSampler::Set c = sampler.start_set(kSetCamera);
  PixelSampler::Set l{0u, 0u};
  uint64_t light_word = 0u;
  if (need_light) {
    l = sampler.start_set(bounce_set(0, kSetLight));
    light_word = sobol_pair_reversed(0, l.index_reversed);
  }
  const __m256i words = _mm256_xor_si256(sobol_words8(c.index_reversed),  // lanes 6-7 of the rows are zero
                                         _mm256_set_epi64x(static_cast<long long>(light_word), 0, 0, 0));
  const __m256i set_seeds = _mm256_blend_epi32(set1(c.seed), set1(l.seed), 0xc0);
  const __m256 f = reversed_to_unit_float8(laine_karras8(words, lane_seeds(set_seeds)));
  const __m128 lo = _mm256_castps256_ps128(f), hi = _mm256_extractf128_ps(f, 1);
  store_low(film, lo);
  store_high(bsdf, lo);
  bsdf[2] = _mm_cvtss_f32(hi);
  bsdf[3] = kUndrawnRr;
  if (need_light) {
    store_high(light, hi);
  } else {
    light[0] = light[1] = kUndrawnLight;
  }
}

namespace {
// reverse_bits in each lane: the byte swap by one vpshufb, then each byte's bits reversed.
inline __m256i reverse_bits8(__m256i x) {
  const __m256i byte_swap = _mm256_setr_epi8(3, 2, 1, 0, 7, 6, 5, 4, 11, 10, 9, 8, 15, 14, 13, 12,  //
                                             3, 2, 1, 0, 7, 6, 5, 4, 11, 10, 9, 8, 15, 14, 13, 12);
  return reverse_byte_bits8(_mm256_shuffle_epi8(x, byte_swap));
}
// hash_u32 (glimmer/rng.h) in each lane: vpmulld for the multiplies, vpsrlvd for the state-dependent shift.
alignas(32) constexpr Lanes8 kHashMul[2] = {lanes8(kPcgMultiplier), lanes8(kPcgOutputMultiplier)};
inline __m256i hash_u32_8(__m256i v) {
  const Lanes8 *m = opaque(kHashMul);
  const __m256i state = _mm256_add_epi32(_mm256_mullo_epi32(v, load(m[0])), set1(kPcgIncrement));
  const __m256i shift = _mm256_add_epi32(_mm256_srli_epi32(state, 28), set1(4u));
  const __m256i word = _mm256_mullo_epi32(_mm256_xor_si256(_mm256_srlv_epi32(state, shift), state), load(m[1]));
  return _mm256_xor_si256(_mm256_srli_epi32(word, 22), word);
}
// hash_combine(seed, v) in each lane.
inline __m256i hash_combine8(__m256i seed, __m256i v) {
  const __m256i mix = _mm256_add_epi32(_mm256_add_epi32(v, set1(0x9e3779b9u)),
                                       _mm256_add_epi32(_mm256_slli_epi32(seed, 6), _mm256_srli_epi32(seed, 2)));
  return hash_u32_8(_mm256_xor_si256(seed, mix));
}
// The starts (seed, shuffled index) of the camera set and of vertex 0's light set for up to eight paths, lane i
// = path i: pixel seed hash_u32x2(seed, pixel), the set seeds, the reversed sample index and its shuffles.
struct PathStartSets {
  alignas(32) uint32_t camera_seed[8], camera_index[8], light_seed[8], light_index[8];
};
void start_sets8(uint32_t seed, const uint32_t *pixels, const uint32_t *samples, int n, bool need_light,
                 PathStartSets &sets, PathStart *out) {
  alignas(32) uint32_t pixel[8] = {}, sample[8] = {};
  for (int i = 0; i < n; ++i) {
    pixel[i] = pixels[i];
    sample[i] = samples[i];
  }
  const __m256i pixel_seed =
      hash_combine8(set1(hash_u32(seed)), _mm256_load_si256(reinterpret_cast<const __m256i *>(pixel)));
  const __m256i sample_reversed = reverse_bits8(_mm256_load_si256(reinterpret_cast<const __m256i *>(sample)));
  // The members of PathStart besides the numbers: five words per path, transposed from the lanes (vertex 1's
  // Sobol words are stored by the caller).
  const __m256i vertex1_seed = hash_combine8(pixel_seed, set1(bounce_set(1, kSetBsdf)));
  alignas(32) uint32_t words[5][8];
  _mm256_store_si256(reinterpret_cast<__m256i *>(words[0]), pixel_seed);
  _mm256_store_si256(reinterpret_cast<__m256i *>(words[1]), sample_reversed);
  _mm256_store_si256(reinterpret_cast<__m256i *>(words[2]),
                     hash_combine8(pixel_seed, _mm256_load_si256(reinterpret_cast<const __m256i *>(sample))));
  _mm256_store_si256(reinterpret_cast<__m256i *>(words[3]), vertex1_seed);
  _mm256_store_si256(reinterpret_cast<__m256i *>(words[4]), laine_karras8(sample_reversed, vertex1_seed));
  for (int i = 0; i < n; ++i) {
    out[i].pixel_seed = words[0][i];
    out[i].sample_reversed = words[1][i];
    out[i].path_seed = words[2][i];
    out[i].vertex1.vertex = 1;
    out[i].vertex1.set = {words[3][i], words[4][i]};
  }
  const __m256i camera_seed = hash_combine8(pixel_seed, set1(kSetCamera));
  _mm256_store_si256(reinterpret_cast<__m256i *>(sets.camera_seed), camera_seed);
  _mm256_store_si256(reinterpret_cast<__m256i *>(sets.camera_index), laine_karras8(sample_reversed, camera_seed));
  __m256i light_seed = _mm256_setzero_si256(), light_index = _mm256_setzero_si256();
  if (need_light) {
    light_seed = hash_combine8(pixel_seed, set1(bounce_set(0, kSetLight)));
    light_index = laine_karras8(sample_reversed, light_seed);
  }
  _mm256_store_si256(reinterpret_cast<__m256i *>(sets.light_seed), light_seed);
  _mm256_store_si256(reinterpret_cast<__m256i *>(sets.light_index), light_index);
}
}  // namespace

// path_start_avx2's values for up to eight paths: their set starts side by side in the lanes (start_sets8),
// then per path the one-vector draw, whose chains are independent of each other; each path's eight floats are
// stored as one row (the undrawn numbers blended in).
void path_starts_avx2(uint32_t seed, const uint32_t *pixels, const uint32_t *samples, int n, bool need_light,
                      PathStart *out) {
  PathStartSets sets;
  start_sets8(seed, pixels, samples, n, need_light, sets, out);
  const __m256 undrawn = _mm256_setr_ps(0.0f, 0.0f, 0.0f, 0.0f, 0.0f, kUndrawnRr, kUndrawnLight, kUndrawnLight);
  const __m256 take_undrawn =
      _mm256_castsi256_ps(_mm256_setr_epi32(0, 0, 0, 0, 0, -1, need_light ? 0 : -1, need_light ? 0 : -1));
  for (int i = 0; i < n; ++i) {
    const uint64_t light_word = need_light ? sobol_pair_reversed(0, sets.light_index[i]) : 0u;
    const __m256i words = _mm256_xor_si256(sobol_words8(sets.camera_index[i]),  // lanes 6-7 of the rows are zero
                                           _mm256_set_epi64x(static_cast<long long>(light_word), 0, 0, 0));
    const __m256i set_seeds = _mm256_blend_epi32(set1(sets.camera_seed[i]), set1(sets.light_seed[i]), 0xc0);
    const __m256 f = reversed_to_unit_float8(laine_karras8(words, lane_seeds(set_seeds)));
    _mm256_store_ps(out[i].value, _mm256_blendv_ps(f, undrawn, take_undrawn));
    _mm256_store_si256(reinterpret_cast<__m256i *>(out[i].vertex1.words), sobol_words8(out[i].vertex1.set.index_reversed));
  }
}

void scramble_to_floats_avx2(const uint32_t (&words)[8], const uint32_t (&seeds)[8], const uint32_t (&rounds)[4],
                             float (&out)[8]) {
  const __m256i w = _mm256_loadu_si256(reinterpret_cast<const __m256i *>(words));
  const __m256i s = _mm256_loadu_si256(reinterpret_cast<const __m256i *>(seeds));
  const __m256i x = laine_karras8_with(w, s, broadcast(rounds[0]), broadcast(rounds[1]), broadcast(rounds[2]), broadcast(rounds[3]));
  _mm256_storeu_ps(out, reversed_to_unit_float8(x));
}

#if defined(__clang__)
#pragma clang attribute pop
#else
#pragma GCC pop_options
#endif

}  // namespace glimmer::render::sampler_draw

namespace glimmer::render {

void draw_path_starts(uint32_t seed, const uint32_t *pixels, const uint32_t *samples, int n, bool need_light,
                      PathStart *out) {
  if (sampler_draw::g_active == sampler_draw::Variant::kAvx2) {
    sampler_draw::path_starts_avx2(seed, pixels, samples, n, need_light, out);
    return;
  }
  for (int i = 0; i < n; ++i) {
    float film[2], bsdf[4], light[2];
    const PixelSampler sampler(seed, pixels[i], samples[i]);
    sampler.get_path_start_scalar(film, bsdf, light, need_light);
    float *v = out[i].value;
    v[0] = film[0], v[1] = film[1], v[2] = bsdf[0], v[3] = bsdf[1], v[4] = bsdf[2], v[5] = bsdf[3];
    v[6] = light[0], v[7] = light[1];
    out[i].pixel_seed = sampler.pixel_seed;
    out[i].sample_reversed = sampler.sample_reversed;
    out[i].path_seed = hash_u32x3(seed, pixels[i], samples[i]);
    const PixelSampler::Set vertex1 = sampler.start_set(bounce_set(1, kSetBsdf));
    out[i].vertex1.vertex = 1;
    out[i].vertex1.set = vertex1;
    for (int d = 0; d < 8; ++d)
      out[i].vertex1.words[d] = d < kSobolDimensions ? sobol_reversed(d, vertex1.index_reversed) : 0u;
  }
}

}  // namespace glimmer::render
