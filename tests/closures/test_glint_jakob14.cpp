// Tests of the Jakob 2014 reference glint closure (glint_jakob14) and its
// agreement with the separable model (glint).
#include <gtest/gtest.h>

#include <cstdlib>

#include "closures/closure_checks.h"
#include "glimmer/microfacet.h"
#include "glimmer/rng.h"

namespace glimmer::test {
namespace {

namespace mf = glimmer::microfacet;

const bool kCacheDirSet = cache_tables_in_build_folder();

constexpr double kDeg = M_PI / 180.0;

double f_of(const host::ClosureInstance &c, const GlimmerShadingContext &ctx, const Vec3 &wo) {
  Spectrum f;
  float pdf;
  c.eval(ctx, wo, f, pdf);
  return f.x;
}

// The particle set is a fixed property of the surface: counts are additive
// over disjoint footprints (f * area of the union = sum over the halves).
TEST(GlintJakob14, CountsAreAdditiveOverDisjointFootprints) {
  auto j = make_closure("glint_jakob14", {{"roughness", "0.4"}, {"gamma", "3"}, {"density", "3e5"}});
  const Vec3 wi = spherical_dir(30.0, 0.0), wo = spherical_dir(32.0, 178.0);
  int nonzero = 0;
  for (int t = 0; t < 200; ++t) {
    const double u = 0.013 * t + 0.2, v = 0.37 + 0.0041 * t, w = 0.02;
    const double whole = f_of(*j, footprint_context(wi, u, v, w, 0, 0, w), wo) * w * w;
    const double left = f_of(*j, footprint_context(wi, u - w / 4, v, w / 2, 0, 0, w), wo) * (w * w / 2);
    const double right = f_of(*j, footprint_context(wi, u + w / 4, v, w / 2, 0, 0, w), wo) * (w * w / 2);
    EXPECT_NEAR(whole, left + right, 1e-5 * std::max(1.0, whole)) << "footprint " << t;
    nonzero += whole > 0.0;
  }
  EXPECT_GT(nonzero, 50);
}

// Mean over surface positions of the reference equals the brute-force smooth
// microfacet BRDF averaged over the query cone (the exact expectation of the
// Jakob 2014 estimator), and equals glint's mean (unfiltered).
TEST(GlintJakob14, MeanMatchesConeAveragedSmoothBrdfAndGlint) {
  const double alpha = 0.25, gamma = 2.0 * kDeg;
  auto j = make_closure("glint_jakob14", {{"roughness", "0.5"}, {"gamma", "2"}, {"density", "1e6"}});
  auto g = make_closure("glint", {{"roughness", "0.5"}, {"gamma", "2"}, {"density", "1e6"}});
  const Vec3 wi = spherical_dir(40.0, 0.0);
  for (const Vec3 &wo : {spherical_dir(40.0, 180.0), spherical_dir(30.0, 150.0)}) {
    // Brute force: W(wo) / sigma * Int_cone q(r) dr, q = D(h) cos_h / (4 wi.h).
    Vec3 h;
    ASSERT_TRUE(mf::half_vector_reflect(wi, wo, h));
    const float a = static_cast<float>(alpha);
    const double weight = mf::G2(mf::Distribution::GGX, wi, wo, a, a) * dot(wi, h) / (wi.z * h.z);
    const Frame frame = Frame::from_normal(wo);
    double integral = 0.0;
    const int rings = 64, phis = 256;
    for (int r = 0; r < rings; ++r)
      for (int p = 0; p < phis; ++p) {
        const double cos_rho = 1.0 - (r + 0.5) / rings * (1.0 - std::cos(gamma));
        const double sin_rho = std::sqrt(1.0 - cos_rho * cos_rho), phi = (p + 0.5) * 2.0 * M_PI / phis;
        const Vec3 rdir = frame.to_world(Vec3(static_cast<float>(sin_rho * std::cos(phi)),
                                              static_cast<float>(sin_rho * std::sin(phi)), static_cast<float>(cos_rho)));
        const Vec3 hh = normalize(wi + rdir);
        if (hh.z > 0 && dot(wi, hh) > 0)
          integral += mf::D(mf::Distribution::GGX, hh, a, a) * hh.z / (4.0 * dot(wi, hh));
      }
    const double sigma = 2.0 * M_PI * (1.0 - std::cos(gamma));
    const double expected = weight * integral / (rings * phis);  // = W * (Int q) / sigma
    const int positions = 4000;
    const double side = 0.05;  // N a = 2500 particles per footprint, ~10 of them reflecting
    double sum_j = 0.0, sum2_j = 0.0, sum_g = 0.0;
    Pcg32 rng(3);
    for (int i = 0; i < positions; ++i) {
      const double u = rng.next_double() * 20.0, v = rng.next_double() * 20.0;
      const GlimmerShadingContext c = footprint_context(wi, u, v, side, 0, 0, side);
      const double fj = f_of(*j, c, wo);
      sum_j += fj;
      sum2_j += fj * fj;
      sum_g += f_of(*g, c, wo);
    }
    const double mean_j = sum_j / positions, mean_g = sum_g / positions;
    const double se = std::sqrt(std::max(sum2_j / positions - mean_j * mean_j, 0.0) / positions);
    std::printf("[jakob14] mean %.5g +- %.2g, cone-averaged smooth %.5g, glint mean %.5g (sigma %.3g)\n", mean_j, se,
                expected, mean_g, sigma);
    EXPECT_NEAR(mean_j, expected, 4.0 * se + 0.01 * expected);
    EXPECT_NEAR(mean_g, expected, 4.0 * se + 0.01 * expected);
  }
}

// The sampler is the one glint uses (tables/glint_common.h, 24 configurations
// in test_glint.cpp); here it is checked through the reference closure: all 24
// configurations under `make stress` (Chi2SamplerMatchesPdfStress, ~4 min on one
// core: every sample evaluates the exact 4D count); `make test` runs the 4
// corners (GGX and Beckmann, roughness 0.2 and 0.9, normal and 70 degrees).
void expect_sampler_matches_pdf(bool full) {
  std::vector<Chi2Config> configs;
  for (const char *dist : {"ggx", "beckmann"})
    for (const char *rough : {"0.2", "0.5", "0.9"}) {
      if (!full && std::string(rough) == "0.5") continue;
      auto c = make_closure("glint_jakob14",
                            {{"distribution", dist}, {"roughness", rough}, {"gamma", "3"}, {"density", "100"}});
      for (double theta_i : {0.0, 25.0, 50.0, 70.0}) {
        // The corners: GGX r=0.2 and Beckmann r=0.9 at normal incidence, the other two at 70 degrees.
        const bool normal_corner = (std::string(dist) == "ggx") == (std::string(rough) == "0.2");
        if (!full && theta_i != (normal_corner ? 0.0 : 70.0)) continue;
        configs.push_back({std::string(dist) + " r=" + rough + " theta_i " + std::to_string(theta_i), c,
                           spherical_dir(theta_i, 0.0)});
      }
    }
  ASSERT_EQ(configs.size(), full ? 24u : 4u);
  expect_chi2_family(configs);
}

TEST(GlintJakob14, Chi2SamplerMatchesPdf) { expect_sampler_matches_pdf(false); }

TEST(GlintJakob14, Chi2SamplerMatchesPdfStress) {
  if (stress_scale() == 1) GTEST_SKIP() << "make stress only";
  expect_sampler_matches_pdf(true);
}

TEST(GlintJakob14, EvalPdfConsistentAndStressClean) {
  auto j = make_closure("glint_jakob14", {{"roughness", "0.4"}, {"density", "1e6"}});
  for (double theta_i : {0.0, 45.0, 80.0}) EXPECT_TRUE(consistent(*j, spherical_dir(theta_i, 0.0), 1e-4, 20000));
  auto j2 = make_closure("glint_jakob14", {{"distribution", "beckmann"}, {"roughness", "0"}, {"gamma", "10"},
                                           {"density", "1e12"}, {"uv_scale", "1000"}});
  auto j3 = make_closure("glint_jakob14", {{"roughness", "1"}, {"gamma", "0.1"}, {"density", "1"}});
  EXPECT_TRUE(stress_clean({j.get(), j2.get(), j3.get()}, 3 * 3000));  // 3000 calls per instance
}

}  // namespace
}  // namespace glimmer::test
