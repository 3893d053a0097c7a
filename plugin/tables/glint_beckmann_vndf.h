// Glint's own Beckmann visible-normal sampler: the distribution of
// microfacet::sample_beckmann_visible_normal (Heitz & d'Eon 2014, sec. 4: the
// stretched visible slope x~ by inverting its exact CDF, y~ ~ N(0, 1/2)), with
// the transcendental functions of the inversion replaced by library-free
// double approximations:
// - exp(x), x <= 0: Cody-Waite reduction by ln 2 / 32, a table of 2^(j/32)
//   and a degree-5 Taylor polynomial (relative error < 1e-14);
// - erfc(z) = erfcx(z) exp(-z^2) for z in [0, 8], erfcx by a degree-14
//   polynomial in s = 12 / (4 + z) - 2 (Chebyshev interpolation of
//   erfcx(4 (1 - t) / t) on t in [1/3, 1], converted to monomials; relative
//   error < 2e-12; tools/glint_vndf_fit.py makes the coefficients);
// - log (atanh series, absolute error < 1e-12);
// - the inverse erf for y~ as x R(w), w = -log(1 - x^2), R by two polynomials
//   (relative error < 4e-12), no Newton step.
// The CDF is then the exact one to ~1e-12 relative and the same safeguarded
// Householder iteration from the same tabulated start (the shared
// detail::beckmann_slope_guess table) inverts it; the test
// GlintBeckmannVndf.SlopeInverseMatchesLongDouble bounds the inverse against a
// long-double bisection over the whole domain. The shared sampler stays the
// one the tables are built with; this one only draws glint's samples (the pdf
// glint reports is the exact visible_D of both).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <utility>

#include "glimmer/math.h"
#include "glimmer/horner.h"
#include "glimmer/microfacet.h"

namespace glimmer::plugin::glint::beckmann_vndf {

// c[0] + c[1] x + ... + c[N-1] x^(N-1) split Depth times into even and odd parts, p(x) = E(x^2) + x O(x^2), each
// part by glimmer::horner at the end (session 32). The same polynomial as one Horner chain (rounding differs by
// ~1e-16 relative), with two more multiply-adds per split and chains of ~N / 2^Depth steps that run side by side:
// the CDF's erfcx (degree 14) was ~112 cycles of latency on the slope's critical path as one chain (no FMA here).
template <std::size_t Depth, std::size_t N>
[[gnu::always_inline]] inline double split_horner(double x, const std::array<double, N> &c) {
  if constexpr (Depth == 0 || N < 4) {
    return horner(x, c);
  } else {
    std::array<double, (N + 1) / 2> even;
    std::array<double, N / 2> odd;
    for (std::size_t k = 0; k < N; ++k) (k % 2 == 0 ? even[k / 2] : odd[k / 2]) = c[k];
    const double x2 = x * x;
    return split_horner<Depth - 1>(x2, even) + x * split_horner<Depth - 1>(x2, odd);
  }
}
// One split (session 32, per draw: depth 1 +12 instructions for most of the latency; depth 2 +40 for 2 % more).
inline constexpr std::size_t kSplitDepth = 1;

// exp(x) for x <= 0 (x below -700 is read as -700: exp < 1e-304): x = (32 q + j) ln 2 / 32 + r, |r| <= ln 2 / 64
// (Cody-Waite: the high part of ln 2 has 32 significant bits, so kd times it is exact), exp(x) = 2^q 2^(j/32) e^r
// with 2^(j/32) from a table of correctly rounded doubles and e^r by its degree-5 Taylor polynomial (truncation
// r^6 / 720 < 2.3e-15; relative error < 1e-14 with the roundings, GlintBeckmannVndf.HelpersMatchLibm). Session 28:
// was a reduction by ln 2 and a degree-11 polynomial (~30 fewer instructions per call, 2..3 calls per draw).
inline constexpr std::array<double, 32> kExp2Fraction = {  // 2^(j/32), j = 0..31
    1.0, 1.0218971486541166, 1.0442737824274138, 1.0671404006768237,
    1.0905077326652577, 1.1143867425958924, 1.1387886347566916, 1.1637248587775775,
    1.189207115002721, 1.215247359980469, 1.241857812073484, 1.2690509571917332,
    1.2968395546510096, 1.3252366431597413, 1.3542555469368927, 1.383909881963832,
    1.4142135623730951, 1.4451808069770467, 1.4768261459394993, 1.5091644275934228,
    1.5422108254079407, 1.5759808451078865, 1.6104903319492543, 1.645755478153965,
    1.681792830507429, 1.718619298122478, 1.7562521603732995, 1.7947090750031072,
    1.8340080864093424, 1.8741676341103, 1.9152065613971474, 1.9571441241754002};
inline double exp_nonpositive(double x) {
  constexpr double k32Log2e = 32.0 * 1.4426950408889634, kRound = 6755399441055744.0;  // 1.5 * 2^52
  constexpr double kLn2Hi = 6.93147180369123816490e-01 / 32.0, kLn2Lo = 1.90821492927058770002e-10 / 32.0;
  x = std::max(x, -700.0);
  const double kd = (x * k32Log2e + kRound) - kRound;  // round to nearest
  const double r = (x - kd * kLn2Hi) - kd * kLn2Lo;    // |r| <= ln 2 / 64
  static constexpr std::array<double, 6> kExpSeries = {1.0, 1.0, 0.5, 1.0 / 6.0, 1.0 / 24.0, 1.0 / 120.0};
  const double p = horner(r, kExpSeries);
  const std::int64_t k = static_cast<std::int64_t>(kd);
  const std::uint64_t bits = static_cast<std::uint64_t>((k >> 5) + 1023) << 52;  // k >> 5 = floor(k / 32)
  double scale;
  std::memcpy(&scale, &bits, sizeof scale);
  return p * kExp2Fraction[static_cast<std::size_t>(k & 31)] * scale;
}

// log(x) for normal x > 0, absolute error < 1e-12 (atanh series to s^13).
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
  const double p =
      1.0 + s2 * (1.0 / 3 + s2 * (1.0 / 5 + s2 * (1.0 / 7 + s2 * (1.0 / 9 + s2 * (1.0 / 11 + s2 * (1.0 / 13))))));
  return e * 0.6931471805599453 + 2.0 * s * p;
}

