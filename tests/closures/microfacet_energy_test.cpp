// Energy of the microfacet closures through the C ABI:
//  - white furnace of the compensated (multi_ggx) conductor (f0 = 1) and glass
//    (R + T) over alpha in [0.01, 1], eta in [1.01, 3] and 1/eta, mu in [0.02, 1];
//  - the compensated conductor's directional albedo against the Heitz 2016
//    random walk (microfacet_random_walk) for f0 in {0.04, 0.5, 0.9, 1}.
// Albedo = mean of sample weights f_cos / pdf over jittered-stratified random numbers.
#include <tbb/parallel_for.h>

#include <cstdio>

#include "closures/microfacet_test_util.h"
#include "glimmer/microfacet_walk.h"

namespace {

using namespace glimmer;
using namespace glimmer::mftest;
namespace mf = glimmer::microfacet;

std::string num(float v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.7g", double(v));
  return b;
}

Vec3 wi_at(float mu) { return normalize(Vec3(std::sqrt(std::max(0.0f, 1.0f - mu * mu)), 0.0f, mu)); }

struct FurnaceCase {
  std::string closure;
  std::vector<std::string> params;
  float mu;
};

// multi_ggx conductor (f0 = 1) and glass (R + T, both IOR directions) over 6 alpha x 6 mu x 6 IOR (468 cases) under
// make stress (WhiteFurnaceCompensatedStress); make test runs the 63 at alpha 0.01 / 0.3 / 1, mu 0.02 / 0.3 / 1 and
// IOR 1.01 / 1.5 / 3 (and their inverses). Each case keeps its seed (77 + its index in the full set) and the tolerance.
void expect_white_furnace_compensated(bool full) {
  const float alphas[] = {0.01f, 0.03f, 0.1f, 0.3f, 0.6f, 1.0f};
  const float mus[] = {0.02f, 0.05f, 0.1f, 0.3f, 0.6f, 1.0f};
  const float iors[] = {1.01f, 1.1f, 1.33f, 1.5f, 2.0f, 3.0f};
  auto in_make_test = [](float a, float mu, float ior) {
    return (a == 0.01f || a == 0.3f || a == 1.0f) && (mu == 0.02f || mu == 0.3f || mu == 1.0f) &&
           (ior == 1.01f || ior == 1.5f || ior == 3.0f);
  };
  std::vector<FurnaceCase> cases;
  std::vector<size_t> run;  // indices into cases
  for (float a : alphas)
    for (float mu : mus) {
      if (full || in_make_test(a, mu, 1.5f)) run.push_back(cases.size());
      cases.push_back({"microfacet_conductor", {"distribution=multi_ggx", "roughness=" + num(std::sqrt(a))}, mu});
      for (float ior : iors)
        for (float e : {ior, 1.0f / ior}) {
          if (full || in_make_test(a, mu, ior)) run.push_back(cases.size());
          cases.push_back(
              {"microfacet_dielectric", {"distribution=multi_ggx", "roughness=" + num(std::sqrt(a)), "ior=" + num(e)}, mu});
        }
    }
  std::vector<Albedo> results(cases.size());
  tbb::parallel_for(size_t(0), run.size(), [&](size_t k) {
    const size_t i = run[k];
    auto c = make_closure(cases[i].closure, cases[i].params);
    results[i] = sampled_albedo(*c, wi_at(cases[i].mu), cases[i].mu <= 0.05f ? 256 : 128, 77 + i);
  });
  double worst_conductor = 0.0, worst_dielectric = 0.0;
  for (const size_t i : run) {
    const double err = std::fabs(1.0 - results[i].mean.x);
    std::string label = cases[i].closure;
    for (const auto &p : cases[i].params) label += " " + p;
    EXPECT_LT(err, 0.005) << label << " mu=" << cases[i].mu << " albedo=" << results[i].mean.x
                          << " +- " << results[i].std_error;
    (cases[i].closure == "microfacet_conductor" ? worst_conductor : worst_dielectric) =
        std::max(cases[i].closure == "microfacet_conductor" ? worst_conductor : worst_dielectric, err);
  }
  std::printf("[furnace] %zu of %zu cases (2^20 stratified samples at mu <= 0.05, 2^17 above): max |1 - albedo| "
              "conductor(f0=1) %.4f%%, glass R+T %.4f%%\n", run.size(), cases.size(), 100 * worst_conductor,
              100 * worst_dielectric);
}

TEST(MicrofacetEnergy, WhiteFurnaceCompensated) { expect_white_furnace_compensated(false); }

TEST(MicrofacetEnergy, WhiteFurnaceCompensatedStress) {
  if (stress_scale() == 1) GTEST_SKIP() << "make stress only";
  expect_white_furnace_compensated(true);
}

// Where no light strategy is MIS-combined (GLIMMER_SAMPLING_UNCOMBINED), the isotropic multi_ggx conductor
// samples its Fresnel-free f cos exactly (docs/microfacet.md), so for white F every sample weighs the albedo 1:
// the per-sample relative standard deviation of f cos / pdf is the tables' interpolation error only. Negative
// control: the same lobes without the flag (the lobe mixture) spread the weight by G2 / G1. Measured: exact
// <= 0.0026 (roughness 0.3, mu 0.2: E_Fms(1) and 1 - E from the tables differ where 1 - E is small), mixture
// >= 0.17 at roughness >= 0.6.
TEST(MicrofacetEnergy, ExactSamplingGivesConstantWeightForWhiteMultiGgx) {
  constexpr uint64_t kSamples = 1u << 14;
  double worst_exact = 0.0, worst_albedo = 0.0, least_mixture = 1e30;
  for (float roughness : {0.3f, 0.6f, 0.9f, 1.0f})
    for (float mu : {0.05f, 0.2f, 0.5f, 1.0f}) {
      auto c = make_closure("microfacet_conductor", {"distribution=multi_ggx", "roughness=" + num(roughness)});
      auto relative_std = [&](uint32_t flags, double &albedo) {
        GlimmerShadingContext ctx = host::make_local_context(wi_at(mu));
        ctx.sampling_flags = flags;
        const lab::FurnaceResult r = lab::furnace(*c, ctx, kSamples, 91);
        EXPECT_EQ(r.invalid_count, 0u);
        albedo = r.albedo.x;
        return r.standard_error.x * std::sqrt(double(kSamples)) / r.albedo.x;
      };
      double albedo_exact = 0.0, albedo_mixture = 0.0;
      const double exact = relative_std(GLIMMER_SAMPLING_UNCOMBINED, albedo_exact);
      const double mixture = relative_std(0u, albedo_mixture);
      EXPECT_LT(exact, 5e-3) << "roughness " << roughness << " mu " << mu;
      EXPECT_NEAR(albedo_exact, 1.0, 5e-3) << "roughness " << roughness << " mu " << mu;
      worst_exact = std::max(worst_exact, exact);
      worst_albedo = std::max(worst_albedo, std::fabs(albedo_exact - 1.0));
      if (roughness >= 0.6f) least_mixture = std::min(least_mixture, mixture);
    }
  EXPECT_GT(least_mixture, 0.05);
  std::printf("[exact multi_ggx] per-sample relative std of the weight: exact <= %.3g (max |albedo - 1| %.3g), "
              "mixture >= %.3g at roughness >= 0.6\n", worst_exact, worst_albedo, least_mixture);
}

// Uncompensated GGX loses energy (the furnace test above is not vacuous).
TEST(MicrofacetEnergy, UncompensatedLosesEnergy) {
  auto c = make_closure("microfacet_conductor", {"distribution=ggx", "roughness=1"});
  const Albedo a = sampled_albedo(*c, wi_at(0.5f), 64, 5);
  EXPECT_LT(a.mean.x, 0.9f);
  auto g = make_closure("microfacet_dielectric", {"distribution=ggx", "roughness=1", "ior=1.5"});
  EXPECT_LT(sampled_albedo(*g, wi_at(0.5f), 64, 6).mean.x, 0.95f);
}

// Random-walk albedo = mean sampled throughput (f_cos / pdf is the walk's throughput).
Spectrum random_walk_albedo(const host::ClosureInstance &c, const Vec3 &wi, long walks, uint64_t seed) {
  GlimmerShadingContext ctx = host::make_local_context(wi);
  Pcg32 rng(seed);
  double sum[3] = {0, 0, 0};
  for (long i = 0; i < walks; ++i) {
    ctx.path_seed = uint32_t(i * 2654435761u + seed);
    const float u[3] = {rng.next_float(), rng.next_float(), rng.next_float()};
    GlimmerSample s = glimmer_blank_sample();
    if (c.sample(ctx, u, s) == GLIMMER_LABEL_NONE) continue;
    for (int k = 0; k < 3; ++k) sum[k] += s.eval[k] / s.pdf;
  }
  return Spectrum(float(sum[0] / walks), float(sum[1] / walks), float(sum[2] / walks));
}

TEST(MicrofacetEnergy, CompensatedConductorMatchesRandomWalk) {
  struct Case {
    float alpha, mu;
  };
  std::vector<Case> cases;
  for (float a : {0.05f, 0.2f, 0.5f, 1.0f})
    for (float mu : {0.1f, 0.4f, 0.8f, 1.0f}) cases.push_back({a, mu});
  // Each case carries the four f0 in its RGB channels plus f0 = 1 separately.
  std::vector<Spectrum> comp(cases.size()), walk(cases.size());
  std::vector<float> comp_white(cases.size()), walk_white(cases.size());
  tbb::parallel_for(size_t(0), cases.size(), [&](size_t i) {
    const std::string r = "roughness=" + num(std::sqrt(cases[i].alpha));
    const Vec3 wi = wi_at(cases[i].mu);
    auto c = make_closure("microfacet_conductor", {"distribution=multi_ggx", r, "f0=0.04,0.5,0.9"});
    auto w = make_closure("microfacet_random_walk", {"type=conductor", r, "f0=0.04,0.5,0.9"});
    auto cw = make_closure("microfacet_conductor", {"distribution=multi_ggx", r});
    auto ww = make_closure("microfacet_random_walk", {"type=conductor", r});
    comp[i] = sampled_albedo(*c, wi, 128, 100 + i).mean;
    walk[i] = random_walk_albedo(*w, wi, 200000, 200 + i);
    comp_white[i] = sampled_albedo(*cw, wi, 96, 300 + i).mean.x;
    walk_white[i] = random_walk_albedo(*ww, wi, 50000, 400 + i).x;
  });
  double worst[4] = {0, 0, 0, 0};
  for (size_t i = 0; i < cases.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      const double rel = std::fabs(comp[i][k] - walk[i][k]) / walk[i][k];
      EXPECT_LT(rel, 0.01) << "alpha=" << cases[i].alpha << " mu=" << cases[i].mu << " f0=" << (k == 0 ? 0.04 : k == 1 ? 0.5 : 0.9)
                           << " compensated=" << comp[i][k] << " walk=" << walk[i][k];
      worst[k] = std::max(worst[k], rel);
    }
    const double rel = std::fabs(comp_white[i] - walk_white[i]) / walk_white[i];
    EXPECT_LT(rel, 0.01) << "alpha=" << cases[i].alpha << " mu=" << cases[i].mu << " f0=1";
    worst[3] = std::max(worst[3], rel);
  }
  std::printf("[random walk] compensated conductor vs Heitz 2016 walk, max relative albedo error: f0=0.04 %.3f%%, "
              "f0=0.5 %.3f%%, f0=0.9 %.3f%%, f0=1 %.3f%%\n", 100 * worst[0], 100 * worst[1], 100 * worst[2],
              100 * worst[3]);
}

