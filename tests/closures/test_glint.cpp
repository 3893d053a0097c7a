// Tests of the glint closure (Wang et al. 2018 separable discrete stochastic
// microfacets), one per acceptance line of issue 5. References are computed
// by brute force in the tests from the smooth microfacet model
// (glimmer/microfacet.h), never hard-coded.
#include <gtest/gtest.h>

#include <atomic>
#include <cstring>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <thread>

#include "closures/closure_checks.h"
#include "closures/glint_statistics.h"
#include "closures/glint_test_util.h"
#include "glimmer/microfacet.h"
#include "glimmer/rng.h"

namespace glimmer::test {
namespace {

namespace mf = glimmer::microfacet;

const bool kCacheDirSet = cache_tables_in_build_folder();

constexpr double kDeg = M_PI / 180.0;

// Square footprint of side `footprint_side` at uv (u, v).
GlimmerShadingContext context(const Vec3 &wi, double u, double v, double footprint_side, float spread = 0.0f) {
  GlimmerShadingContext ctx = footprint_context(wi, u, v, footprint_side, 0.0, 0.0, footprint_side);
  ctx.spread_angle = spread;
  return ctx;
}

// Smooth microfacet reflection f * cos(wo) = F G2 D / (4 cos_i), F = 1.
double smooth_f_cos(mf::Distribution dist, double alpha, const Vec3 &wi, const Vec3 &wo) {
  if (!(wi.z > 0) || !(wo.z > 0)) return 0.0;
  Vec3 h;
  if (!mf::half_vector_reflect(wi, wo, h)) return 0.0;
  const float a = static_cast<float>(alpha);
  return mf::G2(dist, wi, wo, a, a) * mf::D(dist, h, a, a) / (4.0 * wi.z);
}

// Midpoint quadrature of a function of wo over the upper hemisphere.
template <typename Fn>
double hemisphere_integral(Fn fn, int n_theta = 180, int n_phi = 360) {
  double sum = 0.0;
  for (int t = 0; t < n_theta; ++t) {
    const double theta = (t + 0.5) * 90.0 / n_theta;
    const double w = std::sin(theta * kDeg) * (90.0 / n_theta * kDeg) * (360.0 / n_phi * kDeg);
    for (int p = 0; p < n_phi; ++p) sum += w * fn(spherical_dir(theta, (p + 0.5) * 360.0 / n_phi - 180.0));
  }
  return sum;
}

struct LimitCase {
  const char *distribution;
  mf::Distribution dist;
  double roughness;
};

// Limit consistency: with large N and a large footprint the glint BRDF is in
// filtered mode, f cos_o = W P_gamma / sigma (glint.cpp eq. 3), whose exact
// limit is the smooth microfacet BRDF with its NDF term q replaced by the
// mean of q over the query cone (the cone-averaged smooth BRDF,
// docs/glints.md "Limit"). Asserted within 1 % pointwise over the lobe core
// (smooth value >= 20 % of its peak, theta_o up to the horizon) for every
// theta_i including grazing, against that brute-force reference; and the
// glint BRDF is within 1 % of the pointwise smooth BRDF wherever the cone
// effect itself (cone mean / point value of q) is below 1 %. The cone
// effect is a gamma^2 effect of the half-vector Jacobian, large only where
// wi.h is small (grazing, theta_i >= 75 degrees); the test measures it.
// White furnace against the smooth model within 1 %.
// `make test`: GGX 0.4 and Beckmann 0.7 (both distributions, both roughnesses), every incidence; the *Stress twin
// (`make stress`) the four cases.
void expect_limit_matches_smooth(bool full) {
  const LimitCase cases[] = {{"ggx", mf::Distribution::GGX, 0.4},
                             {"ggx", mf::Distribution::GGX, 0.7},
                             {"beckmann", mf::Distribution::Beckmann, 0.4},
                             {"beckmann", mf::Distribution::Beckmann, 0.7}};
  const double gamma_deg = 1.0;
  for (const auto &c : cases) {
    if (!full && (c.dist == mf::Distribution::GGX) != (c.roughness == 0.4)) continue;
    auto glint = make_closure("glint", {{"distribution", c.distribution},
                                        {"roughness", std::to_string(c.roughness)},
                                        {"gamma", "1"},
                                        {"density", "1e10"}});
    const double alpha = c.roughness * c.roughness;
    for (double theta_i : {0.0, 30.0, 60.0, 75.0, 85.0}) {
      const Vec3 wi = spherical_dir(theta_i, 0.0);
      const GlimmerShadingContext ctx = context(wi, 0.37, 0.61, 0.1);
      double peak = 0.0;
      for (double to = 0.5; to < 90.0; to += 1.0)
        for (double po = -180.0; po < 180.0; po += 3.0)
          peak = std::max(peak, smooth_f_cos(c.dist, alpha, wi, spherical_dir(to, po)));
      double worst_vs_cone = 0.0, worst_pointwise = 0.0, worst_cone_effect = 0.0;
      double worst_pointwise_all = 0.0;
      int core_points = 0, pointwise_points = 0;
      for (double to = 0.5; to < 90.0; to += 1.0)
        for (double po = -180.0; po < 180.0; po += 3.0) {
          const Vec3 wo = spherical_dir(to, po);
          const double smooth = smooth_f_cos(c.dist, alpha, wi, wo);
          if (smooth < 0.2 * peak) continue;
          ++core_points;
          const double q = reflected_density(c.dist, alpha, wi, wo);
          ASSERT_GT(q, 0.0);
          const double cone_effect = cone_mean_reflected_density(c.dist, alpha, wi, wo, gamma_deg) / q;
          const double cone_reference = smooth * cone_effect;
          const double f = eval_f(*glint, ctx, wo);
          const double err_cone = std::fabs(f / cone_reference - 1.0);
          const double err_pointwise = std::fabs(f / smooth - 1.0);
          EXPECT_LE(err_cone, 0.01) << c.distribution << " roughness " << c.roughness << " theta_i " << theta_i
                                    << " theta_o " << to << " phi_o " << po << ": glint " << f
                                    << ", cone-averaged smooth " << cone_reference;
          worst_vs_cone = std::max(worst_vs_cone, err_cone);
          worst_cone_effect = std::max(worst_cone_effect, std::fabs(cone_effect - 1.0));
          worst_pointwise_all = std::max(worst_pointwise_all, err_pointwise);
          if (std::fabs(cone_effect - 1.0) < 0.01) {
            ++pointwise_points;
            EXPECT_LE(err_pointwise, 0.01) << c.distribution << " roughness " << c.roughness << " theta_i "
                                           << theta_i << " theta_o " << to << " phi_o " << po << ": glint " << f
                                           << ", smooth " << smooth;
            worst_pointwise = std::max(worst_pointwise, err_pointwise);
          }
        }
      EXPECT_GT(core_points, 50);
      // The pointwise check must cover most of the lobe core below grazing.
      if (theta_i <= 60.0) {
        EXPECT_GT(pointwise_points, core_points * 9 / 10);
      }
      // White furnace of the filtered glint BRDF against the smooth model.
      const double albedo = hemisphere_integral([&](const Vec3 &wo) { return eval_f(*glint, ctx, wo); });
      const double smooth = hemisphere_integral([&](const Vec3 &wo) { return smooth_f_cos(c.dist, alpha, wi, wo); });
      EXPECT_NEAR(albedo / smooth, 1.0, 0.01) << c.distribution << " roughness " << c.roughness << " theta_i "
                                              << theta_i << ": glint albedo " << albedo << ", smooth " << smooth;
      std::printf("[limit] %s r=%.1f theta_i=%2.0f: core %4d pts; max rel err vs cone-averaged smooth %.4f; "
                  "cone effect max %.4f; vs pointwise smooth %.4f (all core) / %.4f (%d pts, cone effect < 1%%); "
                  "albedo %.5f vs smooth %.5f\n",
                  c.distribution, c.roughness, theta_i, core_points, worst_vs_cone, worst_cone_effect,
                  worst_pointwise_all, worst_pointwise, pointwise_points, albedo, smooth);
    }
  }
}

TEST(Glint, LimitMatchesSmoothMicrofacetWithin1Percent) { expect_limit_matches_smooth(false); }

TEST(Glint, LimitMatchesSmoothMicrofacetWithin1PercentStress) {
  if (stress_scale() == 1) GTEST_SKIP() << "make stress only";
  expect_limit_matches_smooth(true);
}

// Mean of the unfiltered (glinty) BRDF over surface positions equals the
// filtered BRDF, and the mean radiance is continuous across the
// filtered/unfiltered switch (expected count just below / above threshold).
TEST(Glint, UnfilteredMeanEqualsFilteredAcrossTheSwitch) {
  const double density = 1e6;
  auto glint = make_closure("glint", {{"roughness", "0.5"}, {"gamma", "2"}, {"density", "1e6"}});
  auto filtered = make_closure("glint", {{"roughness", "0.5"}, {"gamma", "2"}, {"density", "1e6"},
                                         {"filter_threshold", "0"}});
  for (double theta_i : {10.0, 50.0}) {
    const Vec3 wi = spherical_dir(theta_i, 0.0);
    const Vec3 wo = spherical_dir(theta_i + 8.0, 175.0);
    // The filtered value gives P: f_filtered = W P / sigma; find the footprint
    // side that makes N a P equal to the threshold 16.
    const GlimmerShadingContext probe = context(wi, 0.5, 0.5, 0.1);
    const double f_filtered = eval_f(*filtered, probe, wo);
    ASSERT_GT(f_filtered, 0.0);
    // P from the glint at a footprint with a known count: bisect the switch.
    double lo = 1e-6, hi = 1.0;  // footprint side
    for (int it = 0; it < 60; ++it) {
      const double mid = std::sqrt(lo * hi);
      // In filtered mode the value equals f_filtered exactly at any position.
      bool is_filtered = true;
      for (int k = 0; k < 4 && is_filtered; ++k)
        is_filtered = eval_f(*glint, context(wi, 0.1 + 0.2 * k, 0.3, mid), wo) == static_cast<float>(f_filtered);
      (is_filtered ? hi : lo) = mid;
    }
    const double side_switch = hi;
    const double expected_at_switch = density * side_switch * side_switch;  // N a; N a P = 16 there
    EXPECT_GT(expected_at_switch, 16.0);
    for (double factor : {0.97, 1.03}) {
      const double side = side_switch * std::sqrt(factor);
      const int positions = 40000;
      double sum = 0.0;
      Pcg32 rng(17, static_cast<uint64_t>(factor * 1000));
      for (int i = 0; i < positions; ++i) {
        const double u = rng.next_double() * 50.0, v = rng.next_double() * 50.0;
        sum += eval_f(*glint, context(wi, u, v, side), wo);
      }
      const double mean = sum / positions;
      std::printf("[switch] theta_i %.0f: side %.3g (factor %.2f) mean %.6g filtered %.6g ratio %.4f\n", theta_i,
                  side, factor, mean, f_filtered, mean / f_filtered);
      EXPECT_NEAR(mean / f_filtered, 1.0, 0.01) << "theta_i " << theta_i << " footprint factor " << factor;
    }
  }
}

// LOD continuity: the mean radiance (filtered BRDF under a smooth, non-uniform
// environment) changes continuously with the path spread, also across the
// boundaries of the 9 LOD levels.
TEST(Glint, MeanRadianceContinuousAcrossLodLevels) {
  auto glint = make_closure("glint", {{"roughness", "0.9"}, {"gamma", "1"}, {"density", "1e10"}});
  const double alpha = 0.81;
  const Vec3 wi = spherical_dir(40.0, 0.0);
  auto radiance = [&](double spread_deg) {
    const GlimmerShadingContext ctx = context(wi, 0.2, 0.7, 0.1, static_cast<float>(spread_deg * kDeg));
    return hemisphere_integral(
        [&](const Vec3 &wo) { return eval_f(*glint, ctx, wo) * (1.0 + 0.8 * wo.x + 0.5 * wo.z * wo.z); }, 90, 180);
  };
  const double cap_deg = 2.0 * alpha / kDeg;  // LOD sigma is capped by the lobe width
  double previous = radiance(0.0);
  double worst = 0.0;
  for (double level : {1.0, 2.0, 5.0, 10.0, 20.0, 30.0, 45.0, 60.0, 90.0}) {
    if (level > cap_deg) break;
    const double below = radiance(level - 0.05), above = radiance(level + 0.05);
    worst = std::max(worst, std::fabs(above / below - 1.0));
    EXPECT_NEAR(above / below, 1.0, 0.01) << "across LOD level " << level << " deg";
  }
  for (double s = 0.5; s <= cap_deg + 1.0; s += 0.5) {
    const double r = radiance(s);
    worst = std::max(worst, std::fabs(r / previous - 1.0));
    EXPECT_NEAR(r / previous, 1.0, 0.01) << "spread " << s << " deg";
    previous = r;
  }
  std::printf("[lod] largest relative step of the mean radiance: %.5f\n", worst);
}

// A path whose LOD blur is wider than the glint cone (sigma_L > gamma, e.g.
// after a rough bounce) gets the filtered mean (glint.cpp eq. 3), whatever
// the footprint: it equals, bit for bit, the same closure with
// filter_threshold=0. With a blur below gamma the same tiny footprints are
// counted (negative control: most evals are 0 or a multiple of the one-glint
// value, not the mean).
TEST(Glint, BlurWiderThanTheConeIsFiltered) {
  const std::vector<std::pair<std::string, std::string>> base = {
      {"roughness", "0.4"}, {"gamma", "2"}, {"density", "1e6"}};
  auto glint = make_closure("glint", base);
  auto params = base;
  params.push_back({"filter_threshold", "0"});
  auto filtered = make_closure("glint", params);
  Pcg32 rng(17);
  int counted = 0, lobe = 0;
  for (int t = 0; t < 400; ++t) {
    const Vec3 wi = spherical_dir(80.0 * rng.next_double(), 0.0);
    const Vec3 wo = spherical_dir(80.0 * rng.next_double(), 180.0 + 40.0 * (rng.next_double() - 0.5));
    const double u = rng.next_double(), v = rng.next_double();
    const float mean = eval_f(*filtered, context(wi, u, v, 1e-4, static_cast<float>(2.5 * kDeg)), wo);
    if (!(mean > 0.0f)) continue;
    ++lobe;
    EXPECT_EQ(eval_f(*glint, context(wi, u, v, 1e-4, static_cast<float>(2.5 * kDeg)), wo), mean);
    const float sharp = eval_f(*filtered, context(wi, u, v, 1e-4, static_cast<float>(1.5 * kDeg)), wo);
    counted += eval_f(*glint, context(wi, u, v, 1e-4, static_cast<float>(1.5 * kDeg)), wo) != sharp;
  }
  EXPECT_GT(lobe, 200);
  EXPECT_GT(counted, lobe * 9 / 10);
}

// Energy at secondary bounces (issue 10): the LOD blur of P must not add
// energy. White furnace (F0 = 1, filtered mode) at incidences 0..89 degrees
// and LOD blurs from 0 to the cap 2 alpha, by midpoint quadrature (the same
// for the smooth model): every blurred albedo <= the unblurred one + 0.2 %,
// and <= the smooth model's + 1 % up to 85 degrees. At 88..89 degrees the
// unblurred cone estimator itself exceeds the smooth albedo (W averaged over
// the cone, convex near the horizon: docs/glints.md), measured, not asserted.
// Before issue 10 (blurred P times the unblurred weight W): GGX 0.35 had
// albedo 1.35 at 80 degrees and 2.26 at 88 degrees at the largest blur.
// (The 0.5 x 1-degree wo grid under-resolves the smooth albedo at 88..89
// degrees by ~2 %: the next test checks the smooth bound with a converged
// reference.)

// A white-furnace material: a glint of `c` in filtered mode (F0 = 1, gamma 2).
struct FurnaceCase {
  const char *dist;
  mf::Distribution d;
  double roughness;
};
std::shared_ptr<host::ClosureInstance> filtered_glint(const FurnaceCase &c) {
  return make_closure("glint", {{"distribution", c.dist},
                                {"roughness", std::to_string(c.roughness)},
                                {"gamma", "2"},
                                {"density", "1e6"},
                                {"filter_threshold", "0"}});
}

TEST(Glint, LodBlurConservesEnergyAtEveryIncidence) {
  double worst = 0.0;
  for (const FurnaceCase &c :
       {FurnaceCase{"ggx", mf::Distribution::GGX, 0.35}, FurnaceCase{"beckmann", mf::Distribution::Beckmann, 0.5}}) {
    auto glint = filtered_glint(c);
    const double alpha = c.roughness * c.roughness;
    for (double theta_i : {0.0, 30.0, 60.0, 75.0, 80.0, 85.0, 88.0, 89.0}) {
      const Vec3 wi = spherical_dir(theta_i, 0.0);
      const double smooth =
          hemisphere_integral([&](const Vec3 &wo) { return smooth_f_cos(c.d, alpha, wi, wo); }, 180, 360);
      double unblurred = 0.0;
      for (double blur : {0.0, 0.25, 0.5, 1.0}) {
        const float spread = static_cast<float>(blur * 2.0 * alpha);
        const GlimmerShadingContext ctx = context(wi, 0.3, 0.6, 0.1, spread);
        const double albedo =
            hemisphere_integral([&](const Vec3 &wo) { return eval_f(*glint, ctx, wo); }, 180, 360);
        std::printf("[energy] %s r=%.2f theta_i %4.1f blur %.2f x 2 alpha: albedo %.4f smooth %.4f\n", c.dist,
                    c.roughness, theta_i, blur, albedo, smooth);
        if (blur == 0.0) unblurred = albedo;
        worst = std::max(worst, albedo / unblurred);
        EXPECT_LE(albedo, unblurred * 1.002) << c.dist << " theta_i " << theta_i << " blur " << blur;
        if (theta_i <= 85.0) {
          EXPECT_LE(albedo, smooth * 1.01) << c.dist << " theta_i " << theta_i << " blur " << blur;
        }
      }
    }
  }
  std::printf("[energy] largest blurred / unblurred albedo: %.4f\n", worst);
}

// The smooth model's albedo: smooth_albedo_vndf (glint_test_util.h), isotropic here.

// The issue-10 energy line: white-furnace albedo <= the smooth model's + 3
// sigma at every incidence 0..89 degrees (every 5 degrees to 70, then each
// degree, where the horizon makes W convex) and every LOD blur (0,
// 1/4, 1/2, 1 x the cap 2 alpha), GGX 0.35, Beckmann 0.5 and GGX 0.2 (a lobe
// narrower than the cone). sigma: the standard error of the glint albedo by
// its own sampler (2^16 stratified samples); the smooth albedo by a 512^2
// visible-normal quadrature, checked here against a 0.1-degree wo grid away
// from grazing (within 0.05 %).
TEST(Glint, WhiteFurnaceAtMostSmoothAtEveryIncidenceAndBlur) {
  double worst_sigmas = -1e9;
  for (const FurnaceCase &c :
       {FurnaceCase{"ggx", mf::Distribution::GGX, 0.35}, FurnaceCase{"beckmann", mf::Distribution::Beckmann, 0.5},
        FurnaceCase{"ggx", mf::Distribution::GGX, 0.2}}) {
    auto glint = filtered_glint(c);
    const double alpha = c.roughness * c.roughness;
    for (double theta_check : {0.0, 60.0}) {  // the reference against a fine wo grid
      const Vec3 wi = spherical_dir(theta_check, 0.0);
      const double grid =
          hemisphere_integral([&](const Vec3 &wo) { return smooth_f_cos(c.d, alpha, wi, wo); }, 900, 3600);
      EXPECT_NEAR(smooth_albedo_vndf(c.d, alpha, alpha, wi), grid, 5e-4 * grid)
          << c.dist << " theta_i " << theta_check;
    }
    double case_worst = -1e9, case_worst_theta = 0.0, case_worst_ratio = 0.0, ratio_theta = 0.0, ratio_sigma = 0.0;
    for (int theta_i = 0; theta_i <= 89; theta_i += theta_i < 70 ? 5 : 1) {
      const Vec3 wi = spherical_dir(theta_i, 0.0);
      const double smooth = smooth_albedo_vndf(c.d, alpha, alpha, wi);
      for (double blur : {0.0, 0.25, 0.5, 1.0}) {
        const GlimmerShadingContext ctx = context(wi, 0.3, 0.6, 0.1, static_cast<float>(blur * 2.0 * alpha));
        const glint_stats::AlbedoEstimate a = glint_stats::sampled_albedo(*glint, ctx, 256);
        const double sigmas = (a.mean - smooth) / a.standard_error();
        if (sigmas > case_worst) case_worst = sigmas, case_worst_theta = theta_i;
        if (a.mean / smooth > case_worst_ratio)
          case_worst_ratio = a.mean / smooth, ratio_theta = theta_i, ratio_sigma = a.standard_error() / smooth;
        EXPECT_LE(a.mean, smooth + 3.0 * a.standard_error())
            << c.dist << " r=" << c.roughness << " theta_i " << theta_i << " blur " << blur << ": albedo " << a.mean
            << " +- " << a.standard_error() << ", smooth " << smooth;
      }
    }
    std::printf("[furnace] %s r=%.2f: largest (albedo - smooth) / sigma %.2f at theta_i %g; largest albedo / smooth "
                "%.4f (sigma %.4f) at theta_i %g\n",
                c.dist, c.roughness, case_worst, case_worst_theta, case_worst_ratio, ratio_sigma, ratio_theta);
    worst_sigmas = std::max(worst_sigmas, case_worst);
  }
  std::printf("[furnace] largest (albedo - smooth) / sigma over all cases: %.2f\n", worst_sigmas);
}

// Resolution (issue 10): a pixel at single resolution and the mean of its
// four pixels at double resolution (footprints of half the side tiling it)
// see the same glints: one particle level per material makes counts additive
// over the sub-footprints. Correlation across 10 000 pixels >= 0.9 (before
// issue 10, an independent particle field per level: 0.65 in a 320x200 render
// as reported in the issue; not re-measured here).
TEST(Glint, DownsampledDoubleResolutionMatchesSingleResolution) {
  auto glint = make_closure("glint", {{"roughness", "0.4"}, {"gamma", "2"}, {"density", "1e6"}, {"seed", "2"}});
  const Vec3 wi = spherical_dir(35.0, 0.0), wo = spherical_dir(30.0, 170.0);
  const int grid = 100;
  const double side = 1.0 / grid;  // 100 particles per pixel footprint
  std::vector<double> single, downsampled;
  int lit = 0;
  for (int y = 0; y < grid; ++y)
    for (int x = 0; x < grid; ++x) {
      const double u = (x + 0.5) * side, v = (y + 0.5) * side;
      single.push_back(eval_f(*glint, context(wi, u, v, side), wo));
      double sum = 0.0;
      for (int q = 0; q < 4; ++q)
        sum += eval_f(*glint, context(wi, u + ((q & 1) - 0.5) * side / 2, v + ((q >> 1) - 0.5) * side / 2, side / 2),
                      wo);
      downsampled.push_back(sum / 4.0);
      lit += single.back() > 0.0;
    }
  double ms = 0, md = 0;
  for (size_t i = 0; i < single.size(); ++i) ms += single[i], md += downsampled[i];
  ms /= single.size(), md /= single.size();
  double sd = 0, ss = 0, dd = 0;
  for (size_t i = 0; i < single.size(); ++i) {
    sd += (single[i] - ms) * (downsampled[i] - md);
    ss += (single[i] - ms) * (single[i] - ms);
    dd += (downsampled[i] - md) * (downsampled[i] - md);
  }
  const double corr = sd / std::sqrt(ss * dd);
  std::printf("[resolution] %d of %d pixels lit; correlation single vs 2x2-downsampled double resolution %.4f, "
              "means %.4g / %.4g\n", lit, grid * grid, corr, ms, md);
  EXPECT_GT(lit, grid * grid / 10);
  EXPECT_GE(corr, 0.9);
}

// Temporal behaviour (issue 10): when the view or the light moves, the set of
// lit surface points changes as in the exact discrete model: little for a
// move well below the cone angle gamma, mostly for a move of 2 gamma (the
// glints twinkle instead of freezing into a static speckle), and nothing
// special happens when the view crosses a table node. Jaccard overlap of the
// lit sets, glint vs the reference glint_jakob14 (same density and footprints),
// within 0.1. The moves cross the 1-degree table node at theta = 35 degrees;
// the last one is the 3.8-degree light move.
TEST(Glint, LitGlintsChangeLikeTheReferenceWhenViewOrLightMove) {
  // 0.4: direction cells; 0.2: pseudo-normals (lobe narrower than the cone).
  for (const char *roughness : {"0.4", "0.2"}) {
  std::printf("[coherence] roughness %s\n", roughness);
  const Params params = {{"roughness", roughness}, {"gamma", "2"}, {"density", "2e6"}, {"seed", "5"}};
  auto glint = make_closure("glint", params);
  auto reference = make_closure("glint_jakob14", params);
  const int grid = 150;  // 22 500 surface points, footprint 1/300 x 1/300: ~22 particles each
  auto lit_set = [&](const host::ClosureInstance &c, const Vec3 &view, const Vec3 &light) {
    std::set<int> lit;
    for (int y = 0; y < grid; ++y)
      for (int x = 0; x < grid; ++x) {
        const GlimmerShadingContext ctx = context(view, (x + 0.5) / grid, (y + 0.5) / grid, 1.0 / 300.0);
        if (eval_f(c, ctx, light) > 0.0f) lit.insert(y * grid + x);
      }
    return lit;
  };
  auto jaccard = [](const std::set<int> &a, const std::set<int> &b) {
    std::vector<int> both;
    std::set_intersection(a.begin(), a.end(), b.begin(), b.end(), std::back_inserter(both));
    return static_cast<double>(both.size()) / static_cast<double>(a.size() + b.size() - both.size());
  };
  struct Move {
    const char *what;
    Vec3 view_a, light_a, view_b, light_b;
  };
  const Vec3 light = spherical_dir(30.0, 180.0);
  const std::vector<Move> moves = {
      {"view 0.2 deg", spherical_dir(34.9, 0.0), light, spherical_dir(35.1, 0.0), light},
      {"view 1 deg", spherical_dir(34.5, 0.0), light, spherical_dir(35.5, 0.0), light},
      {"view 4 deg", spherical_dir(33.0, 0.0), light, spherical_dir(37.0, 0.0), light},
      {"light 3.8 deg", spherical_dir(35.0, 0.0), spherical_dir(28.1, 180.0), spherical_dir(35.0, 0.0),
       spherical_dir(31.9, 180.0)},
  };
  for (const Move &m : moves) {
    const std::set<int> ga = lit_set(*glint, m.view_a, m.light_a), gb = lit_set(*glint, m.view_b, m.light_b);
    const std::set<int> ra = lit_set(*reference, m.view_a, m.light_a), rb = lit_set(*reference, m.view_b, m.light_b);
    ASSERT_GT(ga.size(), 100u);
    ASSERT_GT(ra.size(), 100u);
    const double jg = jaccard(ga, gb), jr = jaccard(ra, rb);
    std::printf("[coherence] %-14s lit %zu -> %zu, Jaccard glint %.3f, reference %.3f (lit %zu -> %zu)\n", m.what,
                ga.size(), gb.size(), jg, jr, ra.size(), rb.size());
    EXPECT_NEAR(jg, jr, 0.1) << m.what << " roughness " << roughness;
  }
  }
}

// Footprint plumbing: the sampled roughness the host uses to widen the
// footprint is in alpha units, like the conductor's (with a tiny cone the
// glint sampling lobe is the conductor's lobe). Before issue 10 the glint
// closures reported sqrt(alpha), 2x here.
TEST(Glint, SampledRoughnessIsInAlphaUnitsLikeTheConductor) {
  auto conductor = make_closure("microfacet_conductor", {{"roughness", "0.5"}});
  const GlimmerShadingContext ctx = context(spherical_dir(30.0, 0.0), 0.5, 0.5, 1e-3);
  const float r3[3] = {0.3f, 0.6f, 0.5f};
  GlimmerSample reference{};
  ASSERT_TRUE(conductor->sample(ctx, r3, reference));
  for (const char *name : {"glint", "glint_jakob14"}) {
    auto c = make_closure(name, {{"roughness", "0.5"}, {"gamma", "0.1"}});
    GlimmerSample out{};
    ASSERT_TRUE(c->sample(ctx, r3, out)) << name;
    EXPECT_NEAR(out.roughness, reference.roughness, 0.01 * reference.roughness) << name;
  }
}

// Determinism: the same queries give bit-identical results on 1 and 4 threads.
TEST(Glint, DeterministicAcrossThreads) {
  // 0.3: direction cells; 0.2: pseudo-normals (lobe narrower than the cone).
  for (const char *roughness : {"0.3", "0.2"}) {
  auto glint = make_closure("glint", {{"roughness", roughness}, {"density", "1e5"}});
  const int count = 20000;
  auto run = [&](int threads) {
    std::vector<float> out(2 * count);
    std::atomic<int> next{0};
    std::vector<std::thread> pool;
    for (int t = 0; t < threads; ++t)
      pool.emplace_back([&] {
        for (int i = next++; i < count; i = next++) {
          Pcg32 rng(static_cast<uint64_t>(i));
          const Vec3 wi = spherical_dir(80.0 * rng.next_double(), 0.0);
          const GlimmerShadingContext ctx =
              context(wi, rng.next_double() * 10.0, rng.next_double(), std::pow(10.0, -4.0 * rng.next_double()));
          const float r3[3] = {rng.next_float(), rng.next_float(), rng.next_float()};
          GlimmerSample s = glimmer_blank_sample();
          glint->sample(ctx, r3, s);
          out[2 * i] = eval_f(*glint, ctx, spherical_dir(60.0 * rng.next_double(), 360.0 * rng.next_double()));
          out[2 * i + 1] = s.eval[0];
        }
      });
    for (auto &th : pool) th.join();
    return out;
  };
  const std::vector<float> one = run(1), four = run(4);
  int nonzero = 0;
  for (float v : one) nonzero += v > 0.0f;
  EXPECT_GT(nonzero, 100) << roughness;
  EXPECT_EQ(0, std::memcmp(one.data(), four.data(), one.size() * sizeof(float))) << roughness;
  }
}

// chi2 of sample() against pdf over 24 configurations (Sidak-corrected over the 24). `make test` runs the corners
// (as test_glint_jakob14.cpp's: GGX r=0.2 and Beckmann r=0.9 at normal incidence, GGX r=0.9 and Beckmann r=0.2 at
// 70 degrees) and the widened path spread at GGX r=0.2 and Beckmann r=0.9, 6 configurations with the seeds and the
// threshold of the full family; Chi2SamplerMatchesPdfStress (`make stress`) all 24.
void expect_glint_sampler_matches_pdf(bool full) {
  std::vector<Chi2Config> configs;
  for (const char *dist : {"ggx", "beckmann"})
    for (const char *rough : {"0.2", "0.5", "0.9"}) {
      const bool ggx = std::string(dist) == "ggx", r02 = std::string(rough) == "0.2", r09 = std::string(rough) == "0.9";
      // An instance builds its tables (seconds): none for a roughness whose configurations all wait for the twin.
      auto c = full || r02 || r09
                   ? make_closure("glint",
                                  {{"distribution", dist}, {"roughness", rough}, {"gamma", "2"}, {"density", "1e6"}})
                   : nullptr;
      const double corner_theta = ggx == r02 ? 0.0 : 70.0;  // GGX r=0.2 and Beckmann r=0.9 at normal incidence
      for (double theta_i : {0.0, 40.0, 70.0}) {
        const Vec3 wi = spherical_dir(theta_i, 0.0);
        configs.push_back({std::string(dist) + " r=" + rough + " theta_i " + std::to_string(theta_i), c, wi});
        configs.back().stress_only = !(r02 || r09) || theta_i != corner_theta;
      }
      // One with a widened path spread (LOD + widened sampling lobe) and a footprint.
      const Vec3 wi = spherical_dir(30.0, 0.0);
      GlimmerShadingContext ctx = context(wi, 0.3, 0.3, 1e-3, static_cast<float>(10.0 * kDeg));
      configs.push_back({std::string(dist) + " r=" + rough + " spread 10deg", c, wi, ctx});
      configs.back().stress_only = !(ggx ? r02 : r09);
    }
  ASSERT_EQ(configs.size(), 24u);
  size_t run = 0;
  for (const auto &c : configs) run += full || !c.stress_only;
  ASSERT_EQ(run, full ? 24u : 6u);
  expect_chi2_family(configs, {}, full);
}

TEST(Glint, Chi2SamplerMatchesPdf) { expect_glint_sampler_matches_pdf(false); }

TEST(Glint, Chi2SamplerMatchesPdfStress) {
  if (stress_scale() == 1) GTEST_SKIP() << "make stress only";
  expect_glint_sampler_matches_pdf(true);
}

TEST(Glint, EvalPdfConsistentWithSample) {
  auto glint = make_closure("glint", {{"roughness", "0.4"}, {"density", "1e6"}});
  for (double theta_i : {0.0, 30.0, 60.0, 85.0})
    for (double side : {0.0, 1e-4, 1e-2})
      EXPECT_TRUE(consistent(*glint, context(spherical_dir(theta_i, 0.0), 0.4, 0.6, side), 1e-4, 100000));
}

TEST(Glint, StressNoNanInfNegative) {
  std::vector<std::shared_ptr<host::ClosureInstance>> keep;
  std::vector<const host::ClosureInstance *> instances;
  for (const char *dist : {"ggx", "beckmann"})
    for (const auto &[rough, gamma, density] :
         std::vector<std::tuple<const char *, const char *, const char *>>{
             {"0.0001", "0.1", "1"}, {"1", "10", "1e12"}, {"0.5", "2", "1e6"},
             // lobes narrower than the cone: pseudo-normals
             {"0.2", "2", "1e6"}, {"0.15", "6", "1e9"}}) {
      keep.push_back(make_closure("glint", {{"distribution", dist}, {"roughness", rough}, {"gamma", gamma},
                                            {"density", density}, {"uv_scale", "1000"}}));
      instances.push_back(keep.back().get());
    }
  EXPECT_TRUE(stress_clean(instances, 50000 * instances.size()));  // 50000 calls per instance
}

// The footprint's finiteness guard (ParticleField::valid_footprint, x - x == 0 since session 25) still fires in the
// closure: a NaN or infinite uv is read as uv (0, 0), and a NaN or infinite uv differential as the point query (a
// zero footprint), so those evals equal the evals at the sanitised context bit for bit (f and pdf), and are finite.
// Negative control: the same comparison against uv (0.5, 0.5) instead of (0, 0) differs.
TEST(Glint, NonFiniteFootprintIsSanitised) {
  auto glint = make_closure("glint", {{"roughness", "0.3"}, {"density", "1e6"}});
  const float inf = std::numeric_limits<float>::infinity(), nan = std::numeric_limits<float>::quiet_NaN();
  Pcg32 rng(25);
  int compared = 0, lit = 0, control_differs = 0;
  for (int i = 0; i < 3000; ++i) {
    const double theta = 60.0 * rng.next_double();
    const Vec3 wi = spherical_dir(theta, 0.0);
    const Vec3 wo = spherical_dir(theta + 10.0 * (rng.next_double() - 0.5), 180.0 + 10.0 * (rng.next_double() - 0.5));
    const float bad = i % 3 == 0 ? nan : (i % 3 == 1 ? inf : -inf);
    const double side = 6e-3;  // ~36 particles: glint mode, a few lit
    // uv not finite: as uv (0, 0)
    GlimmerShadingContext c_bad = footprint_context(wi, 0.0, 0.0, side, 0.0, 0.0, side);
    c_bad.uv[i % 2] = bad;
    const GlimmerShadingContext c_origin = footprint_context(wi, 0.0, 0.0, side, 0.0, 0.0, side);
    const GlimmerShadingContext c_control = footprint_context(wi, 0.5, 0.5, side, 0.0, 0.0, side);
    // a differential not finite: the point query, as a zero footprint
    GlimmerShadingContext d_bad = footprint_context(wi, 0.3, 0.7, side, 0.0, 0.0, side);
    (i % 4 < 2 ? d_bad.duv_dx : d_bad.duv_dy)[i % 2] = bad;
    const GlimmerShadingContext d_point = footprint_context(wi, 0.3, 0.7, 0.0, 0.0, 0.0, 0.0);
    float p_bad, p_ref, q_bad, q_ref, p_control;
    const float f_bad = eval_f(*glint, c_bad, wo, &p_bad), f_ref = eval_f(*glint, c_origin, wo, &p_ref);
    const float g_bad = eval_f(*glint, d_bad, wo, &q_bad), g_ref = eval_f(*glint, d_point, wo, &q_ref);
    const float f_control = eval_f(*glint, c_control, wo, &p_control);
    ASSERT_TRUE(std::isfinite(f_bad) && std::isfinite(g_bad) && std::isfinite(p_bad) && std::isfinite(q_bad)) << i;
    ASSERT_EQ(f_bad, f_ref) << i;
    ASSERT_EQ(p_bad, p_ref) << i;
    ASSERT_EQ(g_bad, g_ref) << i;
    ASSERT_EQ(q_bad, q_ref) << i;
    ++compared;
    lit += f_ref > 0.0f || g_ref > 0.0f;
    control_differs += f_control != f_ref;
  }
  std::printf("[non-finite footprint] %d evals equal to the sanitised context's (%d lit); control (uv 0.5) differs "
              "on %d\n", compared, lit, control_differs);
  EXPECT_GT(lit, 100);
  EXPECT_GT(control_differs, 50);
}

// The seed is an integer taken exactly (ABI 2.2 payload): 2^24 and 2^24 + 1,
// one float apart from nothing, are different particle fields (a seed read as
// a float would make them one field), and each field is its own seed's.
TEST(Glint, SeedsBeyondTwoToThe24AreDistinctFields) {
  // The glints one closure shows: eval over many small footprints and directions.
  auto glints = [](const std::string &seed) {
    auto glint = make_closure("glint", {{"roughness", "0.3"}, {"density", "1e6"}, {"seed", seed}});
    std::vector<float> out;
    Pcg32 rng(17);
    for (int i = 0; i < 4000; ++i) {  // wo near the mirror direction of wi, ~100 particles per footprint
      const double theta = 60.0 * rng.next_double();
      const Vec3 wi = spherical_dir(theta, 0.0);
      const Vec3 wo = spherical_dir(theta + 20.0 * (rng.next_double() - 0.5), 180.0 + 20.0 * (rng.next_double() - 0.5));
      out.push_back(eval_f(*glint, context(wi, rng.next_double(), rng.next_double(), 1e-2), wo));
    }
    return out;
  };
  const std::vector<float> a = glints("16777216"), b = glints("16777217"), a_again = glints("16777216");
  int lit = 0, differing = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    lit += a[i] > 0.0f;
    differing += a[i] != b[i];
  }
  EXPECT_GT(lit, 100);                    // the footprints do show glints
  EXPECT_GT(differing, lit / 2);          // another field: most lit queries change
  EXPECT_EQ(a, a_again);                  // a seed gives one field
  EXPECT_NO_THROW(make_closure("glint", {{"seed", "2147483648"}}));
  EXPECT_THROW(make_closure("glint", {{"seed", "2147483649"}}), host::ClosureError);
}

TEST(Glint, RejectsBadParametersWithTheirName) {
  for (const auto &[name, value] : std::vector<std::pair<std::string, std::string>>{
           {"roughness", "1.5"}, {"gamma", "0"}, {"density", "-3"}, {"distribution", "phong"}, {"uv_scale", "0"}}) {
    try {
      make_closure("glint", {{name, value}});
      ADD_FAILURE() << name << "=" << value << " was accepted";
    } catch (const std::exception &e) {
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
    }
  }
}

// Tables are cached on disk keyed by their parameters; a corrupt cache file
// is rebuilt with a warning and gives identical results.
std::vector<std::string> g_log;
void capture_log(void *, int level, const char *message) {
  g_log.push_back(std::to_string(level) + ": " + message);
}

TEST(Glint, CorruptTableCacheIsRebuiltWithAWarning) {
  const std::string dir = GLIMMER_TEST_BINARY_DIR "/test_cache_glint_corrupt";
  std::filesystem::remove_all(dir);
  GlimmerHostServices host = *host::default_host_services();
  host.cache_dir = dir.c_str();
  host.log = &capture_log;
  const GlimmerClosureType &type = closure_type("glint");
  host::ParamList params;
  params.set_from_text(type, "roughness", "0.55");
  params.set_from_text(type, "gamma", "3");
  const Vec3 wi = spherical_dir(35.0, 0.0), wo = spherical_dir(40.0, 170.0);
  float first;
  {
    g_log.clear();
    host::ClosureInstance c(type, params, &host);
    first = eval_f(c, context(wi, 0.5, 0.5, 0.1), wo);
    bool reported_time = false;
    for (const auto &m : g_log) reported_time |= m.find("precomputed") != std::string::npos;
    EXPECT_TRUE(reported_time) << "the precompute time must be logged";
  }
  std::vector<std::filesystem::path> files;
  for (const auto &e : std::filesystem::directory_iterator(dir))
    if (e.path().filename().string().rfind("glint_P_", 0) == 0) files.push_back(e.path());  // not secret.key
  ASSERT_EQ(files.size(), 1u);
  {  // A second instance loads the file silently (no precompute).
    g_log.clear();
    host::ClosureInstance c(type, params, &host);
    EXPECT_EQ(eval_f(c, context(wi, 0.5, 0.5, 0.1), wo), first);
    for (const auto &m : g_log) EXPECT_EQ(m.find("precomputed"), std::string::npos) << m;
  }
  {  // Corrupt a byte in the middle.
    std::fstream f(files[0], std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(static_cast<std::streamoff>(std::filesystem::file_size(files[0]) / 2));
    const char junk[4] = {'\x7f', '\x7f', '\x7f', '\x7f'};
    f.write(junk, 4);
  }
  {
    g_log.clear();
    host::ClosureInstance c(type, params, &host);
    EXPECT_EQ(eval_f(c, context(wi, 0.5, 0.5, 0.1), wo), first);
    bool warned = false;
    for (const auto &m : g_log) warned |= m.rfind("2: ", 0) == 0 && m.find("recomputing") != std::string::npos;
    EXPECT_TRUE(warned) << "expected a warning about the corrupt cache";
  }
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace glimmer::test
