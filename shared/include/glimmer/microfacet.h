// Microfacet primitives in the local shading frame (z = N, x = tangent T).
//
// Header-only, shared by the plugin closures (plugin/closures/microfacet_*.cpp),
// the glint closures and the table precomputation. All functions accept any
// direction and any alpha in [1e-4, large]; they return 0 (never NaN/Inf) for
// degenerate configurations (grazing angles, zero-length half vectors).
//
// Conventions (Walter et al. 2007, "Microfacet Models for Refraction through
// Rough Surfaces", EGSR; Heitz 2014, "Understanding the Masking-Shadowing
// Function in Microfacet-Based BRDFs", JCGT 3(2)):
//  - wi, wo point away from the surface; wh (also m) is the microfacet normal,
//    always in the upper hemisphere (wh.z > 0).
//  - eta is the relative IOR n_t / n_i across the interface as seen from wi:
//    eta > 1 when wi is on the outside of a denser medium.
//  - alpha_x is the roughness along the tangent (x), alpha_y along the bitangent.
#pragma once

#include <cmath>
#include <cstdint>

#include "glimmer/math.h"

namespace glimmer::microfacet {

enum class Distribution : int { GGX = 0, Beckmann = 1 };

inline constexpr float kMinAlpha = 1e-4f;

struct Alpha {
  float x = 1.0f, y = 1.0f;
};

// ---- Parameter mapping (Cycles 3.4, intern/cycles/kernel/svm/closure.h) ----
// alpha = roughness^2; anisotropy in [-1, 1] (clamped to +-0.99) stretches the
// lobe: anisotropy > 0 elongates along the bitangent (alpha_x = a (1 - A),
// alpha_y = a / (1 - A)), anisotropy < 0 along the tangent (alpha_x = a / (1 + A),
// alpha_y = a (1 + A)). Results are clamped to [kMinAlpha, inf).
inline Alpha roughness_to_alpha(float roughness, float anisotropy = 0.0f) {
  const float a = sqr(clamp(roughness, 0.0f, 1.0f));
  const float an = clamp(anisotropy, -0.99f, 0.99f);
  Alpha r;
  if (an < 0.0f) {
    r.x = a / (1.0f + an);
    r.y = a * (1.0f + an);
  } else {
    r.x = a * (1.0f - an);
    r.y = a / (1.0f - an);
  }
  r.x = std::max(r.x, kMinAlpha);
  r.y = std::max(r.y, kMinAlpha);
  return r;
}

// ---- Normal distribution D(wh) --------------------------------------------
// Anisotropic GGX (Walter 2007 eq. 33; anisotropic form Heitz 2014 eq. 85),
// written as 1 / (pi ax ay (x^2/ax^2 + y^2/ay^2 + z^2)^2), which is finite for
// every wh including wh.z = 0 and tiny alpha.
inline float ggx_D(const Vec3 &wh, float ax, float ay) {
  if (!(wh.z > 0.0f)) return 0.0f;
  const float k = sqr(wh.x / ax) + sqr(wh.y / ay) + sqr(wh.z);
  const float d = 1.0f / (kPi * ax * ay * k * k);
  return std::isfinite(d) ? d : 0.0f;
}

// Anisotropic Beckmann (Walter 2007 eq. 25; Heitz 2014 eq. 83):
// exp(-(x^2/ax^2 + y^2/ay^2) / z^2) / (pi ax ay z^4).
inline float beckmann_D(const Vec3 &wh, float ax, float ay) {
  if (!(wh.z > 0.0f)) return 0.0f;
  const float z2 = sqr(wh.z);
  const float e = (sqr(wh.x / ax) + sqr(wh.y / ay)) / z2;
  if (!(e < 80.0f)) return 0.0f;
  const float d = std::exp(-e) / (kPi * ax * ay * z2 * z2);
  return std::isfinite(d) ? d : 0.0f;
}

inline float D(Distribution dist, const Vec3 &wh, float ax, float ay) {
  return dist == Distribution::GGX ? ggx_D(wh, ax, ay) : beckmann_D(wh, ax, ay);
}

// ---- Smith Lambda, G1, G2 ---------------------------------------------------
// Squared "alpha tan(theta)" along w: (ax^2 x^2 + ay^2 y^2) / z^2 (Heitz 2014 eq. 80).
inline float alpha2_tan2(const Vec3 &w, float ax, float ay) {
  return (sqr(ax * w.x) + sqr(ay * w.y)) / sqr(w.z);
}

// GGX Lambda (Heitz 2014 eq. 86) for w.z > 0: (-1 + sqrt(1 + a2)) / 2, written
// as a2 / (2 (1 + sqrt(1 + a2))) to avoid cancellation for small a2.
// For w.z < 0 returns Lambda(w) = -1 - Lambda(-w) (Heitz 2016, the volumetric
// view used by the random walk). Grazing w.z = 0 gives +inf.
inline float ggx_lambda(const Vec3 &w, float ax, float ay) {
  if (w.z == 0.0f) return INFINITY;
  const float a2 = alpha2_tan2(w, ax, ay);
  if (!std::isfinite(a2)) return w.z > 0.0f ? INFINITY : -INFINITY;
  const float l = a2 / (2.0f * (1.0f + std::sqrt(1.0f + a2)));
  return w.z > 0.0f ? l : -1.0f - l;
}

// Beckmann Lambda's contract around Lambda as a function of a = 1 / sqrt(alpha2_tan2(w)) (`of_a`, a > 0):
// w.z == 0: infinite; a normal direction (a2 = 0): 0; a2 infinite: infinite; negative values of of_a clamp to 0;
// w.z < 0: -1 - Lambda(-w). Shared by beckmann_lambda (the polynomial, below) and beckmann_lambda_erfc (the closed
// form it is checked against), so both keep the same edges.
template <class LambdaOfA>
inline float beckmann_lambda_with(const Vec3 &w, float ax, float ay, LambdaOfA of_a) {
  if (w.z == 0.0f) return INFINITY;
  const double a2 = alpha2_tan2(w, ax, ay);
  double l;
  if (!(a2 > 0.0)) {
    l = 0.0;
  } else if (!std::isfinite(a2)) {
    l = INFINITY;
  } else {
    l = of_a(1.0 / std::sqrt(a2));
  }
  const float lf = static_cast<float>(std::max(l, 0.0));
  return w.z > 0.0f ? lf : -1.0f - lf;
}

// Beckmann Lambda (Heitz 2014 eq. 84) with a = 1 / sqrt(a2):
// (erf(a) - 1) / 2 + exp(-a^2) / (2 a sqrt(pi)) = (exp(-a^2)/(a sqrt(pi)) - erfc(a)) / 2,
// evaluated in double (the two terms cancel for large a). The closed form that beckmann_lambda (below) is checked
// against (GlintCoords.BeckmannLambdaPolynomialMatchesTheErfcForm).
inline float beckmann_lambda_erfc(const Vec3 &w, float ax, float ay) {
  return beckmann_lambda_with(w, ax, ay, [](double a) {
    if (a > 6.0) return 0.0;  // below 1e-17
    return 0.5 * (std::exp(-a * a) / (a * 1.7724538509055160273) - std::erfc(a));
  });
}

// Beckmann Lambda without erfc and exp, what every closure evaluates (the glint closures since issue 10's session
// 9; the conductor, dielectric and the rest since session 40: libm's double erfc had cost the Beckmann conductor
// ~140 instructions per Lambda). a Lambda(a) = exp(-a^2) / (2 sqrt(pi)) - a erfc(a) / 2 is smooth on [0, 4]: a
// degree-19 polynomial in x = a / 2 - 1 (Chebyshev interpolation at 20 nodes, fitted in 40-digit arithmetic; max
// error 1.9e-10 of a Lambda, so of Lambda 1.9e-10 / a) evaluated in double. Beyond a = 4, Lambda < 2.5e-10 and 0 is
// returned (1 + Lambda rounds to 1 in float from a ~ 3.5). Same contract as beckmann_lambda_erfc (the edges of
// beckmann_lambda_with); GlintCoords.BeckmannLambdaPolynomialMatchesTheErfcForm compares the two (|d(1 + Lambda)|
// <= 2.4e-7). The coefficients are also the glint closures' four-lane form's (glint::eval_lambdas_beckmann_avx2).
inline constexpr double kBeckmannLambdaPoly[20] = {
    0.0004890113652203955, -0.004677734800970086,  0.02066698372428487,    -0.05511199698701841,
    0.09644599897942761,   -0.1102227279168954,    0.0698072884330441,     0.004183614241949296,
    -0.05405087929182188,  0.045357117865371305,   -0.0026295178972669643, -0.02484822617710974,
    0.017932224600181706,  0.0025396699187721994,  -0.010012549308498082,  0.003021427364006197,
    0.0027247767695632854, -0.0015518315693354918, -0.0003259410760252298, 0.0002632927807307566};
inline float beckmann_lambda(const Vec3 &w, float ax, float ay) {
  return beckmann_lambda_with(w, ax, ay, [](double a) {
    if (a >= 4.0) return 0.0;
    const double *c = kBeckmannLambdaPoly;
    const double x = 0.5 * a - 1.0, x2 = x * x;
    // Two Horner chains (even and odd powers) for latency.
    double pe = c[18], po = c[19];
    for (int k = 16; k >= 0; k -= 2) {
      pe = pe * x2 + c[k];
      po = po * x2 + c[k + 1];
    }
    return (pe + x * po) / a;
  });
}

inline float lambda(Distribution dist, const Vec3 &w, float ax, float ay) {
  return dist == Distribution::GGX ? ggx_lambda(w, ax, ay) : beckmann_lambda(w, ax, ay);
}

// Smith masking G1 (Heitz 2014 eq. 43) for w on the visible side (w.z > 0);
// the microfacet side test chi+(w.wh / w.z) is the caller's job.
inline float G1(Distribution dist, const Vec3 &w, float ax, float ay) {
  const Vec3 wa(w.x, w.y, std::fabs(w.z));
  const float l = lambda(dist, wa, ax, ay);
  return std::isfinite(l) ? 1.0f / (1.0f + l) : 0.0f;
}

// Height-correlated masking-shadowing (Heitz 2014 eq. 99):
// G2 = 1 / (1 + Lambda(wi) + Lambda(wo)), both evaluated on their own side
// (|z|), used for reflection and transmission as in Cycles and pbrt-v4.
inline float G2(Distribution dist, const Vec3 &wi, const Vec3 &wo, float ax, float ay) {
  const float li = lambda(dist, Vec3(wi.x, wi.y, std::fabs(wi.z)), ax, ay);
  const float lo = lambda(dist, Vec3(wo.x, wo.y, std::fabs(wo.z)), ax, ay);
  const float s = 1.0f + li + lo;
  return std::isfinite(s) ? 1.0f / s : 0.0f;
}

// G2 for many wo at one wi (the pane walk's resampled events, session 38): wi's part once as one_plus_li =
// G2_incidence(...) = 1 + Lambda(wi), then G2_from_incidence(..., one_plus_li, wo, ...) == G2(dist, wi, wo, ...) bit
// for bit (the same operations in the same order; tests/closures/test_frosted_pane_tail.cpp checks the equality).
// G2 itself is left as it is so that its callers' machine code does not move.
inline float G2_incidence(Distribution dist, const Vec3 &wi, float ax, float ay) {
  return 1.0f + lambda(dist, Vec3(wi.x, wi.y, std::fabs(wi.z)), ax, ay);
}
inline float G2_from_incidence(Distribution dist, float one_plus_li, const Vec3 &wo, float ax, float ay) {
  const float lo = lambda(dist, Vec3(wo.x, wo.y, std::fabs(wo.z)), ax, ay);
  const float s = one_plus_li + lo;
  return std::isfinite(s) ? 1.0f / s : 0.0f;
}

// Smith masking-shadowing model: height-correlated (above; Cycles 4.x) or separable G1(wi) G1(wo) (Heitz 2014
// eq. 98; Cycles 3.4), which counts a microfacet hidden from both directions twice. Both are <= G1(wi).
enum class Shadowing { HeightCorrelated, Separable };
inline float G2(Distribution dist, const Vec3 &wi, const Vec3 &wo, float ax, float ay, Shadowing model) {
  return model == Shadowing::Separable ? G1(dist, wi, ax, ay) * G1(dist, wo, ax, ay) : G2(dist, wi, wo, ax, ay);
}

// ---- Visible normals --------------------------------------------------------
// Distribution of visible normals (Heitz 2014 eq. 38, Heitz & d'Eon 2014):
// D_wi(wh) = G1(wi) max(0, wi.wh) D(wh) / wi.z, for wi.z > 0.
inline float visible_D(Distribution dist, const Vec3 &wi, const Vec3 &wh, float ax, float ay) {
  if (!(wi.z > 0.0f)) return 0.0f;
  const float cos_ih = dot(wi, wh);
  if (!(cos_ih > 0.0f)) return 0.0f;
  const float v = G1(dist, wi, ax, ay) * cos_ih * D(dist, wh, ax, ay) / wi.z;
  return std::isfinite(v) ? v : 0.0f;
}

// std::fma(a, b, c) for floats, the same bits without libm's fmaf call where the CPU has FMA3 (session 33). The
// build has no -mfma: std::fma is a PLT call, and its caller keeps every live float on the stack across it (the GGX
// sampler below: 0.6 calls per glint sample in the GI scene). Here one VFMADD213SS behind a flag set once when the
// library loads (__builtin_cpu_supports also checks that the OS saves the AVX state) and tested at every call; fmaf
// where the CPU lacks FMA3. Both round a b + c once (IEEE 754 fusedMultiplyAdd); MicrofacetFma.* compare the two bit
// for bit. The asm is volatile so that no optimisation may move it ahead of the flag's test (a CPU without FMA3 would
// fault). The flag is an inline variable: a library that includes this header needs hidden visibility (the plugin's)
// or GCC makes it a unique global, which keeps dlclose from unloading the library.
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__)) && !defined(__FMA__)
#define GLIMMER_FMA_DISPATCH 1
namespace detail {
inline bool cpu_has_fma() {
  __builtin_cpu_init();
  return __builtin_cpu_supports("fma") != 0;
}
inline const bool kCpuHasFma = cpu_has_fma();
}  // namespace detail
#else
#define GLIMMER_FMA_DISPATCH 0
#endif
inline float fused_multiply_add(float a, float b, float c) {
#if GLIMMER_FMA_DISPATCH
  if (detail::kCpuHasFma) {
    asm volatile("vfmadd213ss {%2, %1, %0|%0, %1, %2}" : "+x"(a) : "x"(b), "x"(c));  // a = b a + c, rounded once
    return a;
  }
#endif
  return std::fma(a, b, c);
}