// Cycles' Multiscatter GGX colour c multiplies every bounce of the walk: albedo
// sum_k p_k c^k. The host applies c once as the closure weight; the closure with
// bounce_tint = c must give the rest, sum_k p_k c^(k-1) (single bounce: E).
// Reference: Heitz walks with that per-bounce weight, in this test. Also f0
// (Schlick) and the tint together (tables::ggx_ms_node's effective per-bounce
// Fresnel), against walks weighted c (f0 + (1 - f0) s) per bounce.
TEST(MicrofacetEnergy, BounceTintMatchesTintedRandomWalk) {
  struct Case {
    float alpha, mu;
  };
  std::vector<Case> cases;
  for (float a : {0.1f, 0.4f, 0.7f, 1.0f})
    for (float mu : {0.1f, 0.5f, 1.0f}) cases.push_back({a, mu});
  const Spectrum tint(0.2f, 0.5f, 0.8f);
  const Spectrum f0_mixed(0.9f, 0.3f, 0.05f);
  std::vector<Spectrum> comp(cases.size()), walk(cases.size()), comp_mixed(cases.size()), walk_mixed(cases.size());
  tbb::parallel_for(size_t(0), cases.size(), [&](size_t i) {
    const std::string r = "roughness=" + num(std::sqrt(cases[i].alpha));
    const Vec3 wi = wi_at(cases[i].mu);
    auto c = make_closure("microfacet_conductor", {"distribution=multi_ggx", r, "bounce_tint=0.2,0.5,0.8"});
    auto m = make_closure("microfacet_conductor",
                          {"distribution=multi_ggx", r, "bounce_tint=0.2,0.5,0.8", "f0=0.9,0.3,0.05"});
    comp[i] = sampled_albedo(*c, wi, 128, 500 + i).mean;
    comp_mixed[i] = sampled_albedo(*m, wi, 128, 600 + i).mean;
    mf::WalkRng rng(700u + uint32_t(i));
    const mf::WalkSurface surface{cases[i].alpha, cases[i].alpha};
    const long walks = 400000;
    double sum[3] = {0, 0, 0}, sum_mixed[3] = {0, 0, 0};
    for (long n = 0; n < walks; ++n) {
      double weight[3] = {1, 1, 1}, weight_mixed[3] = {1, 1, 1};
      int order = 0, bounce = 0;
      mf::walk_conductor(wi, surface, rng, order, [&](float cos_facet) {
        const double s = mf::schlick_weight(cos_facet);
        for (int k = 0; k < 3; ++k) {
          // The first factor c is the host's closure weight: not in the closure.
          const double ck = bounce == 0 ? 1.0 : tint[k];
          weight[k] *= ck;
          weight_mixed[k] *= ck * (f0_mixed[k] + (1.0 - f0_mixed[k]) * s);
        }
        ++bounce;
      });
      if (order == 0) continue;
      for (int k = 0; k < 3; ++k) sum[k] += weight[k], sum_mixed[k] += weight_mixed[k];
    }
    for (int k = 0; k < 3; ++k) walk[i][k] = float(sum[k] / walks), walk_mixed[i][k] = float(sum_mixed[k] / walks);
  });
  double worst = 0.0, worst_mixed = 0.0;
  for (size_t i = 0; i < cases.size(); ++i)
    for (int k = 0; k < 3; ++k) {
      const double rel = std::fabs(comp[i][k] - walk[i][k]) / walk[i][k];
      const double rel_mixed = std::fabs(comp_mixed[i][k] - walk_mixed[i][k]) / walk_mixed[i][k];
      EXPECT_LT(rel, 0.01) << "alpha=" << cases[i].alpha << " mu=" << cases[i].mu << " tint=" << tint[k]
                           << " closure=" << comp[i][k] << " walk=" << walk[i][k];
      EXPECT_LT(rel_mixed, 0.01) << "f0=" << f0_mixed[k] << " alpha=" << cases[i].alpha << " mu=" << cases[i].mu
                                 << " tint=" << tint[k] << " closure=" << comp_mixed[i][k] << " walk=" << walk_mixed[i][k];
      worst = std::max(worst, rel);
      worst_mixed = std::max(worst_mixed, rel_mixed);
    }
  std::printf("[bounce tint] multi_ggx with bounce_tint 0.2/0.5/0.8 vs tinted Heitz walks (12 (alpha, mu)): max "
              "relative albedo error %.3f%%; with f0 = 0.9/0.3/0.05 too (effective per-bounce Fresnel) %.3f%%\n",
              100 * worst, 100 * worst_mixed);
}

// The dielectric random walk conserves energy (R + T = 1) from both sides,
// and the conductor walk with f0 = 1 as well.
TEST(MicrofacetEnergy, RandomWalkConservesEnergy) {
  for (float ior : {1.5f, 1.0f / 1.5f}) {
    auto w = make_closure("microfacet_random_walk", {"type=dielectric", "roughness=0.8", "ior=" + num(ior)});
    for (float mu : {0.9f, 0.3f, -0.4f}) {
      const Vec3 wi = mu > 0 ? wi_at(mu) : Vec3(wi_at(-mu).x, 0.0f, mu);
      EXPECT_NEAR(random_walk_albedo(*w, wi, 20000, 9).x, 1.0f, 1e-3f) << "ior=" << ior << " mu=" << mu;
    }
  }
}

}  // namespace
