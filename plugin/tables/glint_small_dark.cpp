// The dark test's count for a footprint of a few particle nodes (issue 10, session 24): see glint_small_dark.h.
#include "tables/glint_small_dark.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <optional>

namespace glimmer::plugin::glint {

SmallDarkField::SmallDarkField(const DirectionCellKeys &k, float gamma, int nodes, int steps, double material_density)
    : keys(k), gamma_rad(gamma), max_nodes(nodes), max_steps(steps), density(material_density),
      group_density(material_density / kDirectionGroups), level(particle_level(group_density)) {}

std::unique_ptr<const SmallDarkField> make_small_dark_field(const DirectionCellKeys &k, float gamma, int nodes,
                                                            int steps, double material_density) {
  return std::make_unique<const SmallDarkField>(k, gamma, nodes, steps, material_density);
}

#if GLIMMER_GLINT_WALK_AVX2
namespace {
// small_footprint_dark_avx2's pass 1: every node's four group hashes (node_seed_hash in lanes) and quick rejects, as
// bit 4 n + g of the result (n the node in row-major order of the rows x cols box from (i0, j0)). Session 35: the
// box's (at most kBoxSpan = 4) row keys in the lanes of one node_row_keys_avx2 (node_row_key's words, j as uint32 as
// there) instead of two scalar PCG hashes per row; a node's key row_key + i W as a running sum along the row (the same
// words mod 2^32; GCC had hoisted (i0 + c) W for c = 0..3 out of the row loop); the hashes two nodes per mix_u32x8 by
// the node loop's node_loop_pass1_avx2 (the same words, bits and stores) instead of one mix_u32x4 per node.
[[gnu::target("avx2"), gnu::always_inline]] inline uint64_t passing_pairs(int level, int64_t i0, int64_t j0,
                                                                          int64_t rows, int64_t cols, __m128i seeds,
                                                                          __m128i below, uint32_t all_pass,
                                                                          uint32_t (*hashes)[kDirectionGroups],
                                                                          int64_t *node_i, int64_t *node_j) {
  static_assert(kBoxSpan <= 4 && kBoxSpan * kBoxSpan <= kNodeLoopChunk);
  alignas(16) uint32_t row_keys[4];
  _mm_store_si128(reinterpret_cast<__m128i *>(row_keys),
                  node_row_keys_avx2(level, _mm_add_epi32(_mm_set1_epi32(static_cast<int>(static_cast<uint32_t>(j0))),
                                                          _mm_setr_epi32(0, 1, 2, 3))));
  alignas(16) uint32_t keys[kBoxSpan * kBoxSpan];
  int n = 0;
  for (int64_t r = 0; r < rows; ++r) {
    uint32_t key = row_keys[r] + static_cast<uint32_t>(i0) * kNodeKeyStep;
    for (int64_t c = 0; c < cols; ++c, ++n, key += kNodeKeyStep) {
      keys[n] = key;
      node_i[n] = i0 + c, node_j[n] = j0 + r;
    }
  }
  return node_loop_pass1_avx2(keys, n, seeds, below, all_pass, hashes);
}

// Session 36 (glintdark36): pass 2's positions four per step (two scalar mix_u32 per particle before). Every return
// of pass 2 but the last is kNotDark, so the answer does not depend on the order in which positions are tested:
// kDark iff every lit position is outside, as in the scalar loop. A pair of at most kMaxListed lit particles (most of
// them) appends its positions to a list over the box's pairs, tested at the end (or when full) four per step, each
// lane its own key and node origin; a pair of more is tested by itself by the count at P's particles_inside4_avx2.
struct PositionList {
  static constexpr int kMaxListed = 4;  // one step of four lanes (the lanes past K are written, not counted)
  static constexpr int kCapacity = 32;  // a multiple of 4; tested and emptied when a pair's four lanes do not fit
  alignas(32) uint32_t keys[kCapacity];  // particle k's x key (h0 ^ C) + (2 k + 1) W; its y key is that + W
  alignas(32) double s[kCapacity], t[kCapacity];  // the particle's node origin in the footprint's frame
  int n = 0;
  // The frame's steps (FootprintFrame's; copied, so that the frame itself is not passed out of line: GCC then kept
  // all its fields, +15 per eval at 1e-8).
  double ds_ux = 0.0, ds_uy = 0.0, dt_ux = 0.0, dt_uy = 0.0;

  void set_frame(const FootprintFrame &frame) {
    ds_ux = frame.ds_ux, ds_uy = frame.ds_uy, dt_ux = frame.dt_ux, dt_uy = frame.dt_uy;
  }
  [[gnu::target("avx2"), gnu::always_inline]] FrameLanesAvx2 lanes() const {
    return {_mm256_set1_pd(ds_ux), _mm256_set1_pd(ds_uy), _mm256_set1_pd(dt_ux), _mm256_set1_pd(dt_uy)};
  }