// GGX visible-normal sampling, valid for ANY wi (also wi.z <= 0, the
// volumetric view the random walk needs): in the configuration stretched to
// alpha = 1 the visible normals are normalize(wi + c) with c uniform on the
// spherical cap z >= -wi.z (Dupuy & Benyoub 2023, "Sampling Visible GGX Normals
// with Spherical Caps"; equivalent in distribution to Heitz 2018, "Sampling the
// GGX Distribution of Visible Normals", JCGT 7(4), which covers wi.z > 0).
// In two steps, so that several draws at one wi (session 38: the frosted pane's tail) stretch it once:
// wi_std = ggx_stretched_incidence(wi, ax, ay), then sample_ggx_visible_normal_std(wi_std, ...);
// sample_ggx_visible_normal(wi, ...) is the two in turn (one copy since session 39, glintfixed39: the same
// operations, the same bits; checked in test_frosted_pane_tail.cpp).
// Section 2: stretch to the alpha = 1 configuration.
inline Vec3 ggx_stretched_incidence(const Vec3 &wi, float ax, float ay) {
  return normalize(Vec3(ax * wi.x, ay * wi.y, wi.z));
}
inline Vec3 sample_ggx_visible_normal_std(const Vec3 &wi_std, float ax, float ay, float u1, float u2) {
  // Sample the spherical cap z in [-wi_std.z, 1].
  const float phi = kTwoPi * u1;
  const float z = fused_multiply_add(1.0f - u2, 1.0f + wi_std.z, -wi_std.z);
  const float sin_theta = safe_sqrt(1.0f - z * z);
  const Vec3 c(sin_theta * std::cos(phi), sin_theta * std::sin(phi), z);
  const Vec3 h_std = c + wi_std;
  // Unstretch (the normal transforms with the inverse transpose).
  Vec3 wh = Vec3(ax * h_std.x, ay * h_std.y, std::max(h_std.z, 0.0f));
  const float len2 = dot(wh, wh);
  if (!(len2 > 1e-30f) || !std::isfinite(len2)) return Vec3(0.0f, 0.0f, 1.0f);
  wh = wh / std::sqrt(len2);
  return wh;
}
inline Vec3 sample_ggx_visible_normal(const Vec3 &wi, float ax, float ay, float u1, float u2) {
  return sample_ggx_visible_normal_std(ggx_stretched_incidence(wi, ax, ay), ax, ay, u1, u2);
}

