// Spatial and directional randomness of the separable glint model (after
// Wang et al. 2018, sec. 4.3, Algorithm 1): particles scattered over the uv
// plane, counted inside a footprint, each particle reflecting when its random
// threshold lambda is below the directional probability P(wi, wo).
//
// Direction cells (twinkle). In the exact discrete model (Jakob 2014) a
// particle is lit while its mirror direction lies within gamma of wo: the lit
// set decorrelates when wo (or wi) moves by about gamma. Here the half-vector
// plane is cut into cells of the size of a particle's lit region, and every
// cell carries its own independent particle field: a particle of cell c is
// lit when its threshold for that cell is below P. The lit region of a
// particle in the half-vector domain is an ellipse, semi-axes gamma / 2 in the
// plane of incidence and gamma / (2 wi.h) across it (the half-vector map
// r -> normalize(wi + r) has derivative (I - h h^T) / |wi + r|, foreshortened
// by wo.h = wi.h in the plane of incidence), so the cell coordinates are the
// stereographic chart of h (p = 2 (h.x, h.y) / (1 + h.z), conformal, ~ the
// polar angle near the normal) compressed by wi.h across the plane of
// incidence and divided by kCellSize gamma / 2; the compression vanishes at
// wi.h = 1, so it is continuous where the plane of incidence is undefined.
// kDirectionGroups groups of particles (density N / G each) use grids
// shifted by a fraction of a cell, so crossing a cell border renews 1/G of
// the glints, not all of them. Everything is a pure function of (uv, wi, wo):
// no temporal noise.
//
// Particle field. The (scaled) uv plane is cut into square nodes of side
// s = 2^-l. The particles of a group are a Poisson process of density N / G:
// node (l, i, j) holds Poisson(N s^2 / G) of them (issue 10's speed work; the
// count was floor(N s^2 / G) + Bernoulli before, which needed one more hash per
// node and group and a binomial instead of a Poisson lit count). The
// particles live at ONE level per material, the particle level l* whose nodes
// hold kNodeParticles / 4 .. kNodeParticles particles per group on average, so
// a footprint counts the same particles whatever its size (zoom and resolution keep the glints; counts grow
// monotonically with nested footprints). A footprint is counted over the
// nodes of that level it overlaps, found by rasterising the parallelogram row
// by row (a long thin footprint touches O(length) nodes, not its bounding
// box). Footprints overlapping more than kMaxNodes nodes fall back to a
// coarser level whose node side is >= the footprint's bounding box (at most
// 2 x 2 nodes, an independent field per level: Wang's Algorithm 1); with the
// default filter_threshold these footprints hold thousands of particles and
// are filtered anyway. The lit count of a node comes from one integer hash of
// the node id and the cell seed, and the positions of its
// lit particles from a hash of that hash (drawn only for lit nodes on the
// footprint's border; before the speed work of issue 10 a TEA stream of 8
// rounds per node, which cost more than the rest of a small footprint's
// count).
//
// Lit counts in closed form. Each particle reflects when its i.i.d. uniform
// threshold is below P, so a node holds K ~ Poisson(N s^2 P / G) reflecting
// particles, at i.i.d. uniform positions in the node. K is drawn by
// inverting the Poisson tail at one uniform per node (see LitCountModel):
// monotone in P, so inside one direction cell the set of reflecting
// particles is nested in P (no flicker from the trilinear table lookups),
// and E[K] = N s^2 P / G exactly. A node inside the footprint adds K with
// no position drawn; a node on its border draws the K lit positions and
// counts those inside the parallelogram (exact membership instead of
// Algorithm 1's fractional overlap). Until issue 10's speed work the
// thresholds' order statistics were walked one particle at a time (Renyi's
// representation, a log and an exp per particle).
#pragma once

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <optional>
#include <span>
#include <string_view>
#include <type_traits>
#include <utility>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif
// Session 20: pass 2 of the pair passes has an AVX2 form (two nodes' four
// group hashes per 256-bit register, VPMULLD), chosen at load time where the
// CPU has AVX2 (GCC / Clang on x86-64; `#pragma`-free: only the functions
// marked target("avx2") use it, so the rest of the plugin stays SSE2).
#if defined(__SSE2__) && defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define GLIMMER_GLINT_WALK_AVX2 1
#include <immintrin.h>
#else
#define GLIMMER_GLINT_WALK_AVX2 0
#endif

#include "glimmer/lane_constants.h"
#include "glimmer/math.h"
#include "glimmer/rng.h"

namespace glimmer::plugin::glint {

// Whether the walk uses its AVX2 forms (the pair passes; session 20): where the CPU has AVX2, unless the environment says
// GLIMMER_GLINT_WALK=sse2 (read once, when the plugin loads).
inline bool detect_walk_avx2() {
#if GLIMMER_GLINT_WALK_AVX2
  __builtin_cpu_init();
  if (!__builtin_cpu_supports("avx2")) return false;
  const char *env = std::getenv("GLIMMER_GLINT_WALK");
  return env == nullptr || std::string_view(env) != "sse2";
#else
  return false;
#endif
}
inline const bool kWalkAvx2 = detect_walk_avx2();

// Parallelogram c + s a + t b, |s|, |t| <= 1/2, in scaled uv units.
struct Footprint {
  double cx = 0, cy = 0;
  double ax = 0, ay = 0, bx = 0, by = 0;
  double area() const { return std::fabs(ax * by - ay * bx); }
};

// Inline helpers for the per-eval geometry: without -ffinite-math-only and
// SSE4.1, std::floor, std::fmin/fmax, std::frexp and std::ldexp are library
// calls, which cost more than the rest of a small footprint's count.
// floor(x) as an integer, x clamped to +-2^62 (NaN to -2^62).
inline int64_t floor_to_int64(double x) {
  constexpr double kLimit = 4.611686018427388e18;
  x = x > -kLimit ? (x < kLimit ? x : kLimit) : -kLimit;
  const auto i = static_cast<int64_t>(x);
  return i - (static_cast<double>(i) > x ? 1 : 0);
}
inline int32_t floor_to_int32(float x) {
  constexpr float kLimit = 1.07e9f;
  x = x > -kLimit ? (x < kLimit ? x : kLimit) : -kLimit;
  const auto i = static_cast<int32_t>(x);
  return i - (static_cast<float>(i) > x ? 1 : 0);
}
// e with x = m 2^e, m in [0.5, 1), for a positive normal finite x (std::frexp).
inline int binary_exponent(double x) { return static_cast<int>((std::bit_cast<uint64_t>(x) >> 52) & 0x7ffu) - 1022; }
// 2^e for |e| <= 1022 (std::ldexp(1.0, e)).
inline double power_of_two(int e) { return std::bit_cast<double>(static_cast<uint64_t>(1023 + e) << 52); }
// c ? a : b by bit masks: GCC compiled `c ? std::min(x, a) : x` on doubles to
// a branch, which on random c was mispredicted (issue 10, ninth speed
// session: ~10 per eval at footprint area 1e-4 in the rasteriser).
inline double select_double(bool c, double a, double b) {
  const uint64_t m = uint64_t{0} - static_cast<uint64_t>(c);
  return std::bit_cast<double>((std::bit_cast<uint64_t>(a) & m) | (std::bit_cast<uint64_t>(b) & ~m));
}
// Two double lanes: m ? a : b per lane (m a compare mask), and the smaller /
// larger lane. The rasteriser's four edges and corners in two registers:
// the same values as the scalar selects, in any order (min / max of finite
// values and +-1e300).
#if defined(__SSE2__)
inline __m128d blend_pd(__m128d m, __m128d a, __m128d b) { return _mm_or_pd(_mm_and_pd(m, a), _mm_andnot_pd(m, b)); }
inline double lane_min(__m128d v) { return _mm_cvtsd_f64(_mm_min_sd(v, _mm_unpackhi_pd(v, v))); }
inline double lane_max(__m128d v) { return _mm_cvtsd_f64(_mm_max_sd(v, _mm_unpackhi_pd(v, v))); }
#endif

// A multiply-xorshift integer hash without a data-dependent shift
// ("lowbias32", C. Wellons 2018: two multiplies, three xorshifts; a bijection
// of 32-bit words), so the four direction groups of a node hash in the 32-bit
// lanes of one SSE2 register (group_hashes) with the same values as this
// scalar form (issue 10, eighth speed session; the groups used hash_combine,
// PCG's hash, whose per-lane variable shift has no SSE2 form).
inline constexpr uint32_t kMixMultiplier1 = 0x7feb352du, kMixMultiplier2 = 0x846ca68bu;  // every lane form's too
constexpr uint32_t mix_u32(uint32_t x) {
  x ^= x >> 16;
  x *= kMixMultiplier1;
  x ^= x >> 15;
  x *= kMixMultiplier2;
  x ^= x >> 16;
  return x;
}

#if defined(__SSE2__)
inline __m128i mullo_u32x4(__m128i a, uint32_t c) {  // a * c per 32-bit lane (SSE2 has no pmulld)
  const __m128i k = _mm_set1_epi32(static_cast<int>(c));
  const __m128i even = _mm_mul_epu32(a, k);                         // lanes 0, 2 (64-bit products)
  const __m128i odd = _mm_mul_epu32(_mm_srli_epi64(a, 32), k);      // lanes 1, 3
  return _mm_unpacklo_epi32(_mm_shuffle_epi32(even, _MM_SHUFFLE(0, 0, 2, 0)),
                            _mm_shuffle_epi32(odd, _MM_SHUFFLE(0, 0, 2, 0)));
}
// a * c per lane with lanes 1 and 2 swapped (result lanes a0 c, a2 c, a1 c,
// a3 c): the two products' low halves gathered by one SHUFPS instead of two
// PSHUFD and a PUNPCKLDQ. The swap is its own inverse, so two of these in a
// row (mix_u32x4; the xorshifts between them are per lane) give the lanes in
// order.
inline __m128i mullo_u32x4_swap12(__m128i a, __m128i k) {
  const __m128 even = _mm_castsi128_ps(_mm_mul_epu32(a, k));                     // lanes 0, 2
  const __m128 odd = _mm_castsi128_ps(_mm_mul_epu32(_mm_srli_epi64(a, 32), k));  // lanes 1, 3
  return _mm_castps_si128(_mm_shuffle_ps(even, odd, _MM_SHUFFLE(2, 0, 2, 0)));
}
// mix_u32 per 32-bit lane (the same values). Session 19: the multiplies by
// mullo_u32x4_swap12, 27 -> 22 instructions (standalone, with its ret).
inline __m128i mix_u32x4(__m128i x) {
  x = _mm_xor_si128(x, _mm_srli_epi32(x, 16));
  x = mullo_u32x4_swap12(x, _mm_set1_epi32(static_cast<int>(kMixMultiplier1)));  // lanes 0 2 1 3
  x = _mm_xor_si128(x, _mm_srli_epi32(x, 15));
  x = mullo_u32x4_swap12(x, _mm_set1_epi32(static_cast<int>(kMixMultiplier2)));  // lanes 0 1 2 3 again
  return _mm_xor_si128(x, _mm_srli_epi32(x, 16));
}
#endif

// Node keys. The key of node (level, i, j) is row_key(level, j) + i W (W the
// golden-ratio Weyl step): one pair of hashes per row of a footprint instead
// of three hashes per node (issue 10, eighth speed session). A key is not
// itself random along a row; every use of it goes through mix_u32 of the key
// xor a direction cell's seed (group_hashes), which decorrelates
// neighbouring nodes (GlintParticles.NodeHashesAlongARowAreIndependent).
inline constexpr uint32_t kNodeKeyStep = 0x9e3779b9u;
inline constexpr uint32_t kRowKeySalt = 0x5851f42du;  // j's salt before the row's hash (every lane form's too)
inline uint32_t node_row_key(int level, int64_t j) {
  return hash_combine(hash_u32(static_cast<uint32_t>(j) ^ kRowKeySalt), static_cast<uint32_t>(level));
}
inline uint32_t node_key(int level, int64_t i, int64_t j) {
  return node_row_key(level, j) + static_cast<uint32_t>(i) * kNodeKeyStep;
}

// The nodes a footprint is counted over (at most kMaxNodes), each with its
// key (node_key), computed once when it is added, so the dark test's count
// and the count at P (glint.cpp) key a node once; the row key is kept from
// the previous add of the same row (add_row: once per row).
inline constexpr int kMaxNodes = 64;
// The box path of nodes_at_level_start: a footprint whose bounding box spans at
// most `box_span` x `box_span` nodes takes the whole box. kSmallBoxSpan (2)
// covers every footprint smaller than a node; kBoxSpan (4, session 23) is the
// direction cells' walk (footprint_nodes), whose extra nodes cost less than
// the rasteriser they save. A node outside the footprint adds no particle (the
// membership test is exact), so the counts are the same for any span.
inline constexpr int64_t kSmallBoxSpan = 2, kBoxSpan = 4;
struct NodeList {
  static constexpr int kRowChunk = 4;  // add_row writes whole chunks of this many entries
  // The entries left uninitialised (1 KB per eval); the scalars below as their initialisers were (session 37: written
  // here, not as default member initialisers, so NodeList(Unset) can leave them unwritten).
  NodeList() : level(0), size(1.0), count(0), row_valid_(false), row_level_(0), row_j_(0), row_key_(0) {}  // NOLINT
  // Every entry zeroed, as a constant expression (session 26: FootprintNodeMemo's thread_local is constant-initialised,
  // so reading it needs no guard and one __tls_get_addr, not two).
  struct Zeroed {};
  explicit constexpr NodeList(Zeroed)
      : level(0), size(1.0), count(0), i{}, j{}, id_hash{}, row_valid_(false), row_level_(0), row_j_(0), row_key_(0) {}
  // Nothing written (session 37, glint1e8_37): a list that is never read (GlintSite(Unset)); add() must not be called
  // on it.
  struct Unset {};
  explicit NodeList(Unset) {}  // NOLINT(cppcoreguidelines-pro-type-member-init)
  int level;                   // set before add()
  double size;                 // node side s = 2^-level
  int count;
  // First `count` entries valid (not zeroed: 1 KB per eval); kRowChunk - 1
  // entries of slack for add_row's last chunk.
  std::array<int64_t, kMaxNodes + kRowChunk - 1> i, j;
  std::array<uint32_t, kMaxNodes + kRowChunk - 1> id_hash;  // node_key(level, i, j) of the first `count` nodes
  // Nodes i0..i1 of row nj (i0 <= i1), false when they do not all fit. The
  // row key once, and the entries in chunks of kRowChunk with no branch per
  // node (issue 10, ninth speed session: the per-node row test and the
  // per-node loop exit were ~8 mispredictions per eval at area 1e-4; rows
  // of <= 4 nodes are one chunk). Same entries as add() node by node.
  bool add_row(int64_t i0, int64_t i1, int64_t nj) {
    const int64_t n = i1 - i0 + 1;
    if (n > kMaxNodes - count) return false;
    const uint32_t key = node_row_key(level, nj);
#if defined(__SSE2__)
    // Session 19: a chunk's four keys, i and j in SSE2 lanes (the keys
    // key + (i0 + b + c) W mod 2^32 stepped by 4 W per chunk: the same words).
    static_assert(kRowChunk == 4);
    constexpr uint32_t W = kNodeKeyStep;
    __m128i ids = _mm_add_epi32(_mm_set1_epi32(static_cast<int>(key + static_cast<uint32_t>(i0) * W)),
                                _mm_set_epi32(static_cast<int>(3u * W), static_cast<int>(2u * W), static_cast<int>(W), 0));
    __m128i iv = _mm_set_epi64x(i0 + 1, i0);
    const __m128i jv = _mm_set1_epi64x(nj), two = _mm_set1_epi64x(2), four = _mm_set1_epi64x(4);
    const __m128i ids_step = _mm_set1_epi32(static_cast<int>(4u * W));
    for (int64_t b = 0; b < n; b += kRowChunk) {
      const auto at = static_cast<size_t>(count + b);
      _mm_storeu_si128(reinterpret_cast<__m128i *>(id_hash.data() + at), ids);
      _mm_storeu_si128(reinterpret_cast<__m128i *>(i.data() + at), iv);
      _mm_storeu_si128(reinterpret_cast<__m128i *>(i.data() + at + 2), _mm_add_epi64(iv, two));
      _mm_storeu_si128(reinterpret_cast<__m128i *>(j.data() + at), jv);
      _mm_storeu_si128(reinterpret_cast<__m128i *>(j.data() + at + 2), jv);
      ids = _mm_add_epi32(ids, ids_step), iv = _mm_add_epi64(iv, four);
    }
#else
    for (int64_t b = 0; b < n; b += kRowChunk)
      for (int c = 0; c < kRowChunk; ++c) {
        const auto at = static_cast<size_t>(count + b + c);
        i[at] = i0 + b + c;
        j[at] = nj;
        id_hash[at] = key + static_cast<uint32_t>(i0 + b + c) * kNodeKeyStep;
      }
#endif
    count += static_cast<int>(n);
    row_valid_ = false;
    return true;
  }
#if GLIMMER_GLINT_WALK_AVX2
  // Entries at .. at + 3: keys `ids`, i `iv`, j `jv`.
  [[gnu::target("avx2"), gnu::always_inline]] void put_chunk_avx2(size_t at, __m128i ids, __m256i iv, __m256i jv) {
    _mm_storeu_si128(reinterpret_cast<__m128i *>(id_hash.data() + at), ids);
    _mm256_storeu_si256(reinterpret_cast<__m256i *>(i.data() + at), iv);
    _mm256_storeu_si256(reinterpret_cast<__m256i *>(j.data() + at), jv);
  }
  // The box of rows j0 .. j0 + rows - 1 and columns i0 .. i0 + n - 1 (1 <= rows, n <= 4: one chunk per row) into the
  // empty list, row r's key in lane r of `keys` (node_row_keys_avx2), row after row: the same entries as add_row
  // (session 30: nodes_at_level_start_avx2's box, which called add_row per row with its room test, the count's
  // reload and a store per row). Rows 0, 1 and, when the box has more than two (never where max_rows, the box span,
  // a constant where inlined, is 2), rows 2, 3 are written without a test per row (chunk r at r n; those at or past
  // `rows` are slack past count).
  [[gnu::target("avx2"), gnu::always_inline]] void put_box_avx2(int64_t i0, int64_t n, int64_t j0, int64_t rows,
                                                                int64_t max_rows, __m128i keys) {
    static_assert(kRowChunk == 4 && 3 * 4 + kRowChunk <= kMaxNodes);
    constexpr uint32_t W = kNodeKeyStep;
    const __m128i base = _mm_add_epi32(keys, _mm_set1_epi32(static_cast<int>(static_cast<uint32_t>(i0) * W)));
    const __m128i steps = _mm_setr_epi32(0, static_cast<int>(W), static_cast<int>(2u * W), static_cast<int>(3u * W));
    const __m256i iv = _mm256_add_epi64(_mm256_set1_epi64x(i0), _mm256_setr_epi64x(0, 1, 2, 3));
    const __m256i jv = _mm256_set1_epi64x(j0), one = _mm256_set1_epi64x(1);
    const auto w = static_cast<size_t>(n);
    put_chunk_avx2(0, _mm_add_epi32(_mm_shuffle_epi32(base, 0x00), steps), iv, jv);
    put_chunk_avx2(w, _mm_add_epi32(_mm_shuffle_epi32(base, 0x55), steps), iv, _mm256_add_epi64(jv, one));
    if (max_rows > 2 && rows > 2) {
      put_chunk_avx2(2 * w, _mm_add_epi32(_mm_shuffle_epi32(base, 0xaa), steps), iv,
                     _mm256_add_epi64(jv, _mm256_add_epi64(one, one)));
      put_chunk_avx2(3 * w, _mm_add_epi32(_mm_shuffle_epi32(base, 0xff), steps), iv,
                     _mm256_add_epi64(jv, _mm256_set1_epi64x(3)));
    }
    count = static_cast<int>(rows * n);
    row_valid_ = false;
  }
  // Rows j0 .. j0 + rows - 1 from entry `at` on: row r's nodes i0s[r] .. i0s[r] + ns[r] - 1 (ns[r] >= 0), its first
  // node's key bases[r] = node_key(level, i0s[r], j0 + r) (nodes_at_level_rows_avx2; same entries as add_row). Every
  // row's first chunk is written without a test (session 30: ~12 instructions per row; ~31 with the row's key times
  // i0 W, the chunk loop's set-up and the empty-row test); the further chunks of rows wider than a chunk (`chunky`:
  // some row is) in a second loop. `full`: the rows fill the list (at + the widths' sum = kMaxNodes); then the empty
  // rows at the end are left out (their chunk would start at kMaxNodes, past the slack; an empty row before a
  // nonempty one starts below it). Sets count. GlintParticles.RowPutAvx2MatchesAddRow.
  [[gnu::target("avx2"), gnu::always_inline]] void put_rows_avx2(size_t at, int64_t rows, int64_t j0, const int64_t *i0s,
                                                                 const int64_t *ns, const uint32_t *bases, bool full,
                                                                 bool chunky) {
    if (full)
      while (rows > 0 && ns[rows - 1] == 0) --rows;
    constexpr uint32_t W = kNodeKeyStep;
    const __m128i steps = _mm_setr_epi32(0, static_cast<int>(W), static_cast<int>(2u * W), static_cast<int>(3u * W));
    const __m256i lane = _mm256_setr_epi64x(0, 1, 2, 3), one = _mm256_set1_epi64x(1);
    const size_t start = at;
    __m256i jv = _mm256_set1_epi64x(j0);
    for (int64_t r = 0; r < rows; ++r) {
      // VBROADCASTSS from memory (_mm_set1_epi32 of the word is a VMOVD and a VPSHUFD)
      const __m128i base = _mm_castps_si128(_mm_broadcast_ss(reinterpret_cast<const float *>(bases + r)));
      put_chunk_avx2(at, _mm_add_epi32(base, steps), _mm256_add_epi64(_mm256_set1_epi64x(i0s[r]), lane), jv);
      at += static_cast<size_t>(ns[r]);
      jv = _mm256_add_epi64(jv, one);
    }
    count = static_cast<int>(at);
    row_valid_ = false;
    if (!chunky) return;
    // The next row's entries are written: a wide row's last chunk ends at its last node (it may overlap the one
    // before it, with the same entries), so no chunk here passes the row's own nodes.
    at = start;
    for (int64_t r = 0; r < rows; ++r) {
      const __m256i row_j = _mm256_set1_epi64x(j0 + r);
      const int64_t n = ns[r];
      for (int64_t b = kRowChunk; b < n; b += kRowChunk) {
        const int64_t e = std::min(b, n - kRowChunk);
        put_chunk_avx2(at + static_cast<size_t>(e),
                       _mm_add_epi32(_mm_set1_epi32(static_cast<int>(bases[r] + static_cast<uint32_t>(e) * W)), steps),
                       _mm256_add_epi64(_mm256_set1_epi64x(i0s[r] + e), lane), row_j);
      }
      at += static_cast<size_t>(n);
    }
  }
#endif
  bool add(int64_t ni, int64_t nj) {
    if (count == kMaxNodes) return false;
    i[count] = ni;
    j[count] = nj;
    if (!(row_valid_ && nj == row_j_ && level == row_level_)) {
      row_key_ = node_row_key(level, nj);
      row_j_ = nj;
      row_level_ = level;
      row_valid_ = true;
    }
    id_hash[count] = row_key_ + static_cast<uint32_t>(ni) * kNodeKeyStep;
    ++count;
    return true;
  }

