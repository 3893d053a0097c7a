// Heitz et al. 2016, "Multiple-Scattering Microfacet BSDFs with the Smith
// Model" (SIGGRAPH): the random walk on the GGX microsurface seen as a
// volume, plus the single-scattering albedo integrals the energy tables need.
// Header-only; used by the microfacet_random_walk closure, the
// `glimmer precompute energy` command and the tests.
//
// Height distribution: uniform on [-1, 1] (any height distribution gives the
// same BSDF, Heitz 2016 sec. 5.1): C1(h) = (h + 1) / 2.
// A walk is carried out in the frame of the side it is on: on the inner side
// of a dielectric the microsurface is mirrored (z -> -z, h -> -h) and eta is
// inverted (Heitz 2016 sec. 6.3).
#pragma once

#include <array>
#include <cmath>
#include <limits>

#include "glimmer/microfacet.h"
#include "glimmer/microfacet_energy_grid.h"
#include "glimmer/rng.h"

namespace glimmer::microfacet {

struct WalkSurface {
  float ax = 1.0f, ay = 1.0f;
};

inline double walk_C1(double h) { return clamp(0.5 * (h + 1.0), 0.0, 1.0); }
inline double walk_invC1(double u) { return clamp(2.0 * u - 1.0, -1.0, 1.0); }
inline constexpr double kWalkEscaped = std::numeric_limits<double>::infinity();
inline constexpr double kWalkTop = 2.0;  // above the surface: C1 = 1

// Probability that a ray leaving height h in direction w escapes
// (Heitz 2016 eq. 9): C1(h)^Lambda(w) for w.z > 0, 0 otherwise.
inline double walk_G1(const Vec3 &w, double h, const WalkSurface &s) {
  if (w.z > 0.9999f) return 1.0;
  if (w.z <= 0.0f) return 0.0;
  const double l = ggx_lambda(w, s.ax, s.ay);
  if (!std::isfinite(l)) return 0.0;
  return std::pow(walk_C1(h), l);
}

// Next intersection height of the ray (direction wr, from height hr) with the
// microsurface, or kWalkEscaped (Heitz 2016 eq. 10, inverted: Alg. 2).
inline double walk_sample_height(const Vec3 &wr, double hr, double u, const WalkSurface &s) {
  if (wr.z > 0.9999f) return kWalkEscaped;
  if (wr.z < -0.9999f) return walk_invC1(u * walk_C1(hr));
  if (std::fabs(wr.z) < 1e-4f) return hr;
  const double g1 = walk_G1(wr, hr, s);
  if (u > 1.0 - g1) return kWalkEscaped;
  const double l = ggx_lambda(wr, s.ax, s.ay);
  if (!std::isfinite(l) || l == 0.0) return hr;
  const double h = walk_invC1(walk_C1(hr) / std::pow(1.0 - u, 1.0 / l));
  return std::isfinite(h) ? h : hr;
}

// Projected area of the microsurface toward w (any w.z): (1 + Lambda(w)) w.z
// (Heitz 2016 eq. 2 / Heitz 2014 eq. 5).
inline float walk_projected_area(const Vec3 &w, const WalkSurface &s) {
  Vec3 v = w;
  if (std::fabs(v.z) < 1e-6f) v.z = std::copysign(1e-6f, v.z == 0.0f ? 1.0f : v.z);
  const float l = ggx_lambda(v, s.ax, s.ay);
  const float a = (1.0f + l) * v.z;
  return std::isfinite(a) && a > 0.0f ? a : 0.0f;
}

// Visible normal density for any direction w (Heitz 2016 eq. 3).
inline float walk_visible_D(const Vec3 &w, const Vec3 &m, const WalkSurface &s) {
  const float c = dot(w, m);
  if (!(c > 0.0f)) return 0.0f;
  const float area = walk_projected_area(w, s);
  if (!(area > 0.0f)) return 0.0f;
  const float v = c * ggx_D(m, s.ax, s.ay) / area;
  return std::isfinite(v) ? v : 0.0f;
}

// Tiny deterministic generator for walks (PCG hash of a counter).
struct WalkRng {
  uint32_t state;
  explicit WalkRng(uint32_t seed) : state(seed) {}
  float next() {
    state = state * kPcgMultiplier + kPcgIncrement;
    uint32_t w = ((state >> ((state >> 28u) + 4u)) ^ state) * kPcgOutputMultiplier;
    w = (w >> 22u) ^ w;
    return static_cast<float>(w >> 8) * (1.0f / 16777216.0f);
  }
};

inline constexpr int kWalkMaxOrder = 256;

// ---- Conductor --------------------------------------------------------------
// One conductor walk from wi (wi.z > 0) with Fresnel-free facets. Returns the
// exit direction (wo.z > 0) and writes the scattering order; order 0 = the
// walk was cut at kWalkMaxOrder (energy lost, < 1e-6 in practice).
// `on_bounce(cos_facet)` is called at every facet with dot(w_in, m).
template <typename Rng, typename OnBounce>
inline Vec3 walk_conductor(const Vec3 &wi, const WalkSurface &s, Rng &rng, int &order, OnBounce &&on_bounce) {
  Vec3 wr = -wi;
  double hr = kWalkTop;
  for (int k = 1; k <= kWalkMaxOrder; ++k) {
    hr = walk_sample_height(wr, hr, rng.next(), s);
    if (hr == kWalkEscaped) {
      order = k - 1;
      return wr;
    }
    const Vec3 wv = -wr;
    const float u1 = rng.next(), u2 = rng.next();
    const Vec3 m = sample_ggx_visible_normal(wv, s.ax, s.ay, u1, u2);
    const float c = dot(wv, m);
    on_bounce(c);
    wr = normalize(reflect_about(wv, m));
    if (!is_finite(wr)) break;
  }
  order = 0;
  return Vec3(0.0f, 0.0f, 1.0f);
}

// Stochastic estimate of f * cos(wo) of the multiple-scattering conductor
// (Heitz 2016 sec. 4.2, the "next event" estimator of Alg. 3): at each
// vertex the phase function toward wo times the escape probability of wo.
// `fresnel(cos)` returns the per-channel Fresnel weight.
template <typename Rng, typename Fresnel>
inline Spectrum walk_conductor_eval(const Vec3 &wi, const Vec3 &wo, const WalkSurface &s, Rng &rng, Fresnel &&fresnel) {
  if (!(wo.z > 0.0f) || !(wi.z > 0.0f)) return Spectrum(0.0f);
  Spectrum sum(0.0f), energy(1.0f);
  Vec3 wr = -wi;
  double hr = kWalkTop;
  for (int k = 1; k <= kWalkMaxOrder; ++k) {
    hr = walk_sample_height(wr, hr, rng.next(), s);
    if (hr == kWalkEscaped) break;
    const Vec3 wv = -wr;
    Vec3 wh;
    if (half_vector_reflect(wv, wo, wh)) {
      const float c = dot(wv, wh);
      if (c > 0.0f) {
        const float phase = walk_visible_D(wv, wh, s) / (4.0f * c);
        const float shadow = static_cast<float>(walk_G1(wo, hr, s));
        sum += energy * fresnel(c) * (phase * shadow);
      }
    }
    const Vec3 m = sample_ggx_visible_normal(wv, s.ax, s.ay, rng.next(), rng.next());
    energy *= fresnel(dot(wv, m));
    wr = normalize(reflect_about(wv, m));
    if (!is_finite(wr) || max_component(energy) < 1e-7f) break;
  }
  return sum;
}

// ---- Dielectric -------------------------------------------------------------
// Side-local frame: on the inner side z is mirrored.
inline Vec3 flip_z(const Vec3 &v) { return flip_z_local(v); }

// One scattering event of a dielectric walk at height hr: sample a visible
// normal for wv = -wr, then reflect (probability F, or on TIR) or refract to
// the other side, where the frame and the height are mirrored and eta inverts.
template <typename Rng>
inline void walk_dielectric_scatter(const WalkSurface &s, Rng &rng, Vec3 &wr, double &hr, bool &outside,
                                    float &eta_side) {
  const Vec3 wv = -wr;
  const Vec3 m = sample_ggx_visible_normal(wv, s.ax, s.ay, rng.next(), rng.next());
  const float F = fresnel_dielectric(dot(wv, m), eta_side);
  Vec3 wt;
  if (rng.next() < F || !refract(wv, m, eta_side, wt)) {
    wr = normalize(reflect_about(wv, m));
  } else {
    wr = flip_z(wt);
    hr = -hr;
    outside = !outside;
    eta_side = 1.0f / eta_side;
  }
}

// One dielectric walk from wi (either side; wi.z < 0 means inside, eta is
// n_inside / n_outside). Returns the exit direction in the shading frame
// (z > 0: reflected to wi's... outer side; z < 0: transmitted to the inner side).
template <typename Rng>
inline Vec3 walk_dielectric(const Vec3 &wi, float eta, const WalkSurface &s, Rng &rng, int &order) {
  bool outside = wi.z > 0.0f;
  float eta_side = outside ? eta : 1.0f / eta;  // n_other / n_this
  Vec3 wr = outside ? -wi : flip_z(-wi);         // side-local
  double hr = kWalkTop;
  for (int k = 1; k <= kWalkMaxOrder; ++k) {
    hr = walk_sample_height(wr, hr, rng.next(), s);
    if (hr == kWalkEscaped) {
      order = k - 1;
      return outside ? wr : flip_z(wr);
    }
    walk_dielectric_scatter(s, rng, wr, hr, outside, eta_side);
    if (!is_finite(wr)) break;
  }
  order = 0;
  return Vec3(0.0f, 0.0f, 1.0f);
}

// Stochastic estimate of f * |cos(wo)| for the multiple-scattering dielectric
// (next-event form of Heitz 2016 Alg. 4). Energy-conserving convention: the
// transmission phase includes eta^2 |wo.wh| / |wv + eta wo|^2, so the
// estimate integrates to the albedo (R + T = 1 without absorption).
template <typename Rng>
inline float walk_dielectric_eval(const Vec3 &wi, const Vec3 &wo, float eta, const WalkSurface &s, Rng &rng) {
  if (wi.z == 0.0f || wo.z == 0.0f) return 0.0f;
  bool outside = wi.z > 0.0f;
  float eta_side = outside ? eta : 1.0f / eta;
  Vec3 wr = outside ? -wi : flip_z(-wi);
  double hr = kWalkTop;
  float sum = 0.0f;
  for (int k = 1; k <= kWalkMaxOrder; ++k) {
    hr = walk_sample_height(wr, hr, rng.next(), s);
    if (hr == kWalkEscaped) break;
    const Vec3 wv = -wr;
    const Vec3 wo_side = outside ? wo : flip_z(wo);
    if (wo_side.z > 0.0f) {
      Vec3 wh;
      if (half_vector_reflect(wv, wo_side, wh)) {
        const float c = dot(wv, wh);
        if (c > 0.0f) {
          const float F = fresnel_dielectric(c, eta_side);
          const float phase = F * walk_visible_D(wv, wh, s) / (4.0f * c);
          sum += phase * static_cast<float>(walk_G1(wo_side, hr, s));
        }
      }
    } else {
      Vec3 wh;
      float len2;
      if (half_vector_transmit(wv, wo_side, eta_side, wh, &len2)) {
        const float ci = dot(wv, wh), co = dot(wo_side, wh);
        if (ci > 0.0f && co < 0.0f) {
          const float F = fresnel_dielectric(ci, eta_side);
          const float phase = (1.0f - F) * walk_visible_D(wv, wh, s) * jacobian_transmit(wo_side, wh, eta_side, len2);
          // Escape on the other side: mirrored frame and height.
          sum += phase * static_cast<float>(walk_G1(flip_z(wo_side), -hr, s));
        }
      }
    }
    walk_dielectric_scatter(s, rng, wr, hr, outside, eta_side);
    if (!is_finite(wr)) break;
  }
  return std::isfinite(sum) ? sum : 0.0f;
}

// ---- Single-scattering albedo (for the energy tables) --------------------------
// Stratified visible-normal quadrature of E(mu) = int D_wi(m) w(m) dm with the
// per-normal weight w = sum over lobes of (lobe probability) G2 / G1(wi)
// (exact single-scatter weight of visible-normal sampling), isotropic alpha,
// wi = (sqrt(1 - mu^2), 0, mu). `jitter` supplies uniform numbers.
template <typename Rng>
inline double single_scatter_albedo_conductor(Distribution dist, float mu, float alpha, int strata, Rng &rng) {
  const Vec3 wi(std::sqrt(std::max(0.0f, 1.0f - mu * mu)), 0.0f, mu);
  const float g1 = G1(dist, wi, alpha, alpha);
  if (!(g1 > 0.0f)) return 0.0;
  double sum = 0.0;
  for (int i = 0; i < strata; ++i) {
    for (int j = 0; j < strata; ++j) {
      const float u1 = (i + rng.next()) / strata, u2 = (j + rng.next()) / strata;
      const Vec3 m = sample_visible_normal(dist, wi, alpha, alpha, u1, u2);
      const Vec3 wo = reflect_about(wi, m);
      if (wo.z > 0.0f) sum += G2(dist, wi, wo, alpha, alpha) / g1;
    }
  }
  return sum / (double(strata) * strata);
}

// Same for the dielectric (R + T), wi on the side where eta = n_other / n_this.
template <typename Rng>
inline double single_scatter_albedo_dielectric(Distribution dist, float mu, float alpha, float eta, int strata,
                                               Rng &rng) {
  const Vec3 wi(std::sqrt(std::max(0.0f, 1.0f - mu * mu)), 0.0f, mu);
  const float g1 = G1(dist, wi, alpha, alpha);
  if (!(g1 > 0.0f)) return 0.0;
  double sum = 0.0;
  for (int i = 0; i < strata; ++i) {
    for (int j = 0; j < strata; ++j) {
      const float u1 = (i + rng.next()) / strata, u2 = (j + rng.next()) / strata;
      const Vec3 m = sample_visible_normal(dist, wi, alpha, alpha, u1, u2);
      const float F = fresnel_dielectric(dot(wi, m), eta);
      const Vec3 wr = reflect_about(wi, m);
      if (wr.z > 0.0f) sum += F * G2(dist, wi, wr, alpha, alpha) / g1;
      Vec3 wt;
      if (F < 1.0f && refract(wi, m, eta, wt) && wt.z < 0.0f) sum += (1.0f - F) * G2(dist, wi, wt, alpha, alpha) / g1;
    }
  }
  return sum / (double(strata) * strata);
}

// Hill 2022 Fresnel split: per walk, e[i] is the coefficient of F0^i of the
// product of Schlick factors s_k + F0 (1 - s_k), s_k = (1 - cos_k)^5:
// for i = N-1..1: e[i] = mix(e[i-1], e[i], s); e[0] *= s. The last
// coefficient also keeps the (truncated) higher powers, so sum(e) stays the
// F0 = 1 energy exactly.
template <int N>
struct FresnelSplit {
  std::array<double, N> e{};
  FresnelSplit() { e[0] = 1.0; }
  void bounce(float cos_facet) {
    const double s = schlick_weight(cos_facet);
    const double overflow = e[N - 1] * (1.0 - s);
    for (int i = N - 1; i >= 1; --i) e[i] = e[i - 1] * (1.0 - s) + e[i] * s;
    e[N - 1] += overflow;
    e[0] *= s;
  }
};

inline constexpr int kFresnelSplitTerms = 16;

// E_Fms representation. A bare cubic in F0 cannot follow the walk's
// polynomial p(F0) = sum_i w_i F0^i to 1 % in relative error when alpha is near 1:
// the bounce orders 4..15 carry a third of the energy there (measured minimax
// optimum over F0 in [0, 1] at alpha = 1, mu = 1: 2.4 %). Those higher orders
// form a near-geometric series (each further bounce costs about F0 times the
// chance of another bounce), so the cubic is divided by the series' factor:
//   E_Fms(F0) = P(F0) / (1 - h F0),  P(F0) = c0 + F0 (c1 + F0 (c2 + F0 c3)),
//   h = k (1 - E(mu)),
// E(mu) being the Fresnel-free single-scatter albedo of the cell (1 - E is the
// probability that a walk goes on after its first bounce). k = 1/2 is the
// measured best single rule for the Fresnel split (the free optimum of h lies
// at 0.41-0.58 x (1 - E) over the table's cells); the bounce-tint polynomial
// (below, no Schlick term) is best served by k = 0.6. The cubic P keeps Hill's
// form (one RGBA table, Horner evaluation); the division is the only extra
// operation. Constants and evaluation: glimmer/microfacet_energy_grid.h.
using energy_grid::kBounceTintTail;
using energy_grid::kFresnelSplitTail;
inline double fresnel_split_denominator(double E, double f0, double tail = kFresnelSplitTail) {
  return 1.0 - tail * (1.0 - E) * f0;
}

// Hill 2022 refit: the cubic P of E_Fms(F0) = P(F0) / (1 - h F0) (above)
// minimizing the error RELATIVE to the walk's polynomial p(F0) = sum_i w_i F0^i
// over F0 in [0, 1]: weighted least squares on (P / D - p) / p = (P - p D) / (p D)
// at 129 points x_k = (k / 128)^2 (denser near F0 = 0, where p is small), with
// Lawson's iterative reweighting (weights *= |relative error|) converging to the
// minimax fit, and F0 = 1 interpolated exactly (white furnace: P(1) = p(1) D(1)).
// `E` is the cell's single-scatter albedo and `tail` k (h above). Normal
// equations in double. Returns c0..c3; *max_relative_error (optional) gets the
// fit's max |P/D - p| / p.
inline std::array<double, 4> fit_fresnel_split_cubic(const std::array<double, kFresnelSplitTerms> &w, double E,
                                                     double *max_relative_error = nullptr,
                                                     double tail = kFresnelSplitTail) {
  constexpr int samples = 129;
  double xs[samples], ps[samples], scale[samples], lawson[samples];
  double p1 = 0.0;
  for (double v : w) p1 += v;
  const double P1 = p1 * fresnel_split_denominator(E, 1.0, tail);
  for (int k = 0; k < samples; ++k) {
    const double t = double(k) / (samples - 1);
    xs[k] = t * t;
    double p = 0.0, xp = 1.0;
    for (int i = 0; i < kFresnelSplitTerms; ++i, xp *= xs[k]) p += w[i] * xp;
    ps[k] = p * fresnel_split_denominator(E, xs[k], tail);  // the cubic's target p D
    scale[k] = std::max(ps[k], 1e-9 * P1 + 1e-30);  // p(0) = 0 for the bounce-tint polynomial
    lawson[k] = 1.0 / samples;
  }
  // P(1) = P1 exactly: c3 = P1 - c0 - c1 - c2, so
  // P(x) = c0 (1 - x^3) + c1 (x - x^3) + c2 (x^2 - x^3) + P1 x^3.
  std::array<double, 4> c{};
  double worst = 0.0;
  for (int iteration = 0; iteration < 100; ++iteration) {
    double ata[3][3] = {}, atb[3] = {};
    for (int k = 0; k < samples; ++k) {
      const double x = xs[k], x3 = x * x * x;
      const double weight = lawson[k] / (scale[k] * scale[k]);
      const double basis[3] = {1.0 - x3, x - x3, x * x - x3};
      const double target = ps[k] - P1 * x3;
      for (int r = 0; r < 3; ++r) {
        atb[r] += weight * basis[r] * target;
        for (int q = 0; q < 3; ++q) ata[r][q] += weight * basis[r] * basis[q];
      }
    }
    for (int col = 0; col < 3; ++col) {  // Gaussian elimination, partial pivoting
      int pivot = col;
      for (int r = col + 1; r < 3; ++r)
        if (std::fabs(ata[r][col]) > std::fabs(ata[pivot][col])) pivot = r;
      for (int q = 0; q < 3; ++q) std::swap(ata[col][q], ata[pivot][q]);
      std::swap(atb[col], atb[pivot]);
      if (std::fabs(ata[col][col]) < 1e-300) continue;
      for (int r = col + 1; r < 3; ++r) {
        const double f = ata[r][col] / ata[col][col];
        for (int q = col; q < 3; ++q) ata[r][q] -= f * ata[col][q];
        atb[r] -= f * atb[col];
      }
    }
    for (int r = 2; r >= 0; --r) {
      double sum = atb[r];
      for (int q = r + 1; q < 3; ++q) sum -= ata[r][q] * c[q];
      c[r] = std::fabs(ata[r][r]) < 1e-300 ? 0.0 : sum / ata[r][r];
    }
    c[3] = P1 - c[0] - c[1] - c[2];
    // Lawson update toward the minimax relative error.
    double total = 0.0;
    worst = 0.0;
    for (int k = 0; k < samples; ++k) {
      const double x = xs[k];
      const double err = std::fabs(c[0] + x * (c[1] + x * (c[2] + x * c[3])) - ps[k]) / scale[k];
      worst = std::max(worst, err);
      lawson[k] *= err + 1e-15;
      total += lawson[k];
    }
    if (!(total > 0.0) || worst < 1e-9) break;
    for (double &l : lawson) l /= total;
  }
  if (max_relative_error) *max_relative_error = worst;
  return c;
}

// E_Fms(F0) (or the bounce-tint energy, tail = kBounceTintTail) from the fitted cubic.
inline double fresnel_split_energy(const std::array<double, 4> &c, double E, double f0,
                                   double tail = kFresnelSplitTail) {
  return energy_grid::tail_cubic(c.data(), E, f0, tail);
}

// Fresnel-split multiple-scattering polynomial of the conductor walk at
// (mu, alpha): average e over `walks` walks of order >= 2, rescaled so that
// sum(w) = target (the exact F0 = 1 energy 1 - E; ratio estimator).
// `tint` (optional) gets the bounce-tint polynomial of the same walks: the
// share of walks leaving after k >= 2 bounces (k >= N-1 pooled in the last
// term), same scaling: sum_k tint_k c^k is the multiple-scattering energy when
// every bounce multiplies by a constant c (Cycles' Multiscatter GGX colour)
// instead of Schlick's Fresnel.
template <typename Rng>
inline std::array<double, kFresnelSplitTerms> fresnel_split_polynomial(float mu, float alpha, int walks, double target,
                                                                       Rng &rng,
                                                                       std::array<double, kFresnelSplitTerms> *tint =
                                                                           nullptr) {
  const Vec3 wi(std::sqrt(std::max(0.0f, 1.0f - mu * mu)), 0.0f, mu);
  const WalkSurface surface{alpha, alpha};
  std::array<double, kFresnelSplitTerms> w{}, orders{};
  for (int n = 0; n < walks; ++n) {
    FresnelSplit<kFresnelSplitTerms> split;
    int order = 0;
    walk_conductor(wi, surface, rng, order, [&](float c) { split.bounce(c); });
    if (order >= 2) {
      for (int i = 0; i < kFresnelSplitTerms; ++i) w[i] += split.e[i];
      orders[std::min(order, kFresnelSplitTerms - 1)] += 1.0;
    }
  }
  double sum = 0.0;
  for (double v : w) sum += v;  // = the number of walks of order >= 2
  const double scale = sum > 0.0 ? std::max(target, 0.0) / sum : 0.0;
  for (double &v : w) v *= scale;
  if (tint)
    for (int i = 0; i < kFresnelSplitTerms; ++i) (*tint)[i] = orders[i] * scale;
  return w;
}

}  // namespace glimmer::microfacet