namespace detail {

// Inverse of the standard normal split used for the Beckmann slope y~:
// returns y with erf(y) = 2 u - 1, u in (0, 1). Giles' single-precision
// approximation (2010, "Approximating the erfinv function", GPU Computing
// Gems) as the guess, with its log taken in double from u itself (the former
// erfinv(2 u - 1) rounded 2 u - 1 to float: NaN for u < 1.5e-8),
// then one Halley step on erfc written against the exact target 2 u or
// 2 (1 - u) (cubic convergence: the guess's ~1e-7 becomes ~1e-16).
inline double erfinv_2u_minus_1(double u) {
  u = clamp(u, 1e-300, 1.0 - 1e-16);
  const double x = 2.0 * u - 1.0;
  float w = static_cast<float>(-std::log(4.0 * u * (1.0 - u))), p;
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
  // f(y) = erf(y) - x, written without cancellation in either tail.
  const double f = u < 0.5 ? std::erfc(-y) - 2.0 * u : 2.0 * (1.0 - u) - std::erfc(y);
  const double d = f / (1.1283791670955126 * std::exp(-y * y));  // f / f'
  return y - d / (1.0 + y * d);                                     // Halley: f''/f' = -2y
}

// Visible-slope CDF of the stretched (alpha = 1) Beckmann distribution seen
// from incidence t (Heitz & d'Eon 2014 sec. 4), unnormalised:
//   C(x) = cos(t) erfc(-x) / 2 + sin(t) exp(-x^2) / (2 sqrt(pi)),  x <= x_max = min(cot t, 8),
// density c(x) = (cos t - x sin t) exp(-x^2) / sqrt(pi) (zero at x = cot t),
// c'(x) = (-sin t - 2 x (cos t - x sin t)) exp(-x^2) / sqrt(pi).
struct BeckmannSlopeCdf {
  static constexpr double kInvSqrtPi = 0.56418958354775628695;
  double cos_t, sin_t, x_max, total, e_max;
  BeckmannSlopeCdf(double c, double s) : cos_t(c), sin_t(s) {
    x_max = sin_t * 8.0 < cos_t ? 8.0 : cos_t / sin_t;
    e_max = std::exp(-x_max * x_max);
    // Beyond x = 6 the erfc and exp terms are below 1e-16 of cos t.
    total = x_max > 6.0 ? cos_t : at(x_max, e_max);
  }
  // C(x) given e = exp(-x^2).
  double at(double x, double e) const { return 0.5 * (cos_t * std::erfc(-x) + sin_t * e * kInvSqrtPi); }
  // Lower bound of the root near x_max: there c(y) >= sin t (x_max - y) exp(-x_max^2) / sqrt(pi)
  // (for |y| <= x_max), so total - C(x) >= sin t exp(-x_max^2) (x_max - x)^2 / (2 sqrt(pi)).
  double upper_tail_guess(double target) const {
    const double k = sin_t * e_max * kInvSqrtPi;
    return k > 0.0 ? x_max - std::sqrt(2.0 * std::max(total - target, 0.0) / k) : -8.0;
  }
  // Root far in the lower tail from erfc(z) ~ exp(-z^2) (1 - 1/(2 z^2)) / (z sqrt(pi)), z = -x:
  // C ~ exp(-z^2) (sin t + cos t (1 - 1/(2 z^2)) / z) / (2 sqrt(pi)); one fixed-point pass from z = 1.
  double lower_tail_guess(double target) const {
    const double l = std::log(2.0 * target / kInvSqrtPi);
    double z = std::sqrt(std::max(-l + std::log(sin_t + 0.5 * cos_t), 1.0));
    z = std::sqrt(std::max(-l + std::log(sin_t + cos_t * (1.0 - 0.5 / (z * z)) / z), 1.0));
    return -z;
  }
};

// Safeguarded Householder iteration of order 3 for C(x) = target from the
// guess x in the bracket [lo, hi]: with f = C - target, f' = c, f'' = c',
// f''' = c'' (no further transcendental), one step takes an error e to
// ~e^4, so the guess's ~1e-4 becomes ~1e-16. Stops when |f| < 1e-12 C(x_max)
// (the criterion of the former bisection-Newton solver; 1e-9 of the target
// in the lower tail, where that one left errors of 1e-4 in x), or after a
// step below kStepDone whose curvature term f f'' / f'^2 is below
// kCurvatureDone; a step that leaves the bracket, or whose curvature term
// would dominate (next to x_max, where c -> 0), bisects instead.
// (Until session 41 the iteration took its exp and C(x) as callables for glint's library-free sampler too; since
// glint samples a GGX lobe, libm's are the only ones.)
inline double solve_beckmann_slope(const BeckmannSlopeCdf &c, double target, double x, double lo, double hi) {
  constexpr double isp = BeckmannSlopeCdf::kInvSqrtPi, kStepDone = 1e-3, kCurvatureDone = 1e-2;
  const double tolerance = 1e-12 * std::min(c.total, 1e3 * target);  // relative 1e-9 in the lower tail
  for (int it = 0; it < 64; ++it) {
    const double e = std::exp(-x * x);
    const double value = c.at(x, e) - target;
    if (std::fabs(value) < tolerance) break;
    if (value > 0.0) hi = x; else lo = x;
    const double g = c.cos_t - x * c.sin_t;                            // f' = g exp(-x^2) / sqrt(pi)
    const double n = value / (g * e * isp);                            // f / f'
    const double a2 = (-c.sin_t - 2.0 * x * g) / g;                    // f'' / f'
    const double a3 = (4.0 * x * (c.sin_t + x * g) - 2.0 * g) / g;     // f''' / f'
    const double na2 = n * a2;
    const bool smooth = g > 0.0 && e > 0.0 && std::fabs(na2) < 0.5;
    double next = smooth ? x - n * (6.0 - 3.0 * na2) / (6.0 - 6.0 * na2 + n * n * a3) : 0.5 * (lo + hi);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    const double step = std::fabs(next - x);
    x = next;
    if ((smooth && step < kStepDone && std::fabs(na2) < kCurvatureDone) || hi - lo < 1e-13) break;
  }
  return x;
}

// Start of the iteration: the quantile x(w, v) tabulated on rows
// w = sin t / (sin t + cos t) (smooth in t at both ends) and columns
// v = 1 - sqrt(1 - u) (linear in v where x nears x_max = cot t), solved
// exactly once per process and interpolated bilinearly (median error 2e-4),
// with asymptotic guesses in both tails: most samples then converge in one
// step instead of 6..7 bisection-Newton steps.
struct BeckmannSlopeGuess {
  static constexpr int kRows = 33, kCols = 65;
  static constexpr double kFirstCell = 1.0 / (kCols - 1);  // the tails' cells, where asymptotes guess better
  float x[kRows][kCols];
  BeckmannSlopeGuess() {
    for (int i = 0; i < kRows; ++i) {
      const double w = static_cast<double>(i) / (kRows - 1);
      // sin t / (sin t + cos t) = w  <=>  tan t = w / (1 - w)
      const double len = std::sqrt(w * w + (1.0 - w) * (1.0 - w));
      const BeckmannSlopeCdf c((1.0 - w) / len, w / len);
      for (int j = 0; j < kCols; ++j) {
        const double v = clamp(static_cast<double>(j) / (kCols - 1), 1e-6, 1.0 - 1e-6);
        const double u = 1.0 - (1.0 - v) * (1.0 - v);
        x[i][j] = static_cast<float>(solve_beckmann_slope(c, u * c.total, 0.0, -8.0, c.x_max));
      }
    }
  }
  double guess(double w, double v) const {
    const double fw = w * (kRows - 1), fv = v * (kCols - 1);
    const int i = std::min(static_cast<int>(fw), kRows - 2), j = std::min(static_cast<int>(fv), kCols - 2);
    const double a = fw - i, b = fv - j;
    const double lo = x[i][j] + b * (x[i][j + 1] - x[i][j]);
    const double hi = x[i + 1][j] + b * (x[i + 1][j + 1] - x[i + 1][j]);
    return lo + a * (hi - lo);
  }
};

inline const BeckmannSlopeGuess &beckmann_slope_guess() {
  static const BeckmannSlopeGuess table;
  return table;
}

// The microfacet normal of the stretched (alpha = 1) slopes (slope_x, slope_y) drawn in wi_std's plane of
// incidence: rotated to wi_std's azimuth and unstretched by (ax, ay) (Heitz & d'Eon 2014 Alg. 2); the normal of
// slope (sx, sy) is (-sx, -sy, 1) normalized. Shared by sample_beckmann_visible_normal and glint's own sampler.
inline Vec3 beckmann_normal_of_std_slopes(const Vec3 &wi_std, double slope_x, double slope_y, float ax, float ay) {
  const double len_xy = std::sqrt(double(wi_std.x) * wi_std.x + double(wi_std.y) * wi_std.y);
  const double cos_phi = len_xy > 0.0 ? wi_std.x / len_xy : 1.0;
  const double sin_phi = len_xy > 0.0 ? wi_std.y / len_xy : 0.0;
  const double sx = (cos_phi * slope_x - sin_phi * slope_y) * ax;
  const double sy = (sin_phi * slope_x + cos_phi * slope_y) * ay;
  const double inv_len = 1.0 / std::sqrt(sx * sx + sy * sy + 1.0);
  return Vec3(static_cast<float>(-sx * inv_len), static_cast<float>(-sy * inv_len), static_cast<float>(inv_len));
}
}  // namespace detail