 private:
  bool row_valid_;
  int row_level_;
  int64_t row_j_;
  uint32_t row_key_;
};

// Nodes of the particle level hold kNodeParticles / 4 .. kNodeParticles
// particles per group on average.
inline constexpr double kNodeParticles = 128.0;

// The particle level l* for density N (per unit area): the largest node side
// 2^-l* with N s^2 <= kNodeParticles.
inline int particle_level(double density) {
  const int e = binary_exponent(std::sqrt(kNodeParticles / (density > 1e-30 ? density : 1e-30)));
  return 1 - e;  // 2^(e-1) <= value < 2^e
}

// The footprint parallelogram's four corners, in order around it.
struct FootprintCorners {
  double x[4], y[4];
  explicit FootprintCorners(const Footprint &f)
      : x{f.cx - 0.5 * f.ax - 0.5 * f.bx, f.cx + 0.5 * f.ax - 0.5 * f.bx, f.cx + 0.5 * f.ax + 0.5 * f.bx,
          f.cx - 0.5 * f.ax + 0.5 * f.bx},
        y{f.cy - 0.5 * f.ay - 0.5 * f.by, f.cy + 0.5 * f.ay - 0.5 * f.by, f.cy + 0.5 * f.ay + 0.5 * f.by,
          f.cy - 0.5 * f.ay + 0.5 * f.by} {}
};

// The x range [lo, hi] of the footprint's edges that cross the line y = yc
// strictly (lo > hi when none does).
struct EdgeCrossings {
  double yc, lo, hi;
  // Without a branch per edge (issue 10, seventh speed session): whether an
  // edge crosses is random, and the branch was mispredicted ~5 times per
  // eval at footprint area 1e-4. Every edge's crossing is computed (a
  // non-crossing edge's value, possibly inf or NaN, is discarded by the
  // select), so the crossings and the nodes are the same.
  EdgeCrossings(const FootprintCorners &c, double y) : yc(y), lo(1e300), hi(-1e300) {
#if defined(__SSE2__)  // edges (0, 1), (1, 2) and (2, 3), (3, 0) in two registers
    const __m128d ycv = _mm_set1_pd(yc);
    __m128d lo2 = _mm_set1_pd(1e300), hi2 = _mm_set1_pd(-1e300);
    for (int h = 0; h < 2; ++h) {
      const __m128d ax = _mm_loadu_pd(c.x + 2 * h), ay = _mm_loadu_pd(c.y + 2 * h);
      const __m128d bx = h == 0 ? _mm_loadu_pd(c.x + 1) : _mm_set_pd(c.x[0], c.x[3]);
      const __m128d by = h == 0 ? _mm_loadu_pd(c.y + 1) : _mm_set_pd(c.y[0], c.y[3]);
      const __m128d xc = _mm_add_pd(ax, _mm_div_pd(_mm_mul_pd(_mm_sub_pd(bx, ax), _mm_sub_pd(ycv, ay)), _mm_sub_pd(by, ay)));
      const __m128d crosses = _mm_cmplt_pd(_mm_mul_pd(_mm_sub_pd(ay, ycv), _mm_sub_pd(by, ycv)), _mm_setzero_pd());
      lo2 = _mm_min_pd(blend_pd(crosses, xc, _mm_set1_pd(1e300)), lo2);
      hi2 = _mm_max_pd(blend_pd(crosses, xc, _mm_set1_pd(-1e300)), hi2);
    }
    lo = lane_min(lo2), hi = lane_max(hi2);
#else
    for (int k = 0; k < 4; ++k) {
      const double ax = c.x[k], ay = c.y[k], bx = c.x[(k + 1) % 4], by = c.y[(k + 1) % 4];
      const double xc = ax + (bx - ax) * (yc - ay) / (by - ay);
      const bool crosses = (ay - yc) * (by - yc) < 0.0;
      lo = std::min(lo, select_double(crosses, xc, 1e300));
      hi = std::max(hi, select_double(crosses, xc, -1e300));
    }
#endif
  }
};

// x extent of the footprint parallelogram inside the band y0 <= y <= y1 (its
// corners in the band and its edges' crossings of the band's borders,
// Sutherland-Hodgman); false when the band misses it. The crossings of y0
// are passed in (a row's upper border is the next row's lower one).
inline bool footprint_x_range_in_band(const FootprintCorners &c, const EdgeCrossings &at_y0,
                                      const EdgeCrossings &at_y1, double &x_min, double &x_max) {
  x_min = std::min(at_y0.lo, at_y1.lo), x_max = std::max(at_y0.hi, at_y1.hi);
#if defined(__SSE2__)  // the four corners in two registers (see EdgeCrossings)
  const __m128d y0 = _mm_set1_pd(at_y0.yc), y1 = _mm_set1_pd(at_y1.yc);
  const __m128d x01 = _mm_loadu_pd(c.x), x23 = _mm_loadu_pd(c.x + 2), ya = _mm_loadu_pd(c.y), yb = _mm_loadu_pd(c.y + 2);
  const __m128d in01 = _mm_and_pd(_mm_cmpge_pd(ya, y0), _mm_cmple_pd(ya, y1));
  const __m128d in23 = _mm_and_pd(_mm_cmpge_pd(yb, y0), _mm_cmple_pd(yb, y1));
  const __m128d big = _mm_set1_pd(1e300), small = _mm_set1_pd(-1e300);
  x_min = std::min(x_min, lane_min(_mm_min_pd(blend_pd(in01, x01, big), blend_pd(in23, x23, big))));
  x_max = std::max(x_max, lane_max(_mm_max_pd(blend_pd(in01, x01, small), blend_pd(in23, x23, small))));
#else
  for (int k = 0; k < 4; ++k) {  // selects, not branches (see EdgeCrossings)
    const bool in_band = (c.y[k] >= at_y0.yc) & (c.y[k] <= at_y1.yc);
    x_min = std::min(x_min, select_double(in_band, c.x[k], 1e300));
    x_max = std::max(x_max, select_double(in_band, c.x[k], -1e300));
  }
#endif
  return x_min <= x_max;
}

// The nodes of `level` the footprint overlaps, row by row (the parallelogram
// rasterised, not its bounding box); false when there are more than kMaxNodes.
// In two parts (session 17, so the node-list memo can step in between them):
// nodes_at_level_start sets the list's level, finds the rows and fills a
// small footprint's box; nodes_at_level_rows rasterises the others.
struct NodeRows {
  enum Kind { kDone, kTooMany, kRows } kind;
  int64_t j0, j1;
};
inline NodeRows nodes_at_level_start(const Footprint &f, int level, NodeList &list,
                                     int64_t box_span = kSmallBoxSpan) {
  list.count = 0;
  list.level = level;
  list.size = power_of_two(-level);
  const double inv = power_of_two(level);  // 1 / size, exactly
  const double ey = 0.5 * (std::fabs(f.ay) + std::fabs(f.by));
  const double ex = 0.5 * (std::fabs(f.ax) + std::fabs(f.bx));
  // Far more than kMaxNodes across (or a non-finite extent): the clamped
  // floors below would differ by 2^63, which wraps, and the row loop would
  // run ~2^62 times (a thin finite footprint such as (0, 3e38) x (3e-38, 0)
  // has area 9 and reached it).
  if (!(ex * inv < 1e15) || !(ey * inv < 1e15)) return {NodeRows::kTooMany, 0, 0};
  const int64_t j0 = floor_to_int64((f.cy - ey) * inv);
  const int64_t j1 = floor_to_int64((f.cy + ey) * inv);
  if (j1 - j0 >= kMaxNodes) return {NodeRows::kTooMany, 0, 0};
  // A footprint whose bounding box spans at most box_span x box_span nodes
  // (2: every footprint smaller than a node) takes the whole box: clipping
  // the rows costs more than the nodes it may save, and the count is the
  // same (membership is exact).
  const int64_t box_i0 = floor_to_int64((f.cx - ex) * inv), box_i1 = floor_to_int64((f.cx + ex) * inv);
  if (j1 - j0 < box_span && box_i1 - box_i0 < box_span) {
    for (int64_t j = j0; j <= j1; ++j) list.add_row(box_i0, box_i1, j);
    return {NodeRows::kDone, j0, j1};
  }
  return {NodeRows::kRows, j0, j1};
}
// Rows j0..j1 of `list` (level and size set, count 0); false beyond kMaxNodes.
// The per-row form with EdgeCrossings and footprint_x_range_in_band (the
// rasteriser until session 19; nodes_at_level_rows gives the same nodes:
// GlintParticles.RowRasteriserMatchesTheScalarForm).
inline bool nodes_at_level_rows_scalar(const Footprint &f, int64_t j0, int64_t j1, NodeList &list) {
  const double inv = power_of_two(list.level);
  // The corners once per footprint and each row border's crossings once
  // (they were computed per row and per side; same values, same nodes).
  const FootprintCorners corners(f);
  EdgeCrossings below(corners, static_cast<double>(j0) * list.size);
  for (int64_t j = j0; j <= j1; ++j) {
    double x_min, x_max;
    const double y0 = static_cast<double>(j) * list.size;
    if (below.yc != y0) below = EdgeCrossings(corners, y0);
    const EdgeCrossings above(corners, y0 + list.size);
    const bool hit = footprint_x_range_in_band(corners, below, above, x_min, x_max);
    below = above;
    if (!hit) continue;
    const int64_t i0 = floor_to_int64(x_min * inv);
    const int64_t i1 = floor_to_int64(x_max * inv);
    if (i1 - i0 >= kMaxNodes || !list.add_row(i0, i1, j)) return false;
  }
  return true;
}
#if defined(__SSE2__)
// The rasteriser's rows in SSE2 registers (issue 10, session 19): the four
// edges' constants (start, b - a) once per footprint, a row border's four
// crossings and the band's corners kept in two-lane registers, with the
// lanes that do not count (an edge that does not cross, a corner outside the
// band) set to NaN by an OR with the negated compare mask: MINPD / MAXPD
// return their second operand when either is NaN, so min(masked, acc) skips
// them without a blend. The same crossings (the same expressions: x = ax +
// (bx - ax) (y - ay) / (by - ay); crossing iff (ay - y)(by - y) < 0, here as
// (y - ay)(y - by), the same product) and the same corners as
// nodes_at_level_rows_scalar, so the same x extents (min / max of the same
// set, up to the sign of a zero, which floor ignores) and the same nodes.
struct RowRasteriser {
  __m128d ax[2], ay[2], by[2], dx[2], dy[2];  // edges (0, 1), (1, 2) and (2, 3), (3, 0)
  __m128d cx[2], cy[2];                       // corners 0, 1 and 2, 3
  struct Crossings {
    __m128d lo, hi;  // per lane the smallest / largest crossing of its edges (+-1e300 when none); never NaN
  };
  explicit RowRasteriser(const FootprintCorners &c) {
    ax[0] = _mm_loadu_pd(c.x), ay[0] = _mm_loadu_pd(c.y);
    ax[1] = _mm_loadu_pd(c.x + 2), ay[1] = _mm_loadu_pd(c.y + 2);
    const __m128d bx0 = _mm_loadu_pd(c.x + 1), bx1 = _mm_set_pd(c.x[0], c.x[3]);
    by[0] = _mm_loadu_pd(c.y + 1), by[1] = _mm_set_pd(c.y[0], c.y[3]);
    dx[0] = _mm_sub_pd(bx0, ax[0]), dx[1] = _mm_sub_pd(bx1, ax[1]);
    dy[0] = _mm_sub_pd(by[0], ay[0]), dy[1] = _mm_sub_pd(by[1], ay[1]);
    cx[0] = ax[0], cx[1] = ax[1], cy[0] = ay[0], cy[1] = ay[1];
  }
  Crossings at(double y) const {
    const __m128d yv = _mm_set1_pd(y);
    __m128d lo = _mm_set1_pd(1e300), hi = _mm_set1_pd(-1e300);
    for (int h = 0; h < 2; ++h) {
      const __m128d t = _mm_sub_pd(yv, ay[h]);
      const __m128d xc = _mm_add_pd(ax[h], _mm_div_pd(_mm_mul_pd(dx[h], t), dy[h]));
      const __m128d no_cross = _mm_cmpnlt_pd(_mm_mul_pd(t, _mm_sub_pd(yv, by[h])), _mm_setzero_pd());
      const __m128d masked = _mm_or_pd(xc, no_cross);  // NaN where the edge does not cross
      lo = _mm_min_pd(masked, lo), hi = _mm_max_pd(masked, hi);
    }
    return {lo, hi};
  }
  // The band y0 <= y <= y1's x extent from its borders' crossings and its corners; false when it misses.
  bool band(const Crossings &below, const Crossings &above, double y0, double y1, double &x_min,
            double &x_max) const {
    __m128d lo = _mm_min_pd(below.lo, above.lo), hi = _mm_max_pd(below.hi, above.hi);
    const __m128d y0v = _mm_set1_pd(y0), y1v = _mm_set1_pd(y1);
    for (int h = 0; h < 2; ++h) {
      const __m128d out = _mm_or_pd(_mm_cmpnge_pd(cy[h], y0v), _mm_cmpnle_pd(cy[h], y1v));
      const __m128d masked = _mm_or_pd(cx[h], out);  // NaN where the corner is outside the band
      lo = _mm_min_pd(masked, lo), hi = _mm_max_pd(masked, hi);
    }
    x_min = lane_min(lo), x_max = lane_max(hi);
    return x_min <= x_max;
  }
};
#endif
// Rows j0..j1 of `list` (level and size set, count 0); false beyond kMaxNodes.
// The SSE2 form (session 19); nodes_at_level_rows chooses it or the AVX2 form.
[[gnu::noinline]] inline bool nodes_at_level_rows_sse2(const Footprint &f, int64_t j0, int64_t j1, NodeList &list) {
#if defined(__SSE2__)
  const double inv = power_of_two(list.level);
  const RowRasteriser raster{FootprintCorners(f)};
  double below_y = static_cast<double>(j0) * list.size;
  RowRasteriser::Crossings below = raster.at(below_y);
  for (int64_t j = j0; j <= j1; ++j) {
    const double y0 = static_cast<double>(j) * list.size, y1 = y0 + list.size;
    if (below_y != y0) below = raster.at(y0);
    const RowRasteriser::Crossings above = raster.at(y1);
    double x_min, x_max;
    const bool hit = raster.band(below, above, y0, y1, x_min, x_max);
    below = above, below_y = y1;
    if (!hit) continue;
    const int64_t i0 = floor_to_int64(x_min * inv);
    const int64_t i1 = floor_to_int64(x_max * inv);
    if (i1 - i0 >= kMaxNodes || !list.add_row(i0, i1, j)) return false;
  }
  return true;
#else
  return nodes_at_level_rows_scalar(f, j0, j1, list);
#endif
}
#if GLIMMER_GLINT_WALK_AVX2
// node_row_key of four rows (32-bit lanes; hash_u32's variable shift by
// VPSRLVD): the same words as the scalar hash.
// Their constants (hash_u32's, node_row_key's xor), eight lanes each (32-byte rows; the four-lane forms read the
// first half), read from memory: the table's address passes through an empty asm (row_key_constants), so GCC uses
// them as VPMULLD's / VPADDD's / VPXOR's memory operands instead of building each from an immediate (MOV, VMOVD,
// VPSHUFD; session 30).
alignas(32) inline constexpr Lanes8 kRowKeyConstants[5] = {lanes8(kRowKeySalt), lanes8(kPcgMultiplier),
                                                           lanes8(kPcgIncrement), lanes8(4u),
                                                           lanes8(kPcgOutputMultiplier)};
[[gnu::always_inline]] inline const Lanes8 *row_key_constants() { return opaque(kRowKeyConstants); }
[[gnu::target("avx2"), gnu::always_inline]] inline __m128i row_key_constant4(const Lanes8 *c, int k) {
  return _mm_load_si128(reinterpret_cast<const __m128i *>(c[k].lane));
}
[[gnu::target("avx2"), gnu::always_inline]] inline __m256i row_key_constant8(const Lanes8 *c, int k) {
  return _mm256_load_si256(reinterpret_cast<const __m256i *>(c[k].lane));
}
[[gnu::target("avx2"), gnu::always_inline]] inline __m128i hash_u32x4_avx2(__m128i v, const Lanes8 *c) {
  const __m128i state = _mm_add_epi32(_mm_mullo_epi32(v, row_key_constant4(c, 1)), row_key_constant4(c, 2));
  const __m128i shift = _mm_add_epi32(_mm_srli_epi32(state, 28), row_key_constant4(c, 3));
  const __m128i word = _mm_mullo_epi32(_mm_xor_si128(_mm_srlv_epi32(state, shift), state), row_key_constant4(c, 4));
  return _mm_xor_si128(_mm_srli_epi32(word, 22), word);
}
[[gnu::target("avx2"), gnu::always_inline]] inline __m128i node_row_keys_avx2(int level, __m128i j) {
  const Lanes8 *c = row_key_constants();
  const __m128i seed = hash_u32x4_avx2(_mm_xor_si128(j, row_key_constant4(c, 0)), c);
  // hash_combine(seed, level): seed ^ (level + 0x9e3779b9 + (seed << 6) + (seed >> 2))
  const __m128i v = _mm_set1_epi32(static_cast<int>(static_cast<uint32_t>(level) + 0x9e3779b9u));
  const __m128i mixed = _mm_add_epi32(_mm_add_epi32(v, _mm_slli_epi32(seed, 6)), _mm_srli_epi32(seed, 2));
  return hash_u32x4_avx2(_mm_xor_si128(seed, mixed), c);
}
// The same for eight rows (256-bit lanes; session 30: the rasteriser's keys eight per step): the same words.
[[gnu::target("avx2"), gnu::always_inline]] inline __m256i hash_u32x8_avx2(__m256i v, const Lanes8 *c) {
  const __m256i state = _mm256_add_epi32(_mm256_mullo_epi32(v, row_key_constant8(c, 1)), row_key_constant8(c, 2));
  const __m256i shift = _mm256_add_epi32(_mm256_srli_epi32(state, 28), row_key_constant8(c, 3));
  const __m256i word =
      _mm256_mullo_epi32(_mm256_xor_si256(_mm256_srlv_epi32(state, shift), state), row_key_constant8(c, 4));
  return _mm256_xor_si256(_mm256_srli_epi32(word, 22), word);
}
[[gnu::target("avx2"), gnu::always_inline]] inline __m256i node_row_keys8_avx2(int level, __m256i j) {
  const Lanes8 *c = row_key_constants();
  const __m256i seed = hash_u32x8_avx2(_mm256_xor_si256(j, row_key_constant8(c, 0)), c);
  const __m256i v = _mm256_set1_epi32(static_cast<int>(static_cast<uint32_t>(level) + 0x9e3779b9u));
  const __m256i mixed = _mm256_add_epi32(_mm256_add_epi32(v, _mm256_slli_epi32(seed, 6)), _mm256_srli_epi32(seed, 2));
  return hash_u32x8_avx2(_mm256_xor_si256(seed, mixed), c);
}
// The AVX2 forms' fallbacks (rare), out of line: glint.cpp now reaches GCC's
// inline-unit-growth limit (since session 21 glint_f_cos is no longer inlined
// into f_cos_and_pdf, ~+2.5 M in the GI scene), and inlined copies of these
// would use more of it.
[[gnu::noinline, gnu::cold]] inline bool nodes_at_level_rows_sse2_cold(const Footprint &f, int64_t j0, int64_t j1,
                                                                       NodeList &list) {
  return nodes_at_level_rows_sse2(f, j0, j1, list);
}
[[gnu::noinline, gnu::cold]] inline NodeRows nodes_at_level_start_cold(const Footprint &f, int level, NodeList &list,
                                                                      int64_t box_span) {
  return nodes_at_level_start(f, level, list, box_span);
}
// One edge's crossings of four row borders yv into the borders' lo / hi (the SSE2 form's expressions).
[[gnu::target("avx2"), gnu::always_inline]] inline void raster_edge_avx2(__m256d yv, __m256d ax, __m256d ay, __m256d by,
                                                                        __m256d dx, __m256d dy, __m256d &lo,
                                                                        __m256d &hi) {
  const __m256d t = _mm256_sub_pd(yv, ay);
  const __m256d xc = _mm256_add_pd(ax, _mm256_div_pd(_mm256_mul_pd(dx, t), dy));
  const __m256d no_cross = _mm256_cmp_pd(_mm256_mul_pd(t, _mm256_sub_pd(yv, by)), _mm256_setzero_pd(), _CMP_NLT_UQ);
  const __m256d masked = _mm256_or_pd(xc, no_cross);  // NaN where the edge does not cross
  lo = _mm256_min_pd(masked, lo), hi = _mm256_max_pd(masked, hi);
}
// The corners of f (FootprintCorners: x_k = (cx +- ax / 2) +- bx / 2, the
// same doubles: a - b is a + (-b)), corner k's x and y in all four lanes of
// x[k], y[k] (session 30: edge k's end y[k + 1] and its dx, dy from these, not
// from permutes of a rotated copy: the same doubles, eight fewer permutes).
struct RasterCornersAvx2 {
  __m256d x[4], y[4];
};
[[gnu::target("avx2"), gnu::always_inline]] inline RasterCornersAvx2 raster_corners_avx2(const Footprint &f) {
  const __m256d sa = _mm256_setr_pd(-1.0, 1.0, 1.0, -1.0), sb = _mm256_setr_pd(-1.0, -1.0, 1.0, 1.0);
  const __m256d X = _mm256_add_pd(_mm256_add_pd(_mm256_set1_pd(f.cx), _mm256_mul_pd(sa, _mm256_set1_pd(0.5 * f.ax))),
                                  _mm256_mul_pd(sb, _mm256_set1_pd(0.5 * f.bx)));
  const __m256d Y = _mm256_add_pd(_mm256_add_pd(_mm256_set1_pd(f.cy), _mm256_mul_pd(sa, _mm256_set1_pd(0.5 * f.ay))),
                                  _mm256_mul_pd(sb, _mm256_set1_pd(0.5 * f.by)));
  return {{_mm256_permute4x64_pd(X, 0x00), _mm256_permute4x64_pd(X, 0x55), _mm256_permute4x64_pd(X, 0xaa),
           _mm256_permute4x64_pd(X, 0xff)},
          {_mm256_permute4x64_pd(Y, 0x00), _mm256_permute4x64_pd(Y, 0x55), _mm256_permute4x64_pd(Y, 0xaa),
           _mm256_permute4x64_pd(Y, 0xff)}};
}
// The extent of the footprint (corners c) on each row border y = (j0 + k)
// size, k = 0..rows, written to y / lo / hi (four borders per step; the last
// group's unused lanes and the four entries after it are zeros, not stack
// garbage). Edge k runs from corner k to corner k + 1 (mod 4).
[[gnu::target("avx2")]] inline void raster_borders_avx2(const RasterCornersAvx2 &c, int64_t j0, int64_t rows, double size,
                                                         double *y, double *lo, double *hi) {
  __m256d dx[4], dy[4];
  for (int e = 0; e < 4; ++e)
    dx[e] = _mm256_sub_pd(c.x[(e + 1) & 3], c.x[e]), dy[e] = _mm256_sub_pd(c.y[(e + 1) & 3], c.y[e]);
  const __m256d sizev = _mm256_set1_pd(size), four = _mm256_set1_pd(4.0);
  // j0 + k + lane, exact (|j0| < 2^52, k <= 64): the border's row index, four more per step (session 30).
  __m256d jk = _mm256_add_pd(_mm256_set1_pd(static_cast<double>(j0)), _mm256_setr_pd(0.0, 1.0, 2.0, 3.0));
  const __m256d zero = _mm256_setzero_pd();
  int64_t k = 0;
  for (; k <= rows; k += 4, jk = _mm256_add_pd(jk, four)) {
    const __m256d yv = _mm256_mul_pd(jk, sizev);
    __m256d lov = _mm256_set1_pd(1e300), hiv = _mm256_set1_pd(-1e300);
    for (int e = 0; e < 4; ++e) raster_edge_avx2(yv, c.x[e], c.y[e], c.y[(e + 1) & 3], dx[e], dy[e], lov, hiv);
    _mm256_store_pd(y + k, yv), _mm256_store_pd(lo + k, lov), _mm256_store_pd(hi + k, hiv);
  }
  _mm256_store_pd(y + k, zero), _mm256_store_pd(lo + k, zero), _mm256_store_pd(hi + k, zero);
}

// One corner (cx, cy) into four bands y0 <= y <= y1's lo / hi where it lies in the band.
[[gnu::target("avx2"), gnu::always_inline]] inline void raster_corner_avx2(__m256d y0, __m256d y1, __m256d cx, __m256d cy,
                                                                          __m256d &lo, __m256d &hi) {
  const __m256d out = _mm256_or_pd(_mm256_cmp_pd(cy, y0, _CMP_NGE_UQ), _mm256_cmp_pd(cy, y1, _CMP_NLE_UQ));
  const __m256d masked = _mm256_or_pd(cx, out);  // NaN where the corner is outside the band
  lo = _mm256_min_pd(masked, lo), hi = _mm256_max_pd(masked, hi);
}
// The rasteriser four rows at a time (issue 10, session 21): the row borders
// y_k = (j0 + k) s, k = 0..rows, in the lanes of 256-bit registers, each
// edge's crossings of four borders by one set of the SSE2 form's operations
// (t = y - ay; x = ax + (dx t) / dy; no crossing iff !(t (y - by) < 0), as a
// NaN lane), then each band's extent from its two borders and the corners
// (a corner outside y_r <= y <= y_(r+1) a NaN lane), the floors by VROUNDPD
// and the row keys (eight at a time since session 30). MINPD / MAXPD with the masked value first
// skip the NaN lanes as the SSE2 form does, so every band's extent is the
// min / max of the same set of doubles (up to the sign of a zero, which the
// floor ignores): the same nodes in the same order
// (GlintParticles.RowRasteriserAvx2MatchesSse2). The SSE2 form's borders are
// j s and j s + s, the same doubles as (j0 + k) s while |j| < 2^52 (integers
// below 2^53 times a power of two); beyond that, and where a floor leaves
// +-2^51, the SSE2 form lists the rows.
[[gnu::target("avx2")]] inline bool nodes_at_level_rows_avx2(const Footprint &f, int64_t j0, int64_t j1,
                                                             NodeList &list) {
  constexpr double kExact = 2251799813685248.0;  // 2^51
  const int64_t rows = j1 - j0 + 1;               // 1..kMaxNodes (nodes_at_level_start)
  if (!(j0 > -(int64_t{1} << 52) && j1 < (int64_t{1} << 52)) || rows > kMaxNodes || rows < 1)
    return nodes_at_level_rows_sse2_cold(f, j0, j1, list);
  const double size = list.size, inv = power_of_two(list.level);
  const __m256d lane = _mm256_setr_pd(0.0, 1.0, 2.0, 3.0);
  alignas(32) double y[kMaxNodes + 8], lo[kMaxNodes + 8], hi[kMaxNodes + 8];
  const RasterCornersAvx2 c = raster_corners_avx2(f);
  raster_borders_avx2(c, j0, rows, size, y, lo, hi);
  // Each row's band: its extent, floors (i0, width n; n = 0 where the band
  // misses) and key. Whether the rows fit is decided for all of them at once:
  // the SSE2 form returns false at the first row wider than kMaxNodes or
  // beyond the list's room, which happens iff some row is wider than
  // kMaxNodes or the widths sum past the room (the list is not used after false).
  const __m256d invv = _mm256_set1_pd(inv), limit = _mm256_set1_pd(kExact), zero = _mm256_setzero_pd();
  const __m256d magic = _mm256_set1_pd(6755399441055744.0);  // 2^52 + 2^51: an integer below 2^51 in the low bits
  const __m256i magic_bits = _mm256_castpd_si256(magic), one = _mm256_set1_epi64x(1);
  const __m256i max_width = _mm256_set1_epi64x(kMaxNodes), chunk = _mm256_set1_epi64x(NodeList::kRowChunk);
  alignas(32) int64_t i0s[kMaxNodes + 4], ns[kMaxNodes + 4];
  alignas(32) uint32_t keys[kMaxNodes + 8], bases[kMaxNodes + 4];
  for (int64_t r = 0; r < rows; r += 8)  // the row keys eight per step (session 30; they were four per band step)
    _mm256_store_si256(reinterpret_cast<__m256i *>(keys + r),
                       node_row_keys8_avx2(list.level, _mm256_add_epi32(_mm256_set1_epi32(static_cast<int>(
                                                                            static_cast<uint32_t>(j0 + r))),
                                                                        _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7))));
  const __m256i low_words = _mm256_setr_epi32(0, 2, 4, 6, 1, 3, 5, 7);
  __m256i total = _mm256_setzero_si256(), wide = _mm256_setzero_si256(), chunky = _mm256_setzero_si256();
  __m256d inexact = _mm256_setzero_pd();
  const __m256d rows_left = _mm256_set1_pd(static_cast<double>(rows)), four = _mm256_set1_pd(4.0);
  __m256d row = lane;  // r + lane (session 30: a running count, not r converted per step)
  for (int64_t r = 0; r < rows; r += 4, row = _mm256_add_pd(row, four)) {
    const __m256d y0 = _mm256_load_pd(y + r), y1 = _mm256_loadu_pd(y + r + 1);
    __m256d lov = _mm256_min_pd(_mm256_load_pd(lo + r), _mm256_loadu_pd(lo + r + 1));
    __m256d hiv = _mm256_max_pd(_mm256_load_pd(hi + r), _mm256_loadu_pd(hi + r + 1));
    for (int k = 0; k < 4; ++k) raster_corner_avx2(y0, y1, c.x[k], c.y[k], lov, hiv);
    // Rows that exist (r + lane < rows) and whose band meets the footprint.
    const __m256d hit = _mm256_and_pd(_mm256_cmp_pd(lov, hiv, _CMP_LE_OQ), _mm256_cmp_pd(row, rows_left, _CMP_LT_OQ));
    const __m256d xs = _mm256_mul_pd(lov, invv), xe = _mm256_mul_pd(hiv, invv);
    // |xs|, |xe| < 2^51 where hit (lov <= hiv, so xs <= xe: -2^51 < xs and xe < 2^51; NaN fails as before).
    inexact = _mm256_or_pd(inexact, _mm256_andnot_pd(_mm256_and_pd(_mm256_cmp_pd(xs, _mm256_sub_pd(zero, limit), _CMP_GT_OQ),
                                                                   _mm256_cmp_pd(xe, limit, _CMP_LT_OQ)),
                                                     hit));
    const __m256i i0 = _mm256_sub_epi64(
        _mm256_castpd_si256(_mm256_add_pd(_mm256_round_pd(xs, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC), magic)), magic_bits);
    const __m256i i1 = _mm256_sub_epi64(
        _mm256_castpd_si256(_mm256_add_pd(_mm256_round_pd(xe, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC), magic)), magic_bits);
    const __m256i n = _mm256_and_si256(_mm256_add_epi64(_mm256_sub_epi64(i1, i0), one), _mm256_castpd_si256(hit));
    total = _mm256_add_epi64(total, n);
    wide = _mm256_or_si256(wide, _mm256_cmpgt_epi64(n, max_width));
    chunky = _mm256_or_si256(chunky, _mm256_cmpgt_epi64(n, chunk));
    _mm256_store_si256(reinterpret_cast<__m256i *>(i0s + r), i0);
    _mm256_store_si256(reinterpret_cast<__m256i *>(ns + r), n);
    // The rows' first keys node_key(level, i0, j) = key + i0 W mod 2^32 (i0's low words).
    const __m128i i0_low = _mm256_castsi256_si128(_mm256_permutevar8x32_epi32(i0, low_words));
    _mm_store_si128(reinterpret_cast<__m128i *>(bases + r),
                    _mm_add_epi32(_mm_load_si128(reinterpret_cast<const __m128i *>(keys + r)),
                                  _mm_mullo_epi32(i0_low, _mm_set1_epi32(static_cast<int>(kNodeKeyStep)))));
  }
  if (_mm256_movemask_pd(inexact) != 0) return nodes_at_level_rows_sse2_cold(f, j0, j1, list);  // a floor beyond +-2^51
  alignas(32) int64_t sum[4];
  _mm256_store_si256(reinterpret_cast<__m256i *>(sum), total);
  const int64_t room = kMaxNodes - list.count, nodes = sum[0] + sum[1] + sum[2] + sum[3];
  if (!_mm256_testz_si256(wide, wide) || nodes > room) return false;
  list.put_rows_avx2(static_cast<size_t>(list.count), rows, j0, i0s, ns, bases, nodes == room,
                     !_mm256_testz_si256(chunky, chunky));
  return true;
}
#endif
// Rows j0..j1 of `list` (level and size set, count 0); false beyond kMaxNodes.
// The AVX2 form where the walk uses AVX2 (kWalkAvx2), else the SSE2 form.
inline bool nodes_at_level_rows(const Footprint &f, int64_t j0, int64_t j1, NodeList &list) {
#if GLIMMER_GLINT_WALK_AVX2
  if (kWalkAvx2) return nodes_at_level_rows_avx2(f, j0, j1, list);
#endif
  return nodes_at_level_rows_sse2_cold(f, j0, j1, list);
}
inline bool nodes_at_level(const Footprint &f, int level, NodeList &list, int64_t box_span = kSmallBoxSpan) {
  const NodeRows rows = nodes_at_level_start(f, level, list, box_span);
  if (rows.kind != NodeRows::kRows) return rows.kind == NodeRows::kDone;
  return nodes_at_level_rows(f, rows.j0, rows.j1, list);
}