  // Whether any of the n listed positions lies inside the footprint (particle_inside's expressions by lanes).
  [[gnu::target("avx2"), gnu::always_inline]] bool any_inside() const {
    const FrameLanesAvx2 lanes = this->lanes();
    const __m256d sign = _mm256_set1_pd(-0.0), half = _mm256_set1_pd(0.5);
    for (int i = 0; i < n; i += 4) {
      const __m128i x = _mm_load_si128(reinterpret_cast<const __m128i *>(keys + i));
      const __m128i y = _mm_add_epi32(x, _mm_set1_epi32(static_cast<int>(kNodeKeyStep)));
      const __m256 u = _mm256_mul_ps(_mm256_cvtepi32_ps(_mm256_srli_epi32(mix_u32x8(_mm256_set_m128i(y, x)), 8)),
                                     _mm256_set1_ps(1.0f / 16777216.0f));  // uint_to_unit_float: the x's, the y's
      const __m256d ux = _mm256_cvtps_pd(_mm256_castps256_ps128(u)), uy = _mm256_cvtps_pd(_mm256_extractf128_ps(u, 1));
      const __m256d ps = _mm256_add_pd(_mm256_add_pd(_mm256_load_pd(s + i), _mm256_mul_pd(ux, lanes.ds_ux)),
                                       _mm256_mul_pd(uy, lanes.ds_uy));
      const __m256d pt = _mm256_add_pd(_mm256_add_pd(_mm256_load_pd(t + i), _mm256_mul_pd(ux, lanes.dt_ux)),
                                       _mm256_mul_pd(uy, lanes.dt_uy));
      const __m256d in = _mm256_and_pd(_mm256_cmp_pd(_mm256_andnot_pd(sign, ps), half, _CMP_LE_OS),
                                       _mm256_cmp_pd(_mm256_andnot_pd(sign, pt), half, _CMP_LE_OS));
      uint32_t mask = static_cast<uint32_t>(_mm256_movemask_pd(in));
      if (n - i < 4) mask &= (1u << (n - i)) - 1u;
      if (mask != 0) return true;
    }
    return false;
  }
  // The full list tested and emptied (out of line: its set-up stays out of pass 2's loop).
  [[gnu::target("avx2"), gnu::noinline, gnu::cold]] bool flush_inside() {
    const bool inside = any_inside();
    n = 0;
    return inside;
  }
  // A pair of more than kMaxListed lit particles, by itself (out of line, as flush_inside).
  [[gnu::target("avx2"), gnu::noinline]] bool pair_inside(uint32_t h0, int64_t K,
                                                          const FootprintFrame::NodeOrigin &o) const {
    const FrameLanesAvx2 lanes = this->lanes();
    for (int64_t k = 0; k < K; k += 4) {
      uint32_t in = particles_inside4_avx2(lanes, o, h0, static_cast<uint32_t>(k));
      if (K - k < 4) in &= (1u << (K - k)) - 1u;
      if (in != 0) return true;
    }
    return false;
  }
  // The K >= 1 lit particles of the pair whose hash is h0 at the node origin o; false: one of them, or of a full
  // list, lies inside (kNotDark).
  [[gnu::target("avx2"), gnu::always_inline]] bool add(uint32_t h0, int64_t K, const FootprintFrame::NodeOrigin &o) {
    if (K > kMaxListed) return !pair_inside(h0, K, o);
    if (n > kCapacity - kMaxListed && flush_inside()) return false;
    _mm_storeu_si128(reinterpret_cast<__m128i *>(keys + n),
                    _mm_add_epi32(_mm_set1_epi32(static_cast<int>((h0 ^ kPositionKey) + kNodeKeyStep)),
                                  _mm_load_si128(reinterpret_cast<const __m128i *>(kKeySteps))));  // k = 0..3
    _mm256_storeu_pd(s + n, _mm256_set1_pd(o.s));
    _mm256_storeu_pd(t + n, _mm256_set1_pd(o.t));
    n += static_cast<int>(K);
    return true;
  }
  alignas(16) static constexpr uint32_t kKeySteps[4] = {0u, 2u * kNodeKeyStep, 4u * kNodeKeyStep, 6u * kNodeKeyStep};
};
}  // namespace
#endif

#if GLIMMER_GLINT_WALK_AVX2
[[gnu::target("avx2")]] SmallDark small_footprint_dark_avx2(const SmallDarkField &m,
                                                                                  const Footprint &f, double area,
                                                                                  double density, const Vec3 &wi,
                                                                                  const Vec3 &wo, double P,
                                                                                  GlintSite &site) {
  // The node list (footprint_nodes' start: the same level, size and floors).
  double group_density;
  int level;
  if (density == m.density) [[likely]] {
    group_density = m.group_density, level = m.level;
  } else {
    group_density = density / kDirectionGroups, level = particle_level(group_density);
  }
  const double size = power_of_two(-level), inv = power_of_two(level);
  if (area >= size * size) return SmallDark::kGeneric;  // FootprintFrame::can_hold_a_node: the pair passes count it
  const double ey = 0.5 * (std::fabs(f.ay) + std::fabs(f.by));
  const double ex = 0.5 * (std::fabs(f.ax) + std::fabs(f.bx));
  if (!(ex * inv < 1e15) || !(ey * inv < 1e15)) return SmallDark::kGeneric;
  const __m256d v = _mm256_mul_pd(_mm256_setr_pd(f.cy - ey, f.cy + ey, f.cx - ex, f.cx + ex), _mm256_set1_pd(inv));
  const __m256d abs_v = _mm256_and_pd(v, _mm256_castsi256_pd(_mm256_set1_epi64x(0x7fffffffffffffffll)));
  if (_mm256_movemask_pd(_mm256_cmp_pd(abs_v, _mm256_set1_pd(2251799813685248.0), _CMP_LT_OQ)) != 0xf)
    return SmallDark::kGeneric;  // beyond 2^51 or NaN
  const __m256d magic = _mm256_set1_pd(6755399441055744.0);  // 2^52 + 2^51
  const __m256i e = _mm256_sub_epi64(
      _mm256_castpd_si256(_mm256_add_pd(_mm256_round_pd(v, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC), magic)),
      _mm256_castpd_si256(magic));  // j0, j1, i0, i1
  const __m128i ej = _mm256_castsi256_si128(e), ei = _mm256_extracti128_si256(e, 1);
  const int64_t j0 = _mm_cvtsi128_si64(ej), i0 = _mm_cvtsi128_si64(ei);
  const int64_t rows = _mm_extract_epi64(ej, 1) - j0 + 1, cols = _mm_extract_epi64(ei, 1) - i0 + 1;
  if (rows > kBoxSpan || cols > kBoxSpan || rows * cols > m.max_nodes) return SmallDark::kGeneric;
  // The direction cells (locate_glints; none: count_glints returns an empty, complete count).
  site.group_density = group_density;
  site.has_half_vector = direction_cell_seeds_avx2_body(m.keys, wi, wo, m.gamma_rad, site.cell_seeds);
  if (!site.has_half_vector || !(P > 0.0)) return SmallDark::kDark;
  // count_reflecting_particles' constants.
  const double lambda = std::min(group_density * size * size, 4.0e18) * std::min(P, 1.0);
  const GroupReject reject(static_cast<uint64_t>(std::min(lambda, 1.0) * 4294967296.0) + 1u);
  const __m128i seeds = _mm_loadu_si128(reinterpret_cast<const __m128i *>(site.cell_seeds.data()));
  const __m128i bias = _mm_set1_epi32(static_cast<int>(0x80000000u));  // unsigned compare as signed
  const __m128i below = _mm_xor_si128(_mm_set1_epi32(static_cast<int>(reject.below)), bias);
  const uint32_t all_pass = reject.all_pass ? 0xfu : 0u;
  // Pass 1: every node's four group hashes (node_seed_hash in lanes) and quick rejects, as bit 4 n + g of `pairs`.
  alignas(16) uint32_t hashes[kBoxSpan * kBoxSpan][kDirectionGroups];
  int64_t node_i[kBoxSpan * kBoxSpan], node_j[kBoxSpan * kBoxSpan];
  uint64_t pairs = passing_pairs(level, i0, j0, rows, cols, seeds, below, all_pass, hashes, node_i, node_j);
  if (pairs == 0) return SmallDark::kDark;  // K = 0 in every pair
  // Pass 2: the pairs in count_reflecting_particles' order (node by node, groups in order).
  const LitCountBounds bounds(lambda);
  std::optional<LitCountModel> model;
  std::optional<FootprintFrame> frame;
  FootprintFrame::NodeOrigin origin{};
  int origin_of = -1;  // the node whose origin is `origin`
  int steps = 0;
  PositionList list;
  for (; pairs != 0; pairs &= pairs - 1) {
    const int pair = std::countr_zero(pairs), node = pair / kDirectionGroups;
    const uint32_t h0 = hashes[node][pair % kDirectionGroups];
    const int64_t K = lit_count_at(h0, bounds, model, lambda);
    if (K == 0) continue;
    if (K < 0 || steps + K > m.max_steps) return SmallDark::kNotDark;  // incomplete
    steps += static_cast<int>(K);
    // The footprint is smaller than a node (above), so no node lies inside it: every lit particle's position is
    // tested (count_reflecting_particles' border branch).
    if (!frame) {
      frame.emplace(f, size);
      list.set_frame(*frame);
    }
    if (origin_of != node) {
      origin = frame->origin(static_cast<double>(node_i[node]) * size, static_cast<double>(node_j[node]) * size);
      origin_of = node;
    }
    if (!list.add(h0, K, origin)) return SmallDark::kNotDark;
  }
  return list.n != 0 && list.any_inside() ? SmallDark::kNotDark : SmallDark::kDark;
}
#endif

}  // namespace glimmer::plugin::glint
