// Glint's own Beckmann visible-normal sampler: the distribution of
// microfacet::sample_beckmann_visible_normal (Heitz & d'Eon 2014, sec. 4: the
// stretched visible slope x~ by inverting its exact CDF, y~ ~ N(0, 1/2)), with
// the transcendental functions of the inversion replaced by library-free
// double approximations:
// - exp(x), x <= 0: Cody-Waite reduction by ln 2 and a degree-11 Taylor
//   polynomial (relative error < 1e-14);
// - erfc(z) = erfcx(z) exp(-z^2) for z in [0, 8], erfcx by a degree-14
//   polynomial in s = 12 / (4 + z) - 2 (Chebyshev interpolation of
//   erfcx(4 (1 - t) / t) on t in [1/3, 1], converted to monomials; relative
//   error < 2e-12; tools/erfcx_fit.py makes the coefficients);
// - log only for starting guesses (atanh series, relative error < 1e-10).
// The CDF is then the exact one to ~1e-12 relative and the same safeguarded
// Householder iteration from the same tabulated start (the shared
// detail::beckmann_slope_guess table) inverts it; the test
// GlintBeckmannVndf.SlopeInverseMatchesLongDouble bounds the inverse against a
// long-double bisection over the whole domain. The shared sampler stays the
// one the tables are built with; this one only draws glint's samples (the pdf
// glint reports is the exact visible_D of both).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

#include "glimmer/math.h"
#include "glimmer/microfacet.h"