// The coarse fallback: the (at most 2 x 2) nodes of the level whose node side is >= the footprint's bounding box.
inline void coarse_footprint_nodes(const Footprint &f, NodeList &list) {
  const double ex = 0.5 * (std::fabs(f.ax) + std::fabs(f.bx));
  const double ey = 0.5 * (std::fabs(f.ay) + std::fabs(f.by));
  const int e = binary_exponent(std::max(2.0 * std::max(ex, ey), 1e-30));  // extent < 2^e
  nodes_at_level(f, -e, list);
}
// The nodes a footprint is counted over: those of the particle level it
// overlaps, or, when there are more than kMaxNodes of them, the coarse fallback
// (the list footprint_nodes gives through the memo with kBoxSpan).
inline void footprint_nodes_at(const Footprint &f, int particle_level, NodeList &list) {
  if (nodes_at_level(f, particle_level, list, kBoxSpan)) return;
  coarse_footprint_nodes(f, list);
}
inline void footprint_nodes(const Footprint &f, double density, NodeList &list) {
  footprint_nodes_at(f, particle_level(density), list);
}
inline NodeList footprint_nodes(const Footprint &f, double density) {
  NodeList list;
  footprint_nodes(f, density, list);
  return list;
}

// The last footprint's node list, kept by the caller (glint.cpp: one per
// thread). A host calls a shading point's closure several times over the
// same footprint (the light sample's eval, the BSDF sample, the mixture's
// evals at another closure's sample), and the list depends only on the
// footprint, the density (the particle level) and the box span; the
// direction cells differ per call.
// Issue 10, session 17: in examples/glint.xml (160 x 100, 4 spp)
// nodes_at_level was 92 M of the glint render's 365 M instructions above
// its GGX twin (1311 per call); 37 % of the calls find their list here
// (92 M -> 61 M), and a lookup that misses costs ~130 instructions
// (docs/history/glints_sessions.md, "Session 17"). Session 26: the memo holds the box lists
// too and is asked first (the key is the density's bits, not the level, so
// a hit skips the level, the start and the box fill).
struct FootprintNodeMemo {
  // The key: the footprint's six doubles' bits, the density's bits (the particle level is a function of them) and
  // the box span the list was made with (kSmallBoxSpan or kBoxSpan; 0: no list). In Footprint's order, so that
  // holds() compares it in four SSE2 registers (-0 and NaN are keys like any other).
  alignas(16) std::array<uint64_t, 8> key{};
  NodeList nodes{NodeList::Zeroed{}};
  static_assert(sizeof(Footprint) == 6 * sizeof(double) && std::is_standard_layout_v<Footprint>);
  [[gnu::always_inline]] bool holds(const Footprint &f, double density, int64_t span) const {
#if defined(__SSE2__)
    const auto *k = reinterpret_cast<const __m128i *>(key.data());
    const auto *p = reinterpret_cast<const __m128i *>(&f.cx);
    __m128i eq = _mm_and_si128(_mm_cmpeq_epi32(_mm_loadu_si128(p), _mm_load_si128(k)),
                               _mm_cmpeq_epi32(_mm_loadu_si128(p + 1), _mm_load_si128(k + 1)));
    eq = _mm_and_si128(eq, _mm_cmpeq_epi32(_mm_loadu_si128(p + 2), _mm_load_si128(k + 2)));
    const __m128i tail = _mm_unpacklo_epi64(_mm_castpd_si128(_mm_set_sd(density)), _mm_cvtsi64_si128(span));
    eq = _mm_and_si128(eq, _mm_cmpeq_epi32(tail, _mm_load_si128(k + 3)));
    return _mm_movemask_epi8(eq) == 0xffff;
#else
    return std::bit_cast<std::array<uint64_t, 6>>(f) == std::array<uint64_t, 6>{key[0], key[1], key[2], key[3], key[4],
                                                                              key[5]} &&
           std::bit_cast<uint64_t>(density) == key[6] && static_cast<uint64_t>(span) == key[7];
#endif
  }
  void clear() { key[7] = 0; }
  // The particle level of `density` (particle_level): its division, square root and exponent once per density,
  // not once per list made (session 30: ~20 instructions per list; a scene's densities repeat).
  int level_of(double density) {
    const auto bits = std::bit_cast<uint64_t>(density);
    if (bits != level_density_) level_density_ = bits, level_ = particle_level(density);
    return level_;
  }
  void set_key(const Footprint &f, double density, int64_t span) {
    key = {std::bit_cast<uint64_t>(f.cx), std::bit_cast<uint64_t>(f.cy), std::bit_cast<uint64_t>(f.ax),
           std::bit_cast<uint64_t>(f.ay), std::bit_cast<uint64_t>(f.bx), std::bit_cast<uint64_t>(f.by),
           std::bit_cast<uint64_t>(density), static_cast<uint64_t>(span)};
  }

 private:
  uint64_t level_density_ = std::bit_cast<uint64_t>(kNodeParticles);  // level_of's last density's bits, and
  int level_ = 0;                                                       // its level (particle_level(kNodeParticles))
};

#if GLIMMER_GLINT_WALK_AVX2
// nodes_at_level_start with its four floors (the rows' and the box's ends) in
// one register (VROUNDPD; session 21) and a small footprint's box rows keyed
// by node_row_keys_avx2: the same result and entries (floors of doubles below
// 2^51 in magnitude are exact integers; otherwise, and for NaN, the scalar
// form decides). GlintParticles.NodeListStartAvx2MatchesTheScalarStart.
[[gnu::target("avx2"), gnu::always_inline]] inline NodeRows nodes_at_level_start_avx2_body(const Footprint &f, int level,
                                                                                      NodeList &list,
                                                                                      int64_t box_span) {
  list.count = 0;
  list.level = level;
  list.size = power_of_two(-level);
  const double inv = power_of_two(level);
  const double ey = 0.5 * (std::fabs(f.ay) + std::fabs(f.by));
  const double ex = 0.5 * (std::fabs(f.ax) + std::fabs(f.bx));
  if (!(ex * inv < 1e15) || !(ey * inv < 1e15)) return {NodeRows::kTooMany, 0, 0};
  const __m256d v = _mm256_mul_pd(_mm256_setr_pd(f.cy - ey, f.cy + ey, f.cx - ex, f.cx + ex), _mm256_set1_pd(inv));
  const __m256d abs_v = _mm256_and_pd(v, _mm256_castsi256_pd(_mm256_set1_epi64x(0x7fffffffffffffffll)));
  if (_mm256_movemask_pd(_mm256_cmp_pd(abs_v, _mm256_set1_pd(2251799813685248.0), _CMP_LT_OQ)) != 0xf)
    return nodes_at_level_start_cold(f, level, list, box_span);  // beyond 2^51 or NaN
  const __m256d magic = _mm256_set1_pd(6755399441055744.0);  // 2^52 + 2^51
  alignas(32) int64_t e[4];                                  // j0, j1, box_i0, box_i1
  _mm256_store_si256(reinterpret_cast<__m256i *>(e),
                     _mm256_sub_epi64(_mm256_castpd_si256(_mm256_add_pd(
                                          _mm256_round_pd(v, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC), magic)),
                                      _mm256_castpd_si256(magic)));
  const int64_t j0 = e[0], j1 = e[1];
  if (j1 - j0 >= kMaxNodes) return {NodeRows::kTooMany, 0, 0};
  if (j1 - j0 < box_span && e[3] - e[2] < box_span) {  // the box (see nodes_at_level_start; box_span <= 4)
    const __m128i j = _mm_add_epi32(_mm_set1_epi32(static_cast<int>(static_cast<uint32_t>(j0))), _mm_setr_epi32(0, 1, 2, 3));
    list.put_box_avx2(e[2], e[3] - e[2] + 1, j0, j1 - j0 + 1, box_span, node_row_keys_avx2(level, j));
    return {NodeRows::kDone, j0, j1};
  }
  return {NodeRows::kRows, j0, j1};
}
// The same, out of line (for the tests; footprint_nodes_avx2 inlines the body).
// box_span at most 4.
[[gnu::target("avx2")]] inline NodeRows nodes_at_level_start_avx2(const Footprint &f, int level, NodeList &list,
                                                                   int64_t box_span = kSmallBoxSpan) {
  return nodes_at_level_start_avx2_body(f, level, list, box_span);
}
#endif
// The body of footprint_nodes_avx2 and footprint_nodes_sse2 (session 22: one
// copy; a macro, not a template, because the AVX2 start must be inlined into
// a target("avx2") function and GCC refuses to inline it into a generic
// helper): the start (`start`: the form's nodes_at_level_start: the box,
// or the coarse list) or the rows (`rows_of`: the form's rasteriser) into
// the memo's list, keyed (f, density, kSpan); footprint_nodes has asked the
// memo first.
#define GLIMMER_GLINT_FOOTPRINT_NODES_BODY(start, rows_of)                                          \
  memo.clear();                                                                                     \
  NodeList &out = memo.nodes;                                                                       \
  const NodeRows rows = start(f, memo.level_of(density), out, kSpan);                              \
  if (rows.kind == NodeRows::kTooMany || (rows.kind == NodeRows::kRows && !rows_of(f, rows.j0, rows.j1, out))) \
    coarse_footprint_nodes(f, out);                                                                 \
  memo.set_key(f, density, kSpan);                                                                  \
  return out
#if GLIMMER_GLINT_WALK_AVX2
// footprint_nodes through the memo (below) with the AVX2 start (inlined) and rows.
template <int64_t kSpan>
[[gnu::target("avx2"), gnu::noinline]] inline const NodeList &footprint_nodes_avx2(const Footprint &f, double density,
                                                                                   FootprintNodeMemo &memo) {
  GLIMMER_GLINT_FOOTPRINT_NODES_BODY(nodes_at_level_start_avx2_body, nodes_at_level_rows_avx2);
}
#endif
// footprint_nodes through the memo with the SSE2 start and rows (out of line, as footprint_nodes was until session 21).
template <int64_t kSpan>
[[gnu::noinline]] inline const NodeList &footprint_nodes_sse2(const Footprint &f, double density,
                                                             FootprintNodeMemo &memo) {
  GLIMMER_GLINT_FOOTPRINT_NODES_BODY(nodes_at_level_start, nodes_at_level_rows);
}
#undef GLIMMER_GLINT_FOOTPRINT_NODES_BODY
// footprint_nodes through the memo: the same list (bit for bit; the key is
// the footprint's bits, the density's and the span), returned by reference:
// the memo's own list (valid until the next call with this memo; no copy).
// Footprints whose bounding box spans at most kSpan x kSpan particle nodes
// (kBoxSpan for the direction cells' walk since session 23, kSmallBoxSpan for
// the pseudo-normal count, whose extra nodes cost more) take
// nodes_at_level_start's box, the others the rasterised rows. get_memo()
// returns the memo (a thread-local's address is a call in a shared library).
// Session 21: the AVX2 form (footprint_nodes_avx2) where the walk uses AVX2, else the SSE2 form; this
// dispatch is inlined into the caller (no call in between).
template <int64_t kSpan = kBoxSpan, typename GetMemo>
[[gnu::always_inline]] inline const NodeList &footprint_nodes(const Footprint &f, double density, GetMemo &&get_memo) {
  static_assert(kSpan >= kSmallBoxSpan && kSpan <= 4);
  FootprintNodeMemo &memo = *get_memo();
  if (memo.holds(f, density, kSpan)) return memo.nodes;  // session 26: the hit without a call (~25 fewer per hit)
#if GLIMMER_GLINT_WALK_AVX2
  if (kWalkAvx2) return footprint_nodes_avx2<kSpan>(f, density, memo);
#endif
  return footprint_nodes_sse2<kSpan>(f, density, memo);
}

// Per-node random stream: the node seed comes from 8 TEA rounds, the values
// along the stream from a cheap integer hash of (seed, index).
struct NodeStream {
  uint32_t a, b;
  float operator()(uint32_t index) const { return uint_to_unit_float(hash_u32(a ^ hash_u32(b + index * 0x9e3779b9u))); }
};

inline NodeStream node_stream(uint32_t seed, int level, int64_t i, int64_t j) {
  uint32_t v0 = static_cast<uint32_t>(i) ^ static_cast<uint32_t>(static_cast<uint64_t>(i) >> 32);
  uint32_t v1 = static_cast<uint32_t>(j) ^ hash_u32(seed ^ hash_u32(static_cast<uint32_t>(level) + 0x632be5abu));
  tea<8>(v0, v1);
  return {v0, v1};
}

// Number of particles in node (level, i, j) for density N (per unit area).
inline uint64_t node_particle_count(const NodeStream &stream, double density, double size) {
  const double mean = std::fmin(density * size * size, 4.0e18);
  const double whole = std::floor(mean);
  return static_cast<uint64_t>(whole) + (stream(0) < static_cast<float>(mean - whole) ? 1u : 0u);
}

// ---- Direction cells (see the header comment) ------------------------------
inline constexpr int kDirectionGroups = 4;
// Cell side in units of gamma / 2 (the lit region's in-plane semi-axis).
// Chosen by measurement (docs/glints.md): the correlation of the lit counts
// between directions gamma apart matches the exact model's (~0.4), and one
// cell covers about one cone of reflected directions (c^2 / pi ~ 1), so the
// per-footprint albedo varies like the exact model's.
inline constexpr float kCellSize = 1.75f;
// Grid shifts of the groups, in cells (a 4-point lattice).
inline constexpr std::array<std::array<float, 2>, kDirectionGroups> kGroupShift = {
    {{0.0f, 0.0f}, {0.5f, 0.25f}, {0.25f, 0.75f}, {0.75f, 0.5f}}};

// The part of the cell seeds that depends on the material only: the seed of
// group g's cell (cx, cy) is cell_seed(key[g], cx, cy) with
// key[g] = hash_u32x2(seed, g), hashed once per material instead of once per eval.
struct DirectionCellKeys {
  std::array<uint32_t, kDirectionGroups> group{};
  float gamma_rad = 0.0f;          // the cone of cell_scale (0: none given)
  float cell_scale = 0.0f;         // 2 / (kCellSize gamma_rad): cells per unit of the chart
  explicit DirectionCellKeys(uint32_t seed, float gamma = 0.0f) : gamma_rad(gamma) {
    for (int g = 0; g < kDirectionGroups; ++g) group[g] = hash_u32x2(seed, static_cast<uint32_t>(g));
    if (gamma > 0.0f) cell_scale = 2.0f / (kCellSize * gamma);
  }
  // 2 / (kCellSize gamma), divided once per material when gamma is the keys' own.
  float inv_cell(float gamma) const { return gamma == gamma_rad ? cell_scale : 2.0f / (kCellSize * gamma); }
};

// The groups' cell coordinates floor_to_int32(x + kGroupShift[g][0]) and
// floor_to_int32(y + kGroupShift[g][1]); with SSE2 the four groups in the
// lanes of one register (issue 10, seventh speed session: the eight scalar
// floors were ~100 instructions per eval). Same clamp (NaN to -kLimit, as
// maxps returns its second operand when unordered), same values.
inline void floor_cells(float x, float y, std::array<int32_t, kDirectionGroups> &cx,
                        std::array<int32_t, kDirectionGroups> &cy) {
#if defined(__SSE2__)
  static_assert(kDirectionGroups == 4);
  const __m128 limit = _mm_set1_ps(1.07e9f), neg_limit = _mm_set1_ps(-1.07e9f);
  const auto floor4 = [&](__m128 v) {
    v = _mm_max_ps(_mm_min_ps(limit, v), neg_limit);  // NaN: min gives NaN, max gives -limit
    const __m128i i = _mm_cvttps_epi32(v);
    // i - 1 where the truncation rounded up (negative non-integers)
    return _mm_add_epi32(i, _mm_castps_si128(_mm_cmpgt_ps(_mm_cvtepi32_ps(i), v)));
  };
  const __m128i ix = floor4(_mm_add_ps(_mm_set1_ps(x), _mm_setr_ps(kGroupShift[0][0], kGroupShift[1][0],
                                                                    kGroupShift[2][0], kGroupShift[3][0])));
  const __m128i iy = floor4(_mm_add_ps(_mm_set1_ps(y), _mm_setr_ps(kGroupShift[0][1], kGroupShift[1][1],
                                                                    kGroupShift[2][1], kGroupShift[3][1])));
  _mm_storeu_si128(reinterpret_cast<__m128i *>(cx.data()), ix);
  _mm_storeu_si128(reinterpret_cast<__m128i *>(cy.data()), iy);
#else
  for (int g = 0; g < kDirectionGroups; ++g) {
    cx[g] = floor_to_int32(x + kGroupShift[g][0]);
    cy[g] = floor_to_int32(y + kGroupShift[g][1]);
  }
#endif
}

