// Roughness below 0.15 (issue 10): the directional table (tables/glint_tables.*)
// against the exact probability that one particle of the reference's particle
// distribution reflects wi into the query cone, for lobes far narrower than
// the cone and than the table's 1-degree grid.
//
// The exact P is computed by brute force over the particle normals, not
// over the cone: P_gamma(wi, wo) = Pr[reflect(wi, m) within gamma of wo],
// m ~ D(m) cos(theta_m), i.e. the measure of the direction codes (u, v) of
// glint_jakob14's particles (ParticleHierarchy::reflects, the same test the
// reference applies to every particle) on a fine midpoint grid. A cone
// quadrature of q (the table's own route) needs points on the scale of the
// lobe; this one needs them on the scale of the cone's edge in code space.
#include <gtest/gtest.h>

#include <cstdio>
#include <vector>

#include "closures/closure_checks.h"
#include "closures/glint_test_util.h"
#include "glimmer/rng.h"
#include "tables/glint_hierarchy.h"
#include "tables/glint_tables.h"

namespace glimmer::test {
namespace {

namespace pg = plugin::glint;

const bool kCacheDirSet = cache_tables_in_build_folder();

// Closed form at wi = wo = N: the particle reflects within gamma of the
// normal when theta_m <= gamma / 2, whose probability under D cos is the
// slope CDF at t = tan(gamma / 2): GGX t^2 / (alpha^2 + t^2), Beckmann
// 1 - exp(-t^2 / alpha^2).
double normal_incidence_mass(mf::Distribution dist, double alpha, double gamma_rad) {
  const double t2 = sqr(std::tan(0.5 * gamma_rad)), a2 = alpha * alpha;
  return dist == mf::Distribution::GGX ? t2 / (a2 + t2) : -std::expm1(-t2 / a2);
}

// The brute force is itself validated: against the closed form at normal
// incidence (narrow lobes, where a cone quadrature of q fails), and against
// the dense cone quadrature of q off the normal for a lobe wider than the
// cone (where that quadrature converges). The midpoint grid resolves a
// band edge in u to 0.5 / n_u, so the tolerance is absolute, 1 / n_u.
// Negative control: the closed form of a particle whose normal, not its
// reflection, is within gamma (the factor 2 of the mirror forgotten)
// differs by more than 4 tolerances wherever P < 0.99.
TEST(GlintLowRoughness, LobeMassBruteForceMatchesClosedFormAndConeQuadrature) {
  constexpr int kNu = 4096;
  constexpr double kTolerance = 1.0 / kNu;
  const Vec3 n(0.0f, 0.0f, 1.0f);
  for (auto dist : {mf::Distribution::GGX, mf::Distribution::Beckmann})
    for (double roughness : {0.05, 0.1, 0.2})
      for (double gamma_deg : {0.5, 2.0}) {
        const double alpha = roughness * roughness, gamma = gamma_deg * M_PI / 180.0;
        const double exact = normal_incidence_mass(dist, alpha, gamma);
        const double brute = LobeMassInCone(dist, alpha, kNu, 1024)(n, n, gamma);
        const double control = normal_incidence_mass(dist, alpha, 2.0 * gamma);
        std::printf("[lowr] normal incidence %s r=%.2f gamma %.1f: brute force %.6f, closed form %.6f (control %.6f)\n",
                    dist == mf::Distribution::GGX ? "ggx" : "beckmann", roughness, gamma_deg, brute, exact, control);
        EXPECT_NEAR(brute, exact, kTolerance) << roughness << " " << gamma_deg;
        if (exact < 0.99) {  // (Beckmann's narrowest lobe lies wholly in both cones)
          EXPECT_GT(std::fabs(control - brute), 4.0 * kTolerance) << roughness << " " << gamma_deg;
        }
      }
  const double alpha = 0.3 * 0.3;
  const LobeMassInCone lobe(mf::Distribution::GGX, alpha, kNu, 2048);
  for (double ti : {0.0, 40.0, 75.0})
    for (double dphi : {180.0, 176.0})
      for (double d_to : {0.0, 3.0}) {
        const Vec3 wi = spherical_dir(ti, 0.0), wo = spherical_dir(ti + d_to, dphi);
        const double quadrature =
            pg::directional_probability_reference(ndf_of(mf::Distribution::GGX, static_cast<float>(alpha)), 2.0, ti, ti + d_to, dphi, 96);
        EXPECT_NEAR(lobe(wi, wo, 2.0 * M_PI / 180.0), quadrature, kTolerance) << ti << " " << dphi << " " << d_to;
      }
}

// The rim rule (Green's theorem over the image of the cone's rim, the
// table's rule below roughness 0.15) against the brute-force lobe mass, at
// and around the mirror direction and on the cone's edge, every incidence.
TEST(GlintLowRoughness, RimRuleMatchesBruteForceLobeMass) {
  Pcg32 rng(3);
  double worst = 0.0;
  for (auto dist : {mf::Distribution::GGX, mf::Distribution::Beckmann})
    for (double roughness : {0.05, 0.1, 0.3})
      for (double gamma_deg : {0.5, 2.0, 5.0}) {
        const double alpha = roughness * roughness;
        const LobeMassInCone lobe(dist, alpha, 2048, 1024);
        const auto bd = dist == mf::Distribution::GGX ? pg::BaseDistribution::GGX : pg::BaseDistribution::Beckmann;
        for (int k = 0; k < 6; ++k) {
          const double ti = 85.0 * rng.next_double();
          const double reach = gamma_deg + 2.0 * alpha * 180.0 / M_PI;
          const double to = std::clamp(ti + reach * (2.0 * rng.next_double() - 1.0), 0.0, 89.0);
          const double dphi = 180.0 - reach * rng.next_double() / std::max(std::sin(ti * M_PI / 180.0), 0.2);
          const double rim = pg::directional_probability_by_rim(bd, alpha, gamma_deg, ti, to, dphi);
          const double brute = lobe(spherical_dir(ti, 0.0), spherical_dir(to, dphi), gamma_deg * M_PI / 180.0);
          if (rim < 0.0) continue;
          worst = std::max(worst, std::fabs(rim - brute));
          EXPECT_NEAR(rim, brute, 2e-3) << roughness << " " << gamma_deg << " " << ti << " " << to << " " << dphi;
        }
      }
  std::printf("[rim] largest |rim - brute force| %.2e\n", worst);
}

// Level 0 of the table against the brute-force lobe mass over the lobe
// core (exact P >= `core` of its peak), at table nodes and between them,
// for the theta_i slices `slices`. Per slice the node ratio P_table / P_exact
// is a constant (the energy cap of the build's step 4 scales a whole slice
// down) times 1 + shape error.
struct TableError {
  double node_worst = 0.0;                         // largest |P_table / P_exact - 1| at nodes
  double shape = 0.0;                              // largest max/min - 1 of the node ratio within a slice
  double lowest_scale = 1.0, highest_scale = 0.0;  // range of the slices' largest node ratios
  double between_worst = 0.0, between_rms = 0.0;  // |P_table / P_exact - 1| between nodes
};

TableError table_error(const pg::DirectionalTable &table, mf::Distribution dist, double alpha, double gamma_deg,
                       const std::vector<int> &slices, int between_per_slice, bool print, int n_u = 2048) {
  constexpr double kCore = 0.2;
  const LobeMassInCone lobe(dist, alpha, n_u, n_u / 2);
  const double gamma = gamma_deg * M_PI / 180.0;
  const double reach = gamma_deg + 4.0 * std::max(alpha * 180.0 / M_PI, 0.5);  // degrees around the mirror direction
  TableError e;
  Pcg32 rng(41);
  double sum2 = 0.0;
  int n_between = 0;
  for (int ti : slices) {
    const Vec3 wi = spherical_dir(ti, 0.0);
    const double peak = lobe(wi, spherical_dir(ti, 180.0), gamma);
    const double dphi_reach = reach / std::max(std::sin(ti * M_PI / 180.0), 0.2);
    auto table_p = [&](double to, double dphi) {
      return table.levels[0].lookup(static_cast<float>(ti), static_cast<float>(to), static_cast<float>(dphi));
    };
    double lo = 1e30, hi = 0.0;
    // Nodes: theta_o and dphi at whole degrees around the mirror direction.
    for (int d_to = -static_cast<int>(reach); d_to <= static_cast<int>(reach); ++d_to)
      for (int dphi = 180; dphi >= 180 - static_cast<int>(dphi_reach); --dphi) {
        const int to = ti + d_to;
        if (to < 0 || to > 89) continue;
        const double exact = lobe(wi, spherical_dir(to, dphi), gamma);
        if (!(exact >= kCore * peak)) continue;
        const double ratio = table_p(to, dphi) / exact;
        e.node_worst = std::max(e.node_worst, std::fabs(ratio - 1.0));
        lo = std::min(lo, ratio);
        hi = std::max(hi, ratio);
      }
    e.shape = std::max(e.shape, hi / lo - 1.0);
    e.lowest_scale = std::min(e.lowest_scale, hi);
    e.highest_scale = std::max(e.highest_scale, hi);
    // Between nodes: random (theta_o, dphi) within reach of the mirror
    // direction, theta_i on the node (its interpolation is the same rule).
    for (int k = 0; k < between_per_slice; ++k) {
      const double to = ti + reach * (2.0 * rng.next_double() - 1.0);
      const double dphi = 180.0 - dphi_reach * rng.next_double();
      if (to < 0.0 || to > 89.0) continue;
      const double exact = lobe(wi, spherical_dir(to, dphi), gamma);
      if (!(exact >= kCore * peak)) continue;
      const double rel = table_p(to, dphi) / exact - 1.0;
      e.between_worst = std::max(e.between_worst, std::fabs(rel));
      sum2 += rel * rel;
      ++n_between;
    }
    if (print) std::printf("[lowr]   theta_i %2d: peak P %.4f, nodes table/exact %.4f..%.4f\n", ti, peak, lo, hi);
  }
  e.between_rms = n_between > 0 ? std::sqrt(sum2 / n_between) : 0.0;
  return e;
}

pg::TableSpec table_spec(mf::Distribution dist, double roughness, double gamma_deg) {
  pg::TableSpec spec;
  spec.distribution = dist == mf::Distribution::GGX ? pg::BaseDistribution::GGX : pg::BaseDistribution::Beckmann;
  spec.alpha = static_cast<float>(roughness * roughness);
  spec.gamma_deg = static_cast<float>(gamma_deg);
  return spec;
}

// Where the lobe is too narrow for the interior cone rule (roughness 0.15 at
// gamma 5 degrees near grazing: an axis would need 27..70 points, capped at
// 24; the nodes were off by -10..+6 % at theta_i 80), the table uses the rim
// rule: level 0's nodes equal the brute-force lobe mass within 0.5 % in shape
// over the lobe core, up to the energy cap's per-slice scale (>= 0.98).
// Negative control: the same table against the lobe of 1.1 alpha differs in
// shape by > 2 %.
TEST(GlintLowRoughness, TableNodesEqualLobeMassWhereTheInteriorRuleRunsOutOfPoints) {
  const pg::TableSpec spec = table_spec(mf::Distribution::GGX, 0.15, 5.0);
  const auto table = pg::build_directional_table(spec, ndf_of(mf::Distribution::GGX, spec.alpha), 2);
  const std::vector<int> slices = {0, 40, 70, 80};
  const TableError e = table_error(*table, mf::Distribution::GGX, spec.alpha, 5.0, slices, 0, true, 1024);
  const TableError control = table_error(*table, mf::Distribution::GGX, 1.1 * spec.alpha, 5.0, slices, 0, false, 1024);
  std::printf("[lowr] ggx r=0.15 gamma 5: node shape %.4f (control, 1.1 alpha: %.4f), slice scales %.4f..%.4f; "
              "built in %.1f s\n",
              e.shape, control.shape, e.lowest_scale, e.highest_scale, table->build_seconds);
  EXPECT_LE(e.shape, 0.005);
  EXPECT_LE(e.highest_scale, 1.005);
  EXPECT_GE(e.lowest_scale, 0.98);
  EXPECT_GT(control.shape, 0.02);
}

// The measurement behind docs/glints.md "Roughness below 0.15" (not part of
// make test: ~30 tables): GLIMMER_LOWR_MEASURE=1, optionally
// GLIMMER_LOWR_ROUGHNESS=<one roughness>.
TEST(GlintLowRoughness, MeasureTableAccuracy) {
  if (std::getenv("GLIMMER_LOWR_MEASURE") == nullptr) GTEST_SKIP() << "measurement only";
  for (auto dist : {mf::Distribution::GGX, mf::Distribution::Beckmann})
    for (double roughness : {0.2, 0.15, 0.12, 0.1, 0.07, 0.05})
      for (double gamma_deg : {2.0, 0.5, 5.0}) {
        if (dist == mf::Distribution::Beckmann && gamma_deg != 2.0) continue;
        if (const char *only = std::getenv("GLIMMER_LOWR_ROUGHNESS"); only && std::atof(only) != roughness) continue;
        const pg::TableSpec spec = table_spec(dist, roughness, gamma_deg);
        const auto table = pg::build_directional_table(spec, ndf_of(dist, spec.alpha), 2);
        const std::vector<int> slices = {0, 10, 20, 30, 40, 50, 60, 70, 80};
        const TableError e = table_error(*table, dist, spec.alpha, gamma_deg, slices, 60, true);
        std::printf("[lowr] %s r=%.2f gamma %.1f: nodes worst %.4f (shape %.4f, slice scales %.4f..%.4f), between "
                    "nodes worst %.4f rms %.4f (built %.1f s)\n",
                    dist == mf::Distribution::GGX ? "ggx" : "beckmann", roughness, gamma_deg, e.node_worst, e.shape,
                    e.lowest_scale, e.highest_scale, e.between_worst, e.between_rms, table->build_seconds);
        std::fflush(stdout);
      }
}

}  // namespace
}  // namespace glimmer::test
