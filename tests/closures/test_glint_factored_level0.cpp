// Tests of the factored level 0 (tables/glint_factored_level0.h): level 0 read as the analytic lobe A times a
// residual R on 2-degree nodes, where the table covers (theta_i <= 80). Its accuracy against the
// brute-force cone integral, against the 1-degree level 0 it replaces and with a negative control (the same 2-degree
// nodes without the lobe factored out); its W-weighted energy per theta_i slice; finite, non-negative values at the
// extremes.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "closures/glint_test_util.h"
#include "glimmer/rng.h"
#include "tables/glint_peak.h"
#include "tables/glint_tables.h"

namespace glimmer::test {
namespace {

namespace pg = plugin::glint;

struct Spec {
  const char *name;
  mf::Distribution dist;
  float alpha, gamma_deg;
};
// The GI scene's two tables (examples/glint.xml), the per-eval benchmark's, and a wide lobe.
const Spec kSpecs[] = {{"ggx a0.1225 g2", mf::Distribution::GGX, 0.1225f, 2.0f},
                       {"beckmann a0.25 g3", mf::Distribution::Beckmann, 0.25f, 3.0f},
                       {"ggx a0.16 g2", mf::Distribution::GGX, 0.16f, 2.0f},
                       {"ggx a0.64 g5", mf::Distribution::GGX, 0.64f, 5.0f}};

std::unique_ptr<pg::DirectionalTable> table_of(const Spec &s) {
  pg::TableSpec spec;
  spec.distribution = s.dist == mf::Distribution::GGX ? pg::BaseDistribution::GGX : pg::BaseDistribution::Beckmann;
  spec.alpha = s.alpha;
  spec.gamma_deg = s.gamma_deg;
  return pg::build_directional_table(spec, ndf_of(s.dist, s.alpha), 2);
}

struct ErrorStats {
  double mean = 0.0, p99 = 0.0, max = 0.0;
};
ErrorStats stats_of(std::vector<double> e) {
  ErrorStats s;
  if (e.empty()) return s;
  for (double x : e) s.mean += x;
  s.mean /= static_cast<double>(e.size());
  std::sort(e.begin(), e.end());
  s.p99 = e[static_cast<size_t>(0.99 * static_cast<double>(e.size() - 1))];
  s.max = e.back();
  return s;
}

// Relative errors against the cone integral (48 rings) of the 1-degree lookup, the factored lookup and the control
// (plain 2-degree subsample of level 0), at queries over the covered domain: theta_i uniform in 0..80, half of them
// with wo anywhere (theta_o 0..90, every azimuth) and half around the mirror direction; counted where P > 1e-3 of
// the slice's peak.
TEST(GlintFactoredLevel0, AtLeastAsAccurateAsTheOneDegreeTableOverAllAzimuths) {
  for (const Spec &s : kSpecs) {
    const auto table = table_of(s);
    ASSERT_TRUE(table->factored0.active()) << s.name;
    pg::LodLevel control;  // the negative control: level 0's P on the same 2-degree theta_o / dphi nodes
    control.set_step(2);
    control.values.resize(static_cast<size_t>(pg::kThetaICount) * control.n_theta_o * control.n_phi);
    const pg::LodLevel &l0 = table->levels[0];
    for (int ti = 0; ti < pg::kThetaICount; ++ti)
      for (int o = 0; o < control.n_theta_o; ++o)
        for (int p = 0; p < control.n_phi; ++p)
          control.values[(static_cast<size_t>(ti) * control.n_theta_o + o) * control.n_phi + p] =
              l0.values[(static_cast<size_t>(ti) * l0.n_theta_o + 2 * o) * l0.n_phi + 2 * p];
    control.pack_halves();
    const pg::NdfFunction ndf = ndf_of(s.dist, s.alpha);
    // As the closure reads it at zero blur: clamped to the dark test's bound (glint.cpp, table_probability).
    const pg::DirectionalPeakTable bounds(*table, s.gamma_deg);
    int clamped = 0;
    double worst_over_bound = 0.0;
    Pcg32 rng(42);
    std::vector<double> e_today, e_factored, e_control;
    for (int q = 0; q < 1500; ++q) {
      const double ti = 80.0 * rng.next_float();
      double to, dp;
      if (q % 2 == 0) {
        to = 90.0 * rng.next_float();
        dp = 180.0 * rng.next_float();
      } else {  // around the mirror direction, a few lobe widths
        const double width = 4.0 * s.alpha * 57.29578 + 2.0 * s.gamma_deg;
        to = std::clamp(ti + width * (2.0 * rng.next_float() - 1.0), 0.0, 90.0);
        dp = 180.0 - width * rng.next_float();
      }
      const double truth = pg::directional_probability_reference(ndf, s.gamma_deg, ti, to, dp, 48);
      const double peak = pg::directional_probability_reference(ndf, s.gamma_deg, ti, ti, 180.0, 48);
      if (!(truth > 1e-3 * peak)) continue;
      const float fi = static_cast<float>(ti), fo = static_cast<float>(to), fp = static_cast<float>(dp);
      ASSERT_TRUE(pg::FactoredLevel0::covers(fi, fo));
      e_today.push_back(std::fabs(l0.lookup(fi, fo, fp) / truth - 1.0));
      const float factored = table->factored0.lookup_angles(fi, fo, fp), bound = bounds.bound(fi, fo, fp);
      clamped += factored > bound;
      worst_over_bound = std::max(worst_over_bound, static_cast<double>(factored) / bound - 1.0);
      e_factored.push_back(std::fabs(std::min(factored, bound) / truth - 1.0));
      e_control.push_back(std::fabs(control.lookup(fi, fo, fp) / truth - 1.0));
    }
    const ErrorStats t = stats_of(e_today), f = stats_of(e_factored), c = stats_of(e_control);
    std::printf(
        "[factored] %-18s %4zu queries: rel err mean / p99 / max: 1-degree %.4f / %.4f / %.4f, factored "
        "%.4f / %.4f / %.4f, control (2-degree P) %.4f / %.4f / %.4f; clamped to the dark test's bound at %d "
        "(by up to %.4f)\n",
        s.name, e_today.size(), t.mean, t.p99, t.max, f.mean, f.p99, f.max, c.mean, c.p99, c.max, clamped,
        worst_over_bound);
    ASSERT_GT(e_today.size(), 500u) << s.name;
    // At most the 1-degree table's error, up to the slices' energy scale (<= ~2e-4 of P; for wide lobes both read the
    // integral within ~2e-4 and their means differ only by it), and no error over 5 %.
    auto passes = [&](const ErrorStats &x) {
      return x.mean <= t.mean + 1e-4 && x.p99 <= t.p99 + 1e-4 && x.max <= 0.05;
    };
    EXPECT_TRUE(passes(f)) << s.name;
    // The control fails what the factored level passes: the 2-degree nodes alone are not accurate enough.
    EXPECT_FALSE(passes(c)) << s.name;
  }
}

// W-weighted energy E = Int W P dwo of a theta_i slice (midpoint rule on a 0.25-degree grid: not the 0.5-degree grid
// the table's own scales are computed on), through the closure's reads: factored where covered, 1-degree elsewhere.
double slice_energy(const pg::DirectionalTable &table, const pg::FactoredLevel0 &factored, const Spec &s, int ti,
                    bool through_factored) {
  const Vec3 wi(std::sin(ti * 0.017453292f), 0.0f, std::cos(ti * 0.017453292f));
  double e = 0.0;
  for (int t = 0; t < 360; ++t)
    for (int p = 0; p < 720; ++p) {
      const float to = (t + 0.5f) * 0.25f, dp = (p + 0.5f) * 0.25f;
      const Vec3 wo(std::sin(to * 0.017453292f) * std::cos(dp * 0.017453292f),
                    std::sin(to * 0.017453292f) * std::sin(dp * 0.017453292f), std::cos(to * 0.017453292f));
      Vec3 h;
      if (!mf::half_vector_reflect(wi, wo, h)) continue;
      const float wi_h = dot(wi, h);
      if (!(wi_h > 0.0f) || !(h.z > 0.0f)) continue;
      const double w = mf::G2(s.dist, wi, wo, s.alpha, s.alpha) * wi_h / (wi.z * h.z) * std::sin(to * 0.017453292f);
      const bool f = through_factored && pg::FactoredLevel0::covers(static_cast<float>(ti), to);
      e += w * (f ? factored.lookup_angles(static_cast<float>(ti), to, dp)
                  : table.levels[0].lookup_exact(static_cast<float>(ti), to, dp));
    }
  return e;
}

// Each slice reads level 0's energy (nodes scaled, the slices between them interpolated) (the blurred levels are
// normalised to level 0's, and the white furnace caps level 0's at the smooth albedo); the nodes' R without the
// normalisation do not (control).
TEST(GlintFactoredLevel0, SliceEnergyEqualsTheOneDegreeLevels) {
  for (const Spec &s : {kSpecs[0], kSpecs[1]}) {
    const auto table = table_of(s);
    const pg::FactoredLevel0 raw(table->levels[0], table->spec, table->cone_solid_angle(), false);
    double worst = 0.0, worst_raw = 0.0;
    for (int ti : {0, 1, 41, 60, 79, 80}) {  // nodes of R (even) and slices between them (odd)
      const double e0 = slice_energy(*table, table->factored0, s, ti, false);
      const double ef = slice_energy(*table, table->factored0, s, ti, true);
      const double er = slice_energy(*table, raw, s, ti, true);
      std::printf(
          "[factored] %-18s theta_i %2d: energy 1-degree %.5f factored %.5f (%+.4f %%) unnormalised %.5f "
          "(%+.4f %%)\n",
          s.name, ti, e0, ef, 100.0 * (ef / e0 - 1.0), er, 100.0 * (er / e0 - 1.0));
      worst = std::max(worst, std::fabs(ef / e0 - 1.0));
      worst_raw = std::max(worst_raw, std::fabs(er / e0 - 1.0));
    }
    EXPECT_LE(worst, 5e-4) << s.name;
    EXPECT_GT(worst_raw, 2.0 * worst) << s.name << ": the control does not differ";
  }
}

// The lobe A and the lookups: finite and non-negative at grazing wi.h and theta_h, every alpha the table allows.
TEST(GlintFactoredLevel0, LobeFiniteAndNonNegativeAtTheExtremes) {
  const float tiny[] = {0.0f, 1e-30f, 1e-6f, 1e-3f, 0.05f, 0.5f, 1.0f};
  int checked = 0;
  for (bool ggx : {true, false})
    for (float alpha : {0.0225f, 0.1f, 0.5f, 1.0f})
      for (float gamma_deg : {0.5f, 2.0f, 10.0f}) {
        const double g = gamma_deg * 0.017453292519943295;
        const pg::Level0Lobe lobe(ggx, alpha, g, 6.283185307179586 * (1.0 - std::cos(g)));
        for (float wi_h : tiny)
          for (float cos_h : tiny) {
            const float a = lobe(wi_h, cos_h);
            EXPECT_TRUE(std::isfinite(a) && a >= 0.0f) << ggx << " " << alpha << " " << wi_h << " " << cos_h;
            const double ad = lobe.at(wi_h, cos_h);
            EXPECT_TRUE(std::isfinite(ad) && ad >= 0.0) << ggx << " " << alpha << " " << wi_h << " " << cos_h;
            ++checked;
          }
      }
  EXPECT_EQ(checked, 2 * 4 * 3 * 49);
}

}  // namespace
}  // namespace glimmer::test