// Seed of group g's direction cell (cx, cy): mix_u32(mix_u32(key + cx W) ^ cy),
// key the group's material key; the four groups in SSE2 lanes, the scalar
// form without SSE2, same values (issue 10, eighth speed session; before,
// hash_combine(hash_combine(key, cx), cy), eight PCG hashes per eval).
inline uint32_t cell_seed(uint32_t key, int32_t cx, int32_t cy) {
  return mix_u32(mix_u32(key + static_cast<uint32_t>(cx) * kNodeKeyStep) ^ static_cast<uint32_t>(cy));
}
inline void cell_seeds_scalar(const uint32_t *keys, const std::array<int32_t, kDirectionGroups> &cx,
                              const std::array<int32_t, kDirectionGroups> &cy,
                              std::array<uint32_t, kDirectionGroups> &seeds) {
  for (int g = 0; g < kDirectionGroups; ++g) seeds[g] = cell_seed(keys[g], cx[g], cy[g]);
}
inline void cell_seeds(const uint32_t *keys, const std::array<int32_t, kDirectionGroups> &cx,
                       const std::array<int32_t, kDirectionGroups> &cy, std::array<uint32_t, kDirectionGroups> &seeds) {
#if defined(__SSE2__)
  const __m128i k = _mm_loadu_si128(reinterpret_cast<const __m128i *>(keys));
  const __m128i x = mullo_u32x4(_mm_loadu_si128(reinterpret_cast<const __m128i *>(cx.data())), kNodeKeyStep);
  const __m128i y = _mm_loadu_si128(reinterpret_cast<const __m128i *>(cy.data()));
  _mm_storeu_si128(reinterpret_cast<__m128i *>(seeds.data()), mix_u32x4(_mm_xor_si128(mix_u32x4(_mm_add_epi32(k, x)), y)));
#else
  cell_seeds_scalar(keys, cx, cy, seeds);
#endif
}

// sqrt(x) for x > 0 (the caller's test): SQRTSS (correctly rounded, std::sqrt's bits) without std::sqrt's errno
// branch for x < 0 and the stack frame of its sqrtf call, which GCC 12 keeps after a test x > c (no float ranges;
// _mm_sqrt_ss(_mm_set_ss(x)) costs a VINSERTPS instead). kVex: callers compiled for AVX (VSQRTSS); the others
// (the SSE2 walk, inlined into glint.cpp) keep std::sqrt: glint.cpp's inlining budget. Session 30 (glintcells30).
template <bool kVex>
[[gnu::always_inline]] inline float positive_sqrt(float x) {
#if defined(__SSE2__)
  if constexpr (kVex) {
    float r;
    asm("vsqrtss %1, %1, %0" : "=x"(r) : "x"(x));
    return r;
  }
#endif
  return std::sqrt(x);
}
// The cell coordinates (before the groups' shifts and floors) of (wi, wo)
// in units of cells: (x, y); false when there is no half vector above the
// surface. direction_cell_seeds' chart, shared by its SSE2 and AVX2 forms
// (the same float operations in the same order: the same x, y).
// kVex: the caller is compiled for AVX (positive_sqrt's instruction form).
template <bool kVex = false>
[[gnu::always_inline]] inline bool direction_cell_coords(const DirectionCellKeys &keys, const Vec3 &wi, const Vec3 &wo,
                                                         float gamma_rad, float &x, float &y) {
  // In terms of s = wi + wo (h = s / |s|), with two divisions and one square
  // root (issue 10, sixth speed session; was nine and two: h per component,
  // 2 / (1 + h.z) and n.z / (1 + h.z) apart, e normalised, 1 / cell per
  // call). Same cells up to the rounding of the chart (docs/history/glints_sessions.md,
  // "Session 6").
  const Vec3 s = wi + wo;
  const float len2 = dot(s, s);
  if (!(len2 > 1e-12f) || !(s.z > 0.0f)) return false;
  const float len = positive_sqrt<kVex>(len2);
  // Stereographic chart of h: p = 2 h.xy / (1 + h.z) = 2 s.xy / (|s| + s.z).
  const float d = 1.0f / (len + s.z);
  float px = 2.0f * d * s.x, py = 2.0f * d * s.y;
  // Compress by wi.h across the plane of incidence: n = wi x h (tangent at
  // h) has the chart direction e ~ n.xy - n.z / (1 + h.z) h.xy, parallel to
  // c.xy - c.z d s.xy with c = wi x s; the component of p along e is
  // (p.e) e / |e|^2 (no normalisation), and wi.h = |s| / 2 for unit wi, wo.
  const Vec3 c = cross(wi, s);
  const float t = c.z * d;
  const float ex = c.x - t * s.x, ey = c.y - t * s.y;
  const float e2 = ex * ex + ey * ey;
  if (e2 > 1e-24f * len2) {
    const float along = (0.5f * len - 1.0f) * (px * ex + py * ey) / e2;
    px += along * ex;
    py += along * ey;
  }
  const float inv_cell = keys.inv_cell(gamma_rad);
  x = px * inv_cell, y = py * inv_cell;
  return true;
}
#if GLIMMER_GLINT_WALK_AVX2
// floor_cells' floor4 (NaN to -limit, the clamp, then an exact floor) by VROUNDPS.
[[gnu::target("avx2"), gnu::always_inline]] inline __m128i floor_cells4_avx2(__m128 v) {
  v = _mm_max_ps(_mm_min_ps(_mm_set1_ps(1.07e9f), v), _mm_set1_ps(-1.07e9f));
  return _mm_cvttps_epi32(_mm_round_ps(v, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC));
}
// mix_u32 per 32-bit lane by VPMULLD (mix_u32x4's words).
[[gnu::target("avx2"), gnu::always_inline]] inline __m128i mix_u32x4_avx2(__m128i v) {
  v = _mm_xor_si128(v, _mm_srli_epi32(v, 16));
  v = _mm_mullo_epi32(v, _mm_set1_epi32(static_cast<int>(kMixMultiplier1)));
  v = _mm_xor_si128(v, _mm_srli_epi32(v, 15));
  v = _mm_mullo_epi32(v, _mm_set1_epi32(static_cast<int>(kMixMultiplier2)));
  return _mm_xor_si128(v, _mm_srli_epi32(v, 16));
}
// The same with the multipliers given (direction_cell_seeds_avx2_body: read from kCellConstants' memory).
[[gnu::target("avx2"), gnu::always_inline]] inline __m128i mix_u32x4_avx2(__m128i v, __m128i m1, __m128i m2) {
  v = _mm_xor_si128(v, _mm_srli_epi32(v, 16));
  v = _mm_mullo_epi32(v, m1);
  v = _mm_xor_si128(v, _mm_srli_epi32(v, 15));
  v = _mm_mullo_epi32(v, m2);
  return _mm_xor_si128(v, _mm_srli_epi32(v, 16));
}
// direction_cell_seeds_avx2_body's integer constants (session 30): kNodeKeyStep and mix_u32's two multipliers, four
// lanes each.
alignas(16) inline constexpr Lanes4 kCellConstants[3] = {lanes4(kNodeKeyStep), lanes4(kMixMultiplier1),
                                                        lanes4(kMixMultiplier2)};
// direction_cell_seeds where the walk uses AVX2 (session 22): the same chart
// (direction_cell_coords, inlined: VEX forms of the same float operations;
// avx2 enables no FMA), the floors by VROUNDPS (floor_cells' clamp first:
// the same integers) and the seeds' five 32-bit lane multiplies by VPMULLD
// instead of SSE2's PMULUDQ pairs and shuffles (the same words).
// GlintParticles.DirectionCellSeedsAvx2MatchSse2.
// The body (always inlined; session 24: also inlined into glint_small_dark.h's dark test for small footprints).
[[gnu::target("avx2"), gnu::always_inline]] inline bool direction_cell_seeds_avx2_body(
    const DirectionCellKeys &keys, const Vec3 &wi, const Vec3 &wo, float gamma_rad,
    std::array<uint32_t, kDirectionGroups> &seeds) {
  float x, y;
  if (!direction_cell_coords<true>(keys, wi, wo, gamma_rad, x, y)) return false;
  static_assert(kDirectionGroups == 4);
  const __m128i ix = floor_cells4_avx2(_mm_add_ps(_mm_set1_ps(x), _mm_setr_ps(kGroupShift[0][0], kGroupShift[1][0],
                                                                    kGroupShift[2][0], kGroupShift[3][0])));
  const __m128i iy = floor_cells4_avx2(_mm_add_ps(_mm_set1_ps(y), _mm_setr_ps(kGroupShift[0][1], kGroupShift[1][1],
                                                                    kGroupShift[2][1], kGroupShift[3][1])));
  const __m128i k = _mm_loadu_si128(reinterpret_cast<const __m128i *>(keys.group.data()));
  // Session 30 (glintcells30): the integer constants from memory (VPMULLD's operand, or one load each; were three
  // instructions each from immediates), the table's address through an empty asm so GCC does not fold it back to
  // immediates. (The groups' shifts as well changed GCC's inlining in glint.cpp: ClosureAdapter::sample, measured.)
  const auto *row = reinterpret_cast<const __m128i *>(opaque(kCellConstants));
  const __m128i m1 = _mm_load_si128(row + 1), m2 = _mm_load_si128(row + 2);
  const __m128i h = mix_u32x4_avx2(_mm_add_epi32(k, _mm_mullo_epi32(ix, _mm_load_si128(row))), m1, m2);
  _mm_storeu_si128(reinterpret_cast<__m128i *>(seeds.data()), mix_u32x4_avx2(_mm_xor_si128(h, iy), m1, m2));
  return true;
}
[[gnu::target("avx2"), gnu::noinline]] inline bool direction_cell_seeds_avx2(const DirectionCellKeys &keys,
                                                                             const Vec3 &wi, const Vec3 &wo,
                                                                             float gamma_rad,
                                                                             std::array<uint32_t, kDirectionGroups> &seeds) {
  return direction_cell_seeds_avx2_body(keys, wi, wo, gamma_rad, seeds);
}
#endif
// The SSE2 form (and the form without SSE2): floor_cells and cell_seeds.
inline bool direction_cell_seeds_sse2(const DirectionCellKeys &keys, const Vec3 &wi, const Vec3 &wo, float gamma_rad,
                                      std::array<uint32_t, kDirectionGroups> &seeds) {
  float x, y;
  if (!direction_cell_coords(keys, wi, wo, gamma_rad, x, y)) return false;
  std::array<int32_t, kDirectionGroups> cx, cy;
  floor_cells(x, y, cx, cy);
  cell_seeds(keys.group.data(), cx, cy, seeds);
  return true;
}
// Seed of the particle field of each group's direction cell at (wi, wo);
// false when there is no half vector above the surface. The AVX2 form where
// the walk uses AVX2 (kWalkAvx2), else the SSE2 form: the same seeds.
inline bool direction_cell_seeds(const DirectionCellKeys &keys, const Vec3 &wi, const Vec3 &wo, float gamma_rad,
                                 std::array<uint32_t, kDirectionGroups> &seeds) {
#if GLIMMER_GLINT_WALK_AVX2
  if (kWalkAvx2) return direction_cell_seeds_avx2(keys, wi, wo, gamma_rad, seeds);
#endif
  return direction_cell_seeds_sse2(keys, wi, wo, gamma_rad, seeds);
}

struct GlintCount {
  int count = 0;         // particles in the footprint with lambda < P
  int steps = 0;         // particles visited
  bool complete = true;  // false when max_steps was reached (caller falls back to the mean)
};

// Per-query constants of the lit count of one node. The particles of a
// field of density n (N / G for each of the G direction groups) are a
// Poisson process: a node of side s holds Poisson(n s^2) particles at i.i.d.
// uniform positions, and, each reflecting independently with probability
// P, K ~ Poisson(lambda = n s^2 P) reflecting ones, again at i.i.d. uniform
// positions. K is drawn by
// inversion from one uniform u of the node: K = max{k : u < Pr(K >= k)} (the
// tail walked with the pmf ratio Pr(k) / Pr(k-1) = lambda / k: no log or exp
// per node or particle). For a fixed u the tail Pr(K >= k) grows with P, so
// the lit set of a node is nested in P (no flicker from the trilinear table
// lookups), and the lit particles are the first K of the node's particle
// stream. The constants (one exp) are computed once per query, and only
// when some node passes the bound Pr(K >= 1) = 1 - e^-lambda <= lambda.
struct LitCountModel {
  // A node's tail walk stops (the caller returns the mean) beyond this
  // expected count: e^-lambda would underflow near lambda ~ 700. Reached only
  // by the coarse fallback level of footprints holding thousands of glints.
  static constexpr double kMaxNodeMean = 600.0;

  double lambda = 0.0;
  double p_none = 1.0;  // Pr(K = 0) = e^-lambda
  double p_any = 0.0;   // Pr(K >= 1)
  bool walkable = true;

  // p_any = 1 - e^-lambda without expm1: its absolute error (~1e-16) is far
  // below the 2^-32 resolution of the u it is compared with.
  explicit LitCountModel(double lambda_in)
      : lambda(lambda_in), p_none(std::exp(-lambda_in)), p_any(1.0 - p_none), walkable(lambda_in <= kMaxNodeMean) {}

  // K for the node's uniform u in (0, 1); K = 0 needs u >= p_any (the caller
  // tests that first). -1 when the walk is refused.
  int64_t lit(double u) const {
    if (!walkable) return -1;
    double pmf = p_none, tail = p_any;  // Pr(K = k), Pr(K > k) at k = 0
    int64_t k = 0;
    while (u < tail && pmf > 0.0) {
      ++k;
      pmf *= lambda / static_cast<double>(k);
      tail -= pmf;
    }
    return k;
  }
};

// The lit count K(u) of LitCountModel without its exp, where bounds decide
// it: for lambda <= 1 the series of Pr(K >= 1) = 1 - e^-lambda and of
// Pr(K >= 2) = 1 - (1 + lambda) e^-lambda alternate with decreasing terms,
// so their partial sums bound them:
//   lambda - lambda^2/2 <= Pr(K >= 1) <= lambda - lambda^2/2 + lambda^3/6,
//   lambda^2/2 - lambda^3/3 <= Pr(K >= 2) <= lambda^2/2.
// u above the first upper bound gives K = 0, u between the second upper
// bound and the first lower bound K = 1; only u within O(lambda^3) of a
// bound (or lambda > 1) needs the exact tail walk (kUndecided). A margin of
// 1e-12 lambda keeps float rounding of the bounds from deciding: the result
// is LitCountModel's K for every u (same particles), and most queries,
// whose lambda is well below 1 in glint mode, need no exp at all.
struct LitCountBounds {
  static constexpr int64_t kUndecided = -2;
  double none_above = 0.0;  // u >= this: K = 0
  double one_from = 1.0;    // one_from <= u < one_below: K = 1
  double one_below = 0.0;

  explicit LitCountBounds(double lambda) {
    if (!(lambda <= 1.0)) return;  // every u undecided
    const double l2 = 0.5 * lambda * lambda, l3 = lambda * lambda * lambda;
    const double margin = 1e-12 * lambda;
    none_above = lambda - l2 + l3 / 6.0 + margin;
    one_from = l2 + margin;
    one_below = lambda - l2 - margin;
  }
  // Branches, not selects: an SSE2 mask form (same results, ~5 fewer
  // mispredictions per eval at area 1e-4 in callgrind's model) measured
  // 2.5..4 % slower on the small-footprint rows and no faster at 1e-4
  // (issue 10, ninth speed session).
  int64_t lit(double u) const {
    if (u >= none_above && none_above > 0.0) return 0;
    if (u >= one_from && u < one_below) return 1;
    return kUndecided;
  }
};

// The lit count K of a (node, group) pair from its 32-bit hash h0 (u = (h0 +
// 1/2) 2^-32): the bounds where they decide, else LitCountModel's tail walk
// (the model made at the first undecided pair; K = 0 for u >= Pr(K >= 1)).
// The walks' shared step (the scalar node loop, the AVX2 node loop and the pair
// passes below the table (kLitTableFrom), glint_small_dark.cpp,
// glint_pseudo_normals.h; session 26,
// glintK26). Always inline: a shared step out of line cost ~10 instructions
// per eval (session 24). glint_pseudo_normals.h takes u first and its lazily
// made bounds after (lit_count_at_uniform): with lit_count_at after the
// bounds, roughness 0.2 area 1e-4 measured +165 instructions per eval.
[[gnu::always_inline]] inline double lit_count_uniform(uint32_t h0) {
  return (static_cast<double>(h0) + 0.5) * (1.0 / 4294967296.0);
}
[[gnu::always_inline]] inline int64_t lit_count_at_uniform(double u, const LitCountBounds &bounds,
                                                           std::optional<LitCountModel> &model, double lambda) {
  int64_t K = bounds.lit(u);
  if (K == LitCountBounds::kUndecided) {
    if (!model) model.emplace(lambda);
    K = u < model->p_any ? model->lit(u) : 0;
  }
  return K;
}
[[gnu::always_inline]] inline int64_t lit_count_at(uint32_t h0, const LitCountBounds &bounds,
                                                   std::optional<LitCountModel> &model, double lambda) {
  return lit_count_at_uniform(lit_count_uniform(h0), bounds, model, lambda);
}

// LitCountModel's K for a pair's 32-bit hash h (u = (h + 1/2) 2^-32) by
// integer compares (issue 10, session 23), for the queries whose lambda is
// at least kLitTableFrom (the pair passes since session 24, the AVX2 node loop
// since session 43; from lambda > 1 LitCountBounds decides nothing, and every
// pair of the footprint passes the quick reject): the model's tail walk visits the same terms
// Pr(K > k) for every u, and it goes past term k iff u < Pr(K > k) and its
// pmf is not 0 there (the tails never increase, and a pmf of 0 stays 0), so
// K >= k + 1 iff h < below[k], the number of hashes whose u is under the
// k-th tail (0 once the pmf is 0). below[] is made once per query (the
// model's exp and kSteps terms), and a pair costs kSteps integer compares
// instead of the walk's double compares and a division per step. K >=
// kSteps continues the model's walk from its kSteps-th term (the same
// values). Not walkable (lambda > kMaxNodeMean): -1 where the model's is
// (u < p_any), else 0. GlintParticles.LitCountTableMatchesTheTailWalk.
struct LitCountTable {
  static constexpr int kSteps = 4;
  std::array<uint64_t, kSteps> below{};  // non-increasing
  double lambda, pmf = 0.0, tail = 0.0;  // the walk's terms at k = kSteps
  bool walkable;

  // The number of h in [0, 2^32) with (h + 1/2) 2^-32 < v: h < x = v 2^32 - 1/2, so ceil(x) clamped to [0, 2^32]
  // (the scale by a power of two is exact, and so is the difference wherever x > 0 and v 2^32 < 2^53; beyond, the
  // clamp decides; NaN: 0). Session 30 (glintcells30): the one form for LitCountTable and LitBoundHashes (which had
  // its own copy, clamping after the ceil: GI +0.047 M in count_tabled_avx2 as the one form); the form before
  // returned 2^32 from x >= 2^32 - 1, but at x = 2^32 - 1 exactly (v = 1 - 2^-33) the count is 2^32 - 1 (h = 2^32 - 1
  // has u = v). GlintParticles.HashesBelowMatchesTheHashCount.
  // Session 43: where the target has SSE2, x clamped to [0, 2^32] by its max and min (maxsd gives its second operand,
  // 0, for NaN) before the ceil, instead of two branches that follow lambda: the same values (x <= 0 or NaN: 0;
  // x > 2^32 - 1: 2^32).
  static uint64_t hashes_below(double v) {
    const double x = v * 4294967296.0 - 0.5;
#if defined(__SSE2__)
    const double c = _mm_cvtsd_f64(_mm_min_sd(_mm_max_sd(_mm_set_sd(x), _mm_setzero_pd()), _mm_set_sd(4294967296.0)));
#else
    if (!(x > 0.0)) return 0;                        // also NaN
    if (x > 4294967295.0) return uint64_t{1} << 32;  // ceil(x) >= 2^32: clamped
    const double c = x;
#endif
    // Session 36 (glintorigin36): 0 <= ceil(c) <= 2^32 converted as a signed 64-bit integer (one CVTTSD2SI; the
    // unsigned conversion added a compare, a branch and a subtraction for values from 2^63): the same value.
    return static_cast<uint64_t>(static_cast<int64_t>(std::ceil(c)));
  }
  explicit LitCountTable(const LitCountModel &m) : lambda(m.lambda), walkable(m.walkable) {
    if (!walkable) {
      below.fill(hashes_below(m.p_any));  // K is 0 or kSteps, and lit() gives -1 for the latter
      return;
    }
    double p = m.p_none, t = m.p_any;
    for (size_t k = 0; k < below.size(); ++k) {
      below[k] = p > 0.0 ? hashes_below(t) : 0;
      p *= lambda / static_cast<double>(k + 1);
      t -= p;
    }
    pmf = p, tail = t;
  }
  // h < below[k] as the sign of h - below[k] (both below 2^33): an add per step, no branch (session 43: GCC 12 made
  // the compares branches, which follow the data).
  static int64_t under(uint32_t h, uint64_t b) { return static_cast<int64_t>((uint64_t{h} - b) >> 63); }
  int64_t lit(uint32_t h) const {
    int64_t K = 0;
    for (size_t k = 0; k < below.size(); ++k) K += under(h, below[k]);
    if (K == kSteps) [[unlikely]] return walk_on(h);
    return K;
  }
  // lit(h) for a walkable table's h < below[0] (K >= 1: the exact reject of the pair passes and of the AVX2 node loop
  // let it through; session 26): the first compare known, one register fewer in pass 3.
  int64_t lit_passed(uint32_t h) const {
    int64_t K = 1;
    for (size_t k = 1; k < below.size(); ++k) K += under(h, below[k]);
    if (K == kSteps) [[unlikely]] return walk_on(h);
    return K;
  }
  // K >= kSteps: the model's walk from its kSteps-th term on (-1: not walkable).
  [[gnu::noinline]] int64_t walk_on(uint32_t h) const {
    if (!walkable) return -1;
    const double u = (static_cast<double>(h) + 0.5) * (1.0 / 4294967296.0);
    double p = pmf, t = tail;
    int64_t k = kSteps;
    while (u < t && p > 0.0) {
      ++k;
      p *= lambda / static_cast<double>(k);
      t -= p;
    }
    return k;
  }
};

// Session 29 (glintbounds29): LitCountBounds' K = 1 as a range of the 32-bit hash h of a pair (u = (h + 1/2) 2^-32,
// exact in a double): u >= v iff h >= below(v) (the number of hashes whose u < v), so the
// bounds' one_from <= u < one_below is one_from <= h < one_from + one_span (empty where they decide no K = 1). Their
// K = 0 test (u >= none_above > 0) comes first in LitCountBounds::lit, but for lambda >= 0 none_above >= one_below
// (both add to the same lambda - l2: l3 / 6 + margin >= 0 and -margin <= 0, and rounding is monotonic), and for
// lambda < 0 one_below < 0: no hash in the range has K = 0. So one(h) iff LitCountBounds::lit gives 1
// (GlintParticles.LitBoundHashesMatchTheBounds), by one subtraction and compare, no double per pair.
struct LitBoundHashes {
  uint64_t one_from, one_span;
  // The ends by LitCountTable::hashes_below (the number of h whose u < v).
  explicit LitBoundHashes(const LitCountBounds &b) : one_from(LitCountTable::hashes_below(b.one_from)), one_span(0) {
    const uint64_t one_end = LitCountTable::hashes_below(b.one_below);
    one_span = one_end > one_from ? one_end - one_from : 0;
  }
  // h - one_from wraps above one_span for h < one_from.
  bool one(uint32_t h) const { return uint64_t{h} - one_from < one_span; }
};

