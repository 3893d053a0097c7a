// Upper bounds of the glint table's P lookups over 4-degree blocks of
// (theta_i, theta_o, dphi), small enough (23 x 23 x 46 floats, 97 KB) to stay
// in the L2 cache, where a lookup into the table itself (several MB) waits on
// a miss to L3 that cost about two GGX evals.
//
// Use (glint.cpp): a footprint whose particles, counted at P_max >= P, hold
// no reflecting one holds none at P either, because a node's lit count is
// nested in P (tables/glint_particles.h, LitCountModel) and the lit
// particles' positions do not depend on P. Such an eval (most of them at
// small footprints, where the footprint holds ~0.1..10 particles) returns 0
// without touching the table; the others look P up and count again, with the
// same result as without the bound.
//
// A trilinear lookup is a convex combination of the 8 nodes of its grid
// cell, and a lookup between two LOD levels a convex combination of the two,
// so P <= the largest node any query of the block can read in any level it
// can use. Block b of an axis covers the queries 4b <= x < 4b + 4 (x clamped
// as LodLevel::cell clamps it); the nodes they read are found with the same
// float expressions as LodLevel::cell, so the bound holds for every query,
// not only up to rounding. A final factor 1 + 2^-16 covers the rounding of
// the interpolation itself (a lerp can exceed its larger end by an ulp).
#pragma once

#include <algorithm>
#include <cstdint>
#include <vector>

#include <emmintrin.h>

#include "tables/glint_tables.h"

namespace glimmer::plugin::glint {

class DirectionalPeakTable {
 public:
  static constexpr int kBlockDeg = 4;
  static constexpr float kInvBlockDeg = 1.0f / kBlockDeg;  // exact: block index = floor(x / 4)
  static constexpr float kRoundingMargin = 1.0f + 1.0f / 65536.0f;

  DirectionalPeakTable() = default;

  // Bounds of every lookup at a LOD blur sigma <= max_sigma_deg.
  DirectionalPeakTable(const DirectionalTable &table, float max_sigma_deg) {
    const int last_level = levels_up_to(max_sigma_deg);
    peak_.assign(static_cast<size_t>(n_[0]) * n_[1] * n_[2], 0.0f);
    for (int l = 0; l <= last_level; ++l) add_level(table.levels[static_cast<size_t>(l)]);
    for (float &p : peak_) p *= kRoundingMargin;
  }

  bool empty() const { return peak_.empty(); }

  // >= DirectionalTable::lookup(sigma, theta_i, theta_o, dphi) for every sigma
  // <= max_sigma_deg of the constructor (angles in degrees, as lookup takes them).
  // The three block_of in SSE lanes (the same comparisons, product and
  // truncation, so the same blocks; GlintParticles.PeakTable* tests).
  float bound(float theta_i_deg, float theta_o_deg, float dphi_deg) const {
    return bound(_mm_setr_ps(theta_i_deg, theta_o_deg, dphi_deg, 0.0f));
  }
  // The same with the angles in lanes 0..2 of `x` (lane 3 unused, any value: its block is clamped to 0).
  // block_of's min(b, n - 1) is left out (session 24): the clamped angle is at most hi, and hi / 4 (an exact
  // product) truncates to n - 1, so the min never changes a block; the grid's sizes are constants.
  float bound(__m128 x) const {
    const __m128 clamped = _mm_and_ps(_mm_cmpgt_ps(x, _mm_setzero_ps()),  // clamp_deg: x > 0 ? min : 0 (NaN: 0)
                                      _mm_min_ps(x, _mm_setr_ps(90.0f, 90.0f, 180.0f, 0.0f)));
    const __m128i b = _mm_cvttps_epi32(_mm_mul_ps(clamped, _mm_set1_ps(kInvBlockDeg)));
    const auto bi = static_cast<uint32_t>(_mm_cvtsi128_si32(b));
    const auto bo = static_cast<uint32_t>(_mm_cvtsi128_si32(_mm_shuffle_epi32(b, _MM_SHUFFLE(1, 1, 1, 1))));
    const auto bp = static_cast<uint32_t>(_mm_cvtsi128_si32(_mm_shuffle_epi32(b, _MM_SHUFFLE(2, 2, 2, 2))));
    return peak_[(static_cast<size_t>(bi) * n_[1] + bo) * n_[2] + bp];
  }
  // The scalar form of bound() (the reference of its test).
  float bound_scalar(float theta_i_deg, float theta_o_deg, float dphi_deg) const {
    const int bi = block_of(theta_i_deg, 90.0f, n_[0]);
    const int bo = block_of(theta_o_deg, 90.0f, n_[1]);
    const int bp = block_of(dphi_deg, 180.0f, n_[2]);
    return peak_[(static_cast<size_t>(bi) * n_[1] + bo) * n_[2] + bp];
  }

