// Tests of the directional probability table (tables/glint_tables.*) against
// brute force: level 0 is P_gamma, the integral of the reflected-direction
// density q over the query cone (glint_tables.h equation (1)).
#include <gtest/gtest.h>

#include <cstdio>
#include <cstring>
#include <functional>
#include <limits>
#include <vector>

#include "closures/closure_checks.h"
#include "closures/glint_test_util.h"
#include "tables/glint_tables.h"

namespace glimmer::test {
namespace {

namespace pg = plugin::glint;

pg::NdfFunction ndf_of(mf::Distribution dist, float alpha) {
  return [dist, alpha](double cos_m) {
    const double c = std::min(std::max(cos_m, 0.0), 1.0);
    const Vec3 m(static_cast<float>(std::sqrt(1.0 - c * c)), 0.0f, static_cast<float>(c));
    return static_cast<double>(mf::D(dist, m, alpha, alpha));
  };
}

// Level 0 against the brute-force cone integral over the lobe core
// (reference >= 5 % of the peak): theta_i 0..80 degrees, wo within a few
// degrees of the mirror direction in and across the plane of incidence, at
// table nodes. Per theta_i the ratio P / reference is a constant (the energy
// cap of step 4 scales a whole theta_i slice down where the cone estimator's
// albedo exceeds the smooth one) times 1 + shape error. `reference_gamma` is
// the cone of the reference (the table's gamma, or a wider one for the
// negative control).
struct Level0Error {
  double shape = 0.0;                          // largest max/min - 1 of the ratio within a theta_i slice
  double lowest_scale = 1.0, highest_scale = 0.0;  // range of the slices' largest ratios
};
Level0Error level0_error(const pg::DirectionalTable &table, const pg::NdfFunction &ndf, double reference_gamma) {
  Level0Error e;
  for (int ti = 0; ti <= 80; ti += 5) {
    const double peak = pg::directional_probability_reference(ndf, reference_gamma, ti, ti, 180, 48);
    double lo = 1e30, hi = 0.0;
    for (int d_to : {-3, -1, 0, 1, 2, 4})
      for (int dphi : {180, 178, 175, 170}) {
        const int to = ti + d_to;
        if (to < 0) continue;
        const double ref = pg::directional_probability_reference(ndf, reference_gamma, ti, to, dphi, 48);
        if (!(ref >= 0.05 * peak)) continue;
        const double p = table.levels[0].lookup(static_cast<float>(ti), static_cast<float>(to), static_cast<float>(dphi));
        lo = std::min(lo, p / ref);
        hi = std::max(hi, p / ref);
      }
    e.shape = std::max(e.shape, hi / lo - 1.0);
    e.lowest_scale = std::min(e.lowest_scale, hi);
    e.highest_scale = std::max(e.highest_scale, hi);
  }
  return e;
}

// The table's P_gamma has the shape of the brute-force cone integral (48
// rings of equal solid angle x 192 azimuths; 200 rings change it by < 1e-5)
// within 0.5 % over the lobe core, up to the energy cap's per-slice scale
// (at most 1 + 0.5 %, at least 0.98), for lobes narrower than the cone
// (roughness 0.15 and 0.2 at gamma 2 degrees: alpha 1.3 and 2.3 degrees). Negative control:
// the old table's accumulation added a 1-degree cone's spread to the gamma
// cone's (second moment gamma^2 + 1 deg^2); the same table compared with a
// cone of that spread, gamma' = sqrt(gamma^2 + 1), differs in shape by > 2 %.
TEST(GlintTables, Level0EqualsBruteForceConeIntegralForNarrowLobes) {
  struct Case {
    mf::Distribution dist;
    double roughness;
  };
  for (const Case &c : {Case{mf::Distribution::GGX, 0.2}, Case{mf::Distribution::GGX, 0.15},
                        Case{mf::Distribution::Beckmann, 0.2}}) {
    pg::TableSpec spec;
    spec.distribution = c.dist == mf::Distribution::GGX ? pg::BaseDistribution::GGX : pg::BaseDistribution::Beckmann;
    spec.alpha = static_cast<float>(c.roughness * c.roughness);
    spec.gamma_deg = 2.0f;
    const pg::NdfFunction ndf = ndf_of(c.dist, spec.alpha);
    const auto table = pg::build_directional_table(spec, ndf, 2);
    const Level0Error error = level0_error(*table, ndf, spec.gamma_deg);
    const Level0Error control = level0_error(*table, ndf, std::sqrt(sqr(spec.gamma_deg) + 1.0));
    std::printf("[table] %s r=%.2f gamma 2: P / brute force within a theta_i slice varies by %.4f (control, gamma' = "
                "sqrt(5): %.4f); slice scales %.4f..%.4f; built in %.2f s\n",
                c.dist == mf::Distribution::GGX ? "ggx" : "beckmann", c.roughness, error.shape, control.shape,
                error.lowest_scale, error.highest_scale, table->build_seconds);
    EXPECT_LE(error.shape, 0.005) << c.roughness;
    EXPECT_LE(error.highest_scale, 1.005) << c.roughness;  // the cap only lowers P
    EXPECT_GE(error.lowest_scale, 0.98) << c.roughness;
    EXPECT_GT(control.shape, 0.02) << c.roughness;
  }
}


// LodLevel::cell and lookup in SSE lanes (issue 10, session 20) against
// their scalar forms, bit for bit: every level's step (1..30 degrees, its
// node counts as the builder sets them) over synthetic values, at random
// angles in and around the axes' ranges and at edges (0, -0, the ends and
// beyond, integers and one ulp on either side of them, NaN, +-inf,
// denormals). Compared: the corner (pointer) and the three fractions of
// cell, and the lookup's value. Negative controls: the scalar cell with
// theta_o and dphi divided by the step instead of multiplied by 1 / step
// (the fractions differ), and the lookup with its dphi lerp written
// p0 (1 - t) + p1 t (the values differ), so the comparison sees a change of
// rounding.
TEST(GlintTables, CellAndLookupInLanesMatchTheScalarForm) {
  Pcg32 rng(2020);
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  const float den = std::numeric_limits<float>::denorm_min();
  std::vector<float> edges = {0.0f, -0.0f, nan, -nan, inf, -inf, den, -den, 1e-30f, -1.0f, 1e30f};
  for (int k = 0; k <= 181; ++k)
    for (const float v : {static_cast<float>(k), std::nextafter(static_cast<float>(k), -inf),
                          std::nextafter(static_cast<float>(k), inf)})
      edges.push_back(v);
  auto same = [](float a, float b) { return std::memcmp(&a, &b, sizeof a) == 0; };
  int64_t cells = 0, control_cells = 0, control_values = 0;
  for (int level = 0; level < pg::kLodCount; ++level) {
    pg::LodLevel l;
    l.set_step(pg::kLodStepDeg[static_cast<size_t>(level)]);
    l.values.resize(static_cast<size_t>(pg::kThetaICount) * l.n_theta_o * l.n_phi);
    for (float &v : l.values) v = rng.next_float();
    l.pack_halves();
    auto angle = [&](float hi) {
      const uint32_t pick = rng.next_u32() % 4;
      if (pick == 0) return edges[rng.next_u32() % edges.size()];
      return (rng.next_float() * 1.2f - 0.1f) * hi;
    };
    for (int q = 0; q < 200000; ++q) {
      const float ti = angle(90.0f), to = angle(90.0f), dp = angle(180.0f);
      const pg::LodLevel::Cell v = l.cell(ti, to, dp), s = l.cell_scalar(ti, to, dp);
      ASSERT_TRUE(v.base == s.base && same(v.ti, s.ti) && same(v.to, s.to) && same(v.tp, s.tp))
          << "level " << level << " at " << ti << " " << to << " " << dp << ": " << v.base << " "
          << v.ti << " " << v.to << " " << v.tp << " vs " << s.base << " " << s.ti << " " << s.to
          << " " << s.tp;
      ASSERT_TRUE(same(l.lookup(v), l.lookup_scalar(s))) << "level " << level << " at " << ti << " " << to << " " << dp;
      ++cells;
      // Controls.
      const float fo = pg::LodLevel::clamp_deg(to, 90.0f) / static_cast<float>(l.step_deg);
      const float fp = pg::LodLevel::clamp_deg(dp, 180.0f) / static_cast<float>(l.step_deg);
      const float to_c = fo - static_cast<float>(std::min(static_cast<int>(fo), l.n_theta_o - 2));
      const float tp_c = fp - static_cast<float>(std::min(static_cast<int>(fp), l.n_phi - 2));
      control_cells += !same(to_c, s.to) || !same(tp_c, s.tp);
      const size_t si = l.theta_i_stride(), so = l.theta_o_stride();
      auto lerp_phi = [&](size_t i) {
        return l.decode_half(l.halves[i]) * (1.0f - s.tp) + l.decode_half(l.halves[i + 1]) * s.tp;
      };
      const float a = lerp_phi(s.base) + (lerp_phi(s.base + so) - lerp_phi(s.base)) * s.to;
      const float b = lerp_phi(s.base + si) + (lerp_phi(s.base + si + so) - lerp_phi(s.base + si)) * s.to;
      control_values += !same(a + (b - a) * s.ti, l.lookup_scalar(s));
    }
  }
  std::printf("[cells] %lld cells and lookups equal to the scalar forms; controls differ on %lld cells, %lld values\n",
              static_cast<long long>(cells), static_cast<long long>(control_cells),
              static_cast<long long>(control_values));
  EXPECT_GT(control_cells, cells / 100);
  EXPECT_GT(control_values, cells / 10);
}

// The 16-bit nodes lookups read (session 31, glinttable31: LodLevel::halves, values x 2^k as unsigned 5-bit-exponent
// 11-bit-mantissa floats, rounded up) against the trilinear lookup of the fp32 values, on a built table (GGX roughness
// 0.35, gamma 2 degrees: the GI scene's car paint), every LOD level, 2e5 random queries per level over the whole
// domain. Where the fp32 lookup is >= 2^-16 of the level's largest value, a lookup is at most 2^-11 (one ulp) above it
// and at most 2^-12 below it (nodes below 2^-28 of the peak read 0), so |relative error| <= 2^-11 + 2^-13 covers both;
// below 2^-16 of the peak the difference is at most 2^-26 of the peak. Negative control: the same nodes with their
// three lowest mantissa bits cleared (an 8-bit mantissa) exceed the bound.
TEST(GlintTables, HalvesLookupMatchesTheFp32LookupOnEveryLevel) {
  pg::TableSpec spec;
  spec.distribution = pg::BaseDistribution::GGX;
  spec.alpha = 0.35f * 0.35f;
  spec.gamma_deg = 2.0f;
  const auto table = pg::build_directional_table(spec, ndf_of(mf::Distribution::GGX, spec.alpha), 2);
  constexpr double kBound = 1.0 / 2048 + 1.0 / 8192, kBelow = 1.0 / 4096 + 1e-6;
  Pcg32 rng(31);
  for (int level = 0; level < pg::kLodCount; ++level) {
    const pg::LodLevel &l = table->levels[static_cast<size_t>(level)];
    pg::LodLevel control = l;
    for (uint16_t &h : control.halves) h = static_cast<uint16_t>(h & ~7u);
    float peak = 0.0f;
    for (const float v : l.values) peak = std::max(peak, v);
    ASSERT_GT(peak, 0.0f);
    double worst = 0.0, lowest = 0.0, sum = 0.0, sum_sq = 0.0, worst_control = 0.0, worst_small = 0.0;
    int64_t counted = 0;
    for (int q = 0; q < 200000; ++q) {
      const pg::LodLevel::Cell c =
          l.cell(90.0f * rng.next_float(), 90.0f * rng.next_float(), 180.0f * rng.next_float());
      const double exact = l.lookup_exact(c), half = l.lookup(c), coarse = control.lookup(c);
      if (exact >= peak / 65536.0) {
        const double r = (half - exact) / exact;
        worst = std::max(worst, std::fabs(r));
        lowest = std::min(lowest, r);
        worst_control = std::max(worst_control, std::fabs((coarse - exact) / exact));
        sum += r;
        sum_sq += r * r;
        ++counted;
      } else {
        worst_small = std::max(worst_small, std::fabs(exact - half) / peak);
      }
    }
    const double n = static_cast<double>(std::max<int64_t>(counted, 1));
    std::printf("[halves] level %d: %lld of 2e5 lookups >= 2^-16 peak: max |rel error| %.3g, lowest %.3g, mean %.3g, "
                "rms %.3g (control, 8-bit mantissa: max %.3g); below: max |error| / peak %.3g\n",
                level, static_cast<long long>(counted), worst, lowest, sum / n, std::sqrt(sum_sq / n), worst_control,
                worst_small);
    EXPECT_GT(counted, 10000) << level;
    EXPECT_LE(worst, kBound) << level;
    EXPECT_GE(lowest, -kBelow) << level;
    EXPECT_LE(worst_small, 1.0 / (1 << 26)) << level;
    EXPECT_GT(worst_control, kBound) << level;
  }
}

// Level 0 as lookups read it (session 32, glintlevel0_32: glint::Level0Residual, a coarse ratio R = P / q' times the
// closed-form estimate q' per lookup, and P itself at 1 degree on the grazing forward corner) against the fp32
// 1-degree table it is derived from and against brute force, on tables across the range (GGX and Beckmann, roughness
// 0.15..0.8, gamma 1..5; the coarse (1, 3, 4)-degree ratio grid where alpha' >= 0.09, else the 1-degree one).
//  - Every 1-degree node (where the 1-degree table is exact): max |relative error| (P >= 1e-3 of its slice's peak).
//  - 2e5 random queries (a quarter with theta_o in 85..90, an eighth with theta_i in 85..90) against the 1-degree
//    table's trilinear lookup: rms and max relative error where P >= 1e-3 of the slice peak (the larger of the two
//    theta_i slices the lookup reads), absolute error / slice peak below. Part of this is the 1-degree table's own
//    interpolation error (its lerps across a lobe), which the estimate does not share.
//  - 300 random queries in the lobe (P >= 5 % of the slice peak) against brute force (the rim rule, else dense
//    quadrature of (1)): the level-0 lookup is at least as close as the 1-degree table (rms), up to the slices'
//    energy cap, which both carry.
// Negative control: P itself on the same coarse (1, 3, 4)-degree grid, trilinear (the representation without the
// estimate, at the same size): fails the random-query bounds and the brute-force comparison on the narrower tables.
struct Level0Figures {
  double node_max = 0.0, rms = 0.0, max_rel = 0.0, max_abs = 0.0;
  double brute_rms = 0.0, brute_rms_table = 0.0, brute_max = 0.0, brute_max_table = 0.0;
  float worst_node[3] = {}, worst_abs[3] = {};
};
using Level0Lookup = std::function<float(float, float, float)>;
Level0Figures level0_figures(const pg::DirectionalTable &table, const pg::NdfFunction &ndf, const Level0Lookup &at,
                             bool nodes) {
  const pg::LodLevel &l0 = table.levels[0];
  std::vector<float> slice_peak(pg::kThetaICount, 0.0f);
  for (size_t i = 0; i < l0.values.size(); ++i) {
    float &pk = slice_peak[i / l0.theta_i_stride()];
    pk = std::max(pk, l0.values[i]);
  }
  auto peak_at = [&](float ti) {
    const int i = std::min(static_cast<int>(ti), pg::kThetaICount - 2);
    return std::max(slice_peak[static_cast<size_t>(i)], slice_peak[static_cast<size_t>(i) + 1]);
  };
  Level0Figures f;
  for (int ti = 0; nodes && ti < pg::kThetaICount; ++ti)
    for (int to = 0; to <= 90; ++to)
      for (int dp = 0; dp <= 180; ++dp) {
        const double ref = l0.values[ti * l0.theta_i_stride() + static_cast<size_t>(to) * l0.n_phi + dp];
        if (!(ref >= 1e-3 * slice_peak[static_cast<size_t>(ti)])) continue;
        const double e = std::fabs(at(ti, to, dp) / ref - 1.0);
        if (e > f.node_max) f.node_max = e, f.worst_node[0] = ti, f.worst_node[1] = to, f.worst_node[2] = dp;
      }
  Pcg32 rng(32);
  double sum_sq = 0.0;
  int64_t counted = 0;
  for (int q = 0; q < 200000; ++q) {
    const float ti = q % 8 == 1 ? 85.0f + 5.0f * rng.next_float() : 90.0f * rng.next_float();
    const float to = q % 4 == 0 ? 85.0f + 5.0f * rng.next_float() : 90.0f * rng.next_float();
    const float dp = 180.0f * rng.next_float();
    const double ref = l0.lookup_exact(ti, to, dp), v = at(ti, to, dp), pk = peak_at(ti);
    if (ref >= 1e-3 * pk) {
      const double r = v / ref - 1.0;
      sum_sq += r * r;
      ++counted;
      f.max_rel = std::max(f.max_rel, std::fabs(r));
    } else {
      const double e = std::fabs(v - ref) / pk;
      if (e > f.max_abs) f.max_abs = e, f.worst_abs[0] = ti, f.worst_abs[1] = to, f.worst_abs[2] = dp;
    }
  }
  f.rms = std::sqrt(sum_sq / static_cast<double>(std::max<int64_t>(counted, 1)));
  double bs = 0.0, bt = 0.0;
  int n = 0;
  for (int q = 0; n < 300 && q < 200000; ++q) {
    const float ti = 85.0f * rng.next_float(), to = 90.0f * rng.next_float(), dp = 180.0f * rng.next_float();
    const double table_p = l0.lookup_exact(ti, to, dp);
    if (!(table_p >= 0.05 * peak_at(ti))) continue;
    double ref = pg::directional_probability_by_rim(table.spec.distribution, table.spec.alpha, table.spec.gamma_deg, ti,
                                                    to, dp);
    if (ref < 0.0) ref = pg::directional_probability_reference(ndf, table.spec.gamma_deg, ti, to, dp, 48);
    const double rn = at(ti, to, dp) / ref - 1.0, rt = table_p / ref - 1.0;
    bs += rn * rn, bt += rt * rt, ++n;
    f.brute_max = std::max(f.brute_max, std::fabs(rn));
    f.brute_max_table = std::max(f.brute_max_table, std::fabs(rt));
  }
  f.brute_rms = std::sqrt(bs / std::max(n, 1));
  f.brute_rms_table = std::sqrt(bt / std::max(n, 1));
  return f;
}

TEST(GlintTables, Level0ResidualMatchesTheOneDegreeTableAndBruteForce) {
  struct Case {
    mf::Distribution dist;
    float roughness, gamma;
  };
  constexpr double kRms = 0.01, kMax = 0.10, kAbs = 2e-3, kNode = 0.03;
  int control_failures = 0;
  for (const Case &c : {Case{mf::Distribution::GGX, 0.35f, 2.0f}, Case{mf::Distribution::Beckmann, 0.5f, 3.0f},
                        Case{mf::Distribution::GGX, 0.3f, 2.0f}, Case{mf::Distribution::Beckmann, 0.4f, 1.0f},
                        Case{mf::Distribution::GGX, 0.8f, 5.0f}, Case{mf::Distribution::GGX, 0.15f, 5.0f},
                        Case{mf::Distribution::Beckmann, 0.2f, 2.0f}}) {
    pg::TableSpec spec;
    spec.distribution = c.dist == mf::Distribution::GGX ? pg::BaseDistribution::GGX : pg::BaseDistribution::Beckmann;
    spec.alpha = c.roughness * c.roughness;
    spec.gamma_deg = c.gamma;
    const pg::NdfFunction ndf = ndf_of(c.dist, spec.alpha);
    const auto table = pg::build_directional_table(spec, ndf, 2);
    const bool coarse = table->level0.ratio.n_theta_o < 91;
    const Level0Figures f = level0_figures(
        *table, ndf, [&](float ti, float to, float dp) { return table->lookup(0.0f, ti, to, dp); }, true);
    pg::LodLevel plain;  // the control: P on the (1, 3, 4)-degree grid
    plain.set_grid(3, 4, pg::kThetaICount, 31, 46);
    plain.values.resize(pg::kThetaICount * plain.theta_i_stride());
    for (int ti = 0; ti < pg::kThetaICount; ++ti)
      for (int o = 0; o < 31; ++o)
        for (int p = 0; p < 46; ++p)
          plain.values[ti * plain.theta_i_stride() + static_cast<size_t>(o) * 46 + p] =
              table->levels[0].values[(static_cast<size_t>(ti) * 91 + 3 * o) * 181 + 4 * p];
    const Level0Figures k = level0_figures(
        *table, ndf, [&](float ti, float to, float dp) { return plain.lookup_exact(ti, to, dp); }, false);
    const char *name = c.dist == mf::Distribution::GGX ? "ggx" : "beckmann";
    std::printf("[level0] %s r=%.2f gamma %.0f (%s ratio grid, %.0f KB): nodes max %.4f; random rms %.4f max %.4f, abs "
                "%.2e; brute force rms %.4f (1-degree table %.4f) max %.4f (%.4f) | control (plain 1x3x4 grid): rms "
                "%.4f max %.4f abs %.2e, brute force rms %.4f max %.4f\n",
                name, c.roughness, c.gamma, coarse ? "1x3x4" : "1x1x1",
                (table->level0.ratio.halves.size() + table->level0.corner.halves.size()) * 2.0 / 1024.0, f.node_max,
                f.rms, f.max_rel, f.max_abs, f.brute_rms, f.brute_rms_table, f.brute_max, f.brute_max_table, k.rms,
                k.max_rel, k.max_abs, k.brute_rms, k.brute_max);
    std::printf("[level0]   worst node at (%.0f, %.0f, %.0f), worst absolute error at (%.2f, %.2f, %.2f)\n", f.worst_node[0],
                f.worst_node[1], f.worst_node[2], f.worst_abs[0], f.worst_abs[1], f.worst_abs[2]);
    EXPECT_LE(f.node_max, coarse ? kNode : 1.0 / 1024) << name << " " << c.roughness;
    if (coarse) {
      EXPECT_LE(f.rms, kRms) << name << " " << c.roughness;
      EXPECT_LE(f.max_rel, kMax) << name << " " << c.roughness;
    }
    EXPECT_LE(f.max_abs, kAbs) << name << " " << c.roughness;
    EXPECT_LE(f.brute_rms, f.brute_rms_table * 1.02 + 1e-4) << name << " " << c.roughness;
    EXPECT_LE(f.brute_max, f.brute_max_table + 0.005) << name << " " << c.roughness;
    control_failures += k.rms > kRms || k.max_rel > kMax || k.max_abs > kAbs || k.brute_rms > k.brute_rms_table * 1.02 + 1e-4;
    if (c.roughness <= 0.35f) {
      EXPECT_TRUE(k.rms > kRms || k.max_rel > kMax) << "control passes on " << name << " " << c.roughness;
    }
  }
  EXPECT_GE(control_failures, 5);
}

}  // namespace
}  // namespace glimmer::test