// The footprint's parallelogram coordinates (s, t), inside when |s|, |t| <=
// 1/2, are affine in the position; over a node of side `size` at (x0, y0)
// they are (s, t) = origin + u_x d_ux + u_y d_uy for the position
// (x0 + size u_x, y0 + size u_y). The per-footprint steps are computed once,
// the node origin once per lit node (per lit pair in count_node_loop_avx2, session 43), and a particle costs four
// multiply-adds.
struct FootprintFrame {
  const Footprint &f;
  double inv_det, size;
  double ds_ux, ds_uy, dt_ux, dt_uy;  // steps of (s, t) per unit of u_x, u_y
  bool nodes_can_be_inside;           // the footprint is at least as large as a node

  [[gnu::always_inline]] FootprintFrame(const Footprint &fp, double node_size)
      : f(fp), inv_det(1.0 / (fp.ax * fp.by - fp.ay * fp.bx)), size(node_size),
        ds_ux(node_size * fp.by * inv_det), ds_uy(-node_size * fp.bx * inv_det),
        dt_ux(-node_size * fp.ay * inv_det), dt_uy(node_size * fp.ax * inv_det),
        nodes_can_be_inside(can_hold_a_node(fp, node_size)) {}
  // The footprint is at least as large as a node (nodes_can_be_inside, without the frame).
  static bool can_hold_a_node(const Footprint &fp, double node_size) { return fp.area() >= node_size * node_size; }

  struct NodeOrigin {
    double s, t;
  };
  NodeOrigin origin(double x0, double y0) const {
    const double px = x0 - f.cx, py = y0 - f.cy;
    return {(px * f.by - py * f.bx) * inv_det, (f.ax * py - f.ay * px) * inv_det};
  }
  // Both coordinates tested without a short-circuit branch, and a node's four
  // corners all tested (issue 10, seventh speed session: these outcomes are
  // random, and their branches were ~12 mispredictions per eval at
  // footprint area 1e-4); same results.
  static bool inside(double s, double t) { return (std::fabs(s) <= 0.5) & (std::fabs(t) <= 0.5); }
  // The whole node square inside the footprint (its four corners; it is convex).
  // The corners o, o + d_ux, o + d_uy, (o + d_ux) + d_uy: the values the
  // former form o + a d_ux + b d_uy (a, b in {0, 1}) had, without its eight
  // multiplies by 0 and 1 (not folded without fast math); with SSE2 the two
  // corners of each row of the node in the lanes of one register (issue 10,
  // ninth speed session: the walk tests every node now).
  bool node_inside(const NodeOrigin &o) const {
    if (!nodes_can_be_inside) return false;
#if defined(__SSE2__)
    const __m128d s0 = _mm_add_pd(_mm_set1_pd(o.s), _mm_set_pd(ds_ux, 0.0));  // lanes o.s, o.s + ds_ux
    const __m128d t0 = _mm_add_pd(_mm_set1_pd(o.t), _mm_set_pd(dt_ux, 0.0));
    const __m128d s1 = _mm_add_pd(s0, _mm_set1_pd(ds_uy)), t1 = _mm_add_pd(t0, _mm_set1_pd(dt_uy));
    const __m128d sign = _mm_set1_pd(-0.0), half = _mm_set1_pd(0.5);
    const auto in = [&](__m128d v) { return _mm_cmple_pd(_mm_andnot_pd(sign, v), half); };
    const __m128d all = _mm_and_pd(_mm_and_pd(in(s0), in(s1)), _mm_and_pd(in(t0), in(t1)));
    return _mm_movemask_pd(all) == 3;
#else
    const double s10 = o.s + ds_ux, t10 = o.t + dt_ux;
    return inside(o.s, o.t) & inside(s10, t10) & inside(o.s + ds_uy, o.t + dt_uy) & inside(s10 + ds_uy, t10 + dt_uy);
#endif
  }
  bool particle_inside(const NodeOrigin &o, float ux, float uy) const {
    return inside(o.s + ux * ds_ux + uy * ds_uy, o.t + ux * dt_ux + uy * dt_uy);
  }
};

// The uniform of node x direction cell: mix_u32(node key ^ cell seed). Its
// 32 bits give the node's lit count (u = (hash + 1/2) 2^-32) and seed its lit
// particles' positions. Until issue 10's eighth speed session
// hash_combine(node hash, seed ^ 0x3c6ef372) of a hashed node id.
inline uint32_t node_seed_hash(uint32_t node_key_value, uint32_t seed) { return mix_u32(node_key_value ^ seed); }

// The quick reject of a (node, cell) pair, hash < below (below up to 2^32 + 1;
// at or above 2^32 every hash passes), in the form the SIMD compare uses.
struct GroupReject {
  bool all_pass;
  uint32_t below;  // valid when !all_pass
  uint64_t limit;  // hash < limit, the same test in one compare
  explicit GroupReject(uint64_t maybe_lit_below)
      : all_pass(maybe_lit_below > 0xffffffffu), below(static_cast<uint32_t>(std::min<uint64_t>(maybe_lit_below, 0xffffffffu))),
        limit(maybe_lit_below) {}
};

// A node's expected lit count for a query: density x node area (capped where the product would pass the walks'
// integer counts) times P (at most 1). count_reflecting_particles' and the small dark test's lambda.
inline double node_lit_mean(double density, double node_size, double P) {
  return std::min(density * node_size * node_size, 4.0e18) * std::min(P, 1.0);
}
// The quick reject of lambda: hash >= floor(lambda 2^32) + 1 means u > lambda >= Pr(K >= 1), so K = 0.
inline GroupReject quick_reject(double lambda) {
  return GroupReject(static_cast<uint64_t>(std::min(lambda, 1.0) * 4294967296.0) + 1u);
}
// A walkable table's exact reject (below[0]: the hashes with K >= 1; a subset of quick_reject's), else `quick`: the
// reject of the pair passes and of the AVX2 node loop from kLitTableFrom on.
inline GroupReject exact_reject(const LitCountTable &table, const GroupReject &quick) {
  return table.walkable ? GroupReject(table.below[0]) : quick;
}

// The four groups' node_seed_hash and their quick rejects as one 4-bit mask
// (bit g: hash g < below). group_hashes (the walk's): four independent scalar
// hashes; group_hashes_sse2: the four groups in the lanes of one SSE2
// register, the same values (GlintParticles.GroupHashLanesMatchTheScalarHash),
// but 1..7 % slower per eval in the walk on this project's machine (SSE2 has
// no 32-bit lane multiply: two pmuludq and shuffles per multiply, a longer
// dependency chain before the mask's branch; docs/history/glints_sessions.md "Session 8").
// The node loop keeps the scalar form; count_four_groups_in_passes calls
// this one (its compaction does not branch on the mask).
inline uint32_t group_hashes(uint32_t key, const uint32_t *seeds, const GroupReject &reject, uint32_t *out) {
  uint32_t mask = 0;
  for (int g = 0; g < kDirectionGroups; ++g) {
    out[g] = node_seed_hash(key, seeds[g]);
    mask |= static_cast<uint32_t>(out[g] < reject.limit) << g;  // no short-circuit branch (ninth session)
  }
  return mask;
}
inline uint32_t group_hashes_sse2(uint32_t key, const uint32_t *seeds, const GroupReject &reject, uint32_t *out) {
#if defined(__SSE2__)
  static_assert(kDirectionGroups == 4);
  const __m128i h = mix_u32x4(
      _mm_xor_si128(_mm_set1_epi32(static_cast<int>(key)), _mm_loadu_si128(reinterpret_cast<const __m128i *>(seeds))));
  _mm_storeu_si128(reinterpret_cast<__m128i *>(out), h);
  const __m128i bias = _mm_set1_epi32(static_cast<int>(0x80000000u));  // unsigned compare as signed
  const __m128i lt = _mm_cmplt_epi32(_mm_xor_si128(h, bias),
                                     _mm_xor_si128(_mm_set1_epi32(static_cast<int>(reject.below)), bias));
  // all_pass without a branch (the pair passes call this per node).
  return (reject.all_pass ? 0xfu : 0u) | static_cast<uint32_t>(_mm_movemask_ps(_mm_castsi128_ps(lt)));
#else
  return group_hashes(key, seeds, reject, out);
#endif
}

// Position (u_x, u_y in [0, 1)) of lit particle k of the node whose hash in
// the direction cell is h0: mix_u32 of (h0 ^ C) + (2 k + 1) W and of that
// + W (issue 10, eighth speed session; before, a position-seed hash
// hash_u32(h0 ^ C) per node and two PCG hashes per particle). Two particles
// per 4-lane SSE2 hash gave the same values but was slower in the walk
// (an extra loop and its mispredicted branches; docs/history/glints_sessions.md "Session 8").
inline constexpr uint32_t kPositionKey = 0x27d4eb2fu;
// Session 27 (glintpass27): the pair passes' particle list holds particle k's step (2 k + 1) W (position_step),
// not k, so the flush adds it to h0 ^ C without a multiply; particle_position_stepped gives the same values.
inline constexpr uint32_t position_step(uint32_t k) { return (2u * k + 1u) * kNodeKeyStep; }
inline std::array<float, 2> particle_position_stepped(uint32_t h0, uint32_t step) {
  const uint32_t key = (h0 ^ kPositionKey) + step;
  return {uint_to_unit_float(mix_u32(key)), uint_to_unit_float(mix_u32(key + kNodeKeyStep))};
}
inline std::array<float, 2> particle_position(uint32_t h0, uint32_t k) {
  return particle_position_stepped(h0, position_step(k));
}

// Counts the reflecting particles of a footprint over the given cell seeds
// (one particle field each, same density; see the header comment and
// LitCountModel). Per node and seed: one hash, the uniform u of K; a node
// with K = 0 (most of them) stops at an integer compare. A lit node
// inside the footprint adds K without positions (closed form); a lit node on
// the border draws the positions of its K lit particles (particle_position) and
// counts those inside the parallelogram.
// Per-particle visitor of the count (default: none). A visitor with
// kVisitsParticles is called as visit(h0, k) for every counted particle, k
// its index among the lit particles of the node whose hash in the direction
// cell is h0 (per-flake colours, glint_flake_colour.h).
struct NoParticleVisitor {
  static constexpr bool kVisitsParticles = false;
  void operator()(uint32_t, uint32_t) {}
};

#if GLIMMER_GLINT_WALK_AVX2
// mix_u32 per 32-bit lane of a 256-bit register (VPMULLD: one instruction per
// multiply; SSE2 needs two PMULUDQ and a shuffle). The same values.
// The multipliers given (in all eight lanes: kFlushConstants' rows 1 and 2 read them from memory).
[[gnu::target("avx2"), gnu::always_inline]] inline __m256i mix_u32x8(__m256i x, __m256i m1, __m256i m2) {
  x = _mm256_xor_si256(x, _mm256_srli_epi32(x, 16));
  x = _mm256_mullo_epi32(x, m1);
  x = _mm256_xor_si256(x, _mm256_srli_epi32(x, 15));
  x = _mm256_mullo_epi32(x, m2);
  return _mm256_xor_si256(x, _mm256_srli_epi32(x, 16));
}
[[gnu::target("avx2")]] inline __m256i mix_u32x8(__m256i x) {
  return mix_u32x8(x, _mm256_set1_epi32(static_cast<int>(kMixMultiplier1)),
                   _mm256_set1_epi32(static_cast<int>(kMixMultiplier2)));
}
// flush_avx2's constants: kPositionKey, mix_u32's two multipliers, the padding node (PairPassCounter::kPadNode =
// kMaxNodes), eight lanes each (32-byte rows).
alignas(32) inline constexpr Lanes8 kFlushConstants[4] = {lanes8(kPositionKey), lanes8(kMixMultiplier1),
                                                         lanes8(kMixMultiplier2), lanes8(kMaxNodes)};
// Session 25 (glintcount25): which of the lit particles k0 .. k0 + 3 of a node
// (its hash h0 in the direction cell, its origin o in `frame`) lie inside the
// footprint, as bits 0..3 (all four computed; the caller masks those >= K):
// particle_position's eight keys (h0 ^ C) + (2 k + 1) W and that + W in one
// mix_u32x8, uint_to_unit_float by lanes, and particle_inside's (s, t) in
// 256-bit double lanes by its expressions (no FMA: the same values).
// GlintParticles.NodeLoopAvx2MatchesTheNodeLoop.
// The frame's steps in lanes, made once per count (the caller's registers, not a broadcast per lit pair).
struct FrameLanesAvx2 {
  __m256d ds_ux, ds_uy, dt_ux, dt_uy;
};
[[gnu::target("avx2"), gnu::always_inline]] inline FrameLanesAvx2 frame_lanes_avx2(const FootprintFrame &frame) {
  return {_mm256_set1_pd(frame.ds_ux), _mm256_set1_pd(frame.ds_uy), _mm256_set1_pd(frame.dt_ux),
          _mm256_set1_pd(frame.dt_uy)};
}
[[gnu::target("avx2"), gnu::always_inline]] inline uint32_t particles_inside4_avx2(const FrameLanesAvx2 &frame,
                                                                                  const FootprintFrame::NodeOrigin &o,
                                                                                  uint32_t h0, uint32_t k0) {
  const uint32_t base = (h0 ^ kPositionKey) + (2u * k0 + 1u) * kNodeKeyStep;
  constexpr uint32_t W = kNodeKeyStep;
  const auto lane = [](uint32_t m) { return static_cast<int>(m * W); };  // m W mod 2^32
  const __m256i keys = _mm256_add_epi32(_mm256_set1_epi32(static_cast<int>(base)),
                                        _mm256_setr_epi32(0, lane(1), lane(2), lane(3), lane(4), lane(5), lane(6),
                                                          lane(7)));
  const __m256 u = _mm256_mul_ps(_mm256_cvtepi32_ps(_mm256_srli_epi32(mix_u32x8(keys), 8)),
                                 _mm256_set1_ps(1.0f / 16777216.0f));
  const __m256 xy = _mm256_permutevar8x32_ps(u, _mm256_setr_epi32(0, 2, 4, 6, 1, 3, 5, 7));  // the x's, the y's
  const __m256d ux = _mm256_cvtps_pd(_mm256_castps256_ps128(xy)), uy = _mm256_cvtps_pd(_mm256_extractf128_ps(xy, 1));
  const __m256d s = _mm256_add_pd(_mm256_add_pd(_mm256_set1_pd(o.s), _mm256_mul_pd(ux, frame.ds_ux)),
                                  _mm256_mul_pd(uy, frame.ds_uy));
  const __m256d t = _mm256_add_pd(_mm256_add_pd(_mm256_set1_pd(o.t), _mm256_mul_pd(ux, frame.dt_ux)),
                                  _mm256_mul_pd(uy, frame.dt_uy));
  const __m256d sign = _mm256_set1_pd(-0.0), half = _mm256_set1_pd(0.5);
  const __m256d in = _mm256_and_pd(_mm256_cmp_pd(_mm256_andnot_pd(sign, s), half, _CMP_LE_OS),
                                   _mm256_cmp_pd(_mm256_andnot_pd(sign, t), half, _CMP_LE_OS));
  return static_cast<uint32_t>(_mm256_movemask_pd(in));
}
#endif

// The four direction groups' count without a visitor, in passes with few
// random branches (issue 10, ninth speed session; the same count, steps and
// completeness as the node-by-node loop below, which the visitor and other
// seed counts use: GlintParticles.PairPassesMatchTheNodeLoop). The node-by-
// node loop branched on whether a node had a lit group, on every lit group,
// on the first lit group's inside test and on each lit particle count
// (~25 mispredictions per eval at footprint area 1e-4, 1000 particles over
// ~14 nodes). Here: (2) the (node, group) pairs passing the quick reject
// compacted into a list without a branch per pair, and the nodes with a
// pair into another, (1) those nodes' origins and inside flags (branch-
// free; the inside test only when a node can be inside), (3) per pair the
// lit count K (bounds, or the model's walk), interior nodes adding K by a mask, border nodes appending their K lit
// particles to a list, (4) the listed particles' positions and membership
// in one flat loop. The count is a sum of integers: the order does not
// change it, and the step total is the same sum, so the cap is reached iff
// the node loop reaches it.
// Pass (2)'s result: every node's four group hashes (node_hash[4 node + g],
// session 19), and the (node, group) pairs passing the quick reject as the
// set bits 4 node + g of `mask` (one 64-bit word per 16 nodes; the bits of
// nodes past the list 0). Session 23: bits, not lists of pairs and of nodes
// with a pair: the other passes take the pairs and nodes from the words' set
// bits in order (a bit scan where they loaded a list entry), so pass 2 does
// no compaction; and apart from PairPassCounter, whose frame and set-up are
// made only when a pair passes.
struct PairMasks {
  static constexpr int kMaxPairs = kMaxNodes * kDirectionGroups;
  static constexpr int kWords = kMaxPairs / 64;
  alignas(32) std::array<uint32_t, kMaxPairs> node_hash;
  alignas(32) std::array<uint64_t, kWords> mask;
  // The words of a list of `count` nodes.
  static int words(int count) { return (count + 15) / 16; }
  // Bit 4 n set where node 16 w + n has a passing pair in the word m (w's).
  static uint64_t nodes_with_pair(uint64_t m) {
    m |= m >> 1;
    return (m | (m >> 2)) & 0x1111111111111111ull;
  }
  // The words of a list of `count` nodes whose every pair passes.
  void set_all(int count) {
    for (int w = 0; w < kWords; ++w) {
      const int left = kDirectionGroups * count - 64 * w;
      mask[static_cast<size_t>(w)] = left >= 64 ? ~uint64_t{0} : left <= 0 ? 0 : (uint64_t{1} << left) - 1u;
    }
  }
};
static_assert(kMaxNodes <= 64 && kDirectionGroups == 4, "PairMasks: 16 nodes per word, at most four words");

// list_pairs_avx2's tables: lanes[b] the set bits of byte b in increasing order, then zeros (the compaction lanes);
// count[b] their number, popcount(b) (session 30: the list grown by one ADD with a memory operand at a fixed offset
// from the lanes' address, instead of a register copy, POPCNT and ADD per byte).
struct CompactLanes {
  std::array<std::array<uint8_t, 8>, 256> lanes;
  std::array<uint64_t, 256> count;
};
inline constexpr CompactLanes kCompactLanes = [] {
  CompactLanes t{};
  for (uint32_t b = 0; b < 256; ++b) {
    uint32_t n = 0;
    for (uint32_t k = 0; k < 8; ++k)
      if (b >> k & 1u) t.lanes[b][n++] = static_cast<uint8_t>(k);
    t.count[b] = n;
  }
  return t;
}();

struct PairPassCounter {
  static constexpr int kMaxParticles = 256;  // flushed when full
  const FootprintFrame &frame;
  // kMaxNodes + 1: flush_avx2's padding node kPadNode.
  std::array<FootprintFrame::NodeOrigin, kMaxNodes + 1> origin;
  static constexpr uint32_t kPadNode = kMaxNodes;
  static_assert(kFlushConstants[3].lane[0] == kPadNode);
  std::array<int32_t, kMaxNodes> inside_mask;  // -1 inside, 0 not
  // Listed particle: its pair's hash h0, its position_step(k) and its node (32-bit nodes: no memset call per fill);
  // 8 more for flush_avx2's padding (its four entries from n_parts <= kMaxParticles on) and list_pairs_avx2's
  // whole-register stores (eight entries from n_parts <= kMaxParticles - 1 on).
  std::array<uint32_t, kMaxParticles + 8> part_hash, part_step, part_node;
  int n_parts = 0;
  int64_t count = 0;

  explicit PairPassCounter(const FootprintFrame &fr) : frame(fr) {}
  // Inlined into the pair passes (as GCC chose until session 21; out of line it cost ~3 M in the GI scene's 160x100 render).
  [[gnu::always_inline]] void flush() { flush_from(0, 0); }
#if GLIMMER_GLINT_WALK_AVX2
  // flush with four particles per step first (session 22: their eight
  // position keys in one mix_u32x8, their (s, t) in 256-bit double lanes by
  // flush_from's expressions, the same values), the rest by flush_from.
  // Session 27: the steps (2 k + 1) W listed (no multiply per step), the bits counted by POPCNT; noinline: with
  // count_paired_avx2's target GCC inlined it there (GI +2 M: the pair passes' registers).
  // Session 28 (glintwalk28): the list padded to a multiple of four by particles of node kPadNode, whose origin
  // (+inf, +inf) puts them outside (s = inf + finite; NaN where the frame's steps are not finite: outside too), so
  // the last one to three particles take a step of four too (they took flush_from's SSE2 pair and scalar steps:
  // ~77 instructions per flush in the GI render).
  // Session 30 (glintcells30): the padding's origin is (NaN, NaN) (all bits set: the gathers' mask register), which
  // puts the padding outside as well (s and t NaN, and NaN <= 1/2 is false), and kPadNode's lanes are read from
  // kFlushConstants (were three instructions from an immediate); the two origin stores one 128-bit store.
  [[gnu::target("avx2,popcnt"), gnu::noinline]] void flush_avx2() {
    int64_t c = 0;
    int q = 0;
    const auto end = static_cast<size_t>(n_parts);
    // Session 29 (glintlast29): the position key and mix_u32's multipliers read from memory in the loop (VPXOR's
    // and VPMULLD's memory operands), not built from immediates (3 instructions each, two spilled): the table's
    // address passes through an empty asm each step, so GCC neither folds it to immediates nor hoists the loads.
    const Lanes8 *consts = opaque(kFlushConstants);  // kPadNode's lanes below a load
    _mm_storeu_si128(reinterpret_cast<__m128i *>(part_node.data() + end),
                     _mm_load_si128(reinterpret_cast<const __m128i *>(consts[3].lane)));
    _mm_storeu_si128(reinterpret_cast<__m128i *>(part_hash.data() + end), _mm_setzero_si128());
    _mm_storeu_si128(reinterpret_cast<__m128i *>(part_step.data() + end), _mm_setzero_si128());
    // The gathers' mask: every lane gathered (the masked form: GCC 12 warns on the other).
    const __m256d all = _mm256_castsi256_pd(_mm256_set1_epi64x(-1));
    static_assert(sizeof(FootprintFrame::NodeOrigin) == 2 * sizeof(double));
    _mm_storeu_pd(&origin[kPadNode].s, _mm256_castpd256_pd128(all));  // (s, t) = (NaN, NaN)
    // Session 30: the eight keys as the four x keys, then the four y keys (were interleaved: x0 y0 x1 y1 ..., then
    // split by a VPERMPS whose index was reloaded each step): the halves of u are ux's and uy's floats.
    const __m256i second = _mm256_setr_epi32(0, 0, 0, 0, static_cast<int>(kNodeKeyStep),
                                             static_cast<int>(kNodeKeyStep), static_cast<int>(kNodeKeyStep),
                                             static_cast<int>(kNodeKeyStep));
    const __m256 scale = _mm256_set1_ps(1.0f / 16777216.0f);
    const __m256d ds_ux = _mm256_set1_pd(frame.ds_ux), ds_uy = _mm256_set1_pd(frame.ds_uy);
    const __m256d dt_ux = _mm256_set1_pd(frame.dt_ux), dt_uy = _mm256_set1_pd(frame.dt_uy);
    const __m256d sign = _mm256_set1_pd(-0.0), half = _mm256_set1_pd(0.5);
    for (; q < n_parts; q += 4) {
      const auto a = static_cast<size_t>(q);
      // (h ^ C) + (2 k + 1) W per particle, mod 2^32 (the step listed).
      const __m128i step = _mm_loadu_si128(reinterpret_cast<const __m128i *>(part_step.data() + a));
      const __m128i h = _mm_loadu_si128(reinterpret_cast<const __m128i *>(part_hash.data() + a));
      consts = opaque(consts);  // the three loads below stay memory operands
      const auto *row = reinterpret_cast<const __m256i *>(consts);
      const __m128i keys = _mm_add_epi32(_mm_xor_si128(h, _mm_load_si128(reinterpret_cast<const __m128i *>(row))), step);
      const __m256i keys8 = _mm256_add_epi32(_mm256_set_m128i(keys, keys), second);
      const __m256i mixed = mix_u32x8(keys8, _mm256_load_si256(row + 1), _mm256_load_si256(row + 2));
      const __m256 u = _mm256_mul_ps(_mm256_cvtepi32_ps(_mm256_srli_epi32(mixed, 8)), scale);  // the x's, the y's
      const __m256d ux = _mm256_cvtps_pd(_mm256_castps256_ps128(u)), uy = _mm256_cvtps_pd(_mm256_extractf128_ps(u, 1));
      // Session 29 (glintpaired29): the four origins' s and t by two VGATHERDPD at the doubles 2 node and 2 node + 1
      // (were four index loads and shifts, four 128-bit loads, two inserts and two unpacks); the same lanes.
      const __m128i at = _mm_slli_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i *>(part_node.data() + a)), 1);
      const __m256d os = _mm256_mask_i32gather_pd(_mm256_setzero_pd(), &origin[0].s, at, all, 8);
      const __m256d ot = _mm256_mask_i32gather_pd(_mm256_setzero_pd(), &origin[0].t, at, all, 8);
      const __m256d s = _mm256_add_pd(_mm256_add_pd(os, _mm256_mul_pd(ux, ds_ux)), _mm256_mul_pd(uy, ds_uy));
      const __m256d t = _mm256_add_pd(_mm256_add_pd(ot, _mm256_mul_pd(ux, dt_ux)), _mm256_mul_pd(uy, dt_uy));
      const __m256d in = _mm256_and_pd(_mm256_cmp_pd(_mm256_andnot_pd(sign, s), half, _CMP_LE_OS),
                                       _mm256_cmp_pd(_mm256_andnot_pd(sign, t), half, _CMP_LE_OS));
      const auto m = static_cast<uint32_t>(_mm256_movemask_pd(in));
      c += std::popcount(m);
    }
    count += c;
    n_parts = 0;
  }