// erfcx(z) = exp(z^2) erfc(z) for z in [0, 8] (larger z read as 8).
struct ErfcxPoly {
  double operator()(double z) const {
    const double s = 12.0 / (4.0 + std::min(z, 8.0)) - 2.0;  // t = 4 / (4 + z) in [1/3, 1] -> s in [-1, 1]
    static constexpr std::array<double, 15> kCoefficients = {
        0.25539567631050597, 0.32038938555813934, 0.21603008065136262, 0.12130979268129895, 0.05666389896521743,
        0.02176255432638497, 0.006685681724356588, 0.0015442636811318522, 0.00022439838421674333,
        2.6480697785065862e-06, -7.265406858062799e-06, -1.2840884612804379e-06, 1.1217047036401102e-07,
        5.6671435307483384e-08, 3.011772757114765e-10};
    return split_horner<kSplitDepth>(s, kCoefficients);
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
    // Beyond x = 6 the erfc and exp terms are below 1e-16 of cos t; e_max < 2.4e-16 is then read as 0 (the upper
    // tail's start, its only other use, is -8 for both: x_max - sqrt(2 (1 - u) total / k) < -8 for u <= 1 - 1e-9).
    e_max = 0.0;
    total = cos_t;
    if (x_max <= 6.0) {
      e_max = exp_nonpositive(-x_max * x_max);
      total = at(x_max, e_max);
    }
  }
  // C(x) given e = exp(-x^2); erfc(-x) from erfc(|x|) = erfcx(|x|) e without cancellation for x <= 0.
  double at(double x, double e) const {
    const double tail = Erfcx()(std::fabs(x)) * e;  // erfc(|x|)
    return 0.5 * (cos_t * (x > 0.0 ? 2.0 - tail : tail) + sin_t * e * kInvSqrtPi);
  }
  [[gnu::noinline, gnu::cold]] double upper_tail_guess(double target) const {
    const double k = sin_t * e_max * kInvSqrtPi;
    return k > 0.0 ? x_max - std::sqrt(2.0 * std::max(total - target, 0.0) / k) : -8.0;
  }
  [[gnu::noinline, gnu::cold]] double lower_tail_guess(double target) const {
    const double l = log_positive(2.0 * target / kInvSqrtPi);
    double z = std::sqrt(std::max(-l + log_positive(sin_t + 0.5 * cos_t), 1.0));
    z = std::sqrt(std::max(-l + log_positive(sin_t + cos_t * (1.0 - 0.5 / (z * z)) / z), 1.0));
    return -z;
  }
};

