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
#include <cmath>
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
    add_level0(table.level0);
    for (int l = 1; l <= last_level; ++l) add_level(table.levels[static_cast<size_t>(l)]);
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

  // Level 0 (session 32: Level0Residual). A block inside the corner (theta_i, theta_o >= 60, dphi >= 120; blocks
  // are 4 degrees, so a block is inside or outside it whole, and out-of-range angles clamp into the block the
  // lookup's clamp puts them in) reads the corner's nodes: their largest, as add_level. Any other block reads
  // q' x R: at most the largest R node its queries read (convexity) times an upper bound of q' over the block
  // (q_upper_bound: interval arithmetic over the block's angles, widened by 0.01 degree for table_coords' acos
  // error; x (1 + 1e-3) for the float rounding of q' and of s, d from the vectors).
  void add_level0(const Level0Residual &l0) {
    const LodLevel &ratio = l0.ratio;
    for (int bi = 0; bi < n_[0]; ++bi)
      for (int bo = 0; bo < n_[1]; ++bo)
        for (int bp = 0; bp < n_[2]; ++bp) {
          const bool corner = bi * kBlockDeg >= Level0Residual::kCornerDeg[0] &&
                              bo * kBlockDeg >= Level0Residual::kCornerDeg[1] &&
                              bp * kBlockDeg >= Level0Residual::kCornerDeg[2];
          float m = corner ? corner_peak(l0, bi, bo, bp) : 0.0f;
          if (!corner) {
            int i0, i1, o0, o1, p0, p1;
            node_range(bi, 90.0f, 1, kThetaICount, i0, i1);
            node_range(bo, 90.0f, ratio.step_deg, ratio.n_theta_o, o0, o1);
            node_range(bp, 180.0f, static_cast<int>(1.0f / ratio.lane_scale[2] + 0.5f), ratio.n_phi, p0, p1);
            float r = 0.0f;
            for (int i = i0; i <= i1; ++i)
              for (int o = o0; o <= o1; ++o) {
                const size_t row = i * ratio.theta_i_stride() + static_cast<size_t>(o) * ratio.n_phi;
                for (int p = p0; p <= p1; ++p) r = std::max(r, ratio.node(row + p));
              }
            m = r * q_upper_bound(l0, bi, bo, bp) * (1.0f + 1e-3f);
          }
          float &peak = peak_[(static_cast<size_t>(bi) * n_[1] + bo) * n_[2] + bp];
          peak = std::max(peak, m);
        }
  }
  static float corner_peak(const Level0Residual &l0, int bi, int bo, int bp) {
    const LodLevel &c = l0.corner;
    const int oi = static_cast<int>(Level0Residual::kCornerDeg[0]) / kBlockDeg;
    const int oo = static_cast<int>(Level0Residual::kCornerDeg[1]) / kBlockDeg;
    const int op = static_cast<int>(Level0Residual::kCornerDeg[2]) / kBlockDeg;
    int i0, i1, o0, o1, p0, p1;  // the corner grid's nodes (its origin is on a block border)
    node_range(bi - oi, 90.0f - Level0Residual::kCornerDeg[0], 1, c.lane_last[0] + 2, i0, i1);
    node_range(bo - oo, 90.0f - Level0Residual::kCornerDeg[1], 1, c.n_theta_o, o0, o1);
    node_range(bp - op, 180.0f - Level0Residual::kCornerDeg[2], 1, c.n_phi, p0, p1);
    float m = 0.0f;
    for (int i = i0; i <= i1; ++i)
      for (int o = o0; o <= o1; ++o) {
        const size_t row = i * c.theta_i_stride() + static_cast<size_t>(o) * c.n_phi;
        for (int p = p0; p <= p1; ++p) m = std::max(m, c.node(row + p));
      }
    return m;
  }
  // An upper bound of Level0Residual::estimate over the directions of block (bi, bo, bp): intervals of s and d
  // from those of cos and sin of the angles (monotone on [0, 90] and [0, 180]), then of each factor of q'.
  static float q_upper_bound(const Level0Residual &l0, int bi, int bo, int bp) {
    constexpr double kPad = 0.01, kRad = 0.017453292519943295, kPiD = 3.14159265358979323846;
    auto range = [](int b, double hi, double &lo_deg, double &hi_deg) {
      lo_deg = std::max(0.0, b * kBlockDeg - kPad);
      hi_deg = std::min(hi, (b + 1) * kBlockDeg + kPad);
    };
    double ti0, ti1, to0, to1, p0, p1;
    range(bi, 90.0, ti0, ti1);
    range(bo, 90.0, to0, to1);
    range(bp, 180.0, p0, p1);
    const double ci_lo = std::cos(ti1 * kRad), ci_hi = std::cos(ti0 * kRad), si_lo = std::sin(ti0 * kRad), si_hi = std::sin(ti1 * kRad);
    const double co_lo = std::cos(to1 * kRad), co_hi = std::cos(to0 * kRad), so_lo = std::sin(to0 * kRad), so_hi = std::sin(to1 * kRad);
    const double cp_lo = std::cos(p1 * kRad), cp_hi = std::cos(p0 * kRad);
    const double s_raw_lo = std::max(0.0, ci_lo + co_lo - 1e-6), s_raw_hi = ci_hi + co_hi + 1e-6;
    const double ss_lo = si_lo * so_lo, ss_hi = si_hi * so_hi;
    const double x_lo = std::min({ss_lo * cp_lo, ss_hi * cp_lo, ss_lo * cp_hi, ss_hi * cp_hi});
    const double x_hi = std::max({ss_lo * cp_lo, ss_hi * cp_lo, ss_lo * cp_hi, ss_hi * cp_hi});
    const double d_raw_lo = 1.0 + ci_lo * co_lo + x_lo - 1e-6, d_raw_hi = 1.0 + ci_hi * co_hi + x_hi + 1e-6;
    const double a2 = l0.a2, q_max = l0.q_max, e2 = l0.eps2;
    if (!(s_raw_hi > 0.0) || !(d_raw_hi > 0.0)) return l0.q_floor;  // estimate() is the floor alone there
    // estimate()'s regularised s and d (s^2 + eps2, d + eps2 / 2) over the block's positive s and d.
    const double s_lo = std::sqrt(s_raw_lo * s_raw_lo + e2), s_hi = std::sqrt(s_raw_hi * s_raw_hi + e2);
    const double d_lo = std::max(0.0, d_raw_lo) + 0.5 * e2, d_hi = d_raw_hi + 0.5 * e2;
    double q = q_max;
    if (l0.dist == BaseDistribution::GGX) {
      // den = 2 d + (a2 - 1) s^2 >= 2 d - (1 - a2) s^2, >= 2 a2 d and >= a2 s^2 (s^2 <= 2 d); >= 2 d if a2 >= 1.
      const double den_lo = a2 >= 1.0 ? 2.0 * d_lo
                                       : std::max({2.0 * d_lo - (1.0 - a2) * s_hi * s_hi, 2.0 * a2 * d_lo, a2 * s_lo * s_lo});
      if (den_lo > 0.0) q = std::min(q_max, a2 / kPiD * s_hi * d_hi / (den_lo * den_lo));
    } else if (s_lo > 0.0) {
      const double x = std::max(0.0, 2.0 * d_lo - s_hi * s_hi) / (a2 * s_hi * s_hi);  // exponent >= x
      q = std::min(q_max, std::exp(-x) * (1.0 + 1e-5) * d_hi / (kPiD * a2 * s_lo * s_lo * s_lo));
    }
    return static_cast<float>(q + l0.q_floor);
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