// Beckmann visible-normal sampling for wi.z > 0 (Heitz & d'Eon 2014,
// "Importance Sampling Microfacet-Based BSDFs using the Distribution of
// Visible Normals", CGF 33(4), sec. 4): stretch to alpha = 1, sample the
// visible slope x~ from its marginal by inverting the exact CDF
// (detail::BeckmannSlopeCdf; safeguarded Householder in double from a tabulated
// start: exact, not the paper's fit), then y~ ~ N(0, 1/2) by an inverse erf,
// rotate by phi_i, unstretch.
inline Vec3 sample_beckmann_visible_normal(const Vec3 &wi, float ax, float ay, float u1, float u2) {
  const Vec3 wi_std = normalize(Vec3(ax * wi.x, ay * wi.y, std::max(wi.z, 1e-7f)));
  const double cos_t = wi_std.z;
  const double sin_t = std::sqrt(std::max(0.0, 1.0 - cos_t * cos_t));
  double slope_x, slope_y;
  if (sin_t < 1e-6) {
    // Normal incidence: the slope distribution itself, radius sqrt(-log(1-u)).
    const double r = std::sqrt(-std::log(std::max(1.0 - u1, 1e-300)));
    slope_x = r * std::cos(kTwoPi * u2);
    slope_y = r * std::sin(kTwoPi * u2);
  } else {
    const detail::BeckmannSlopeCdf c(cos_t, sin_t);
    const double u = clamp(static_cast<double>(u1), 1e-9, 1.0 - 1e-9), target = u * c.total;
    const double v = 1.0 - std::sqrt(1.0 - u);
    double x = detail::beckmann_slope_guess().guess(sin_t / (sin_t + cos_t), v);
    if (v < detail::BeckmannSlopeGuess::kFirstCell) x = c.lower_tail_guess(target);
    if (c.x_max < 8.0 && (x >= c.x_max || v > 1.0 - detail::BeckmannSlopeGuess::kFirstCell))
      x = std::max(std::min(x, c.x_max), c.upper_tail_guess(target));
    slope_x = detail::solve_beckmann_slope(c, target, clamp(x, -8.0, c.x_max), -8.0, c.x_max);
    slope_y = detail::erfinv_2u_minus_1(clamp(static_cast<double>(u2), 1e-9, 1.0 - 1e-9));
  }
  return detail::beckmann_normal_of_std_slopes(wi_std, slope_x, slope_y, ax, ay);
}

