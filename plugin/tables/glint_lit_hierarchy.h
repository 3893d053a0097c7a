// Lit counts of a block of particle nodes split to its nodes (issue 10, session 21, glintdark21): the building block
// of a quick-reject hierarchy over the particle nodes. Not used by the plugin (docs/history/glints_sessions.md "Session
// 21 (glintdark21)": measured first, by benchmarks/glint_dark_sim.cpp).
//
// A block of 2 x 2 particle nodes (side 2 s) holds K_B ~ Poisson(4 lambda) lit particles of a direction group,
// lambda = n s^2 P the node's mean, drawn from the block's uniform by the walk's tail inversion (LitCountModel).
// K_B is split to the four nodes by three binomial splits with p = 1/2 (first the two columns, then each column's
// two nodes), each Binomial(K, 1/2) drawn by inverting its CDF at a uniform that depends on the block's hash only.
// Why it is right:
//  * Exact: given K_B, the splits give a Multinomial(K_B; 1/4 x 4) (each particle uniformly in one node), and a
//    Poisson(4 lambda) count split multinomially gives four independent Poisson(lambda) counts (Poisson
//    thinning): the same law as four independent nodes.
//  * Nested: for a fixed uniform u, the inverse CDF X(K, u) of Binomial(K, p) satisfies X(K, u) <= X(K + 1, u) <=
//    X(K, u) + 1, because F_{K+1}(x) = (1 - p) F_K(x) + p F_K(x - 1) lies between F_K(x - 1) and F_K(x). So when
//    K grows by one, exactly one child grows by one and the others keep their counts; as K_B is nested in P
//    (LitCountModel) and the split uniforms do not depend on P, every node's count is nested in P (no flicker
//    from the trilinear table lookups).
// Tested by GlintLitHierarchy.* (tests/closures/test_glint_lit_hierarchy.cpp).
#pragma once

#include <array>
#include <cmath>
#include <cstdint>

#include "tables/glint_particles.h"

namespace glimmer::plugin::glint {

// Binomial(K, p) by inversion of its CDF at u in [0, 1): the smallest x with u < F_K(x). O(x) steps with the pmf
// ratio (K - x) / (x + 1) p / (1 - p); K <= 1000 (the pmf at 0, (1 - p)^K, stays a normal double for p <= 1/2).
inline int64_t binomial_inverse(int64_t K, double p, double u) {
  if (K <= 0) return 0;
  const double q = 1.0 - p, ratio = p / q;
  double pmf = std::pow(q, static_cast<double>(K)), cdf = pmf;
  int64_t x = 0;
  while (u >= cdf && x < K) {
    pmf *= static_cast<double>(K - x) / static_cast<double>(x + 1) * ratio;
    ++x;
    cdf += pmf;
  }
  return x;
}

// The split uniforms of a block whose (node x direction cell) hash is h: mix_u32 of (h ^ kSplitKey) + (k + 1) W,
// as u = (v + 1/2) 2^-32 (independent of the hash's own use as the block's uniform and of the positions' keys).
inline constexpr uint32_t kSplitKey = 0x165667b1u;
inline double split_uniform(uint32_t h, uint32_t k) {
  const uint32_t v = mix_u32((h ^ kSplitKey) + (k + 1u) * kNodeKeyStep);
  return (static_cast<double>(v) + 0.5) * (1.0 / 4294967296.0);
}

// K split to the 2 x 2 children of a block with hash h, in the order (0, 0), (0, 1), (1, 0), (1, 1) (column,
// row): column 0 gets X(K, u0), its row 0 X(column 0, u1), column 1's row 0 X(column 1, u2).
inline std::array<int64_t, 4> split_block_2x2(uint32_t h, int64_t K) {
  const int64_t col0 = binomial_inverse(K, 0.5, split_uniform(h, 0)), col1 = K - col0;
  const int64_t c00 = binomial_inverse(col0, 0.5, split_uniform(h, 1));
  const int64_t c10 = binomial_inverse(col1, 0.5, split_uniform(h, 2));
  return {c00, col0 - c00, c10, col1 - c10};
}

// The hash a child block of a 2 x 2 split uses (for its own split, or its particles' positions): a hash of the
// parent's hash and the child's index.
inline uint32_t child_hash(uint32_t h, uint32_t child) { return mix_u32(h + (child + 1u) * 0x85ebca6bu); }

}  // namespace glimmer::plugin::glint
