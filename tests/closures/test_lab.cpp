// The closure laboratory's own machinery: statistics against brute-force
// references, determinism across thread counts, plot output.
#include <tbb/global_control.h>

#include <cmath>
#include <filesystem>

#include "closures/closure_checks.h"
#include "render/image_io.h"

namespace glimmer::test {
namespace {

// Q(a, x) for integer a is the Poisson tail sum_{k < a} e^-x x^k / k!.
long double poisson_tail(int a, long double x) {
  long double term = std::exp(-x), sum = 0.0L;
  for (int k = 0; k < a; ++k) {
    sum += term;
    term *= x / (k + 1);
  }
  return sum;
}

TEST(LabStatistics, IncompleteGammaMatchesPoissonSums) {
  for (int a : {1, 2, 5, 10, 50, 200, 1000}) {
    for (double ratio : {0.2, 0.5, 0.9, 1.0, 1.1, 1.5, 2.0}) {
      const double x = ratio * a;
      const double expected = static_cast<double>(poisson_tail(a, x));
      if (expected < 1e-280) continue;
      EXPECT_NEAR(lab::regularized_gamma_q(a, x) / expected, 1.0, 1e-9) << "a=" << a << " x=" << x;
    }
  }
  EXPECT_EQ(lab::regularized_gamma_q(3.0, 0.0), 1.0);
}

TEST(LabStatistics, Chi2SurvivalOfTwoDegreesIsExponential) {
  for (double x : {0.1, 1.0, 4.0, 20.0}) EXPECT_NEAR(lab::chi2_survival(x, 2.0), std::exp(-0.5 * x), 1e-12);
}

TEST(LabStatistics, SidakCorrection) {
  EXPECT_NEAR(lab::sidak_significance(0.01, 1), 0.01, 1e-15);
  EXPECT_NEAR(lab::sidak_significance(0.01, 6), 1.0 - std::pow(0.99, 1.0 / 6.0), 1e-15);
  EXPECT_LT(lab::sidak_significance(0.01, 6), 0.01 / 5.9);
}

// Under the null hypothesis (a correct sampler) p-values are uniform: over 40
// independent seeds about 2 fall below 0.05 and about 20 above 0.5. A test
// that rejected correct closures too often, or never could reject, fails here.
// (Fixed seeds: the outcome is deterministic; the bounds are the binomial
// 99.9 % ranges.)
TEST(LabStatistics, Chi2PValuesAreUniformForACorrectSampler) {
  const auto emission = make_closure("emission");
  const auto ctx = host::make_local_context(Vec3(0, 0, 1));
  lab::Chi2Options options;
  options.samples = 100000;
  options.theta_bins = 20;
  options.phi_bins = 40;
  int below_005 = 0, above_05 = 0;
  for (uint64_t seed = 100; seed < 140; ++seed) {
    options.seed = seed;
    const double p = lab::chi2_test(*emission, ctx, options).p_value;
    below_005 += p < 0.05;
    above_05 += p > 0.5;
  }
  std::printf("p < 0.05: %d of 40, p > 0.5: %d of 40\n", below_005, above_05);
  EXPECT_LE(below_005, 8);
  EXPECT_GE(above_05, 9);
  EXPECT_LE(above_05, 31);
}

// Random numbers are uniform: mean 1/2 and variance 1/12 per dimension.
TEST(LabRandom, SampleNumbersAreUniform) {
  constexpr int n = 200000;
  double sum[3] = {0, 0, 0}, sum_sq[3] = {0, 0, 0};
  for (int i = 0; i < n; ++i) {
    float u[3];
    lab::sample_random3(42, i, u);
    for (int d = 0; d < 3; ++d) {
      ASSERT_GE(u[d], 0.0f);
      ASSERT_LT(u[d], 1.0f);
      sum[d] += u[d];
      sum_sq[d] += double(u[d]) * u[d];
    }
  }
  for (int d = 0; d < 3; ++d) {
    EXPECT_NEAR(sum[d] / n, 0.5, 5.0 * std::sqrt(1.0 / 12.0 / n));
    EXPECT_NEAR(sum_sq[d] / n - sqr(float(sum[d] / n)), 1.0 / 12.0, 2e-3);
  }
}

// sample() reports a pdf that varies with wo, so the furnace weights vary and
// the sum's rounding would expose any thread-dependent reduction order.
uint32_t uneven_weight_sample(const GlimmerInstance *instance, const GlimmerShadingContext *ctx,
                              const float rand3[3], GlimmerSample *out) {
  const uint32_t label = TamperedType::original().sample(instance, ctx, rand3, out);
  out->pdf *= 1.0f + 0.5f * out->wo.x;
  return label;
}

TEST(LabDeterminism, ResultsDoNotDependOnThreadCount) {
  TamperedType tampered(closure_type("diffuse"));
  tampered.type().sample = &uneven_weight_sample;
  const auto closure = make_closure(tampered.type(), {{"color", "0.5,0.25,0.8"}});
  const auto ctx = host::make_local_context(Vec3(0.3f, 0.0f, 0.95f));
  lab::Chi2Options options;
  options.samples = 200000;

  const auto furnace_parallel = lab::furnace(*closure, ctx, 300000, 9);
  const auto chi2_parallel = lab::chi2_test(*closure, ctx, options);
  lab::FurnaceResult furnace_serial;
  lab::Chi2Result chi2_serial;
  {
    tbb::global_control one_thread(tbb::global_control::max_allowed_parallelism, 1);
    furnace_serial = lab::furnace(*closure, ctx, 300000, 9);
    chi2_serial = lab::chi2_test(*closure, ctx, options);
  }
  for (int c = 0; c < 3; ++c) {
    EXPECT_EQ(furnace_parallel.albedo[c], furnace_serial.albedo[c]);
    EXPECT_EQ(furnace_parallel.standard_error[c], furnace_serial.standard_error[c]);
  }
  EXPECT_GT(furnace_parallel.standard_error.x, 0.0f);
  EXPECT_EQ(chi2_parallel.chi2, chi2_serial.chi2);
  EXPECT_EQ(chi2_parallel.pdf_integral, chi2_serial.pdf_integral);
  // A different seed gives a different estimate.
  EXPECT_NE(lab::furnace(*closure, ctx, 300000, 10).albedo.x, furnace_parallel.albedo.x);
}

TEST(LabPlot, WritesThreePanelPngAtomically) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::path(GLIMMER_TEST_BINARY_DIR) / "lab_plot_test";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path png = dir / "lobe.png";
  const auto diffuse = make_closure("diffuse");
  lab::PlotOptions options;
  options.width = 64;
  options.height = 32;
  options.samples = 100000;
  lab::plot_lobe(*diffuse, host::make_local_context(Vec3(0, 0, 1)), png.string(), options);

