// Smith G model difference against Cycles 3.4 (docs/microfacet.md, "Differences from Cycles 3.4"): Glimmer
// uses the height-correlated G2 = 1 / (1 + Lambda_i + Lambda_o) (Heitz 2014 eq. 99, as Cycles 4.x); Cycles 3.4
// the separable G1(wi) G1(wo). This measures the white GGX conductor's single-scatter albedo
// E(mu) = integral f cos dwo under both, by visible-normal sampling (weight G2 / G1(wi) resp. G1(wo)), and
// prints the table the doc quotes. Checks: height-correlated >= separable everywhere (G2 >= G1 G1), both
// estimators reach 1 for a nearly smooth surface (validation), and the documented sizes at roughness 0.9 (the models agree at normal incidence, where Lambda_i = 0).
#include <gtest/gtest.h>

#include <cstdio>

#include "glimmer/microfacet.h"
#include "glimmer/rng.h"

namespace glimmer {
namespace {

namespace mf = glimmer::microfacet;

struct Albedos {
  double height_correlated = 0.0, separable = 0.0;
};

Albedos white_ggx_albedo(float alpha, float mu, int samples) {
  const Vec3 wi(std::sqrt(1.0f - mu * mu), 0.0f, mu);
  Albedos a;
  for (int i = 0; i < samples; ++i) {
    const float u1 = (i + 0.5f) / samples;  // stratified in u1, van der Corput in u2
    uint32_t r = static_cast<uint32_t>(i);
    r = (r << 16) | (r >> 16);
    r = ((r & 0x00ff00ffu) << 8) | ((r & 0xff00ff00u) >> 8);
    r = ((r & 0x0f0f0f0fu) << 4) | ((r & 0xf0f0f0f0u) >> 4);
    r = ((r & 0x33333333u) << 2) | ((r & 0xccccccccu) >> 2);
    r = ((r & 0x55555555u) << 1) | ((r & 0xaaaaaaaau) >> 1);
    const float u2 = uint_to_unit_float(r);
    const Vec3 m = mf::sample_visible_normal(mf::Distribution::GGX, wi, alpha, alpha, u1, u2);
    const Vec3 wo = mf::reflect_about(wi, m);
    if (!(wo.z > 0.0f)) continue;
    a.height_correlated += mf::G2(mf::Distribution::GGX, wi, wo, alpha, alpha) /
                           mf::G1(mf::Distribution::GGX, wi, alpha, alpha);
    a.separable += mf::G1(mf::Distribution::GGX, wo, alpha, alpha);
  }
  a.height_correlated /= samples;
  a.separable /= samples;
  return a;
}

TEST(SmithGModels, HeightCorrelatedVersusSeparableAlbedo) {
  const int n = 1 << 18;
  const Albedos smooth = white_ggx_albedo(1e-3f, 0.5f, 4096);
  EXPECT_NEAR(smooth.height_correlated, 1.0, 1e-3);
  EXPECT_NEAR(smooth.separable, 1.0, 1e-3);
  for (float roughness : {0.3f, 0.6f, 0.9f}) {
    const float alpha = roughness * roughness;
    double avg_hc = 0.0, avg_sep = 0.0;  // cosine-weighted hemispherical averages, 2 int E(mu) mu dmu
    const int nodes = 32;
    for (int k = 0; k < nodes; ++k) {
      const float mu = (k + 0.5f) / nodes;
      const Albedos a = white_ggx_albedo(alpha, mu, n / 8);
      avg_hc += 2.0 * a.height_correlated * mu / nodes;
      avg_sep += 2.0 * a.separable * mu / nodes;
      EXPECT_GE(a.height_correlated, a.separable - 1e-6) << "roughness " << roughness << " mu " << mu;
    }
    std::printf("[smith G] roughness %.1f: E_avg height-correlated %.4f, separable %.4f (+%.2f %%);", roughness, avg_hc,
                avg_sep, 100.0 * (avg_hc / avg_sep - 1.0));
    for (float mu : {1.0f, 0.5f, 0.2f, 0.05f}) {
      const Albedos a = white_ggx_albedo(alpha, mu, n);
      std::printf("  mu %.2f: %.4f vs %.4f (+%.2f %%)", mu, a.height_correlated, a.separable,
                  100.0 * (a.height_correlated / a.separable - 1.0));
      if (mu == 1.0f) {
        EXPECT_NEAR(a.height_correlated / a.separable, 1.0, 1e-4);  // Lambda_i = 0: the models agree
      }
      if (roughness == 0.9f && mu == 0.5f) {  // documented: +6.1 %
        EXPECT_GT(a.height_correlated / a.separable, 1.055);
        EXPECT_LT(a.height_correlated / a.separable, 1.067);
      }
    }
    std::printf("\n");
    if (roughness == 0.9f) {  // documented: +5.2 % on the cosine-weighted average
      EXPECT_GT(avg_hc / avg_sep, 1.045);
      EXPECT_LT(avg_hc / avg_sep, 1.058);
    }
  }
}

}  // namespace
}  // namespace glimmer
