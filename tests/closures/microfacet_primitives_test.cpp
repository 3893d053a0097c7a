// Checks of shared/include/glimmer/microfacet.h against brute-force quadrature.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

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

// Beckmann visible slope by brute force: bisection of the exact CDF
// C(x) = cos t erfc(-x) / 2 + sin t exp(-x^2) / (2 sqrt(pi)), x <= min(cot t, 8),
// in long double (200 halvings), and of the normal split erf(y) = 2 u - 1.
long double beckmann_cdf_ld(long double x, long double c, long double s) {
  return 0.5L * (c * std::erfc(-x) + s * std::exp(-x * x) * 0.564189583547756286948L);
}
long double bisect_slope_x(double cos_t, double sin_t, double u) {
  const long double c = cos_t, s = sin_t, x_max = s * 8.0L < c ? 8.0L : c / s;
  const long double target = u * beckmann_cdf_ld(x_max, c, s);
  long double lo = -10.0L, hi = x_max;
  for (int i = 0; i < 200; ++i) {
    const long double mid = 0.5L * (lo + hi);
    (beckmann_cdf_ld(mid, c, s) > target ? hi : lo) = mid;
  }
  return 0.5L * (lo + hi);
}
long double bisect_slope_y(double u) {
  long double lo = -10.0L, hi = 10.0L;
  for (int i = 0; i < 200; ++i) {
    const long double mid = 0.5L * (lo + hi);
    (0.5L * std::erfc(-mid) > u ? hi : lo) = mid;
  }
  return 0.5L * (lo + hi);
}

// Random numbers of the tails, where the CDF's inversion is hardest.
float tail_heavy_unit(Pcg32 &rng) {
  const float q = rng.next_float();
  if (q < 0.1f) return std::pow(10.0f, -9.0f * rng.next_float());
  if (q < 0.2f) return std::max(1.0f - std::pow(10.0f, -7.0f * rng.next_float()), 0.0f);
  return rng.next_float();
}

// The sampler's slopes (alpha = 1, wi in the xz plane, so m = (-x, -y, 1) /
// |.|) against bisection over all incidences and tail-heavy (u1, u2). The
// tolerance is the float output's resolution; negative control: the
// tabulated start alone (no iteration) misses it.
TEST(MicrofacetPrimitives, BeckmannSlopeInversionMatchesBisection) {
  Pcg32 rng(11);
  double worst = 0.0, worst_guess = 0.0;
  for (int i = 0; i < 20000; ++i) {
    const float t = 1.5707963f * rng.next_float();
    const Vec3 wi(std::sin(t), 0.0f, std::cos(t));
    const float u1 = tail_heavy_unit(rng), u2 = tail_heavy_unit(rng);
    const Vec3 m = sample_visible_normal(Distribution::Beckmann, wi, 1.0f, 1.0f, u1, u2);
    ASSERT_TRUE(is_finite(m) && m.z > 0.0f);
    const Vec3 wi_std = normalize(wi);
    const double cos_t = wi_std.z, sin_t = std::sqrt(std::max(0.0, 1.0 - cos_t * cos_t));
    if (sin_t < 1e-6) continue;  // the normal-incidence branch samples in polar form
    const double u = std::clamp(double(u1), 1e-9, 1.0 - 1e-9);
    const double x_ref = double(bisect_slope_x(cos_t, sin_t, u));
    const double y_ref = double(bisect_slope_y(std::clamp(double(u2), 1e-9, 1.0 - 1e-9)));
    const double x = -double(m.x) / m.z, y = -double(m.y) / m.z;
    const double tol = 2e-6 * (1.0 + x_ref * x_ref + y_ref * y_ref);  // float m: ~1e-7 relative per component
    worst = std::max(worst, std::max(std::fabs(x - x_ref), std::fabs(y - y_ref)) / tol);
    const detail::BeckmannSlopeCdf c(cos_t, sin_t);
    const double guess = detail::beckmann_slope_guess().guess(sin_t / (sin_t + cos_t), 1.0 - std::sqrt(1.0 - u));
    worst_guess = std::max(worst_guess, std::fabs(std::clamp(guess, -8.0, c.x_max) - x_ref) / tol);
  }
  std::printf("[beckmann slope] worst error / tolerance: sampler %.3f, tabulated start alone %.1f\n", worst, worst_guess);
  EXPECT_LE(worst, 1.0);
  EXPECT_GT(worst_guess, 1.0);  // negative control
}

// The inverse erf this sampler used before: Giles' float guess from
// float(2 u - 1), then two Newton steps. For u below 1.5e-8, 2 u - 1 rounds
// to -1 in float and the result was NaN.
double former_erfinv(double x) {
  x = std::clamp(x, -1.0 + 1e-15, 1.0 - 1e-15);
  const float xf = static_cast<float>(x);
  float w = -std::log((1.0f - xf) * (1.0f + xf)), p;
  if (w < 5.0f) {
    w = w - 2.5f;
    p = 2.81022636e-08f;
    for (float k : {3.43273939e-07f, -3.5233877e-06f, -4.39150654e-06f, 0.00021858087f, -0.00125372503f,
                    -0.00417768164f, 0.246640727f, 1.50140941f})
      p = k + p * w;
  } else {
    w = std::sqrt(w) - 3.0f;
    p = -0.000200214257f;
    for (float k : {0.000100950558f, 0.00134934322f, -0.00367342844f, 0.00573950773f, -0.0076224613f,
                    0.00943887047f, 1.00167406f, 2.83297682f})
      p = k + p * w;
  }
  double y = static_cast<double>(p) * x;
  for (int i = 0; i < 2; ++i) y -= (std::erf(y) - x) / (1.1283791670955126 * std::exp(-y * y));
  return y;
}

// Extreme random numbers (0, 1e-9.., the largest float below 1) at every
// incidence and roughness: finite, upper-hemisphere normals. Negative
// control: the former inverse erf is NaN at u2 = 0 (what the sampler
// returned there).
TEST(MicrofacetPrimitives, BeckmannVisibleNormalFiniteAtExtremeRandomNumbers) {
  const float us[] = {0.0f, 1e-9f, 1e-8f, 1.4e-8f, 6e-8f, 1e-4f, 0.5f, 1.0f - 1e-4f, 1.0f - 6e-8f,
                      std::nextafter(1.0f, 0.0f)};
  for (float z : {1.0f, 0.9f, 0.5f, 0.1f, 1e-3f, 1e-6f})
    for (float a : {1e-4f, 1e-2f, 0.5f, 1.0f})
      for (float u1 : us)
        for (float u2 : us) {
          const Vec3 wi(std::sqrt(1.0f - z * z), 0.0f, z);
          const Vec3 m = sample_visible_normal(Distribution::Beckmann, wi, a, a, u1, u2);
          ASSERT_TRUE(is_finite(m) && m.z >= 0.0f) << z << " " << a << " " << u1 << " " << u2;
        }
  EXPECT_TRUE(std::isnan(former_erfinv(2.0 * 1e-9 - 1.0)));  // negative control
}

}  // namespace
