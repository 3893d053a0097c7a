// The glint statistics of issue 10 (closures/glint_statistics.h), measured
// on `glint` and on the exact reference `glint_jakob14` over a grid of
// particles per footprint (10, 100, 1000), roughness (0.2, 0.5) and
// incidence (0..80 degrees). `make test` runs the grazing corners of the grid
// (GGX, both roughnesses, 10 and 1000 particles per footprint, incidence 80
// degrees: the rows nearest a bound in every earlier session, see
// docs/glints.md "Statistics"); `make stress` (GLIMMER_STRESS=1) runs the
// whole grid: normal incidence, 100 particles, 20, 40 and 60 degrees,
// Beckmann, and 4x the footprints.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "closures/glint_statistics.h"

namespace glimmer::test {
namespace {

using glint_stats::Config;

const bool kCacheDirSet = cache_tables_in_build_folder();

// The harness against closed forms, on the exact reference: lit counts
// decorrelate as the two cones stop overlapping (planar overlap of two
// discs of radius gamma at distance gamma: 0.391; none at 2 gamma), nested
// footprints correlate as sqrt(a1 / a2) = 0.958 and never lose particles,
// the mean is the cone-averaged smooth BRDF, and the closed-form per-footprint
// albedo agrees with the Monte Carlo estimator applied to the reference.
TEST(GlintStatistics, ReferenceMatchesClosedForms) {
  Config cfg;
  cfg.roughness = 0.5;
  cfg.per_footprint = 1000;
  cfg.theta_i_deg = 30;
  auto ref = make_closure("glint_jakob14", cfg.params(true));
  const int n = 1500;
  const double c1 = glint_stats::lit_correlation(*ref, cfg, cfg.gamma(), n);
  const double c2 = glint_stats::lit_correlation(*ref, cfg, 2 * cfg.gamma(), n);
  const glint_stats::Doubling d = glint_stats::doubling(*ref, cfg, n);
  const glint_stats::MeanRatio m = glint_stats::mean_ratio(*ref, cfg, n);
  const double cv_closed = glint_stats::reference_albedo_cv(cfg, 400);
  Config sparse = cfg;
  sparse.per_footprint = 10;
  auto ref_sparse = make_closure("glint_jakob14", sparse.params(true));
  const double cv_closed_sparse = glint_stats::reference_albedo_cv(sparse, 400);
  const double cv_mc_sparse = glint_stats::albedo_cv(*ref_sparse, sparse, 400, 1024);
  std::printf("[stats] reference: lit corr gamma %.3f (0.391), 2 gamma %.3f (0); doubling corr %.3f (0.958) drops %.3f "
              "(0); mean ratio %.4f +- %.4f; albedo cv closed form %.4f (1/sqrt(n) %.4f), n=10: closed form %.3f, "
              "Monte Carlo %.3f\n",
              c1, c2, d.correlation, d.drop_fraction, m.ratio, m.standard_error, cv_closed, 1.0 / std::sqrt(1000.0),
              cv_closed_sparse, cv_mc_sparse);
  EXPECT_NEAR(c1, 0.391, 0.1);
  EXPECT_NEAR(c2, 0.0, 0.1);
  EXPECT_NEAR(d.correlation, std::sqrt(std::exp2(-0.125)), 0.03);
  EXPECT_EQ(d.drop_fraction, 0.0);
  EXPECT_NEAR(m.ratio, 1.0, 4.0 * m.standard_error + 0.01);
  EXPECT_NEAR(cv_mc_sparse, cv_closed_sparse, 0.25 * cv_closed_sparse);
}

// The albedo CV estimator of the grid (split-half covariance, albedo_cv)
// does not depend on the Monte Carlo noise: on glint at roughness 0.2,
// theta_i 80, 1000 particles per footprint (the Monte Carlo noise of 1024
// samples exceeds the footprints' spread) the estimates at 32^2 and 64^2
// samples per half agree within 30 %. Negative control: the former
// estimator (the i.i.d. Monte Carlo variance subtracted from one estimate;
// the samples are stratified, so it over-subtracts) reads less than half of
// it at 32^2 samples.
TEST(GlintStatistics, AlbedoCvEstimatorIsUnbiased) {
  Config cfg;
  cfg.roughness = 0.2;
  cfg.per_footprint = 1000;
  cfg.theta_i_deg = 80;
  auto model = make_closure("glint", cfg.params(false));
  const int footprints = 300;
  const double coarse = glint_stats::albedo_cv(*model, cfg, footprints, 1024);
  const double fine = glint_stats::albedo_cv(*model, cfg, footprints, 4096);
  const double subtracted = glint_stats::albedo_cv(*model, cfg, footprints, 1024,
                                                   glint_stats::AlbedoCvEstimator::SubtractedVariance);
  std::printf("[stats] albedo cv (r 0.2, 1000 particles, 80 deg): split half 2 x 1024 samples %.4f, 2 x 4096 %.4f; "
              "subtracted variance 1024 %.4f\n", coarse, fine, subtracted);
  EXPECT_NEAR(coarse, fine, 0.3 * fine);
  EXPECT_LT(subtracted, 0.5 * fine);
}

struct Row {
  Config cfg;
  double corr[3][2];  // separations gamma, 2 gamma, 4 gamma; [model, reference]
  double cv[2];
  glint_stats::Doubling doubling[2];
  glint_stats::MeanRatio mean;
};

// The acceptance lines of issue 10, every one on every row (the lit-set
// correlation at gamma at roughness 0.2 since the pseudo-normals of narrow
// lobes, tables/glint_pseudo_normals.h: 0.23..0.36 against 0.43..0.47
// before, with the direction cells). The mean is asserted on every row (at roughness
// 0.2 it was 2.7..6.9 % low before the table integrated P over the cone
// directly, tables/glint_tables.cpp), and the albedo CV on every row since
// the split-half estimator (glint_statistics.h, albedo_cv: the former
// estimator read the CV up to 1.55x low at 80 degrees).
void expect_acceptance(const Row &r) {
  const std::string where = r.cfg.name();
  EXPECT_NEAR(r.corr[1][0], r.corr[1][1], 0.1) << where << ": lit-set correlation at 2 gamma";
  EXPECT_NEAR(r.corr[2][0], r.corr[2][1], 0.1) << where << ": lit-set correlation at 4 gamma";
  EXPECT_NEAR(r.mean.ratio, 1.0, 0.01 + 3.0 * r.mean.standard_error) << where << ": mean";
  EXPECT_NEAR(r.corr[0][0], r.corr[0][1], 0.1) << where << ": lit-set correlation at gamma";
  EXPECT_LE(r.cv[0], 1.5 * r.cv[1]) << where << ": albedo coefficient of variation";
  EXPECT_GE(r.cv[0], r.cv[1] / 1.5) << where << ": albedo coefficient of variation";
  EXPECT_GE(r.doubling[0].correlation, 0.9) << where << ": count correlation across a level boundary";
  EXPECT_EQ(r.doubling[0].drop_fraction, 0.0) << where << ": counts dropping as the footprint grows";
}

// Rows [first, last] of the grid (0-based, in its loop order; printed as
// "row k") from GLIMMER_STATS_GRID_ROWS="first-last", so the stress grid
// (~1 h on one core once the tables are cached) can be run in pieces or in parallel; unset: all rows.
bool grid_row_wanted(int index) {
  const char *range = std::getenv("GLIMMER_STATS_GRID_ROWS");
  if (range == nullptr) return true;
  int first = 0, last = 0;
  if (std::sscanf(range, "%d-%d", &first, &last) != 2) {
    ADD_FAILURE() << "GLIMMER_STATS_GRID_ROWS=" << range << ": expected first-last, e.g. 0-14";
    return false;
  }
  return index >= first && index <= last;
}

std::vector<Row> measure_grid(bool full) {
  std::vector<Row> rows;
  const int n = full ? 4000 : 1000;
  int index = -1;
  for (auto dist : {mf::Distribution::GGX, mf::Distribution::Beckmann}) {
    if (!full && dist == mf::Distribution::Beckmann) continue;
    for (double roughness : {0.2, 0.5})
      for (double per_footprint : {10.0, 100.0, 1000.0})
        for (double theta_i : {0.0, 20.0, 40.0, 60.0, 80.0}) {
          // make test: the four 80-degree corners (the rows nearest a bound in every session) and two at normal
          // incidence (session 39: the cells' chart where the plane of incidence is undefined, and the pseudo-normals).
          const bool corner = per_footprint != 100.0 && theta_i == 80.0;
          const bool normal = theta_i == 0.0 && ((roughness == 0.2 && per_footprint == 10.0) ||
                                                 (roughness == 0.5 && per_footprint == 1000.0));
          if (!full && !corner && !normal) continue;
          if (!grid_row_wanted(++index)) continue;
          Row r{};
          r.cfg.dist = dist;
          r.cfg.roughness = roughness;
          r.cfg.per_footprint = per_footprint;
          r.cfg.theta_i_deg = theta_i;
          auto model = make_closure("glint", r.cfg.params(false));
          auto ref = make_closure("glint_jakob14", r.cfg.params(true));
          // Sparse footprints need more of them for a stable correlation.
          const int corr_footprints = 4 * n * std::max(1, static_cast<int>(100.0 / per_footprint));
          for (int k = 0; k < 3; ++k) {
            const double d = (1 << k) * r.cfg.gamma();
            r.corr[k][0] = glint_stats::lit_correlation(*model, r.cfg, d, corr_footprints);
            r.corr[k][1] = glint_stats::lit_correlation(*ref, r.cfg, d, corr_footprints);
          }
          r.cv[0] = glint_stats::albedo_cv(*model, r.cfg, n / 5, 4096);
          r.cv[1] = glint_stats::reference_albedo_cv(r.cfg, n / 4);
          r.doubling[0] = glint_stats::doubling(*model, r.cfg, n);
          r.doubling[1] = glint_stats::doubling(*ref, r.cfg, n);
          r.mean = glint_stats::mean_ratio(*model, r.cfg, 4 * n);
          std::printf("[stats] row %2d %-32s corr g %.2f/%.2f 2g %.2f/%.2f 4g %.2f/%.2f | albedo cv %.3f/%.3f | doubling "
                      "%.3f/%.3f drops %.2f/%.2f | mean %.3f+-%.3f\n",
                      index, r.cfg.name().c_str(), r.corr[0][0], r.corr[0][1], r.corr[1][0], r.corr[1][1], r.corr[2][0],
                      r.corr[2][1], r.cv[0], r.cv[1], r.doubling[0].correlation, r.doubling[1].correlation,
                      r.doubling[0].drop_fraction, r.doubling[1].drop_fraction, r.mean.ratio, r.mean.standard_error);
          std::fflush(stdout);
          rows.push_back(r);
          expect_acceptance(r);
        }
  }
  return rows;
}

// Model/reference figures over the grid (printed; docs/glints.md), asserted
// by expect_acceptance. The model before issue 10 (position-only randomness,
// an independent field per level) fails every line: lit-set correlation
// 0.9..1.0 at 4 gamma, albedo CV 3..30x, count correlation ~0 across a level
// boundary with 3..40 % drops.
TEST(GlintStatistics, ModelVersusReferenceGrid) { measure_grid(false); }

// Measurement of chosen rows over several realisations (particle seeds),
// for decisions (docs/glints.md "Statistics"): the mean and standard error
// over the seeds of each statistic. Skipped unless GLIMMER_STATS_ROWS is set,
// e.g. GLIMMER_STATS_ROWS="0.2:1000:80,b0.5:10:80" (roughness:particles:theta_i,
// GGX; a leading b: Beckmann);
// GLIMMER_STATS_SEEDS (default 4), GLIMMER_STATS_SCALE (footprints x, default
// 1), GLIMMER_STATS_REF=1 to measure the reference too, GLIMMER_STATS_SAMPLES
// (albedo samples per footprint and half, default 4096),
// GLIMMER_STATS_CV_SUBTRACTED=1 for the former albedo CV estimator,
// GLIMMER_STATS_WHAT (any of "corr,cv,doubling,mean"; default all).
TEST(GlintStatistics, MeasureRows) {
  const char *rows_env = std::getenv("GLIMMER_STATS_ROWS");
  if (rows_env == nullptr) GTEST_SKIP() << "set GLIMMER_STATS_ROWS to measure";
  const auto env_int = [](const char *name, int fallback) {
    const char *v = std::getenv(name);
    return v != nullptr ? std::atoi(v) : fallback;
  };
  const int seeds = std::max(env_int("GLIMMER_STATS_SEEDS", 4), 1);
  const double scale = std::getenv("GLIMMER_STATS_SCALE") ? std::atof(std::getenv("GLIMMER_STATS_SCALE")) : 1.0;
  const bool with_ref = env_int("GLIMMER_STATS_REF", 0) != 0;
  const int samples = env_int("GLIMMER_STATS_SAMPLES", 4096);
  const std::string what = std::getenv("GLIMMER_STATS_WHAT") ? std::getenv("GLIMMER_STATS_WHAT") : "corr,cv,doubling,mean";
  const auto wants = [&](const char *k) { return what.find(k) != std::string::npos; };
  std::string rows = rows_env;
  size_t at = 0;
  while (at < rows.size()) {
    const size_t end = std::min(rows.find(',', at), rows.size());
    std::string row = rows.substr(at, end - at);
    at = end + 1;
    const bool beckmann = !row.empty() && row[0] == 'b';  // "b0.5:10:80": Beckmann
    if (beckmann) row.erase(0, 1);
    double r = 0, n = 0, t = 0;
    if (std::sscanf(row.c_str(), "%lf:%lf:%lf", &r, &n, &t) != 3) continue;
    const int base = static_cast<int>(1000 * scale);
    // statistic k (corr g, 2g, 4g, cv, doubling, mean) of model [0] and reference [1] per seed
    std::vector<double> v[6][2];
    for (int s = 0; s < seeds; ++s) {
      Config cfg;
      cfg.roughness = r, cfg.per_footprint = n, cfg.theta_i_deg = t, cfg.seed = 11 + static_cast<uint32_t>(s);
      if (beckmann) cfg.dist = mf::Distribution::Beckmann;
      for (int m = 0; m < (with_ref ? 2 : 1); ++m) {
        auto c = make_closure(m == 0 ? "glint" : "glint_jakob14", cfg.params(m == 1));
        const int corr_footprints = 4 * base * std::max(1, static_cast<int>(100.0 / n));
        if (wants("corr"))
          for (int k = 0; k < 3; ++k) v[k][m].push_back(glint_stats::lit_correlation(*c, cfg, (1 << k) * cfg.gamma(), corr_footprints));
        const auto estimator = std::getenv("GLIMMER_STATS_CV_SUBTRACTED") ? glint_stats::AlbedoCvEstimator::SubtractedVariance
                                                                          : glint_stats::AlbedoCvEstimator::SplitHalf;
        if (wants("cv"))
          v[3][m].push_back(m == 0 ? glint_stats::albedo_cv(*c, cfg, base / 5, samples, estimator)
                                   : glint_stats::reference_albedo_cv(cfg, base / 4));
        if (wants("doubling")) v[4][m].push_back(glint_stats::doubling(*c, cfg, base).correlation);
        if (wants("mean") && m == 0) v[5][m].push_back(glint_stats::mean_ratio(*c, cfg, 4 * base).ratio);
      }
    }
    static const char *names[6] = {"corr g", "corr 2g", "corr 4g", "albedo cv", "doubling", "mean"};
    for (int k = 0; k < 6; ++k)
      for (int m = 0; m < 2; ++m) {
        const auto &x = v[k][m];
        if (x.empty()) continue;
        double mean = 0, var = 0;
        for (double a : x) mean += a;
        mean /= static_cast<double>(x.size());
        for (double a : x) var += (a - mean) * (a - mean);
        const double se = x.size() > 1 ? std::sqrt(var / static_cast<double>(x.size() - 1) / static_cast<double>(x.size())) : 0.0;
        std::printf("[measure] %s r=%.2g n=%g theta_i=%g %-9s %s %.4f +- %.4f (%zu seeds:", beckmann ? "beckmann" : "ggx", r, n, t, names[k],
                    m == 0 ? "model" : "ref  ", mean, se, x.size());
        for (double a : x) std::printf(" %.3f", a);
        std::printf(")\n");
      }
    std::fflush(stdout);
  }
}

TEST(GlintStatistics, ModelVersusReferenceGridStress) {
  if (stress_scale() == 1) GTEST_SKIP() << "make stress only";
  measure_grid(true);
}

}  // namespace
}  // namespace glimmer::test
