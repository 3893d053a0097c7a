// The estimator of `glimmer bench error-vs-time` (bridge/cli/bench_error.h): with N >= 2 references on different
// seeds, MSE(m - mean ref) - var_ref_mean is the method's own MSE (its noise + bias^2), not inflated by the
// references' noise. Synthetic images with a known truth, a known bias and known noise levels give the answer in
// closed form; negative controls show that the check fails for the raw MSE, for a variance not divided by N
// (the variance of one reference instead of their mean's) and for two references on the same seed.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "cli/bench_error.h"

namespace {

using glimmer::cli::bench::binary_id_regions;
using glimmer::cli::bench::combine_references;
using glimmer::cli::bench::Reference;
using glimmer::cli::bench::region_errors;
using glimmer::cli::bench::seed_errors;

constexpr size_t kPixels = 100000;  // x 3 channels
constexpr double kBias = 0.05, kSigmaMethod = 0.1, kSigmaRef = 0.3;

double truth(size_t i) { return 1.0 + 0.5 * std::sin(0.37 * static_cast<double>(i)); }

std::vector<float> noisy(double bias, double sigma, std::mt19937_64 &rng) {
  std::normal_distribution<double> g(0.0, sigma);
  std::vector<float> img(3 * kPixels);
  for (size_t i = 0; i < img.size(); ++i) img[i] = static_cast<float>(truth(i) + bias + g(rng));
  return img;
}

// The statistical tolerance (6 standard deviations of the estimate, Gaussian values): the raw MSE's mean of d^2
// with d ~ N(b, s^2), s^2 = sigma_m^2 + sigma_r^2 / N, has variance (2 s^4 + 4 b^2 s^2) / n; the variance of the
// mean's estimate s_r^2 / N with N - 1 degrees of freedom per value has variance 2 (sigma_r^2 / N)^2 / (N - 1) / n.
double tolerance(int n_refs) {
  const double n = 3.0 * kPixels, vr = kSigmaRef * kSigmaRef / n_refs;
  const double s2 = kSigmaMethod * kSigmaMethod + vr;
  const double var_raw = (2 * s2 * s2 + 4 * kBias * kBias * s2) / n, var_ref = 2 * vr * vr / (n_refs - 1) / n;
  return 6.0 * std::sqrt(var_raw + var_ref);
}

TEST(BenchErrorEstimator, SubtractingTheReferencesNoiseGivesTheMethodsOwnMse) {
  const double expected = kBias * kBias + kSigmaMethod * kSigmaMethod;  // 0.0125
  for (int n_refs : {2, 4}) {
    std::mt19937_64 rng(1234 + n_refs);
    std::vector<std::vector<float>> refs;
    for (int k = 0; k < n_refs; ++k) refs.push_back(noisy(0.0, kSigmaRef, rng));
    const Reference ref = combine_references(refs);
    const auto e = region_errors(noisy(kBias, kSigmaMethod, rng), ref, {}, 0).back();
    const double tol = tolerance(n_refs), ref_var = kSigmaRef * kSigmaRef / n_refs;
    ASSERT_LT(tol, 0.1 * expected) << "the check must be able to tell the answer from the controls";
    EXPECT_NEAR(e.mse(), expected, tol) << n_refs << " references";
    EXPECT_NEAR(e.var_ref_mean, ref_var, 6.0 * ref_var * std::sqrt(2.0 / (n_refs - 1) / (3.0 * kPixels)));
    EXPECT_NEAR(e.rmse(), std::sqrt(expected), tol / std::sqrt(expected));
    // Negative controls: the raw MSE (nothing subtracted) and one reference's variance subtracted (the /N
    // forgotten) both miss the answer by far more than the tolerance.
    EXPECT_GT(std::fabs(e.mse_raw - expected), 10.0 * tol) << "raw MSE";
    EXPECT_GT(std::fabs(e.mse_raw - n_refs * e.var_ref_mean - expected), 10.0 * tol) << "variance not divided by N";
    std::printf("N=%d: MSE %.5f (expected %.5f, tolerance %.5f), raw %.5f, var of the mean %.5f (expected %.5f)\n",
                n_refs, e.mse(), expected, tol, e.mse_raw, e.var_ref_mean, ref_var);
  }
}

TEST(BenchErrorEstimator, ReferencesOnOneSeedAreNotSubtractedAndTheCheckFails) {
  // Negative control: a bench that rendered its references on the same seed has no spread to subtract.
  std::mt19937_64 rng(99);
  const std::vector<float> one = noisy(0.0, kSigmaRef, rng);
  const Reference ref = combine_references({one, one});
  const auto e = region_errors(noisy(kBias, kSigmaMethod, rng), ref, {}, 0).back();
  EXPECT_EQ(e.var_ref_mean, 0.0);
  EXPECT_GT(std::fabs(e.mse() - (kBias * kBias + kSigmaMethod * kSigmaMethod)), 10.0 * tolerance(2));
}

TEST(BenchErrorEstimator, OneReferenceSubtractsNothing) {
  std::mt19937_64 rng(7);
  const Reference ref = combine_references({noisy(0.0, kSigmaRef, rng)});
  const auto e = region_errors(noisy(kBias, kSigmaMethod, rng), ref, {}, 0).back();
  EXPECT_EQ(e.var_ref_mean, 0.0);
  EXPECT_EQ(e.rmse(), e.rmse_raw());
}

TEST(BenchErrorEstimator, RegionsSplitTheErrorAndAddUpToTheWholeImage) {
  // Region 0 (even pixels): no bias; region 1 (odd pixels): bias 0.2; references noise-free and exact.
  std::vector<float> truth_img(3 * kPixels), img(3 * kPixels);
  std::vector<int> region(kPixels);
  for (size_t p = 0; p < kPixels; ++p) {
    region[p] = static_cast<int>(p % 2);
    for (size_t c = 0; c < 3; ++c) {
      truth_img[3 * p + c] = static_cast<float>(truth(3 * p + c));
      img[3 * p + c] = truth_img[3 * p + c] + (p % 2 ? 0.2f : 0.0f);
    }
  }
  const auto e = region_errors(img, combine_references({truth_img, truth_img}), region, 2);
  ASSERT_EQ(e.size(), 3u);
  EXPECT_EQ(e[0].pixels, kPixels / 2);
  EXPECT_NEAR(e[0].rmse(), 0.0, 1e-6);
  EXPECT_NEAR(e[1].rmse(), 0.2, 1e-6);
  EXPECT_NEAR(e[2].mse(), 0.5 * (e[0].mse() + e[1].mse()), 1e-9);
}

TEST(BenchErrorEstimator, SeveralSeedsSplitTheMseIntoTheMethodsBiasAndNoise) {
  // One rung on N = 4 seeds (bench --seeds 4) against 2 references of noise 0.05 (a converged pair; kSigmaRef's
  // would bury kBias^2 in the tolerance): bias2 estimates kBias^2 and variance
  // kSigmaMethod^2 (one image's), and their sum is the rung's MSE (the mean of the 4 images' MSEs) exactly.
  // Tolerances: 6 standard deviations; bias2 = mean(d^2) - mean(s^2) / N - var_ref with d = M - R ~ N(b, s_d^2),
  // s_d^2 = sigma_m^2 / N + sigma_r^2 / 2: var(mean d^2) = (2 s_d^4 + 4 b^2 s_d^2) / n, plus the two subtracted
  // estimates' (3 and 1 degrees of freedom per value).
  constexpr int kSeeds = 4;
  constexpr double kSigmaConverged = 0.05;
  std::mt19937_64 rng(4242);
  const Reference ref = combine_references({noisy(0.0, kSigmaConverged, rng), noisy(0.0, kSigmaConverged, rng)});
  std::vector<std::vector<float>> images;
  for (int k = 0; k < kSeeds; ++k) images.push_back(noisy(kBias, kSigmaMethod, rng));
  const auto s = seed_errors(images, ref, {}, 0);
  ASSERT_EQ(s.bias2.size(), 1u);
  ASSERT_EQ(s.variance.size(), 1u);
  const double n = 3.0 * kPixels, vm = kSigmaMethod * kSigmaMethod, vr = kSigmaConverged * kSigmaConverged / 2;
  const double sd2 = vm / kSeeds + vr;
  const double tol_b = 6.0 * std::sqrt((2 * sd2 * sd2 + 4 * kBias * kBias * sd2) / n +
                                       2 * (vm / kSeeds) * (vm / kSeeds) / (kSeeds - 1) / n + 2 * vr * vr / n);
  const double tol_v = 6.0 * vm * std::sqrt(2.0 / (kSeeds - 1) / n);
  ASSERT_LT(tol_b, 0.25 * kBias * kBias) << "the check must tell the bias from the controls";
  EXPECT_NEAR(s.bias2[0], kBias * kBias, tol_b);
  EXPECT_NEAR(s.variance[0], vm, tol_v);
  EXPECT_NEAR(s.errors.back().mse(), s.bias2[0] + s.variance[0], 1e-9);
  double mean_mse = 0.0;
  for (const auto &image : images) mean_mse += region_errors(image, ref, {}, 0).back().mse() / kSeeds;
  EXPECT_NEAR(s.errors.back().mse(), mean_mse, 1e-12);
  // Negative controls: the images' own noise not subtracted (mean((M - R)^2) - var_ref), and the spread of one
  // image taken for the mean's (s^2 instead of s^2 / N), both miss kBias^2 by far more than the tolerance.
  const Reference spread = combine_references(images);
  const auto of_mean = region_errors(spread.mean, ref, {}, 0).back();
  EXPECT_GT(std::fabs(of_mean.mse() - kBias * kBias), 10.0 * tol_b) << "images' noise kept";
  EXPECT_GT(std::fabs(of_mean.mse() - s.variance[0] - kBias * kBias), 10.0 * tol_b) << "s^2 not divided by N";
  std::printf("4 seeds: bias2 %.6f (expected %.6f, tolerance %.6f), variance %.6f (expected %.6f), controls %.6f "
              "/ %.6f\n", s.bias2[0], kBias * kBias, tol_b, s.variance[0], vm, of_mean.mse(),
              of_mean.mse() - s.variance[0]);
  // One image: no split, the rung's MSE is that image's.
  const auto one = seed_errors({images[0]}, ref, {}, 0);
  EXPECT_TRUE(one.bias2.empty());
  EXPECT_EQ(one.errors.back().mse_raw, region_errors(images[0], ref, {}, 0).back().mse_raw);
}

TEST(BenchErrorEstimator, IdImagesGiveOneRegionPerBinaryColourAndEdgesForMixtures) {
  const std::vector<float> ids = {0, 0, 0,  1, 0, 0,  0, 1, 0,  1, 1, 1,  0.5f, 0, 0,  0.5f, 0.5f, 0,  0, 0, 1};
  const std::vector<int> r = binary_id_regions(ids);
  EXPECT_EQ(r, (std::vector<int>{0, 1, 2, 7, 8, 8, 4}));
}

}  // namespace