  // Read through the host's image module (render/image_io.h: OpenImageIO behind dlopen), so that this test
  // binary does not link OpenImageIO, whose 260 shared libraries cost every test process ~0.6 s of CPU to load.
  // An 8-bit PNG reads as code / 255.
  int width = 0, height = 0;
  const std::vector<float> rgb = render::image_io().read_rgb(png.string(), width, height);
  EXPECT_EQ(width, 3 * 64 + 2 * 2);
  EXPECT_EQ(height, 32);
  ASSERT_EQ(rgb.size(), size_t(width) * height * 3);
  auto brightness = [&](int x, int y) {
    const float *p = &rgb[(size_t(y) * width + x) * 3];
    return int(std::lround(255.0f * p[0])) + int(std::lround(255.0f * p[1])) + int(std::lround(255.0f * p[2]));
  };
  // Near the pole the cosine lobe is bright in every panel; below the horizon
  // it is black (the colour map's 0).
  for (int panel = 0; panel < 3; ++panel) {
    const int x = panel * (64 + 2) + 20;
    EXPECT_GT(brightness(x, 2), 400) << "panel " << panel;
    EXPECT_LT(brightness(x, 28), 10) << "panel " << panel;
  }
  // Only the final file is left behind.
  int files = 0;
  for (const auto &entry : fs::directory_iterator(dir)) files += entry.is_regular_file();
  EXPECT_EQ(files, 1);
  EXPECT_THROW(lab::plot_lobe(*diffuse, host::make_local_context(Vec3(0, 0, 1)), (dir / "missing" / "x.png").string(),
                              options),
               std::runtime_error);
}

TEST(LabBench, ReportsPositiveTimes) {
  const auto diffuse = make_closure("diffuse");
  const auto r = lab::bench(*diffuse, host::make_local_context(Vec3(0, 0, 1)), 20000, 3);
  EXPECT_GT(r.ns_per_eval, 0.0);
  EXPECT_GT(r.ns_per_sample, 0.0);
  EXPECT_TRUE(std::isfinite(r.ns_per_eval) && std::isfinite(r.ns_per_sample));
}

}  // namespace
}  // namespace glimmer::test
