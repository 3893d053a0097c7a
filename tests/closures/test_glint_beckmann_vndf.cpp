// Glint's library-free Beckmann visible-normal sampler
// (plugin/tables/glint_beckmann_vndf.h) against high-precision references:
// the slope CDF inverse against a long-double bisection of the exact CDF over
// the whole domain, the inverse erf against long-double erfc, the helpers
// against libm, and the whole sampler against the shared exact one
// (microfacet::sample_beckmann_visible_normal). Negative controls: an erfcx
// 1e-6 off (a fit of too low a degree errs by ~1e-7) must fail the bounds.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "glimmer/math.h"
#include "glimmer/microfacet.h"
#include "tables/glint_beckmann_vndf.h"

namespace glimmer::test {
namespace {

namespace bv = plugin::glint::beckmann_vndf;
namespace mf = glimmer::microfacet;

// Exact stretched slope CDF in long double.
struct LongDoubleCdf {
  long double c, s, x_max, total;
  LongDoubleCdf(double cos_t, double sin_t) : c(cos_t), s(sin_t) {
    x_max = sin_t * 8.0 < cos_t ? 8.0L : c / s;
    total = at(x_max);
  }
  long double at(long double x) const {
    return 0.5L * (c * std::erfc(-x) + s * std::exp(-x * x) * 0.564189583547756286948079451560772586L);
  }
  // Root of at(x) = target by 80 bisections on [-8, x_max] (width 16 / 2^80).
  long double inverse(long double target) const {
    long double lo = -8.0L, hi = x_max;
    for (int i = 0; i < 80; ++i) {
      const long double mid = 0.5L * (lo + hi);
      (at(mid) < target ? lo : hi) = mid;
    }
    return 0.5L * (lo + hi);
  }
};

// The incidences of the domain in the stretched configuration, as the sampler
// forms them (float normalize of (ax wi.x, ay wi.y, wi.z)): wi.z from 1e-6 to
// ~1 (sin t >= 1e-6), alpha 0.05..1.
std::vector<std::pair<double, double>> incidences() {
  std::vector<std::pair<double, double>> out;
  for (float alpha : {0.05f, 0.1f, 0.2f, 0.4f, 0.7f, 1.0f})
    for (float z : {1e-6f, 1e-5f, 1e-4f, 1e-3f, 0.01f, 0.05f, 0.1f, 0.2f, 0.3f, 0.5f, 0.7f, 0.85f, 0.95f, 0.99f,
                    0.999f, 0.99999f}) {
      const float x = std::sqrt(std::max(0.0f, 1.0f - z * z));
      const Vec3 w = normalize(Vec3(alpha * x, 0.0f, z));
      const double cos_t = w.z, sin_t = std::sqrt(std::max(0.0, 1.0 - cos_t * cos_t));
      if (sin_t >= 1e-6) out.emplace_back(cos_t, sin_t);
    }
  return out;
}

// u over (0, 1) including both ends and the tails' decades.
std::vector<double> fractions() {
  std::vector<double> out = {0.0, 1e-12, 1e-9, 3e-9, 1e-8, 1e-7, 1e-6, 1e-5, 1e-4, 1e-3, 0.005};
  for (int i = 1; i < 400; ++i) out.push_back(i / 400.0);
  for (double t : {0.005, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 5.9604644775390625e-8, 1e-8, 3e-9, 1e-9, 0.0})
    out.push_back(1.0 - t);
  return out;
}

// Worst errors of a slope inverse over the domain: in the CDF (|C(x) - u T| / T,
// the Kolmogorov distance of the sampled slope's distribution), relative to u
// in the lower tail (|C(x) / (u T) - 1| for u <= 1e-3), and in x where the
// density c(x) / T >= 1e-3 (elsewhere a CDF error moves x far for nothing).
struct InverseErrors {
  double cdf = 0.0, lower_tail_rel = 0.0, x = 0.0;
};
template <typename SlopeX>
InverseErrors inverse_errors(SlopeX &&slope_x) {
  InverseErrors worst;
  for (const auto &[cos_t, sin_t] : incidences()) {
    const LongDoubleCdf ref(cos_t, sin_t);
    for (double u_in : fractions()) {
      const double u = clamp(u_in, 1e-9, 1.0 - 1e-9);  // both samplers clamp u so
      const double x = slope_x(cos_t, sin_t, u_in);
      const long double target = u * ref.total, got = ref.at(x);
      worst.cdf = std::max(worst.cdf, static_cast<double>(std::fabs(got - target) / ref.total));
      if (u <= 1e-3) worst.lower_tail_rel = std::max(worst.lower_tail_rel, static_cast<double>(std::fabs(got / target - 1)));
      const long double x_ref = ref.inverse(target);
      const long double density = (ref.c - x_ref * ref.s) * std::exp(-x_ref * x_ref) * 0.5641895835477563L;
      if (density / ref.total >= 1e-3L) worst.x = std::max(worst.x, static_cast<double>(std::fabs(x - x_ref)));
    }
  }
  return worst;
}

TEST(GlintBeckmannVndf, HelpersMatchLibm) {
  double exp_err = 0.0, log_err = 0.0, erfcx_err = 0.0;
  for (int i = 0; i <= 100000; ++i) {
    const double x = -700.0 * std::pow(i / 100000.0, 3.0);
    exp_err = std::max(exp_err, std::fabs(bv::exp_nonpositive(x) / std::exp(x) - 1.0));
    const double y = std::exp(-690.0 * i / 100000.0) * 1.9;
    log_err = std::max(log_err, std::fabs(bv::log_positive(y) - std::log(y)) / std::max(1.0, std::fabs(std::log(y))));
    const long double z = 8.0L * i / 100000;
    const long double ref = std::exp(z * z) * std::erfc(z);
    erfcx_err = std::max(erfcx_err, static_cast<double>(std::fabs(bv::ErfcxPoly()(static_cast<double>(z)) / ref - 1)));
  }
  std::printf("exp rel %.3g, log err %.3g, erfcx rel %.3g\n", exp_err, log_err, erfcx_err);
  EXPECT_LT(exp_err, 1e-14);
  EXPECT_LT(log_err, 1e-12);
  EXPECT_LT(erfcx_err, 5e-12);
}

// An erfcx and an erfinv ratio 1e-6 off: the negative controls of the bounds below.
struct ErfcxOff {
  double operator()(double z) const { return bv::ErfcxPoly()(z) * (1.0 + 1e-6); }
};
struct RatioOff {
  double operator()(double w) const { return bv::ErfinvRatioPoly()(w) * (1.0 + 1e-6); }
};

// The bounds: CDF (Kolmogorov) error < 1e-10, lower tail relative < 2e-9 (the
// iteration stops at 1e-9 of the target there, as the shared solver does),
// x error < 1e-8 where c(x) / T >= 1e-3; the shared libm solver's errors are
// printed beside them (measured: glint 2.3e-12 / 1.0e-9 / 4.6e-10, shared
// 1.9e-11 / 9.4e-10 / 3.7e-10).
TEST(GlintBeckmannVndf, SlopeInverseMatchesLongDouble) {
  const InverseErrors fast = inverse_errors([](double c, double s, double u) { return bv::slope_x(c, s, u); });
  const InverseErrors shared = inverse_errors([](double c, double s, double u) {
    const mf::detail::BeckmannSlopeCdf cdf(c, s);
    const double uc = clamp(u, 1e-9, 1.0 - 1e-9);
    return mf::detail::solve_beckmann_slope(cdf, uc * cdf.total, 0.0, -8.0, cdf.x_max);
  });
  std::printf("glint: cdf %.3g, lower tail rel %.3g, x %.3g; shared libm solver: cdf %.3g, lower tail rel %.3g, "
              "x %.3g\n", fast.cdf, fast.lower_tail_rel, fast.x, shared.cdf, shared.lower_tail_rel, shared.x);
  EXPECT_LT(fast.cdf, 1e-10);
  EXPECT_LT(fast.lower_tail_rel, 2e-9);
  EXPECT_LT(fast.x, 1e-8);
  // Negative control: an erfcx 1e-6 off fails every bound.
  const InverseErrors off = inverse_errors([](double c, double s, double u) { return bv::slope_x<ErfcxOff>(c, s, u); });
  std::printf("control (erfcx 1e-6 off): cdf %.3g, lower tail rel %.3g, x %.3g\n", off.cdf, off.lower_tail_rel, off.x);
  EXPECT_GT(off.cdf, 1e-10);
  EXPECT_GT(off.lower_tail_rel, 2e-9);
  EXPECT_GT(off.x, 1e-8);
}

// erf(y) = 2 u - 1 written as erfc(|y|) = 2 min(u, 1 - u), relative error.
template <typename Erfinv>
double erfinv_error(Erfinv &&erfinv) {
  double worst = 0.0;
  for (double u_in : fractions()) {
    const double u = clamp(u_in, 1e-9, 1.0 - 1e-9);
    const long double y = erfinv(u);
    const long double want = 2.0L * std::min<long double>(u, 1.0L - static_cast<long double>(u));
    worst = std::max(worst, static_cast<double>(std::fabs(std::erfc(std::fabs(y)) / want - 1)));
  }
  return worst;
}

TEST(GlintBeckmannVndf, ErfinvMatchesLongDouble) {
  const double fast = erfinv_error([](double u) { return bv::erfinv_2u_minus_1(u); });
  const double shared = erfinv_error([](double u) { return mf::detail::erfinv_2u_minus_1(u); });
  const double off = erfinv_error([](double u) { return bv::erfinv_2u_minus_1<RatioOff>(u); });
  std::printf("erfc(|y|) rel: glint %.3g, shared %.3g, control (ratio 1e-6 off) %.3g\n", fast, shared, off);
  // The polynomials' 9e-11 (tools/glint_vndf_fit.py); the shared one's Halley step leaves ~1e-9.
  EXPECT_LT(fast, 5e-10);
  EXPECT_GT(off, 5e-10);
}

// The whole sampler against the shared exact one: the same normal to float
// rounding (components within 1.2e-7, two float steps at 1) over incidences
// (grazing 1e-6, azimuths), alphas 0.05..1 (also anisotropic) and u1, u2 over
// (0, 1) with the ends; the control (erfcx 1e-6 off) differs by more.
template <typename Sampler>
std::pair<double, double> sampler_difference(Sampler &&sample) {
  const std::vector<float> us = {0.0f, 1e-8f, 1e-6f, 1e-4f, 0.01f, 0.1f, 0.25f, 0.5f, 0.75f, 0.9f, 0.99f,
                                 0.9999f, 0.99999994f};
  double worst = 0.0;
  long equal = 0, total = 0;
  for (const auto &[ax, ay] : std::vector<std::pair<float, float>>{{0.05f, 0.05f}, {0.2f, 0.2f}, {0.5f, 0.5f},
                                                                   {1.0f, 1.0f}, {0.1f, 0.6f}})
    for (float z : {1e-6f, 1e-3f, 0.05f, 0.3f, 0.7f, 0.95f, 1.0f})
      for (float phi : {0.0f, 1.0f, 2.5f, 4.0f}) {
        const float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
        const Vec3 wi(r * std::cos(phi), r * std::sin(phi), z);
        for (float u1 : us)
          for (float u2 : us) {
            const Vec3 a = sample(wi, ax, ay, u1, u2);
            const Vec3 b = mf::sample_beckmann_visible_normal(wi, ax, ay, u1, u2);
            const bool finite = std::isfinite(a.x) && std::isfinite(a.y) && std::isfinite(a.z);
            EXPECT_TRUE(finite);
            const double d = !finite ? 1.0 : std::max({std::fabs(a.x - b.x), std::fabs(a.y - b.y), std::fabs(a.z - b.z)});
            worst = std::max(worst, d);
            equal += d == 0.0;
            ++total;
          }
      }
  return {worst, static_cast<double>(equal) / total};
}

TEST(GlintBeckmannVndf, SamplerMatchesTheSharedExactSampler) {
  const auto [worst, equal] = sampler_difference(
      [](const Vec3 &wi, float ax, float ay, float u1, float u2) { return bv::sample_visible_normal(wi, ax, ay, u1, u2); });
  const auto [off_worst, off_equal] = sampler_difference([](const Vec3 &wi, float ax, float ay, float u1, float u2) {
    return bv::sample_visible_normal<ErfcxOff>(wi, ax, ay, u1, u2);
  });
  std::printf("sampler vs shared: %.4f of the normals equal, max component difference %.3g; control %.4f, %.3g\n",
              equal, worst, off_equal, off_worst);
  EXPECT_LT(worst, 1.2e-7);
  EXPECT_GT(off_worst, 1.2e-7);
}

}  // namespace
}  // namespace glimmer::test