namespace glimmer::plugin::glint::beckmann_vndf {

// exp(x) for x <= 0 (x below -700 is read as -700: exp < 1e-304).
inline double exp_nonpositive(double x) {
  constexpr double kLog2e = 1.4426950408889634, kRound = 6755399441055744.0;  // 1.5 * 2^52
  constexpr double kLn2Hi = 6.93147180369123816490e-01, kLn2Lo = 1.90821492927058770002e-10;
  x = std::max(x, -700.0);
  const double kd = (x * kLog2e + kRound) - kRound;  // round to nearest
  const double r = (x - kd * kLn2Hi) - kd * kLn2Lo;  // |r| <= ln 2 / 2
  double p = 1.0 / 39916800.0;                       // 1 / 11!
  p = 1.0 / 3628800.0 + r * p;
  p = 1.0 / 362880.0 + r * p;
  p = 1.0 / 40320.0 + r * p;
  p = 1.0 / 5040.0 + r * p;
  p = 1.0 / 720.0 + r * p;
  p = 1.0 / 120.0 + r * p;
  p = 1.0 / 24.0 + r * p;
  p = 1.0 / 6.0 + r * p;
  p = 0.5 + r * p;
  p = 1.0 + r * p;
  p = 1.0 + r * p;
  const std::uint64_t bits = static_cast<std::uint64_t>(static_cast<std::int64_t>(kd) + 1023) << 52;
  double scale;
  std::memcpy(&scale, &bits, sizeof scale);
  return p * scale;
}

// log(x) for normal x > 0, relative error < 1e-10 (used for starting guesses only).
inline double log_positive(double x) {
  std::uint64_t bits;
  std::memcpy(&bits, &x, sizeof bits);
  int e = static_cast<int>((bits >> 52) & 0x7ff) - 1023;
  bits = (bits & 0x000fffffffffffffull) | 0x3ff0000000000000ull;  // mantissa in [1, 2)
  double m;
  std::memcpy(&m, &bits, sizeof m);
  if (m > 1.4142135623730951) {
    m *= 0.5;
    ++e;
  }
  const double s = (m - 1.0) / (m + 1.0), s2 = s * s;  // |s| <= 0.172
  const double p = 1.0 + s2 * (1.0 / 3 + s2 * (1.0 / 5 + s2 * (1.0 / 7 + s2 * (1.0 / 9 + s2 * (1.0 / 11)))));
  return e * 0.6931471805599453 + 2.0 * s * p;
}

// erfcx(z) = exp(z^2) erfc(z) for z in [0, 8] (larger z read as 8).
struct ErfcxPoly {
  double operator()(double z) const {
    const double s = 12.0 / (4.0 + std::min(z, 8.0)) - 2.0;  // t = 4 / (4 + z) in [1/3, 1] -> s in [-1, 1]
    double p = 2.9988882488396483e-10;
    p = 5.667095024364244e-08 + s * p;
    p = 1.1217465025007793e-07 + s * p;
    p = -1.284086894296858e-06 + s * p;
    p = -7.265412072972784e-06 + s * p;
    p = 2.6480678354090517e-06 + s * p;
    p = 0.000224398387327381 + s * p;
    p = 0.0015442636822781944 + s * p;
    p = 0.006685681723471045 + s * p;
    p = 0.021762554326063124 + s * p;
    p = 0.056663898965316865 + s * p;
    p = 0.1213097926813364 + s * p;
    p = 0.216030080651361 + s * p;
    p = 0.3203893855581382 + s * p;
    p = 0.25539567631050586 + s * p;
    return p;
  }
};

// The stretched visible-slope CDF of microfacet::detail::BeckmannSlopeCdf,
// C(x) = cos t erfc(-x) / 2 + sin t exp(-x^2) / (2 sqrt(pi)), x <= x_max = min(cot t, 8),
// evaluated by the approximations above.
template <typename Erfcx = ErfcxPoly>
struct SlopeCdf {
  static constexpr double kInvSqrtPi = 0.56418958354775628695;
  double cos_t, sin_t, x_max, total, e_max;
  SlopeCdf(double c, double s) : cos_t(c), sin_t(s) {
    x_max = sin_t * 8.0 < cos_t ? 8.0 : cos_t / sin_t;
    e_max = exp_nonpositive(-x_max * x_max);
    total = x_max > 6.0 ? cos_t : at(x_max, e_max);
  }
  // C(x) given e = exp(-x^2); erfc(-x) from erfc(|x|) = erfcx(|x|) e without cancellation for x <= 0.
  double at(double x, double e) const {
    const double tail = Erfcx()(std::fabs(x)) * e;  // erfc(|x|)
    return 0.5 * (cos_t * (x > 0.0 ? 2.0 - tail : tail) + sin_t * e * kInvSqrtPi);
  }
  double upper_tail_guess(double target) const {
    const double k = sin_t * e_max * kInvSqrtPi;
    return k > 0.0 ? x_max - std::sqrt(2.0 * std::max(total - target, 0.0) / k) : -8.0;
  }
  double lower_tail_guess(double target) const {
    const double l = log_positive(2.0 * target / kInvSqrtPi);
    double z = std::sqrt(std::max(-l + log_positive(sin_t + 0.5 * cos_t), 1.0));
    z = std::sqrt(std::max(-l + log_positive(sin_t + cos_t * (1.0 - 0.5 / (z * z)) / z), 1.0));
    return -z;
  }
};

// Safeguarded Householder iteration of order 3 for C(x) = target from x in
// [lo, hi] (the method of microfacet::detail::solve_beckmann_slope): stops when
// |C - target| < 1e-12 min(C(x_max), 1e3 target) (as the shared solver), or after a step below 1e-3
// whose curvature term is below 1e-2 (the error is then ~step^4); bisects when
// a step leaves the bracket or the curvature term dominates.
template <typename Erfcx>
inline double solve_slope(const SlopeCdf<Erfcx> &c, double target, double x, double lo, double hi) {
  constexpr double isp = SlopeCdf<Erfcx>::kInvSqrtPi;
  const double tolerance = 1e-12 * std::min(c.total, 1e3 * target);
  for (int it = 0; it < 64; ++it) {
    const double e = exp_nonpositive(-x * x);
    const double value = c.at(x, e) - target;
    if (std::fabs(value) < tolerance) break;
    if (value > 0.0) hi = x; else lo = x;
    const double g = c.cos_t - x * c.sin_t;                         // f' = g exp(-x^2) / sqrt(pi)
    const double n = value / (g * e * isp);                         // f / f'
    const double a2 = (-c.sin_t - 2.0 * x * g) / g;                 // f'' / f'
    const double a3 = (4.0 * x * (c.sin_t + x * g) - 2.0 * g) / g;  // f''' / f'
    const double na2 = n * a2;
    const bool smooth = g > 0.0 && e > 0.0 && std::fabs(na2) < 0.5;
    double next = smooth ? x - n * (6.0 - 3.0 * na2) / (6.0 - 6.0 * na2 + n * n * a3) : 0.5 * (lo + hi);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    const double step = std::fabs(next - x);
    x = next;
    if ((smooth && step < 1e-3 && std::fabs(na2) < 1e-2) || hi - lo < 1e-13) break;
  }
  return x;
}

// The stretched slope x~ of CDF fraction u (clamped to [1e-9, 1 - 1e-9]) at
// incidence (cos t, sin t), sin t >= 1e-6: the shared sampler's start (table,
// tail asymptotes), then solve_slope.
template <typename Erfcx = ErfcxPoly>
inline double slope_x(double cos_t, double sin_t, double u) {
  namespace md = glimmer::microfacet::detail;
  const SlopeCdf<Erfcx> c(cos_t, sin_t);
  u = clamp(u, 1e-9, 1.0 - 1e-9);
  const double target = u * c.total, v = 1.0 - std::sqrt(1.0 - u);
  double x = md::beckmann_slope_guess().guess(sin_t / (sin_t + cos_t), v);
  if (v < md::BeckmannSlopeGuess::kFirstCell) x = c.lower_tail_guess(target);
  if (c.x_max < 8.0 && (x >= c.x_max || v > 1.0 - md::BeckmannSlopeGuess::kFirstCell))
    x = std::max(std::min(x, c.x_max), c.upper_tail_guess(target));
  return solve_slope(c, target, clamp(x, -8.0, c.x_max), -8.0, c.x_max);
}

// y with erf(y) = 2 u - 1 for u in [1e-9, 1 - 1e-9]: Giles' single-precision
// approximation (2010, GPU Computing Gems) as the guess (the guess of
// microfacet::detail::erfinv_2u_minus_1), then one Halley step on erfc written
// against 2 u or 2 (1 - u) (no cancellation in either tail).
template <typename Erfcx = ErfcxPoly>
inline double erfinv_2u_minus_1(double u) {
  const double x = 2.0 * u - 1.0;
  float w = static_cast<float>(-log_positive(4.0 * u * (1.0 - u))), p;
  if (w < 5.0f) {
    w = w - 2.5f;
    p = 2.81022636e-08f;
    p = 3.43273939e-07f + p * w;
    p = -3.5233877e-06f + p * w;
    p = -4.39150654e-06f + p * w;
    p = 0.00021858087f + p * w;
    p = -0.00125372503f + p * w;
    p = -0.00417768164f + p * w;
    p = 0.246640727f + p * w;
    p = 1.50140941f + p * w;
  } else {
    w = std::sqrt(w) - 3.0f;
    p = -0.000200214257f;
    p = 0.000100950558f + p * w;
    p = 0.00134934322f + p * w;
    p = -0.00367342844f + p * w;
    p = 0.00573950773f + p * w;
    p = -0.0076224613f + p * w;
    p = 0.00943887047f + p * w;
    p = 1.00167406f + p * w;
    p = 2.83297682f + p * w;
  }
  const double y = static_cast<double>(p) * x;
  const double e = exp_nonpositive(-y * y);
  const double tail = Erfcx()(std::fabs(y)) * e;             // erfc(|y|)
  const double f = u < 0.5 ? tail - 2.0 * u : 2.0 * (1.0 - u) - tail;  // erf(y) - x, no cancellation
  const double d = f / (1.1283791670955126 * e);            // f / f'
  return y - d / (1.0 + y * d);                             // Halley: f''/f' = -2y
}

// Beckmann visible normal for wi.z > 0 at (ax, ay): the distribution of
// microfacet::sample_beckmann_visible_normal (whose pdf is visible_D).
template <typename Erfcx = ErfcxPoly>
inline Vec3 sample_visible_normal(const Vec3 &wi, float ax, float ay, float u1, float u2) {
  const Vec3 wi_std = normalize(Vec3(ax * wi.x, ay * wi.y, std::max(wi.z, 1e-7f)));
  const double cos_t = wi_std.z;
  const double sin_t = std::sqrt(std::max(0.0, 1.0 - cos_t * cos_t));
  // Normal incidence (rare): the shared sampler's closed form.
  if (sin_t < 1e-6) return glimmer::microfacet::sample_beckmann_visible_normal(wi, ax, ay, u1, u2);
  const double slope_x_std = slope_x<Erfcx>(cos_t, sin_t, static_cast<double>(u1));
  const double slope_y_std = erfinv_2u_minus_1<Erfcx>(clamp(static_cast<double>(u2), 1e-9, 1.0 - 1e-9));
  // Rotate from the plane of incidence and unstretch (Heitz & d'Eon 2014 Alg. 2).
  const double len_xy = std::sqrt(double(wi_std.x) * wi_std.x + double(wi_std.y) * wi_std.y);
  const double cos_phi = len_xy > 0.0 ? wi_std.x / len_xy : 1.0;
  const double sin_phi = len_xy > 0.0 ? wi_std.y / len_xy : 0.0;
  const double sx = (cos_phi * slope_x_std - sin_phi * slope_y_std) * ax;
  const double sy = (sin_phi * slope_x_std + cos_phi * slope_y_std) * ay;
  const double inv_len = 1.0 / std::sqrt(sx * sx + sy * sy + 1.0);
  return Vec3(static_cast<float>(-sx * inv_len), static_cast<float>(-sy * inv_len), static_cast<float>(inv_len));
}

}  // namespace glimmer::plugin::glint::beckmann_vndf