#endif
  // flush from particle q on with c already counted.
  [[gnu::always_inline]] void flush_from(int q, int64_t c) {
#if defined(__SSE2__)
    // Session 19: two particles' positions per mix_u32x4 (lanes: particle
    // q's two keys, particle q + 1's), the same values as particle_position
    // (uint_to_unit_float in lanes: v >> 8 < 2^24 converts exactly as a
    // signed integer, and the scale is a power of two).
    const __m128i step = _mm_set_epi32(static_cast<int>(kNodeKeyStep), 0, static_cast<int>(kNodeKeyStep), 0);
    const __m128 scale = _mm_set1_ps(1.0f / 16777216.0f);
    const __m128d ds_ux = _mm_set1_pd(frame.ds_ux), ds_uy = _mm_set1_pd(frame.ds_uy);
    const __m128d dt_ux = _mm_set1_pd(frame.dt_ux), dt_uy = _mm_set1_pd(frame.dt_uy);
    const __m128d sign = _mm_set1_pd(-0.0), half = _mm_set1_pd(0.5);
    for (; q + 1 < n_parts; q += 2) {
      const auto a = static_cast<size_t>(q), b = a + 1;
      const uint32_t ka = (part_hash[a] ^ kPositionKey) + part_step[a];
      const uint32_t kb = (part_hash[b] ^ kPositionKey) + part_step[b];
      const __m128i keys = _mm_add_epi32(
          _mm_set_epi32(static_cast<int>(kb), static_cast<int>(kb), static_cast<int>(ka), static_cast<int>(ka)), step);
      const __m128 u = _mm_mul_ps(_mm_cvtepi32_ps(_mm_srli_epi32(mix_u32x4(keys), 8)), scale);  // ax ay bx by
      // Session 19: both particles' membership in double lanes: particle_inside's
      // expressions ((o + ux d_ux) + uy d_uy, |s|, |t| <= 1/2), the same values.
      const __m128d ux = _mm_cvtps_pd(_mm_shuffle_ps(u, u, _MM_SHUFFLE(2, 0, 2, 0)));  // ax bx
      const __m128d uy = _mm_cvtps_pd(_mm_shuffle_ps(u, u, _MM_SHUFFLE(3, 1, 3, 1)));  // ay by
      const __m128d oa = _mm_loadu_pd(&origin[part_node[a]].s), ob = _mm_loadu_pd(&origin[part_node[b]].s);
      const __m128d s = _mm_add_pd(_mm_add_pd(_mm_unpacklo_pd(oa, ob), _mm_mul_pd(ux, ds_ux)), _mm_mul_pd(uy, ds_uy));
      const __m128d t = _mm_add_pd(_mm_add_pd(_mm_unpackhi_pd(oa, ob), _mm_mul_pd(ux, dt_ux)), _mm_mul_pd(uy, dt_uy));
      const __m128d in = _mm_and_pd(_mm_cmple_pd(_mm_andnot_pd(sign, s), half), _mm_cmple_pd(_mm_andnot_pd(sign, t), half));
      const int m = _mm_movemask_pd(in);
      c += (m & 1) + (m >> 1);
    }
#endif
    for (; q < n_parts; ++q) {
      const auto [ux, uy] = particle_position_stepped(part_hash[static_cast<size_t>(q)], part_step[static_cast<size_t>(q)]);
      c += frame.particle_inside(origin[part_node[static_cast<size_t>(q)]], ux, uy) ? 1 : 0;
    }
    count += c;
    n_parts = 0;
  }
  // add_lit's rare case, out of line (session 22: inlined, its flush kept the
  // pair pass's counters in memory): the list flushed, and K >= kMaxParticles
  // (only at the coarse fallback level) counted here (true: done).
  [[gnu::noinline]] bool flush_for(int node, uint32_t h0, int64_t K, int32_t in) {
    flush();
    if (K < kMaxParticles) return false;
    if (in == 0)
      for (int64_t k = 0; k < K; ++k) {
        const auto [ux, uy] = particle_position(h0, static_cast<uint32_t>(k));
        count += frame.particle_inside(origin[static_cast<size_t>(node)], ux, uy) ? 1 : 0;
      }
    return true;
  }
  // K >= 0 lit particles of pair (node, h0): interior nodes add K, border
  // nodes list them. False (nothing added) when the list is full and
  // stop() says so (session 24: the caller's step cap is tested there, not
  // per pair).
  template <typename Stop>
  [[gnu::always_inline]] bool add_lit(int node, uint32_t h0, int64_t K, Stop &&stop) {
    const int32_t in = inside_mask[static_cast<size_t>(node)];
    count += K & static_cast<int64_t>(in);
    // Keeps two free slots for the writes below (n_parts + K: one add, session 24).
    if (n_parts + K >= kMaxParticles - 1) [[unlikely]] {
      if (stop()) return false;
      if (flush_for(node, h0, K, in)) return true;
    }
    add_listed(node, h0, K, in);
    return true;
  }
  // The pairs 64 w + b of the set bits b of `border` (their hashes in node_hash), each with the step `step` (room
  // checked by the caller; tabled_layers_pass). Session 27: the list's length in a register (the uint32 stores may
  // alias n_parts: it was reloaded and stored per particle); the empty asm hides its progression from GCC, which
  // otherwise split the loop into one loop per array (loop distribution: ~20 instructions per particle, not 13).
  [[gnu::always_inline]] void list_pairs(uint64_t border, int w, uint32_t step, const uint32_t *node_hash) {
    auto n = static_cast<size_t>(n_parts);
    for (; border != 0; border &= border - 1, ++n) {
      asm("" : "+r"(n));
      const auto pair = static_cast<uint32_t>(64 * w + std::countr_zero(border));
      part_hash[n] = node_hash[pair], part_step[n] = step, part_node[n] = pair / 4;
    }
    n_parts = static_cast<int>(n);
  }
#if GLIMMER_GLINT_WALK_AVX2
  // list_pairs by bytes of `border` (session 28, glintwalk28): a byte's (two nodes') set bits compacted in one
  // VPERMD of its eight hashes (kCompactLanes: the set bits' lanes in order), their nodes by the same lanes, the
  // step broadcast; eight entries stored per array, the list grown by the byte's bit count. The same entries in the
  // same order as list_pairs (~13 instructions per particle there; ~2.5 border pairs per nonzero byte in the GI
  // render). Session 29 (glintpaired29): the bytes in order from the first nonzero one to the last (a zero byte
  // between them stores entries the list does not take: its count adds 0), the hashes' address and the byte's
  // first pair advanced by eight per byte: no tzcnt / shift / clear per byte (26 -> 16 instructions per byte; in
  // the GI render 111 353 bytes for 101 299 nonzero ones).
  // `border` != 0 (the caller's test).
  // Session 30 (glintcells30): the list grown by kCompactLanes.count (above); the first pair's index as one unsigned
  // 32-bit value for both the hashes' address and the pairs' lanes (GCC computed it twice, sign-extended).
  [[gnu::target("avx2,popcnt")]] void list_pairs_avx2(uint64_t border, int w, uint32_t step,
                                                       const uint32_t *node_hash) {
    auto n = static_cast<size_t>(n_parts);
    const __m256i steps = _mm256_set1_epi32(static_cast<int>(step));
    const auto at = static_cast<uint32_t>(std::countr_zero(border)) & ~7u;  // the first nonzero byte's first bit
    border >>= at;
    const uint32_t first = 64u * static_cast<uint32_t>(w) + at;  // the byte's first pair
    const uint32_t *h = node_hash + first;
    __m256i pairs = _mm256_set1_epi32(static_cast<int>(first));
    do {
      const auto byte = static_cast<uint32_t>(border & 0xffu);
      const __m256i lanes =
          _mm256_cvtepu8_epi32(_mm_loadl_epi64(reinterpret_cast<const __m128i *>(kCompactLanes.lanes[byte].data())));
      _mm256_storeu_si256(reinterpret_cast<__m256i *>(part_hash.data() + n),
                          _mm256_permutevar8x32_epi32(_mm256_loadu_si256(reinterpret_cast<const __m256i *>(h)), lanes));
      _mm256_storeu_si256(reinterpret_cast<__m256i *>(part_node.data() + n), _mm256_srli_epi32(_mm256_add_epi32(pairs, lanes), 2));
      _mm256_storeu_si256(reinterpret_cast<__m256i *>(part_step.data() + n), steps);
      n += kCompactLanes.count[byte];
      h += 8;
      pairs = _mm256_add_epi32(pairs, _mm256_set1_epi32(8));
      border >>= 8;
    } while (border != 0);
    n_parts = static_cast<int>(n);
  }
#endif
  [[gnu::always_inline]] void add_listed(int node, uint32_t h0, int64_t K, int32_t in) {
    // The first two entries always (K is mostly 0 or 1), more only for K >= 3
    // (session 22; the loop from k = 1 was vectorised with a setup paid at
    // every K >= 2); the list grows by K on the border and by 0 inside (or
    // when K = 0).
    const auto at = static_cast<size_t>(n_parts);
    const auto nd = static_cast<uint32_t>(node);
    part_hash[at] = h0, part_step[at] = position_step(0), part_node[at] = nd;
    part_hash[at + 1] = h0, part_step[at + 1] = position_step(1), part_node[at + 1] = nd;
    if (K > 2) [[unlikely]]
      for (int64_t k = 2; k < K; ++k) {
        const auto a = at + static_cast<size_t>(k);
        part_hash[a] = h0, part_step[a] = position_step(static_cast<uint32_t>(k)), part_node[a] = nd;
      }
    n_parts += static_cast<int>(K & static_cast<int64_t>(~in));
  }
};

// Pass (2) of count_four_groups_in_passes: every node's four group hashes
// into pm.node_hash and their quick rejects into pm.mask (bit 4 node + g).
inline void group_pass_sse2(const NodeList &nodes, const uint32_t *seeds, const GroupReject &reject, PairMasks &pm) {
  pm.mask = {};
  for (int node = 0; node < nodes.count; ++node) {
    const auto at = static_cast<size_t>(node);
    // The four groups' hashes in the lanes of one SSE2 register (mix_u32x4,
    // the same values as group_hashes): no branch reads them here, unlike
    // the node loop where the lanes measured slower (session 8). Session 17:
    // 1e-4 5714 -> 5470 instructions per eval, same f and pdf bits.
    // Session 19: the passing groups as a 4-bit mask (group_hashes_sse2);
    // session 23: or-ed into the node's word.
    const uint32_t mask =
        group_hashes_sse2(nodes.id_hash[at], seeds, reject, pm.node_hash.data() + kDirectionGroups * at);
    pm.mask[at / 16] |= uint64_t{mask} << (kDirectionGroups * (at % 16));
  }
}

#if GLIMMER_GLINT_WALK_AVX2
// One step of group_pass_avx2: the two nodes whose keys are the low two
// lanes of two_keys, their eight (node, group) hashes stored from
// node_hash (the first node's), and their 8-bit mask (bit 4 d + g: node d of
// the two, group g).
[[gnu::target("avx2"), gnu::always_inline]] inline uint32_t group_pass_step_avx2(__m128i two_keys, __m256i seeds8,
                                                                                __m256i below, uint32_t *node_hash) {
  const __m256i keys = _mm256_permutevar8x32_epi32(_mm256_castsi128_si256(two_keys), _mm256_setr_epi32(0, 0, 0, 0, 1, 1, 1, 1));
  const __m256i h = mix_u32x8(_mm256_xor_si256(keys, seeds8));
  _mm256_storeu_si256(reinterpret_cast<__m256i *>(node_hash), h);
  const __m256i bias = _mm256_set1_epi32(static_cast<int>(0x80000000u));  // unsigned compare as signed
  const __m256i lt = _mm256_cmpgt_epi32(below, _mm256_xor_si256(h, bias));
  return static_cast<uint32_t>(_mm256_movemask_ps(_mm256_castsi256_ps(lt)));
}
// group_pass_sse2 with two nodes per step (session 20): their eight (node,
// group) hashes in one register, and their 8-bit mask stored as byte s of
// the words (session 23; before, each step compacted its pairs into a list by
// a table entry: 35 -> 20 instructions per step). An odd last node is a step
// whose second key is 0 (its hashes stored past the list's, never read; its
// mask bits cleared) instead of the SSE2 form. The same hashes and words
// (GlintParticles.GroupPassAvx2MatchesSse2). Inlined into
// count_four_groups_in_passes_avx2; an SSE2 caller calls it out of line.
[[gnu::target("avx2")]] inline void group_pass_avx2(const NodeList &nodes, const uint32_t *seeds,
                                                   const GroupReject &reject, PairMasks &pm) {
  const __m256i seeds8 = _mm256_broadcastsi128_si256(_mm_loadu_si128(reinterpret_cast<const __m128i *>(seeds)));
  const __m256i below = _mm256_set1_epi32(static_cast<int>(reject.below ^ 0x80000000u));
  pm.mask = {};
  auto *mask_bytes = reinterpret_cast<unsigned char *>(pm.mask.data());  // byte s: bits 8 s .. 8 s + 7 (little-endian)
  const int full = nodes.count / 2;
  // Session 27: unrolled by two (four nodes per iteration): GI -0.27 M, r0.4 1e-4 -5.5 per eval.
#pragma GCC unroll 2
  for (int s = 0; s < full; ++s)
    mask_bytes[s] = static_cast<unsigned char>(group_pass_step_avx2(
        _mm_loadl_epi64(reinterpret_cast<const __m128i *>(nodes.id_hash.data() + 2 * s)), seeds8, below,
        pm.node_hash.data() + 2 * kDirectionGroups * s));
  if (nodes.count & 1)
    mask_bytes[full] = static_cast<unsigned char>(
        0xfu & group_pass_step_avx2(_mm_cvtsi32_si128(static_cast<int>(nodes.id_hash[static_cast<size_t>(2 * full)])),
                                    seeds8, below, pm.node_hash.data() + 2 * kDirectionGroups * full));
  if (reject.all_pass) pm.set_all(nodes.count);
}
#endif

#if GLIMMER_GLINT_WALK_AVX2
// No pair passes: the four words in one VPTEST (session 24; three ORs of loads before).
[[gnu::target("avx2")]] inline bool pair_masks_empty_avx2(const PairMasks &pm) {
  const __m256i m = _mm256_load_si256(reinterpret_cast<const __m256i *>(pm.mask.data()));
  return _mm256_testz_si256(m, m) != 0;
}
#endif

// Pass (2) in the form `avx2` says (AVX2 only where compiled in).
inline void group_pass(bool avx2, const NodeList &nodes, const uint32_t *seeds, const GroupReject &reject,
                       PairMasks &pm) {
#if GLIMMER_GLINT_WALK_AVX2
  if (avx2) return group_pass_avx2(nodes, seeds, reject, pm);
#else
  (void)avx2;
#endif
  group_pass_sse2(nodes, seeds, reject, pm);
}

// Pass (1) of count_four_groups_in_passes: the origin and inside flag of the
// nodes with a pair passing the quick reject (pm.mask's).
inline void paired_node_origins(const FootprintFrame &frame, const NodeList &nodes, const PairMasks &pm,
                                PairPassCounter &pc) {
  const bool can_be_inside = frame.nodes_can_be_inside;
#if defined(__SSE2__)
  const __m128d centre = _mm_set_pd(frame.f.cy, frame.f.cx), by_ax = _mm_set_pd(frame.f.ax, frame.f.by);
  const __m128d bx_ay = _mm_set_pd(frame.f.ay, frame.f.bx), inv_det = _mm_set1_pd(frame.inv_det);
#endif
  for (int w = 0; w < PairMasks::words(nodes.count); ++w)
    for (uint64_t with = PairMasks::nodes_with_pair(pm.mask[static_cast<size_t>(w)]); with != 0; with &= with - 1) {
    const auto at = static_cast<size_t>(16 * w + std::countr_zero(with) / 4);
#if defined(__SSE2__)
    // (s, t) in double lanes: origin()'s products and differences in the same
    // order (a product's operands commute exactly), the same values.
    const __m128d p = _mm_sub_pd(_mm_set_pd(static_cast<double>(nodes.j[at]) * nodes.size,
                                            static_cast<double>(nodes.i[at]) * nodes.size), centre);  // px py
    const __m128d st = _mm_mul_pd(_mm_sub_pd(_mm_mul_pd(p, by_ax), _mm_mul_pd(_mm_shuffle_pd(p, p, 1), bx_ay)), inv_det);
    _mm_storeu_pd(&pc.origin[at].s, st);
    const FootprintFrame::NodeOrigin o = pc.origin[at];
#else
    const auto o = frame.origin(static_cast<double>(nodes.i[at]) * nodes.size, static_cast<double>(nodes.j[at]) * nodes.size);
    pc.origin[at] = o;
#endif
    pc.inside_mask[at] = can_be_inside && frame.node_inside(o) ? -1 : 0;
  }
}

#if GLIMMER_GLINT_WALK_AVX2
// The four corners c, c + d_ux, c + d_uy, (c + d_ux) + d_uy (node_inside's sums) all within 1/2 per lane, as the
// largest |corner| <= 1/2 (session 29, glintpaired29: three VMAXPD and one compare where four compares and three
// ANDs were). The same flags, NaN included: VMAXPD returns its second operand when either is NaN, and a NaN
// corner makes (c + d_ux) + d_uy NaN (c NaN makes every corner NaN; c + d_ux NaN makes the last one NaN; c + d_uy
// NaN with c not NaN is d_uy NaN or c = -d_uy = +-inf, and then (c + d_ux) + d_uy is NaN for every d_ux), which is
// the second operand of both maxima it goes through: the maximum is NaN and the compare false.
[[gnu::target("avx2"), gnu::always_inline]] inline __m256d corners_within_half_avx2(__m256d c, __m256d d_ux,
                                                                                    __m256d d_uy) {
  const __m256d sign = _mm256_set1_pd(-0.0), c10 = _mm256_add_pd(c, d_ux);
  const __m256d near = _mm256_max_pd(_mm256_andnot_pd(sign, c), _mm256_andnot_pd(sign, c10));
  const __m256d far =
      _mm256_max_pd(_mm256_andnot_pd(sign, _mm256_add_pd(c, d_uy)), _mm256_andnot_pd(sign, _mm256_add_pd(c10, d_uy)));
  return _mm256_cmp_pd(_mm256_max_pd(near, far), _mm256_set1_pd(0.5), _CMP_LE_OS);
}
// paired_node_origins in AVX2, two nodes per 256-bit register (session 29, glintbounds29; session 24's form took one
// node per step, 35 instructions per node with a pair in the GI render's bounds walks): the lanes (s_a, t_a, s_b,
// t_b) of nodes a and b, the next two nodes with a pair of a word (a word's odd last node is its own b).
// origin()'s products in the SSE2 form's lanes and order ((px by - py bx, py ax - px ay) inv_det: the same values),
// node_inside's corners o, o + d_ux, o + d_uy and (o + d_ux) + d_uy as its sums (its lanes o.s + 0 are o.s up to
// the sign of a zero, which |.| drops), |.| <= 1/2 in every corner's s and t lane, the s and t lanes ANDed by a
// swap within each half. The flags' low 32 bits (-1 or 0) stored as inside_mask. The same origins and flags as
// paired_node_origins (GlintParticles.GroupPassAvx2MatchesSse2 compares the whole passes of both forms).
[[gnu::target("avx2"), gnu::always_inline]] inline void paired_nodes_chunk_avx2(const NodeList &nodes, size_t a,
                                                                               size_t b, const __m256d (&l)[7],
                                                                               __m256d can_be_inside,
                                                                               PairPassCounter &pc) {
  const __m256d size = l[0], centre = l[1], by_ax = l[2], bx_ay = l[3], inv_det = l[4];
  const __m128d xa = _mm_setr_pd(static_cast<double>(nodes.i[a]), static_cast<double>(nodes.j[a]));
  const __m128d xb = _mm_setr_pd(static_cast<double>(nodes.i[b]), static_cast<double>(nodes.j[b]));
  const __m256d p = _mm256_sub_pd(_mm256_mul_pd(_mm256_set_m128d(xb, xa), size), centre);  // px py, per node
  const __m256d st =
      _mm256_mul_pd(_mm256_sub_pd(_mm256_mul_pd(p, by_ax), _mm256_mul_pd(_mm256_permute_pd(p, 0x5), bx_ay)), inv_det);
  _mm_storeu_pd(&pc.origin[a].s, _mm256_castpd256_pd128(st));
  _mm_storeu_pd(&pc.origin[b].s, _mm256_extractf128_pd(st, 1));
  // Session 36 (glintorigin36): the corners by corners_within_half_avx2 (three VMAXPD and one compare per lane; were
  // four compares and three ANDs): the same flags, NaN included (its comment). Each lane (s or t of node a or b)
  // tests its own four corners; the s and t flags are ANDed below.
  const __m256d all = corners_within_half_avx2(st, l[5], l[6]);  // (ds_ux dt_ux ds_ux dt_ux), (ds_uy dt_uy ...)
  const __m256d flag = _mm256_and_pd(_mm256_and_pd(all, _mm256_permute_pd(all, 0x5)), can_be_inside);
  _mm_store_ss(reinterpret_cast<float *>(&pc.inside_mask[a]), _mm_castpd_ps(_mm256_castpd256_pd128(flag)));
  _mm_store_ss(reinterpret_cast<float *>(&pc.inside_mask[b]), _mm_castpd_ps(_mm256_extractf128_pd(flag, 1)));
}
[[gnu::target("avx2")]] inline void paired_node_origins_avx2(const FootprintFrame &frame, const NodeList &nodes,
                                                            const PairMasks &pm, PairPassCounter &pc) {
  const Footprint &f = frame.f;
  const __m256d l[7] = {_mm256_set1_pd(nodes.size), _mm256_setr_pd(f.cx, f.cy, f.cx, f.cy),
                        _mm256_setr_pd(f.by, f.ax, f.by, f.ax), _mm256_setr_pd(f.bx, f.ay, f.bx, f.ay),
                        _mm256_set1_pd(frame.inv_det), _mm256_setr_pd(frame.ds_ux, frame.dt_ux, frame.ds_ux, frame.dt_ux),
                        _mm256_setr_pd(frame.ds_uy, frame.dt_uy, frame.ds_uy, frame.dt_uy)};
  const __m256d can_be_inside = _mm256_castsi256_pd(_mm256_set1_epi64x(frame.nodes_can_be_inside ? -1 : 0));
  for (int w = 0; w < PairMasks::words(nodes.count); ++w) {
    const auto first = static_cast<size_t>(16 * w);
    for (uint64_t with = PairMasks::nodes_with_pair(pm.mask[static_cast<size_t>(w)]); with != 0;) {
      const size_t a = first + static_cast<uint32_t>(std::countr_zero(with)) / 4;
      with &= with - 1;
      const size_t b = with == 0 ? a : first + static_cast<uint32_t>(std::countr_zero(with)) / 4;
      with &= with - 1;
      paired_nodes_chunk_avx2(nodes, a, b, l, can_be_inside, pc);
    }
  }
}
#endif

