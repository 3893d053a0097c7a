// Tests of the directional probability table (tables/glint_tables.*) against
// brute force: level 0 is P_gamma, the integral of the reflected-direction
// density q over the query cone (glint_tables.h equation (1)).
#include <gtest/gtest.h>

#include <cstdio>
#include <cstring>
#include <limits>
#include <vector>

#include "closures/closure_checks.h"
#include "closures/glint_test_util.h"
#include "tables/glint_tables.h"

namespace glimmer::test {
namespace {

namespace pg = plugin::glint;

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

}  // namespace
}  // namespace glimmer::test