// Visible-normal sampling for wi.z > 0; pdf of the result is visible_D().
inline Vec3 sample_visible_normal(Distribution dist, const Vec3 &wi, float ax, float ay, float u1, float u2) {
  return dist == Distribution::GGX ? sample_ggx_visible_normal(wi, ax, ay, u1, u2)
                                   : sample_beckmann_visible_normal(wi, ax, ay, u1, u2);
}

// ---- Fresnel ----------------------------------------------------------------
// Exact unpolarized dielectric Fresnel reflectance (Walter 2007 eq. 22 in the
// rs/rp form). cos_i = wi.m may be negative (wi on the inner side: eta is then
// inverted). eta = n_t / n_i for cos_i > 0. Returns 1 for total internal
// reflection; writes |cos| of the transmitted angle to *cos_t (0 for TIR).
inline float fresnel_dielectric(float cos_i, float eta, float *cos_t = nullptr) {
  if (cos_i < 0.0f) {
    eta = 1.0f / eta;
    cos_i = -cos_i;
  }
  cos_i = std::min(cos_i, 1.0f);
  const float sin2_t = (1.0f - cos_i * cos_i) / (eta * eta);
  if (!(sin2_t < 1.0f)) {
    if (cos_t) *cos_t = 0.0f;
    return 1.0f;
  }
  const float ct = std::sqrt(1.0f - sin2_t);
  if (cos_t) *cos_t = ct;
  const float rs = (cos_i - eta * ct) / (cos_i + eta * ct);
  const float rp = (eta * cos_i - ct) / (eta * cos_i + ct);
  const float f = 0.5f * (rs * rs + rp * rp);
  return std::isfinite(f) ? clamp(f, 0.0f, 1.0f) : 1.0f;
}