// The interior pairs of a walkable table's walk (tabled_layers_pass): bits 4 n .. 4 n + 3 of word w set where node
// 16 w + n lies inside the footprint (pc.inside_mask of the nodes with a pair; other nodes' bits 0).
inline std::array<uint64_t, PairMasks::kWords> interior_words(const PairMasks &pm, int node_count,
                                                              const PairPassCounter &pc) {
  std::array<uint64_t, PairMasks::kWords> interior{};
  for (int w = 0; w < PairMasks::words(node_count); ++w)
    for (uint64_t with = PairMasks::nodes_with_pair(pm.mask[static_cast<size_t>(w)]); with != 0; with &= with - 1) {
      const int bit = std::countr_zero(with);
      interior[static_cast<size_t>(w)] |=
          static_cast<uint64_t>(static_cast<uint32_t>(pc.inside_mask[static_cast<size_t>(16 * w + bit / 4)]) & 0xfu)
          << bit;
    }
  return interior;
}

#if GLIMMER_GLINT_WALK_AVX2
// Session 28 (glintwalk28): pass (1) of a walkable table's walk in AVX2, four nodes per step in 256-bit double lanes
// (every node: in the tabled walks ~85 % of the nodes have a pair, and a node's origin and corners cost 35
// instructions one by one): the origins by origin()'s products in the same order (the same values, stored for the
// flush), node_inside's four corners (s, s + ds_ux, s + ds_uy, (s + ds_ux) + ds_uy, the same for t: its sums), and
// the nodes inside as the nibbles of `interior` (interior_words' bits, and those of inside nodes without a pair,
// which no layer bit reads). No inside_mask: the tabled walk reads only `interior`. The last chunk's missing lanes
// have their bits cleared (their origins, stored past the list's, are not read). GlintParticles.PairPassesMatchTheNodeLoop and
// GroupPassAvx2MatchesSse2 (the SSE2 passes: paired_node_origins and interior_words).
// The frame's constants in lanes (tabled_node_origins_avx2).
struct TabledOriginLanesAvx2 {
  __m256d cx, cy, size, ax, ay, bx, by, inv_det, ds_ux, ds_uy, dt_ux, dt_uy;
};
// Nodes a0 .. a0 + 3 at (x, y) (their i, j as doubles): their origins stored at a0 .. a0 + 3, and bit k set where
// node a0 + k lies inside.
[[gnu::target("avx2"), gnu::always_inline]] inline uint32_t tabled_origins_chunk_avx2(const TabledOriginLanesAvx2 &l,
                                                                                    __m256d x, __m256d y,
                                                                                    PairPassCounter &pc, size_t a0) {
  const __m256d px = _mm256_sub_pd(_mm256_mul_pd(x, l.size), l.cx), py = _mm256_sub_pd(_mm256_mul_pd(y, l.size), l.cy);
  const __m256d s = _mm256_mul_pd(_mm256_sub_pd(_mm256_mul_pd(px, l.by), _mm256_mul_pd(py, l.bx)), l.inv_det);
  const __m256d t = _mm256_mul_pd(_mm256_sub_pd(_mm256_mul_pd(py, l.ax), _mm256_mul_pd(px, l.ay)), l.inv_det);
  const __m256d lo = _mm256_unpacklo_pd(s, t), hi = _mm256_unpackhi_pd(s, t);  // (s0 t0 s2 t2), (s1 t1 s3 t3)
  _mm256_storeu_pd(&pc.origin[a0].s, _mm256_permute2f128_pd(lo, hi, 0x20));
  _mm256_storeu_pd(&pc.origin[a0 + 2].s, _mm256_permute2f128_pd(lo, hi, 0x31));
  return static_cast<uint32_t>(
      _mm256_movemask_pd(_mm256_and_pd(corners_within_half_avx2(s, l.ds_ux, l.ds_uy), corners_within_half_avx2(t, l.dt_ux, l.dt_uy))));
}
// Nibble k of the result 0xf where bit k of m (< 16) is set: four lanes' flags to their nodes' four pairs.
inline constexpr std::array<uint16_t, 16> kFlagNibbles = [] {
  std::array<uint16_t, 16> t{};
  for (uint32_t m = 0; m < 16; ++m)
    for (uint32_t k = 0; k < 4; ++k) t[m] = static_cast<uint16_t>(t[m] | ((m >> k & 1u) * (0xfu << (4 * k))));
  return t;
}();
inline uint64_t flag_nibbles(uint32_t m) { return kFlagNibbles[m]; }
// Exact int64 -> double per lane for -2^51 <= v < 2^51 (session 29, glintpaired29): v + 2^51 as the mantissa of 2^52,
// minus 2^52 + 2^51 (both steps exact). `range` collects v + 2^51: every lane was in range iff its bits from 52 up
// are clear (tabled_node_origins_avx2 then redoes the pass with the scalar conversions).
[[gnu::target("avx2"), gnu::always_inline]] inline __m256d small_int64_to_double_avx2(__m256i v, __m256i &range) {
  const __m256i biased = _mm256_add_epi64(v, _mm256_set1_epi64x(int64_t{1} << 51));
  range = _mm256_or_si256(range, biased);
  return _mm256_sub_pd(_mm256_castsi256_pd(_mm256_or_si256(biased, _mm256_set1_epi64x(0x4330000000000000ll))),
                       _mm256_set1_pd(6755399441055744.0));
}
// The frame's constants in lanes.
[[gnu::target("avx2"), gnu::always_inline]] inline TabledOriginLanesAvx2 tabled_origin_lanes_avx2(const FootprintFrame &fr,
                                                                                              double size) {
  return {_mm256_set1_pd(fr.f.cx),    _mm256_set1_pd(fr.f.cy),    _mm256_set1_pd(size),
          _mm256_set1_pd(fr.f.ax),    _mm256_set1_pd(fr.f.ay),    _mm256_set1_pd(fr.f.bx),
          _mm256_set1_pd(fr.f.by),    _mm256_set1_pd(fr.inv_det), _mm256_set1_pd(fr.ds_ux),
          _mm256_set1_pd(fr.ds_uy),   _mm256_set1_pd(fr.dt_ux),   _mm256_set1_pd(fr.dt_uy)};
}
// v[a], v[a + 1], v[a + 2], v[a + 3] as doubles (cvtsi2sd), past `last` v[last].
[[gnu::target("avx2"), gnu::always_inline]] inline __m256d converted_lanes_avx2(const int64_t *v, size_t a, size_t last) {
  return _mm256_setr_pd(static_cast<double>(v[a]), static_cast<double>(v[std::min(a + 1, last)]),
                        static_cast<double>(v[std::min(a + 2, last)]), static_cast<double>(v[std::min(a + 3, last)]));
}
// The pass with i, j converted one by one (cvtsi2sd: exact or rounded as the SSE2 passes' conversions), where some
// |i| or |j| >= 2^51 (out of line, cold). The last chunk repeats node count - 1 in its missing lanes.
[[gnu::target("avx2"), gnu::noinline, gnu::cold]] inline void tabled_node_origins_far_avx2(
    const FootprintFrame &frame, const NodeList &nodes, PairPassCounter &pc,
    std::array<uint64_t, PairMasks::kWords> &interior) {
  const TabledOriginLanesAvx2 l = tabled_origin_lanes_avx2(frame, nodes.size);
  const uint32_t can_be_inside = frame.nodes_can_be_inside ? 0xfu : 0u;
  interior = {};
  const int n = nodes.count;
  for (int c = 0; c < n; c += 4) {
    const auto a = static_cast<size_t>(c), last = static_cast<size_t>(n - 1);
    const uint32_t m = tabled_origins_chunk_avx2(l, converted_lanes_avx2(nodes.i.data(), a, last), converted_lanes_avx2(nodes.j.data(), a, last), pc, a) & can_be_inside &
                       ((1u << std::min(n - c, 4)) - 1u);
    interior[a / 16] |= flag_nibbles(m) << (4 * (a % 16));
  }
}
// Session 29 (glintpaired29): i and j four per step by small_int64_to_double_avx2 (two adds, an OR and a subtract per
// register, where eight scalar conversions and six shuffles were), the last one to three nodes by a masked load
// (the lanes past the list read 0: node (0, 0), its bits cleared); where some |i| or |j| >= 2^51 (never in the
// renders: the coordinates of a footprint 2^51 nodes from the origin), the pass again by
// tabled_node_origins_far_avx2. The same origins and bits (GlintParticles.TabledOriginsFarFromTheOriginMatchSse2).
[[gnu::target("avx2")]] inline void tabled_node_origins_avx2(const FootprintFrame &frame, const NodeList &nodes,
                                                            PairPassCounter &pc,
                                                            std::array<uint64_t, PairMasks::kWords> &interior) {
  const TabledOriginLanesAvx2 l = tabled_origin_lanes_avx2(frame, nodes.size);
  const uint32_t can_be_inside = frame.nodes_can_be_inside ? 0xfu : 0u;
  const auto *ni = reinterpret_cast<const long long *>(nodes.i.data());
  const auto *nj = reinterpret_cast<const long long *>(nodes.j.data());
  __m256i range = _mm256_setzero_si256();
  interior = {};
  const int n = nodes.count;
  int c = 0;
  for (; c + 4 <= n; c += 4) {
    const auto a = static_cast<size_t>(c);
    const __m256d x = small_int64_to_double_avx2(_mm256_loadu_si256(reinterpret_cast<const __m256i *>(ni + a)), range);
    const __m256d y = small_int64_to_double_avx2(_mm256_loadu_si256(reinterpret_cast<const __m256i *>(nj + a)), range);
    const uint32_t m = tabled_origins_chunk_avx2(l, x, y, pc, a) & can_be_inside;
    interior[a / 16] |= flag_nibbles(m) << (4 * (a % 16));
  }
  if (c < n) {
    const auto a = static_cast<size_t>(c);
    const __m256i in_list = _mm256_cmpgt_epi64(_mm256_set1_epi64x(n - c), _mm256_setr_epi64x(0, 1, 2, 3));
    const __m256d x = small_int64_to_double_avx2(_mm256_maskload_epi64(ni + a, in_list), range);
    const __m256d y = small_int64_to_double_avx2(_mm256_maskload_epi64(nj + a, in_list), range);
    const uint32_t m = tabled_origins_chunk_avx2(l, x, y, pc, a) & can_be_inside & ((1u << (n - c)) - 1u);
    interior[a / 16] |= flag_nibbles(m) << (4 * (a % 16));
  }
  if (!_mm256_testz_si256(range, _mm256_set1_epi64x(-(int64_t{1} << 52)))) [[unlikely]]
    tabled_node_origins_far_avx2(frame, nodes, pc, interior);
}
#endif

// The passes' body; kAvx2: pass 2 in AVX2 (inlined into
// count_four_groups_in_passes_avx2, whose target("avx2") also gives the other
// passes VEX three-operand forms; no FMA, so the same values).
// Session 24: from this lambda on the passes make LitCountTable (the
// model's exp and thresholds) before pass 2, and its below[0] (the hashes
// with K >= 1, exactly) is the quick reject: pass 3 visits no pair with K =
// 0 (at lambda ~ 0.5..1 a fifth to a third of the pairs passing the reject of
// Pr(K >= 1) <= lambda, each ~40 instructions in pass 3 for nothing), and
// pass 3 takes K by the table's compares, where the bounds left a third of
// the pairs undecided (u < lambda^2 / 2) to the tail walk. Below it: the
// bounds and the reject of lambda, no exp unless a pair is undecided (GI
// render, 160 x 100 4 spp: from 1/16 652.2 M, 1/8 651.9 M, 1/4 651.8 M).
inline constexpr double kLitTableFrom = 1.0 / 4.0;
// (2) and its empty test: true when some pair passes the quick reject (pm holds the passing pairs' masks). No pair
// passes in ~70 % of the walks in examples/glint.xml: count 0, no steps, complete, without the other passes' set-up
// (the bounds' division, the frame's constants; session 22; session 23: the frame itself, its division and
// products, made by the caller only after this).
template <bool kAvx2>
[[gnu::always_inline]] inline bool group_pass_finds_a_pair(const NodeList &nodes, const uint32_t *seeds,
                                                           const GroupReject &reject, PairMasks &pm) {
#if GLIMMER_GLINT_WALK_AVX2
  if constexpr (kAvx2)
    group_pass_avx2(nodes, seeds, reject, pm);  // (2)
  else
#endif
    group_pass_sse2(nodes, seeds, reject, pm);
  static_assert(PairMasks::kWords == 4);
#if GLIMMER_GLINT_WALK_AVX2
  if constexpr (kAvx2) return !pair_masks_empty_avx2(pm);
#endif
  return (pm.mask[0] | pm.mask[1] | pm.mask[2] | pm.mask[3]) != 0;
}

// (3)'s outcome: the walk is incomplete (the step cap, or a pair the walk refuses), no pair is lit (a refused
// walk's table gave every pair K = 0), or the lit pairs were added to the counter.
enum class LitPairs { kIncomplete, kNoneLit, kAdded };

// (3) by the bounds (lambda < kLitTableFrom; session 29, glintbounds29): the pairs in order as lit_pairs_pass' walk
// took them, the usual K = 1 (LitBoundHashes, ~86 % of the GI render's pairs) added here with the counter's count
// and list length in registers (add_lit's sums for K = 1: count += [inside], the particle listed on the border), the
// other pairs (K = 0, the bounds' undecided, a list within two of full) by lit_count_at and add_lit as before (the
// same K, the same flush when full). The same particles in the same order, the same count and steps
// (GlintParticles.PairPassesMatchTheNodeLoop). GI render's bounds walks: ~38 -> ~26 instructions per K = 1 pair.
[[gnu::always_inline]] inline bool bounds_pairs_pass(const PairMasks &pm, int node_count, double lambda,
                                                     int max_steps, PairPassCounter &pc, int64_t &steps) {
  const LitCountBounds bounds(lambda);
  const LitBoundHashes hashes(bounds);
  std::optional<LitCountModel> model;
  int64_t count = pc.count, total = steps;
  auto n = static_cast<size_t>(pc.n_parts);
  for (int w = 0; w < PairMasks::words(node_count); ++w) {
    const auto first = static_cast<size_t>(64 * w);
    for (uint64_t m = pm.mask[static_cast<size_t>(w)]; m != 0; m &= m - 1) {
      const size_t pair = first + static_cast<uint32_t>(std::countr_zero(m));  // (unsigned: no sign extension)
      const uint32_t h0 = pm.node_hash[pair], node = static_cast<uint32_t>(pair / kDirectionGroups);
      if (hashes.one(h0) && n < PairPassCounter::kMaxParticles - 2) [[likely]] {  // add_lit's room test for K = 1
        const int64_t in = pc.inside_mask[node];  // -1 inside, 0 on the border
        total += 1;
        count -= in;
        pc.part_hash[n] = h0, pc.part_step[n] = position_step(0), pc.part_node[n] = node;
        n += static_cast<size_t>(1 + in);  // listed on the border only
        continue;
      }
      const int64_t K = lit_count_at(h0, bounds, model, lambda);
      if (K < 0) __builtin_unreachable();  // the bounds' walk is walkable (lambda < kLitTableFrom)
      if (K == 0) continue;  // add_lit adds nothing (it may flush: the same count)
      total += K;
      pc.count = count, pc.n_parts = static_cast<int>(n);
      if (!pc.add_lit(static_cast<int>(node), h0, K, [&] { return total > max_steps; })) return false;
      count = pc.count, n = static_cast<size_t>(pc.n_parts);
    }
  }
  pc.count = count, pc.n_parts = static_cast<int>(n);
  steps = total;
  return total <= max_steps;
}

// (3): the pairs 4 node + g in order, K by the table's compares (from kLitTableFrom) or by the bounds, added to pc;
// `steps` their total.
[[gnu::always_inline]] inline LitPairs lit_pairs_pass(const PairMasks &pm, int node_count,
                                                     const LitCountTable *table, double lambda,
                                                     int max_steps, PairPassCounter &pc, int64_t &steps) {
  const auto lit_pass = [&](auto &&lit_of) {
    for (int w = 0; w < PairMasks::words(node_count); ++w)
      for (uint64_t m = pm.mask[static_cast<size_t>(w)]; m != 0; m &= m - 1) {
        const auto pair = static_cast<uint32_t>(64 * w + std::countr_zero(m));
        const uint32_t h0 = pm.node_hash[pair];
        const int64_t K = lit_of(h0);
        if (K < 0) __builtin_unreachable();  // lit_of's K >= 0 (a refused walk is handled before)
        steps += K;
        // Session 24: the step cap tested after the loop, and where the list
        // is flushed (bounding the work past the cap), not per pair: the
        // steps only grow, so the cap is passed iff the total passes it.
        if (!pc.add_lit(static_cast<int>(pair / kDirectionGroups), h0, K, [&] { return steps > max_steps; }))
          return false;
      }
    return steps <= max_steps;
  };
  bool walked;
  if (table) {
    // Session 23: for lambda > 1 every pair passed the quick reject, and the
    // bounds decided none: the walk's thresholds once (LitCountTable), then
    // integer compares. Session 24: from kLitTableFrom on.
    if (!table->walkable) [[unlikely]] {
      // The walk refuses (K = -1: incomplete) every pair whose u < Pr(K >= 1), and gives K = 0 to the others.
      for (int w = 0; w < PairMasks::words(node_count); ++w)
        for (uint64_t m = pm.mask[static_cast<size_t>(w)]; m != 0; m &= m - 1)
          if (table->lit(pm.node_hash[static_cast<size_t>(64 * w + std::countr_zero(m))]) < 0)
            return LitPairs::kIncomplete;
      return LitPairs::kNoneLit;
    }
    walked = lit_pass([&](uint32_t h0) { return table->lit_passed(h0); });  // h0 < below[0]: pass 2's reject
  } else {
    walked = bounds_pairs_pass(pm, node_count, lambda, max_steps, pc, steps);
  }
  return walked ? LitPairs::kAdded : LitPairs::kIncomplete;
}

#if GLIMMER_GLINT_WALK_AVX2
// tabled_layers_pass' layers 1..3 in AVX2: eight hashes per compare, bytes in pass 2's layout (before the AND with
// layer 0 and the thresholds' all_pass). The words holding the list's nodes are written: every byte the steps write,
// and the last word zeroed first for its bytes past (node_count + 1) / 2 (session 29, glintpaired29: the caller zeroed
// all twelve words, a `rep stos` per walk).
[[gnu::target("avx2")]] inline void tabled_layer_bytes_avx2(
    const PairMasks &pm, int node_count, const GroupReject &r1, const GroupReject &r2, const GroupReject &r3,
    std::array<std::array<uint64_t, PairMasks::kWords>, 4> &layer) {
  const __m256i bias = _mm256_set1_epi32(static_cast<int>(0x80000000u));
  const __m256i b1 = _mm256_set1_epi32(static_cast<int>(r1.below ^ 0x80000000u));
  const __m256i b2 = _mm256_set1_epi32(static_cast<int>(r2.below ^ 0x80000000u));
  const __m256i b3 = _mm256_set1_epi32(static_cast<int>(r3.below ^ 0x80000000u));
  auto *l1 = reinterpret_cast<unsigned char *>(layer[1].data());
  auto *l2 = reinterpret_cast<unsigned char *>(layer[2].data());
  auto *l3 = reinterpret_cast<unsigned char *>(layer[3].data());
  const auto last = static_cast<size_t>(PairMasks::words(node_count) - 1);
  layer[1][last] = layer[2][last] = layer[3][last] = 0;
  for (int st = 0; st < (node_count + 1) / 2; ++st) {
    const __m256i h = _mm256_xor_si256(
        _mm256_load_si256(reinterpret_cast<const __m256i *>(pm.node_hash.data() + 2 * kDirectionGroups * st)), bias);
    l1[st] = static_cast<unsigned char>(_mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(b1, h))));
    l2[st] = static_cast<unsigned char>(_mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(b2, h))));
    l3[st] = static_cast<unsigned char>(_mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(b3, h))));
  }
}
#endif

// Pass (3) for a walkable table (session 26, glintK26): every pair pass 2 let through has K >= 1 (its exact
// reject), K = 1 + [h < below[1]] + [h < below[2]] + [h < below[3]] (lit_passed), so the pairs with K >= k + 1
// are the bits of layer k: layer 0 pm.mask, layers 1..3 from the hashes' compares with below[1..3] (AVX2: eight
// hashes per compare, the bytes of pass 2's layout). The steps are the layers' bit counts plus K - 3 of each
// layer-3 pair (LitCountTable::walk_on); the cap is tested on that total before any particle (the steps only
// grow, so it is passed iff the node loop passes it). Interior nodes add their pairs' layer bits; border pairs
// list particle k for each layer k they are in (and k >= 3 from walk_on), flushed as the list fills. The same
// particles as lit_pairs_pass, so the same count and steps (GlintParticles.PairPassesMatchTheNodeLoop).
template <bool kAvx2>
[[gnu::always_inline]] inline bool tabled_layers_pass(const PairMasks &pm, int node_count, const LitCountTable &t,
                                                      const std::array<uint64_t, PairMasks::kWords> &interior,
                                                      int max_steps, PairPassCounter &pc, int64_t &steps) {
  constexpr int kW = PairMasks::kWords;
  const int W = PairMasks::words(node_count);  // the words holding the list's nodes (one up to 16 nodes)
  std::array<std::array<uint64_t, kW>, 4> layer;  // words < W read (session 29: not zeroed here)
  layer[0] = pm.mask;
  const GroupReject r1(t.below[1]), r2(t.below[2]), r3(t.below[3]);
#if GLIMMER_GLINT_WALK_AVX2
  if constexpr (kAvx2) {
    tabled_layer_bytes_avx2(pm, node_count, r1, r2, r3, layer);
  } else
#endif
  {
    layer[1] = layer[2] = layer[3] = std::array<uint64_t, kW>{};
    for (int w = 0; w < W; ++w)
      for (uint64_t m = layer[0][static_cast<size_t>(w)]; m != 0; m &= m - 1) {
        const int bit = std::countr_zero(m);
        const uint64_t h = pm.node_hash[static_cast<size_t>(64 * w + bit)];
        layer[1][static_cast<size_t>(w)] |= static_cast<uint64_t>(h < r1.limit) << bit;
        layer[2][static_cast<size_t>(w)] |= static_cast<uint64_t>(h < r2.limit) << bit;
        layer[3][static_cast<size_t>(w)] |= static_cast<uint64_t>(h < r3.limit) << bit;
      }
  }
  int64_t total = 0;
  for (int w = 0; w < W; ++w) {
    const auto a = static_cast<size_t>(w);
    layer[1][a] = (r1.all_pass ? ~uint64_t{0} : layer[1][a]) & layer[0][a];
    layer[2][a] = (r2.all_pass ? ~uint64_t{0} : layer[2][a]) & layer[0][a];
    layer[3][a] = (r3.all_pass ? ~uint64_t{0} : layer[3][a]) & layer[0][a];
    total += std::popcount(layer[0][a]) + std::popcount(layer[1][a]) + std::popcount(layer[2][a]);
  }
  for (int w = 0; w < W; ++w)  // K >= 4 (rare): the walk's K
    for (uint64_t m = layer[3][static_cast<size_t>(w)]; m != 0; m &= m - 1)
      total += t.walk_on(pm.node_hash[static_cast<size_t>(64 * w + std::countr_zero(m))]) - 3;
  steps = total;
  if (total > max_steps) return false;
  const auto list_full = [&](int room) {
    if (pc.n_parts + room <= PairPassCounter::kMaxParticles) return;
#if GLIMMER_GLINT_WALK_AVX2
    if constexpr (kAvx2) return pc.flush_avx2();
#endif
    pc.flush();
  };
  for (int k = 0; k < 3; ++k) {
    const uint32_t step = position_step(static_cast<uint32_t>(k));
    for (int w = 0; w < W; ++w) {
      const auto a = static_cast<size_t>(w);
      pc.count += std::popcount(layer[static_cast<size_t>(k)][a] & interior[a]);
      uint64_t border = layer[static_cast<size_t>(k)][a] & ~interior[a];
      if (border == 0) continue;
      list_full(64);
#if GLIMMER_GLINT_WALK_AVX2
      if constexpr (kAvx2) {
        pc.list_pairs_avx2(border, w, step, pm.node_hash.data());
        continue;
      }
#endif
      pc.list_pairs(border, w, step, pm.node_hash.data());
    }
  }
  for (int w = 0; w < W; ++w)
    for (uint64_t m = layer[3][static_cast<size_t>(w)]; m != 0; m &= m - 1) {
      const auto pair = static_cast<uint32_t>(64 * w + std::countr_zero(m));
      const uint32_t h0 = pm.node_hash[pair];
      const int64_t K = t.walk_on(h0);
      if (interior[static_cast<size_t>(w)] >> (pair % 64) & 1u) {
        pc.count += K - 3;
        continue;
      }
      for (int64_t k = 3; k < K; ++k) {
        list_full(1);
        const auto n = static_cast<size_t>(pc.n_parts++);
        pc.part_hash[n] = h0, pc.part_step[n] = position_step(static_cast<uint32_t>(k)), pc.part_node[n] = pair / 4;
      }
    }
  return true;
}

