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

// Beckmann Lambda (Heitz 2014 eq. 84) with a = 1 / sqrt(a2):
// (erf(a) - 1) / 2 + exp(-a^2) / (2 a sqrt(pi)) = (exp(-a^2)/(a sqrt(pi)) - erfc(a)) / 2,
// evaluated in double (the two terms cancel for large a).
inline float beckmann_lambda(const Vec3 &w, float ax, float ay) {
  if (w.z == 0.0f) return INFINITY;
  const double a2 = alpha2_tan2(w, ax, ay);
  double l;
  if (!(a2 > 0.0)) {
    l = 0.0;
  } else if (!std::isfinite(a2)) {
    l = INFINITY;
  } else {
    const double a = 1.0 / std::sqrt(a2);
    if (a > 6.0) {
      l = 0.0;  // below 1e-17
    } else {
      l = 0.5 * (std::exp(-a * a) / (a * 1.7724538509055160273) - std::erfc(a));
    }
  }
  const float lf = static_cast<float>(std::max(l, 0.0));
  return w.z > 0.0f ? lf : -1.0f - lf;
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

// GGX visible-normal sampling, valid for ANY wi (also wi.z <= 0, the
// volumetric view the random walk needs): in the configuration stretched to
// alpha = 1 the visible normals are normalize(wi + c) with c uniform on the
// spherical cap z >= -wi.z (Dupuy & Benyoub 2023, "Sampling Visible GGX Normals
// with Spherical Caps"; equivalent in distribution to Heitz 2018, "Sampling the
// GGX Distribution of Visible Normals", JCGT 7(4), which covers wi.z > 0).
inline Vec3 sample_ggx_visible_normal(const Vec3 &wi, float ax, float ay, float u1, float u2) {
  // Section 2: stretch to the alpha = 1 configuration.
  const Vec3 wi_std = normalize(Vec3(ax * wi.x, ay * wi.y, wi.z));
  // Sample the spherical cap z in [-wi_std.z, 1].
  const float phi = kTwoPi * u1;
  const float z = std::fma(1.0f - u2, 1.0f + wi_std.z, -wi_std.z);
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

// Inverse error function: Giles 2010 single-precision approximation
// ("Approximating the erfinv function", GPU Computing Gems) refined by two
// Newton steps in double.
inline double erfinv(double x) {
  x = clamp(x, -1.0 + 1e-15, 1.0 - 1e-15);
  const float xf = static_cast<float>(x);
  float w = -std::log((1.0f - xf) * (1.0f + xf)), p;
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
  double y = static_cast<double>(p) * x;
  for (int i = 0; i < 2; ++i) {  // Newton on erf(y) - x
    const double err = std::erf(y) - x;
    y -= err / (1.1283791670955126 * std::exp(-y * y));
  }
  return y;
}

// Beckmann visible-normal sampling for wi.z > 0 (Heitz & d'Eon 2014,
// "Importance Sampling Microfacet-Based BSDFs using the Distribution of
// Visible Normals", CGF 33(4), sec. 4): stretch to alpha = 1, sample the
// visible slope x~ from its marginal by inverting the exact CDF
//   C(x) = cos(t) (1 + erf(x)) / 2 + sin(t) exp(-x^2) / (2 sqrt(pi)),  x <= cot(t)
// (safeguarded Newton in double, to 1e-12: exact, not the paper's fit), then
// y~ ~ N(0, 1/2) by erfinv, rotate by phi_i, unstretch.
inline Vec3 sample_beckmann_visible_normal(const Vec3 &wi, float ax, float ay, float u1, float u2) {
  const Vec3 wi_std = normalize(Vec3(ax * wi.x, ay * wi.y, std::max(wi.z, 1e-7f)));
  const double cos_t = wi_std.z;
  const double sin_t = std::sqrt(std::max(0.0, 1.0 - cos_t * cos_t));
  double slope_x, slope_y;
  const double inv_sqrt_pi = 0.56418958354775628695;
  if (sin_t < 1e-6) {
    // Normal incidence: the slope distribution itself, radius sqrt(-log(1-u)).
    const double r = std::sqrt(-std::log(std::max(1.0 - u1, 1e-300)));
    slope_x = r * std::cos(kTwoPi * u2);
    slope_y = r * std::sin(kTwoPi * u2);
  } else {
    const double x_max = std::min(cos_t / sin_t, 8.0);
    auto cdf = [&](double x) { return cos_t * 0.5 * (1.0 + std::erf(x)) + sin_t * std::exp(-x * x) * 0.5 * inv_sqrt_pi; };
    const double total = cdf(x_max);
    const double target = clamp(static_cast<double>(u1), 1e-9, 1.0 - 1e-9) * total;
    double lo = -8.0, hi = x_max;
    double x = 0.5 * (lo + hi);
    for (int it = 0; it < 64; ++it) {
      const double value = cdf(x) - target;
      if (std::fabs(value) < 1e-12 * total) break;
      if (value > 0.0) hi = x; else lo = x;
      const double density = (cos_t - x * sin_t) * std::exp(-x * x) * inv_sqrt_pi;
      double next = density > 0.0 ? x - value / density : 0.5 * (lo + hi);
      if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
      x = next;
      if (hi - lo < 1e-13) break;
    }
    slope_x = x;
    slope_y = erfinv(2.0 * clamp(static_cast<double>(u2), 1e-9, 1.0 - 1e-9) - 1.0);
  }
  // Rotate from the plane of incidence and unstretch (Heitz & d'Eon 2014 Alg. 2).
  const double len_xy = std::sqrt(double(wi_std.x) * wi_std.x + double(wi_std.y) * wi_std.y);
  const double cos_phi = len_xy > 0.0 ? wi_std.x / len_xy : 1.0;
  const double sin_phi = len_xy > 0.0 ? wi_std.y / len_xy : 0.0;
  const double sx = (cos_phi * slope_x - sin_phi * slope_y) * ax;
  const double sy = (sin_phi * slope_x + cos_phi * slope_y) * ay;
  // The microfacet normal of slope (sx, sy) is (-sx, -sy, 1) normalized.
  const double inv_len = 1.0 / std::sqrt(sx * sx + sy * sy + 1.0);
  return Vec3(static_cast<float>(-sx * inv_len), static_cast<float>(-sy * inv_len), static_cast<float>(inv_len));
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

// Refract wi through the microfacet m (Walter 2007 eq. 40). eta = n_t / n_i
// for wi on the side m points to (dot(wi, m) > 0); a negative dot flips both.
// Returns false on total internal reflection.
inline bool refract(const Vec3 &wi, const Vec3 &m, float eta, Vec3 &wt) {
  float c = dot(wi, m);
  Vec3 n = m;
  if (c < 0.0f) {
    eta = 1.0f / eta;
    c = -c;
    n = -m;
  }
  const float sin2_t = std::max(0.0f, 1.0f - c * c) / (eta * eta);
  if (!(sin2_t < 1.0f)) return false;
  const float ct = std::sqrt(1.0f - sin2_t);
  wt = normalize(-wi / eta + (c / eta - ct) * n);
  return true;
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