// Dielectric Fresnel from both cosines of a refraction pair (cos_i = |wi.m|,
// cos_t = |wt.m|, eta = n_t / n_i): the rs/rp form of Walter 2007 eq. 22. It is
// exactly symmetric under (cos_i, cos_t, eta) -> (cos_t, cos_i, 1 / eta), so a
// BTDF using it is reciprocal to rounding even near the critical angle, where
// recomputing cos_t from cos_i amplifies rounding errors.
inline float fresnel_dielectric_pair(float cos_i, float cos_t, float eta) {
  const float rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
  const float rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
  const float f = 0.5f * (rs * rs + rp * rp);
  return std::isfinite(f) ? clamp(f, 0.0f, 1.0f) : 1.0f;
}

// Exact conductor Fresnel reflectance for complex IOR eta + i k (per
// channel; e.g. Lazanyi & Szirmay-Kalos 2005 / pbrt-v3 FrConductor form).
inline float fresnel_conductor(float cos_i, float eta, float k) {
  const float c = clamp(std::fabs(cos_i), 0.0f, 1.0f);
  const float c2 = c * c, s2 = 1.0f - c2;
  const float eta2 = eta * eta, k2 = k * k;
  const float t0 = eta2 - k2 - s2;
  const float a2b2 = std::sqrt(t0 * t0 + 4.0f * eta2 * k2);
  const float a = safe_sqrt(0.5f * (a2b2 + t0));
  const float t1 = a2b2 + c2, t2 = 2.0f * a * c;
  const float rs = (t1 - t2) / std::max(t1 + t2, 1e-30f);
  const float t3 = c2 * a2b2 + s2 * s2, t4 = t2 * s2;
  const float rp = rs * (t3 - t4) / std::max(t3 + t4, 1e-30f);
  const float f = 0.5f * (rs + rp);
  return std::isfinite(f) ? clamp(f, 0.0f, 1.0f) : 1.0f;
}
inline Spectrum fresnel_conductor(float cos_i, const Spectrum &eta, const Spectrum &k) {
  return {fresnel_conductor(cos_i, eta.x, k.x), fresnel_conductor(cos_i, eta.y, k.y),
          fresnel_conductor(cos_i, eta.z, k.z)};
}

