// Checks of shared/include/glimmer/microfacet.h against brute-force quadrature.
#include <gtest/gtest.h>

#include <cmath>

#include "glimmer/microfacet.h"
#include "glimmer/rng.h"

namespace {

using namespace glimmer;
using namespace glimmer::microfacet;

// Midpoint quadrature over the upper hemisphere in (cos theta, phi) of g(wh).
template <typename F>
double integrate_hemisphere(F &&g, int n_theta = 1024, int n_phi = 512) {
  double sum = 0.0;
  for (int i = 0; i < n_theta; ++i) {
    // cos theta = 1 - t^2 concentrates nodes near the pole where D peaks.
    const double t0 = double(i) / n_theta, t1 = double(i + 1) / n_theta;
    const double tm = 0.5 * (t0 + t1);
    const double z = 1.0 - tm * tm, dz = (t1 * t1 - t0 * t0);
    const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
    for (int j = 0; j < n_phi; ++j) {
      const double phi = 2.0 * M_PI * (j + 0.5) / n_phi;
      const Vec3 w(float(r * std::cos(phi)), float(r * std::sin(phi)), float(z));
      sum += g(w) * dz * (2.0 * M_PI / n_phi);
    }
  }
  return sum;
}

struct Case {
  Distribution dist;
  float ax, ay;
};

TEST(MicrofacetPrimitives, ProjectedAreaAndVisibleNormalsNormalized) {
  const Case cases[] = {{Distribution::GGX, 0.3f, 0.3f},     {Distribution::GGX, 0.8f, 0.2f},
                        {Distribution::GGX, 1.0f, 1.0f},     {Distribution::Beckmann, 0.3f, 0.3f},
                        {Distribution::Beckmann, 0.7f, 0.15f}, {Distribution::Beckmann, 1.0f, 1.0f}};
  for (const Case &c : cases) {
    const double proj = integrate_hemisphere([&](const Vec3 &m) { return D(c.dist, m, c.ax, c.ay) * m.z; });
    EXPECT_NEAR(proj, 1.0, 2e-3) << int(c.dist) << " " << c.ax << " " << c.ay;
    for (float wz : {1.0f, 0.7f, 0.2f, 0.02f}) {
      const Vec3 wi = normalize(Vec3(std::sqrt(1 - wz * wz) * 0.6f, std::sqrt(1 - wz * wz) * 0.8f, wz));
      const double vis = integrate_hemisphere([&](const Vec3 &m) { return visible_D(c.dist, wi, m, c.ax, c.ay); });
      EXPECT_NEAR(vis, 1.0, 3e-3) << int(c.dist) << " " << c.ax << " wz=" << wz;
    }
  }
}

// The sampled normals' moments match the quadrature moments of visible_D.
TEST(MicrofacetPrimitives, VisibleNormalSamplingMoments) {
  const Case cases[] = {{Distribution::GGX, 0.5f, 0.5f}, {Distribution::GGX, 0.9f, 0.2f},
                        {Distribution::Beckmann, 0.5f, 0.5f}, {Distribution::Beckmann, 0.9f, 0.25f}};
  for (const Case &c : cases) {
    for (float wz : {0.9f, 0.3f, 0.05f}) {
      const Vec3 wi = normalize(Vec3(std::sqrt(1 - wz * wz) * 0.6f, std::sqrt(1 - wz * wz) * 0.8f, wz));
      Pcg32 rng(11);
      const int n = 200000;
      double mx = 0, my = 0, mz = 0;
      for (int i = 0; i < n; ++i) {
        const Vec3 m = sample_visible_normal(c.dist, wi, c.ax, c.ay, rng.next_float(), rng.next_float());
        ASSERT_TRUE(is_finite(m));
        mx += m.x; my += m.y; mz += m.z;
      }
      const double qx = integrate_hemisphere([&](const Vec3 &m) { return m.x * visible_D(c.dist, wi, m, c.ax, c.ay); });
      const double qy = integrate_hemisphere([&](const Vec3 &m) { return m.y * visible_D(c.dist, wi, m, c.ax, c.ay); });
      const double qz = integrate_hemisphere([&](const Vec3 &m) { return m.z * visible_D(c.dist, wi, m, c.ax, c.ay); });
      EXPECT_NEAR(mx / n, qx, 4e-3) << int(c.dist) << " wz=" << wz;
      EXPECT_NEAR(my / n, qy, 4e-3) << int(c.dist) << " wz=" << wz;
      EXPECT_NEAR(mz / n, qz, 4e-3) << int(c.dist) << " wz=" << wz;
    }
  }
}

TEST(MicrofacetPrimitives, FresnelLimits) {
  EXPECT_NEAR(fresnel_dielectric(1.0f, 1.5f), 0.04f, 1e-6f);
  EXPECT_EQ(fresnel_dielectric(0.1f, 1.0f / 1.5f), 1.0f);  // TIR
  EXPECT_NEAR(fresnel_dielectric(-1.0f, 1.0f / 1.5f), 0.04f, 1e-6f);
  EXPECT_NEAR(fresnel_dielectric(0.5f, 1.0f), 0.0f, 1e-7f);
  EXPECT_NEAR(fresnel_conductor(1.0f, 1.5f, 0.0f), 0.04f, 1e-5f);
  EXPECT_NEAR(fresnel_conductor(1e-4f, 0.2f, 3.0f), 1.0f, 1e-2f);
  Vec3 wt;
  const Vec3 wi = normalize(Vec3(0.5f, 0.0f, 0.8f));
  ASSERT_TRUE(refract(wi, Vec3(0, 0, 1), 1.5f, wt));
  EXPECT_NEAR(std::sqrt(1 - wt.z * wt.z) * 1.5f, std::sqrt(1 - wi.z * wi.z), 1e-5f);
  Vec3 wh;
  float len2;
  ASSERT_TRUE(half_vector_transmit(wi, wt, 1.5f, wh, &len2));
  EXPECT_NEAR(wh.z, 1.0f, 1e-5f);
}

TEST(MicrofacetPrimitives, NoNaNAtExtremes) {
  Pcg32 rng(3);
  for (int i = 0; i < 200000; ++i) {
    const float ax = std::pow(10.0f, -4.0f + 4.5f * rng.next_float());
    const float ay = std::pow(10.0f, -4.0f + 4.5f * rng.next_float());
    const float z = (i & 1) ? std::pow(10.0f, -7.0f * rng.next_float()) : rng.next_float();
    const float phi = kTwoPi * rng.next_float();
    const float r = std::sqrt(std::max(0.0f, 1 - z * z));
    const Vec3 wi(r * std::cos(phi), r * std::sin(phi), z);
    for (Distribution d : {Distribution::GGX, Distribution::Beckmann}) {
      const Vec3 m = sample_visible_normal(d, wi, ax, ay, rng.next_float(), rng.next_float());
      ASSERT_TRUE(is_finite(m)) << ax << " " << ay << " " << z;
      ASSERT_GE(m.z, 0.0f);
      const float v = visible_D(d, wi, m, ax, ay);
      ASSERT_TRUE(std::isfinite(v) && v >= 0.0f);
      const float g = G2(d, wi, m, ax, ay);
      ASSERT_TRUE(std::isfinite(g) && g >= 0.0f && g <= 1.0f);
    }
  }
}

}  // namespace