// The shared sampler's safeguarded Householder iteration of order 3 for C(x) =
// target from x in [lo, hi] (microfacet::detail::solve_beckmann_slope_by: the
// same steps, stopping rule and bisection) with glint's exp and C(x), the step
// written with one division (session 32; the shared one divides four times).
// With q = (C - target) sqrt(pi), g = cos t - x sin t, e = exp(-x^2): f / f' = n = q / (g e),
// f'' / f' = a2 = A / g, f''' / f' = a3 = B / g (A = -sin t - 2 x g, B = 4 x (sin t + x g) - 2 g);
// the step n (6 - 3 n a2) / (6 - 6 n a2 + n^2 a3), numerator and denominator times g^3 e^2, is
// q (6 D - 3 P) / (g e (6 D - 6 P) + q^2 B) with D = g^2 e, P = q A (n a2 = P / D: the tests
// |n a2| < 0.5 and < 1e-2 become |P| < 0.5 D and < 1e-2 D, g and e being > 0 there).
template <typename Erfcx>
[[gnu::always_inline]] inline double solve_slope(const SlopeCdf<Erfcx> &c, double target, double x, double lo, double hi) {
  constexpr double kSqrtPi = 1.7724538509055160273, kStepDone = 1e-3, kCurvatureDone = 1e-2;
  const double tolerance = 1e-12 * std::min(c.total, 1e3 * target);  // relative 1e-9 in the lower tail
  for (int it = 0; it < 64; ++it) {
    const double e = exp_nonpositive(-x * x);
    const double value = c.at(x, e) - target;
    if (std::fabs(value) < tolerance) break;
    if (value > 0.0) hi = x; else lo = x;
    const double g = c.cos_t - x * c.sin_t, q = value * kSqrtPi, ge = g * e, d = g * ge;
    const double p = q * (-c.sin_t - 2.0 * x * g);
    const double b = 4.0 * x * (c.sin_t + x * g) - 2.0 * g;
    const bool smooth = g > 0.0 && e > 0.0 && std::fabs(p) < 0.5 * d;
    double next = smooth ? x - q * (6.0 * d - 3.0 * p) / (ge * (6.0 * d - 6.0 * p) + q * q * b) : 0.5 * (lo + hi);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    const double step = std::fabs(next - x);
    x = next;
    if ((smooth && step < kStepDone && std::fabs(p) < kCurvatureDone * d) || hi - lo < 1e-13) break;
  }
  return x;
}

// u clamped to [1e-9, 1 - 1e-9] by minsd / maxsd (glimmer::clamp's compare-and-branch form costs more; same value
// for every u that is not NaN).
inline double clamp01(double u) { return std::min(std::max(u, 1e-9), 1.0 - 1e-9); }
// The shared start table (microfacet::detail::beckmann_slope_guess) behind a guard whose slow path is one call:
// asked for inside the sampler, the table's constructor (2145 libm solves) was inlined into it (+1.4 KB of code).
[[gnu::noinline, gnu::cold]] inline const glimmer::microfacet::detail::BeckmannSlopeGuess &built_slope_start() {
  return glimmer::microfacet::detail::beckmann_slope_guess();
}
inline const glimmer::microfacet::detail::BeckmannSlopeGuess &slope_start() {
  static const glimmer::microfacet::detail::BeckmannSlopeGuess &table = built_slope_start();
  return table;
}

// The stretched slope x~ of CDF fraction u (clamped to [1e-9, 1 - 1e-9]) at
// incidence (cos t, sin t), sin t >= 1e-6: the shared sampler's start (table,
// tail asymptotes), then solve_slope.
template <typename Erfcx = ErfcxPoly>
[[gnu::always_inline]] inline double slope_x(double cos_t, double sin_t, double u,
                                           const glimmer::microfacet::detail::BeckmannSlopeGuess &start) {
  namespace md = glimmer::microfacet::detail;
  const SlopeCdf<Erfcx> c(cos_t, sin_t);
  u = clamp01(u);
  const double target = u * c.total, v = 1.0 - std::sqrt(1.0 - u);
  double x = start.guess(sin_t / (sin_t + cos_t), v);
  if (v < md::BeckmannSlopeGuess::kFirstCell) x = c.lower_tail_guess(target);
  if (c.x_max < 8.0 && (x >= c.x_max || v > 1.0 - md::BeckmannSlopeGuess::kFirstCell))
    x = std::max(std::min(x, c.x_max), c.upper_tail_guess(target));
  return solve_slope(c, target, std::min(std::max(x, -8.0), c.x_max), -8.0, c.x_max);
}
template <typename Erfcx = ErfcxPoly>
inline double slope_x(double cos_t, double sin_t, double u) {
  return slope_x<Erfcx>(cos_t, sin_t, u, slope_start());
}

