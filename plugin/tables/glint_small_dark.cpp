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
  // The direction cells (locate_glints; none: count_glints returns an empty, complete count). The caller's site is
  // unwritten (GlintSite(Unset)): no kNotDark answer may come before these writes.
  site.group_density = group_density;
  site.has_half_vector = direction_cell_seeds_avx2_body(m.keys, wi, wo, m.gamma_rad, site.cell_seeds);
  if (!site.has_half_vector || !(P > 0.0)) return SmallDark::kDark;
  // count_reflecting_particles' constants.
  const double lambda = node_lit_mean(group_density, size, P);
  const GroupReject reject = quick_reject(lambda);
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
  for (; pairs != 0; pairs &= pairs - 1) {
    const int pair = std::countr_zero(pairs), node = pair / kDirectionGroups;
    const uint32_t h0 = hashes[node][pair % kDirectionGroups];
    const int64_t K = lit_count_at(h0, bounds, model, lambda);
    if (K == 0) continue;
    if (K < 0 || steps + K > m.max_steps) return SmallDark::kNotDark;  // incomplete
    steps += static_cast<int>(K);
    // The footprint is smaller than a node (above), so no node lies inside it: every lit particle's position is
    // tested (count_reflecting_particles' border branch).
    if (!frame) frame.emplace(f, size);
    if (origin_of != node) {
      origin = frame->origin(static_cast<double>(node_i[node]) * size, static_cast<double>(node_j[node]) * size);
      origin_of = node;
    }
    for (int64_t k = 0; k < K; ++k) {
      const auto [ux, uy] = particle_position(h0, static_cast<uint32_t>(k));
      if (frame->particle_inside(origin, ux, uy)) return SmallDark::kNotDark;
    }
  }
  return SmallDark::kDark;
}
#endif

}  // namespace glimmer::plugin::glint