// Passes (1), (3) and (4), for a walk where pass 2 found a pair (pm). Out of line (session 26, glintK26): in the
// GI render ~70 % of the walks end after pass 2, and with these passes in the same function each of them paid
// its frame (the callee-saved registers, the stack realigned for the flush's 256-bit spills) and set-up.
template <bool kAvx2>
[[gnu::always_inline]] inline GlintCount count_paired_body(const Footprint &f, const NodeList &nodes,
                                                           const PairMasks &pm,
                                                           const LitCountTable *table, double lambda,
                                                           int max_steps) {
  const FootprintFrame frame(f, nodes.size);
  PairPassCounter pc(frame);
  int64_t steps = 0;
  if (table != nullptr && table->walkable) {
    std::array<uint64_t, PairMasks::kWords> interior;  // (1): the origins and the interior pairs
#if GLIMMER_GLINT_WALK_AVX2
    if constexpr (kAvx2) {
      tabled_node_origins_avx2(frame, nodes, pc, interior);
    } else
#endif
    {
      paired_node_origins(frame, nodes, pm, pc);
      interior = interior_words(pm, nodes.count, pc);
    }
    if (!tabled_layers_pass<kAvx2>(pm, nodes.count, *table, interior, max_steps, pc, steps))  // (3)
      return {0, 0, false};
  } else {
    // Session 17 (glintwalk17b): the origin and inside flag of only the nodes
    // with a pair passing the quick reject (no other pass reads them; ~1/3 of
    // the nodes have none at area 1e-4): 1e-4 5615 -> 5380 instructions per
    // eval, same f and pdf bits.
#if GLIMMER_GLINT_WALK_AVX2
    if constexpr (kAvx2)
      paired_node_origins_avx2(frame, nodes, pm, pc);  // (1)
    else
#endif
      paired_node_origins(frame, nodes, pm, pc);  // (1)
    switch (lit_pairs_pass(pm, nodes.count, table, lambda, max_steps, pc, steps)) {  // (3)
      case LitPairs::kIncomplete: return {0, 0, false};
      case LitPairs::kNoneLit: return {};
      case LitPairs::kAdded: break;
    }
  }
#if GLIMMER_GLINT_WALK_AVX2
  if constexpr (kAvx2)
    pc.flush_avx2();  // (4)
  else
#endif
    pc.flush();  // (4)
  GlintCount result;
  result.count = static_cast<int>(pc.count);
  result.steps = static_cast<int>(steps);
  return result;
}
#if GLIMMER_GLINT_WALK_AVX2
[[gnu::target("avx2,popcnt"), gnu::noinline]] inline GlintCount count_paired_avx2(const Footprint &f, const NodeList &nodes,
                                                                          const PairMasks &pm,
                                                                          const LitCountTable *table,
                                                                          double lambda, int max_steps) {
  return count_paired_body<true>(f, nodes, pm, table, lambda, max_steps);
}
#endif
[[gnu::noinline]] inline GlintCount count_paired_sse2(const Footprint &f, const NodeList &nodes, const PairMasks &pm,
                                                      const LitCountTable *table, double lambda,
                                                      int max_steps) {
  return count_paired_body<false>(f, nodes, pm, table, lambda, max_steps);
}

template <bool kAvx2>
[[gnu::always_inline]] inline GlintCount count_paired(const Footprint &f, const NodeList &nodes, const PairMasks &pm,
                                                      const LitCountTable *table, double lambda, int max_steps) {
#if GLIMMER_GLINT_WALK_AVX2
  if constexpr (kAvx2) return count_paired_avx2(f, nodes, pm, table, lambda, max_steps);
#endif
  return count_paired_sse2(f, nodes, pm, table, lambda, max_steps);
}

// The passes from lambda >= kLitTableFrom (session 24): LitCountTable (the model's exp and thresholds) made before
// pass 2, whose below[0] (h >= below[0]: u >= Pr(K >= 1), K = 0; a walkable table's below[0] <= lambda_reject's
// limit) is pass 2's exact reject; not walkable: lambda's reject, K = -1 below below[0] (see lit_pairs_pass). Out of
// line (session 26): the walks below kLitTableFrom, most of them ending after pass 2, keep a frame without the
// table, its exp call and the registers saved across it.
template <bool kAvx2>
[[gnu::always_inline]] inline GlintCount count_tabled_body(const Footprint &f, const NodeList &nodes,
                                                           const uint32_t *seeds, const GroupReject &lambda_reject,
                                                           double lambda, int max_steps) {
  const LitCountTable table{LitCountModel(lambda)};
  const GroupReject reject = exact_reject(table, lambda_reject);
  PairMasks pm;
  if (!group_pass_finds_a_pair<kAvx2>(nodes, seeds, reject, pm)) return {};
  return count_paired<kAvx2>(f, nodes, pm, &table, lambda, max_steps);
}
#if GLIMMER_GLINT_WALK_AVX2
[[gnu::target("avx2"), gnu::noinline]] inline GlintCount count_tabled_avx2(const Footprint &f, const NodeList &nodes,
                                                                          const uint32_t *seeds,
                                                                          const GroupReject &lambda_reject,
                                                                          double lambda, int max_steps) {
  return count_tabled_body<true>(f, nodes, seeds, lambda_reject, lambda, max_steps);
}
#endif
[[gnu::noinline]] inline GlintCount count_tabled_sse2(const Footprint &f, const NodeList &nodes, const uint32_t *seeds,
                                                      const GroupReject &lambda_reject, double lambda, int max_steps) {
  return count_tabled_body<false>(f, nodes, seeds, lambda_reject, lambda, max_steps);
}

template <bool kAvx2>
[[gnu::always_inline]] inline GlintCount count_four_groups_in_passes_body(const Footprint &f, const NodeList &nodes,
                                                                          const uint32_t *seeds,
                                                                          const GroupReject &lambda_reject,
                                                                          double lambda, int max_steps) {
  static_assert(kDirectionGroups == 4);
  if (lambda >= kLitTableFrom) {
#if GLIMMER_GLINT_WALK_AVX2
    if constexpr (kAvx2) return count_tabled_avx2(f, nodes, seeds, lambda_reject, lambda, max_steps);
#endif
    return count_tabled_sse2(f, nodes, seeds, lambda_reject, lambda, max_steps);
  }
  PairMasks pm;
  if (!group_pass_finds_a_pair<kAvx2>(nodes, seeds, lambda_reject, pm)) return {};
  return count_paired<kAvx2>(f, nodes, pm, nullptr, lambda, max_steps);
}
#if GLIMMER_GLINT_WALK_AVX2
[[gnu::target("avx2"), gnu::noinline]] inline GlintCount count_four_groups_in_passes_avx2(
    const Footprint &f, const NodeList &nodes, const uint32_t *seeds, const GroupReject &reject, double lambda,
    int max_steps) {
  return count_four_groups_in_passes_body<true>(f, nodes, seeds, reject, lambda, max_steps);
}
#endif
// Out of line too (session 23: inlined into the dispatch below, its frame's
// set-up ran before the dispatch's test, ~20 instructions per AVX2 walk).
[[gnu::noinline]] inline GlintCount count_four_groups_in_passes_sse2(const Footprint &f, const NodeList &nodes,
                                                                     const uint32_t *seeds, const GroupReject &reject,
                                                                     double lambda, int max_steps) {
  return count_four_groups_in_passes_body<false>(f, nodes, seeds, reject, lambda, max_steps);
}
// The pair passes in the form `avx2` says (kWalkAvx2: AVX2 where the CPU has
// it), over the nodes of a footprint at least as large as a node (the
// caller's test, FootprintFrame::nodes_can_be_inside). Out of line, as GCC
// chose while the SSE2 body was inlined here: inlined into
// count_reflecting_particles, it left that out of line in glint.cpp's
// provably_dark (session 23: r0.4 area 1e-8 +14, 1e-6 +19 instructions per eval).
[[gnu::noinline]] inline GlintCount count_four_groups_in_passes(const Footprint &f, const NodeList &nodes, const uint32_t *seeds,
                                              const GroupReject &reject, double lambda, int max_steps,
                                              bool avx2 = kWalkAvx2) {
#if GLIMMER_GLINT_WALK_AVX2
  if (avx2) return count_four_groups_in_passes_avx2(f, nodes, seeds, reject, lambda, max_steps);
#else
  (void)avx2;
#endif
  return count_four_groups_in_passes_sse2(f, nodes, seeds, reject, lambda, max_steps);
}

#if GLIMMER_GLINT_WALK_AVX2
// Session 25 (glintcount25): count_reflecting_particles' node loop with four
// seeds where the walk uses AVX2 (the footprints smaller than a node, and
// the visitor's counts): sixteen nodes at a time, pass 1 each node's four
// group hashes in one register (mix_u32x4_avx2: node_seed_hash's words) and
// their quick rejects as one compare, the passing pairs as bits 4 c + g; then
// the loop's steps over those pairs in its order (node by node, groups in
// order): the lit count K by the bounds or the model (from kLitTableFrom on
// by LitCountTable, session 43), the step cap, the node's origin and
// node_inside (per lit pair since session 43), the positions and
// particle_inside four particles per step (particles_inside4_avx2), the
// visits in k order. The same count, steps, completeness and visits
// (GlintParticles.NodeLoopAvx2MatchesTheNodeLoop). The frame's steps are
// broadcast once per count (FrameLanesAvx2; per lit pair, as GCC placed
// them when the frame was made at the first lit pair: aspect 64 +16.5 per eval).
inline constexpr int kNodeLoopChunk = 16;
[[gnu::target("avx2"), gnu::always_inline]] inline uint64_t node_loop_pass1_avx2(const uint32_t *keys, int n,
                                                                                __m128i seeds, __m128i below,
                                                                                uint32_t all_pass,
                                                                                uint32_t (*hashes)[kDirectionGroups]) {
  const __m128i bias = _mm_set1_epi32(static_cast<int>(0x80000000u));  // unsigned compare as signed
  uint64_t pairs = 0;
  int c = 0;
  // Two nodes per mix_u32x8 (the same words), then an odd last node by the 4-lane form.
  const __m256i seeds8 = _mm256_set_m128i(seeds, seeds), below8 = _mm256_set_m128i(below, below);
  const __m256i bias8 = _mm256_set_m128i(bias, bias);
  for (; c + 1 < n; c += 2) {
    const __m256i k = _mm256_set_m128i(_mm_set1_epi32(static_cast<int>(keys[c + 1])),
                                       _mm_set1_epi32(static_cast<int>(keys[c])));
    const __m256i h = mix_u32x8(_mm256_xor_si256(k, seeds8));
    _mm256_storeu_si256(reinterpret_cast<__m256i *>(hashes[c]), h);
    const int lt = _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(below8, _mm256_xor_si256(h, bias8))));
    pairs |= static_cast<uint64_t>((all_pass * 0x11u) | static_cast<uint32_t>(lt)) << (kDirectionGroups * c);
  }
  for (; c < n; ++c) {
    const __m128i h = mix_u32x4_avx2(_mm_xor_si128(_mm_set1_epi32(static_cast<int>(keys[c])), seeds));
    _mm_store_si128(reinterpret_cast<__m128i *>(hashes[c]), h);
    const int lt = _mm_movemask_ps(_mm_castsi128_ps(_mm_cmpgt_epi32(below, _mm_xor_si128(h, bias))));
    pairs |= static_cast<uint64_t>(all_pass | static_cast<uint32_t>(lt)) << (kDirectionGroups * c);
  }
  return pairs;
}
template <typename Visitor>
[[gnu::target("avx2"), gnu::noinline]] inline GlintCount count_node_loop_avx2(const Footprint &f, const NodeList &nodes,
                                                                              const uint32_t *seed_words, double lambda,
                                                                              const GroupReject &lambda_reject,
                                                                              int max_steps, Visitor &visit) {
  GlintCount result;
  // Session 43: from kLitTableFrom on (as the pair passes), K by LitCountTable's compares instead of the model's tail
  // walk (a division per step and an exit branch that follows K), and its below[0] as the exact reject.
  std::optional<LitCountTable> table;
  if (lambda >= kLitTableFrom) table.emplace(LitCountModel(lambda));
  const GroupReject reject = table ? exact_reject(*table, lambda_reject) : lambda_reject;
  const __m128i seeds = _mm_loadu_si128(reinterpret_cast<const __m128i *>(seed_words));
  const __m128i below = _mm_xor_si128(_mm_set1_epi32(static_cast<int>(reject.below)),
                                      _mm_set1_epi32(static_cast<int>(0x80000000u)));
  const uint32_t all_pass = reject.all_pass ? 0xfu : 0u;
  const LitCountBounds bounds(lambda);
  std::optional<LitCountModel> model;
  const FootprintFrame frame(f, nodes.size);
  const FrameLanesAvx2 lanes = frame_lanes_avx2(frame);
  for (int first = 0; first < nodes.count; first += kNodeLoopChunk) {
    alignas(16) uint32_t hashes[kNodeLoopChunk][kDirectionGroups];
    uint64_t pairs = node_loop_pass1_avx2(nodes.id_hash.data() + first, std::min(nodes.count - first, kNodeLoopChunk),
                                          seeds, below, all_pass, hashes);
    for (; pairs != 0; pairs &= pairs - 1) {
      const int pair = std::countr_zero(pairs), c = pair / kDirectionGroups;
      const uint32_t h0 = hashes[c][pair % kDirectionGroups];
      const int64_t K = !table            ? lit_count_at(h0, bounds, model, lambda)
                        : table->walkable ? table->lit_passed(h0)
                                          : table->lit(h0);
      if (K == 0) continue;
      if (K < 0 || result.steps + K > max_steps) {
        result.complete = false;
        return result;
      }
      result.steps += static_cast<int>(K);
      // The node's origin per lit pair (session 43: not kept across the node's pairs, whose "same node?" branch
      // followed the data; node_inside ends at its first test where the footprint is smaller than a node, the
      // walk's calls).
      const auto at = static_cast<size_t>(first + c);
      const FootprintFrame::NodeOrigin origin =
          frame.origin(static_cast<double>(nodes.i[at]) * nodes.size, static_cast<double>(nodes.j[at]) * nodes.size);
      if (frame.node_inside(origin)) {
        result.count += static_cast<int>(K);
        if constexpr (std::decay_t<Visitor>::kVisitsParticles)
          for (int64_t k = 0; k < K; ++k) visit(h0, static_cast<uint32_t>(k));
        continue;
      }
      for (int64_t k = 0; k < K; k += 4) {  // four positions per step (particles_inside4_avx2)
        uint32_t in = particles_inside4_avx2(lanes, origin, h0, static_cast<uint32_t>(k));
        in &= 0xfu >> (4 - std::min<int64_t>(K - k, 4));  // the first K - k lanes (a select, not a branch)
        result.count += static_cast<int>((0x4332322132212110ull >> (4 * in)) & 0xfu);  // set bits of in
        if constexpr (std::decay_t<Visitor>::kVisitsParticles)
          for (; in != 0; in &= in - 1) visit(h0, static_cast<uint32_t>(k + std::countr_zero(in)));
      }
    }
  }
  return result;
}
#endif

// node_loop: always the scalar node-by-node loop (for the tests that compare the passes and the AVX2 loop with it).
// Session 29 (glintbounds29): `area` is f.area(), which the caller knows (glint.cpp's Particles::area: the same
// double), so the test of the passes' footprint size (FootprintFrame::can_hold_a_node's) does not recompute it.
template <typename Visitor = NoParticleVisitor>
inline GlintCount count_reflecting_particles_of_area(const Footprint &f, double area, const NodeList &nodes,
                                                     double density, std::span<const uint32_t> seeds, double P,
                                                     int max_steps, Visitor &&visit = Visitor{},
                                                     bool node_loop = false) {
  GlintCount result;
  if (!(P > 0.0)) return result;
  const double lambda = node_lit_mean(density, nodes.size, P);
  const GroupReject reject = quick_reject(lambda);  // on the node's 32-bit hash
  // The passes pay where nodes can lie inside the footprint (larger than a node; on 1..4 nodes they measured 2..5 %
  // slower than the node loop). can_hold_a_node: the frame's nodes_can_be_inside without the frame.
  if constexpr (!std::decay_t<Visitor>::kVisitsParticles)
    if (!node_loop && seeds.size() == kDirectionGroups && area >= nodes.size * nodes.size)
      return count_four_groups_in_passes(f, nodes, seeds.data(), reject, lambda, max_steps);
#if GLIMMER_GLINT_WALK_AVX2
  if (!node_loop && kWalkAvx2 && seeds.size() == kDirectionGroups)
    return count_node_loop_avx2(f, nodes, seeds.data(), lambda, reject, max_steps, visit);
#endif
  const FootprintFrame frame(f, nodes.size);
  constexpr size_t kMaxSeeds = 32;
  if (seeds.size() > kMaxSeeds) return {0, 0, false};  // callers pass 1 or kDirectionGroups seeds
  const size_t n_seeds = seeds.size();
  const LitCountBounds bounds(lambda);  // decides most nodes without the model's exp
  std::optional<LitCountModel> model;  // built at the first node the bounds leave undecided
  for (int node = 0; node < nodes.count; ++node) {
    const int64_t i = nodes.i[node], j = nodes.j[node];
    const uint32_t node_hash = nodes.id_hash[node];
    std::array<uint32_t, kMaxSeeds> hashes;  // per seed, no branch per seed (a node's lit state is random)
    uint32_t maybe_lit;  // bit g: seed g passes the quick reject
    if (n_seeds == kDirectionGroups) {
      maybe_lit = group_hashes(node_hash, seeds.data(), reject, hashes.data());
    } else {
      maybe_lit = 0;
      for (size_t g = 0; g < n_seeds; ++g) {
        hashes[g] = node_seed_hash(node_hash, seeds[g]);
        maybe_lit |= static_cast<uint32_t>(hashes[g] < reject.limit) << g;
      }
    }
    if (maybe_lit == 0) continue;  // K = 0 for every seed
    int inside = -1;  // node inside the footprint: tested at its first lit group (-1 = not yet)
    FootprintFrame::NodeOrigin origin{};
    for (; maybe_lit != 0; maybe_lit &= maybe_lit - 1) {
      const uint32_t h0 = hashes[static_cast<size_t>(std::countr_zero(maybe_lit))];
      const int64_t K = lit_count_at(h0, bounds, model, lambda);
      if (K == 0) continue;
      if (K < 0 || result.steps + K > max_steps) {
        result.complete = false;
        return result;
      }
      result.steps += static_cast<int>(K);
      if (inside < 0) {
        origin = frame.origin(static_cast<double>(i) * nodes.size, static_cast<double>(j) * nodes.size);
        inside = frame.node_inside(origin) ? 1 : 0;
      }
      if (inside == 1) {
        result.count += static_cast<int>(K);
        if constexpr (std::decay_t<Visitor>::kVisitsParticles)
          for (int64_t k = 0; k < K; ++k) visit(h0, static_cast<uint32_t>(k));
        continue;
      }
      for (int64_t k = 0; k < K; ++k) {
        const auto [ux, uy] = particle_position(h0, static_cast<uint32_t>(k));
        const bool counted = frame.particle_inside(origin, ux, uy);
        result.count += counted ? 1 : 0;
        if constexpr (std::decay_t<Visitor>::kVisitsParticles)
          if (counted) visit(h0, static_cast<uint32_t>(k));
      }
    }
  }
  return result;
}

template <typename Visitor = NoParticleVisitor>
inline GlintCount count_reflecting_particles(const Footprint &f, const NodeList &nodes, double density,
                                             std::span<const uint32_t> seeds, double P, int max_steps,
                                             Visitor &&visit = Visitor{}, bool node_loop = false) {
  return count_reflecting_particles_of_area(f, f.area(), nodes, density, seeds, P, max_steps,
                                            std::forward<Visitor>(visit), node_loop);
}
inline GlintCount count_reflecting_particles(const Footprint &f, const NodeList &nodes, double density, uint32_t seed,
                                             double P, int max_steps) {
  return count_reflecting_particles(f, nodes, density, std::span<const uint32_t>(&seed, 1), P, max_steps);
}

// The direction cells of (wi, wo) and the particle nodes of a footprint:
// what a count needs besides P, so a caller can count at a bound of P first
// (glint.cpp's dark test) and count again at P without recomputing them.
struct GlintSite {
  GlintSite() : has_half_vector(false), cell_seeds{}, group_density(0.0), memo_nodes(nullptr) {}  // NOLINT
  // Nothing written (session 37, glint1e8_37: ~13 stores per eval on the dark test's small route, whose dark answer
  // reads nothing of the site): the writer sets has_half_vector, cell_seeds and group_density (glint_small_dark.h) and,
  // before the site is counted, memo_nodes (locate_glint_nodes); `nodes` is never read.
  struct Unset {};
  explicit GlintSite(Unset) : nodes(NodeList::Unset{}) {}  // NOLINT(cppcoreguidelines-pro-type-member-init)
  bool has_half_vector;                                    // false: no half vector above the surface, no glint
  std::array<uint32_t, kDirectionGroups> cell_seeds;
  double group_density;                 // N / G
  NodeList nodes;                       // the footprint's nodes, unless memo_nodes is set
  const NodeList *memo_nodes;           // a FootprintNodeMemo's list (locate_glints with a memo)
  const NodeList &node_list() const { return memo_nodes != nullptr ? *memo_nodes : nodes; }
};

inline void locate_glints(const Footprint &f, double density, const DirectionCellKeys &keys, const Vec3 &wi,
                          const Vec3 &wo, float gamma_rad, GlintSite &site) {
  site.has_half_vector = direction_cell_seeds(keys, wi, wo, gamma_rad, site.cell_seeds);
  if (!site.has_half_vector) return;
  site.group_density = density / kDirectionGroups;
  site.memo_nodes = nullptr;
  footprint_nodes(f, site.group_density, site.nodes);
}
// The node list of a site whose direction cells and group density are set: footprint_nodes at
// site.group_density through the caller's memo (locate_glints below; glint_small_dark.h's kNotDark).
template <typename GetMemo>
inline void locate_glint_nodes(const Footprint &f, GlintSite &site, GetMemo &&get_memo) {
  site.memo_nodes = &footprint_nodes(f, site.group_density, get_memo);
}
// The same through the caller's node-list memo (footprint_nodes with get_memo).
template <typename GetMemo>
inline void locate_glints(const Footprint &f, double density, const DirectionCellKeys &keys, const Vec3 &wi,
                          const Vec3 &wo, float gamma_rad, GlintSite &site, GetMemo &&get_memo) {
  site.has_half_vector = direction_cell_seeds(keys, wi, wo, gamma_rad, site.cell_seeds);
  if (!site.has_half_vector) return;
  site.group_density = density / kDirectionGroups;
  locate_glint_nodes(f, site, get_memo);
}

// Reflecting particles of a footprint over the kDirectionGroups groups
// (density N / G each), each group counted in its own direction cell at
// (wi, wo); the caller falls back to the mean when `complete` is false.
// The count never decreases as P grows (a node's lit set is nested in P and
// its lit particles' positions do not depend on P), and neither do its steps.
// The same with the footprint's area known (area = f.area(); session 29).
template <typename Visitor = NoParticleVisitor>
inline GlintCount count_glints(const Footprint &f, double area, const GlintSite &site, double P, int max_steps,
                               Visitor &&visit = Visitor{}) {
  if (!site.has_half_vector) return {};
  return count_reflecting_particles_of_area(f, area, site.node_list(), site.group_density, site.cell_seeds, P,
                                            max_steps, std::forward<Visitor>(visit));
}
template <typename Visitor = NoParticleVisitor>
inline GlintCount count_glints(const Footprint &f, const GlintSite &site, double P, int max_steps,
                               Visitor &&visit = Visitor{}) {
  return count_glints(f, f.area(), site, P, max_steps, std::forward<Visitor>(visit));
}

}  // namespace glimmer::plugin::glint