 private:
  static constexpr int n_[3] = {static_cast<int>(90.0f * kInvBlockDeg) + 1, static_cast<int>(90.0f * kInvBlockDeg) + 1,
                                 static_cast<int>(180.0f * kInvBlockDeg) + 1};  // blocks(90), blocks(90), blocks(180)
  static_assert(static_cast<int>(90.0f * kInvBlockDeg) == n_[0] - 1 && static_cast<int>(180.0f * kInvBlockDeg) == n_[2] - 1,
                "bound() relies on the largest clamped angle falling in the last block");
  std::vector<float> peak_;

  static int block_of(float x_deg, float hi, int n) {
    return std::min(static_cast<int>(LodLevel::clamp_deg(x_deg, hi) * kInvBlockDeg), n - 1);
  }

  // The last level a lookup at sigma <= max_sigma reads (DirectionalTable::levels_at).
  static int levels_up_to(float max_sigma_deg) {
    int l = 0;
    while (l + 1 < kLodCount && max_sigma_deg > kLodSigmaDeg[static_cast<size_t>(l)]) ++l;
    return l;
  }

  // Node index range [lo, hi] that queries of block b read along an axis of
  // `n_nodes` nodes at `step` degrees (LodLevel::cell's corner and corner + 1).
  static void node_range(int b, float hi_deg, int step, int n_nodes, int &lo, int &hi) {
    const float inv_step = 1.0f / static_cast<float>(step);
    const float x0 = LodLevel::clamp_deg(static_cast<float>(b * kBlockDeg), hi_deg);
    const float x1 = LodLevel::clamp_deg(static_cast<float>((b + 1) * kBlockDeg), hi_deg);
    lo = std::min(static_cast<int>(x0 * inv_step), n_nodes - 2);
    hi = std::min(static_cast<int>(x1 * inv_step), n_nodes - 2) + 1;
  }

  void add_level(const LodLevel &level) {
    for (int bi = 0; bi < n_[0]; ++bi) {
      int i0, i1;
      node_range(bi, 90.0f, 1, kThetaICount, i0, i1);
      for (int bo = 0; bo < n_[1]; ++bo) {
        int o0, o1;
        node_range(bo, 90.0f, level.step_deg, level.n_theta_o, o0, o1);
        for (int bp = 0; bp < n_[2]; ++bp) {
          int p0, p1;
          node_range(bp, 180.0f, level.step_deg, level.n_phi, p0, p1);
          float m = 0.0f;
          for (int i = i0; i <= i1; ++i)
            for (int o = o0; o <= o1; ++o) {
              const size_t row = (static_cast<size_t>(i) * level.n_theta_o + o) * level.n_phi;
              for (int p = p0; p <= p1; ++p) m = std::max(m, level.node(row + p));  // what lookups read
            }
          float &peak = peak_[(static_cast<size_t>(bi) * n_[1] + bo) * n_[2] + bp];
          peak = std::max(peak, m);
        }
      }
    }
  }
};

}  // namespace glimmer::plugin::glint