// erfinv(x) / x for x^2 = 1 - exp(-w), w in [0, 20.25] (1 - |x| >= 2e-9): two
// polynomials (the form of Giles 2010, "Approximating the erfinv function",
// with coefficients of our own: Chebyshev interpolants from
// tools/glint_vndf_fit.py erfinv1 / erfinv2), relative error < 4e-12.
struct ErfinvRatioPoly {
  double operator()(double w) const {
    if (w < 6.25) {
      const double v = w * 0.32 - 1.0;  // w / 3.125 - 1
      static constexpr std::array<double, 17> kCentral = {
          1.653654562683103, 0.7504943200589564, -0.05892256708626069, -0.022604446447928382, 0.017808360975457283,
          -0.004137328356113808, -0.0012716803967058484, 0.001232572323216379, -0.00026446908852887296,
          -0.00011717167430280075, 9.362306993038521e-05, -1.4514358540776918e-05, -1.1753793802092654e-05,
          6.623516877452322e-06, -1.25117661381784e-07, -8.358844805864945e-07, 1.9338714243049787e-07};
      return split_horner<kSplitDepth>(v, kCentral);
    }
    const double v = std::sqrt(w) - 3.5;
    static constexpr std::array<double, 15> kTail = {
        3.3354857170835577, 1.0073688125908868, 0.0032768662076646457, -0.002063169340638075, 0.0010934567909945514,
        -0.0006799186909956251, 0.0004307672008091383, -0.00022478361067517955, 7.844002852076907e-05,
        -6.25568451179485e-06, -1.341284976206225e-05, 1.0482554694135615e-05, -2.860369537908506e-06,
        -9.436087869592787e-07, 6.139218991544718e-07};
    return split_horner<kSplitDepth>(v, kTail);
  }
};

// y with erf(y) = 2 u - 1 for u in [1e-9, 1 - 1e-9]: y = (2 u - 1) R(w),
// w = -log(4 u (1 - u)), no Newton step (erfc(|y|) within 1e-10 of 2 min(u, 1 - u)).
template <typename Ratio = ErfinvRatioPoly>
inline double erfinv_2u_minus_1(double u) {
  return (2.0 * u - 1.0) * Ratio()(-log_positive(4.0 * u * (1.0 - u)));
}

// Beckmann visible normal for wi.z > 0 at (ax, ay): the distribution of
// microfacet::sample_beckmann_visible_normal (whose pdf is visible_D).
template <typename Erfcx = ErfcxPoly>
inline Vec3 sample_visible_normal(const Vec3 &wi, float ax, float ay, float u1, float u2) {
  const glimmer::microfacet::detail::BeckmannSlopeGuess &start = slope_start();
  const Vec3 wi_std = normalize(Vec3(ax * wi.x, ay * wi.y, std::max(wi.z, 1e-7f)));
  const double cos_t = wi_std.z;
  const double sin_t = std::sqrt(std::max(0.0, 1.0 - cos_t * cos_t));
  // Normal incidence (rare): the shared sampler's closed form.
  if (sin_t < 1e-6) return glimmer::microfacet::sample_beckmann_visible_normal(wi, ax, ay, u1, u2);
  // y~ first: its chain (log, polynomial) is independent of x~'s and overlaps it when issued before it.
  const double slope_y_std = erfinv_2u_minus_1(clamp01(static_cast<double>(u2)));
  const double slope_x_std = slope_x<Erfcx>(cos_t, sin_t, static_cast<double>(u1), start);
  return glimmer::microfacet::detail::beckmann_normal_of_std_slopes(wi_std, slope_x_std, slope_y_std, ax, ay);
}

// sample_visible_normal as the glint closures draw it, compiled in its own unit
// (glint_beckmann_vndf.cpp): inlined into glint.cpp's sample, the sampler made
// GCC stop inlining glint_f_cos into f_cos_and_pdf (+2.4 M instructions on the
// GI scene's evals), and a noinline copy in that unit did the same.
Vec3 draw_visible_normal(const Vec3 &wi, float ax, float ay, float u1, float u2);

}  // namespace glimmer::plugin::glint::beckmann_vndf