// Schlick 1994: F = F0 + (1 - F0) (1 - cos)^5.
inline float schlick_weight(float cos_i) {
  const float m = clamp(1.0f - std::fabs(cos_i), 0.0f, 1.0f);
  const float m2 = m * m;
  return m2 * m2 * m;
}
inline Spectrum fresnel_schlick(float cos_i, const Spectrum &f0) {
  const float s = schlick_weight(cos_i);
  return f0 + (Spectrum(1.0f) - f0) * s;
}
// Normal-incidence reflectance of a dielectric with relative IOR eta.
inline float dielectric_f0(float eta) { return sqr((eta - 1.0f) / (eta + 1.0f)); }

// ---- Reflection / refraction helpers ----------------------------------------
// Mirror wi about m (both away from the surface).
inline Vec3 reflect_about(const Vec3 &wi, const Vec3 &m) { return 2.0f * dot(wi, m) * m - wi; }

// refract's orientation: c = |wi.m|, with eta and the normal n flipped alike when wi is on m's back side.
inline float refraction_orient(const Vec3 &wi, const Vec3 &m, float &eta, Vec3 &n) {
  float c = dot(wi, m);
  n = m;
  if (c < 0.0f) {
    eta = 1.0f / eta;
    c = -c;
    n = -m;
  }
  return c;
}

// Refract wi through the microfacet m (Walter 2007 eq. 40). eta = n_t / n_i
// for wi on the side m points to (dot(wi, m) > 0); a negative dot flips both.
// Returns false on total internal reflection, and for a NaN in wi, m or eta (fresnel_dielectric's F = 1).
inline bool refract(const Vec3 &wi, const Vec3 &m, float eta, Vec3 &wt) {
  Vec3 n;
  const float c = refraction_orient(wi, m, eta, n);
  const float s = 1.0f - c * c;
  const float sin2_t = (s < 0.0f ? 0.0f : s) / (eta * eta);  // max(0, s), but a NaN stays NaN (std::max gave 0)
  if (!(sin2_t < 1.0f)) return false;
  const float ct = std::sqrt(1.0f - sin2_t);
  wt = normalize(-wi / eta + (c / eta - ct) * n);
  return true;
}

// refract(wi, m, eta, wt) where fresnel_dielectric(dot(wi, m), eta, &cos_t) < 1 already gave cos_t: the same wt bit
// for bit without the second square root. Both flip (eta, c, m) alike for c = wi.m < 0, and Fresnel's
// sin2_t = (1 - min(c, 1)^2) / eta^2 equals refract's max(0, 1 - c^2) / eta^2 exactly (both 0 for c >= 1; for c <= 1,
// 1 - c c >= 0 in floats), so its cos_t is refract's ct; F < 1 implies sin2_t < 1, where refract succeeds (session
// 39: the frosted pane walk's resampled events; checked in test_frosted_pane_tail.cpp).
inline Vec3 refract_with_cos_t(const Vec3 &wi, const Vec3 &m, float eta, float cos_t) {
  Vec3 n;
  const float c = refraction_orient(wi, m, eta, n);
  return normalize(-wi / eta + (c / eta - cos_t) * n);
}

// Mirror z: maps the inner side of an interface to the outer side.
inline Vec3 flip_z_local(const Vec3 &v) { return {v.x, v.y, -v.z}; }

// Reflection half vector normalize(wi + wo) oriented to the upper hemisphere
// (Walter 2007 eq. 13). Returns false when degenerate.
inline bool half_vector_reflect(const Vec3 &wi, const Vec3 &wo, Vec3 &wh) {
  const Vec3 h = wi + wo;
  const float len2 = dot(h, h);
  if (!(len2 > 1e-20f)) return false;
  wh = h / std::sqrt(len2);
  if (wh.z < 0.0f) wh = -wh;
  return true;
}

// Generalized transmission half vector -(wi + eta wo) (Walter 2007 eq. 16),
// eta = n_o / n_i (IOR on wo's side over wi's side), oriented to wh.z >= 0.
// *len2 receives |wi + eta wo|^2 = (wi.wh + eta wo.wh)^2, the Jacobian's
// denominator (Walter 2007 eq. 17).
inline bool half_vector_transmit(const Vec3 &wi, const Vec3 &wo, float eta, Vec3 &wh, float *len2_out = nullptr) {
  const Vec3 h = wi + eta * wo;
  const float len2 = dot(h, h);
  if (!(len2 > 1e-20f) || !std::isfinite(len2)) return false;
  wh = h / std::sqrt(len2);
  if (wh.z < 0.0f) wh = -wh;
  if (len2_out) *len2_out = len2;
  return true;
}

// Jacobians of the half-vector maps (Walter 2007 eqs. 14 and 17):
// reflection dwh/dwo = 1 / (4 |wo.wh|); transmission dwh/dwo = eta^2 |wo.wh| / |wi + eta wo|^2.
inline float jacobian_reflect(const Vec3 &wo, const Vec3 &wh) {
  const float c = std::fabs(dot(wo, wh));
  return c > 0.0f ? 1.0f / (4.0f * c) : 0.0f;
}
inline float jacobian_transmit(const Vec3 &wo, const Vec3 &wh, float eta, float len2) {
  return eta * eta * std::fabs(dot(wo, wh)) / len2;
}

}  // namespace glimmer::microfacet
