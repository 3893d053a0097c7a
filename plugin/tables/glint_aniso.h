// Anisotropic base roughness of the glint closure (brushed / stretched
// flakes; issue 10, docs/glints.md "Anisotropic base roughness").
//
// An anisotropic P_gamma(wi, wo) depends on phi_i and phi_o separately (a 4D
// table of 4.3 G entries at 1 degree), so P is computed per query instead: a
// disk rule of the analytic reflected density
//   q(wi, r) = D(h; alpha_x, alpha_y) cos(theta_h) / (4 wi.h),  h = normalize(wi + r)
// on the query cone of half-angle gamma around wo (the exponential map of a
// disk of radius gamma in the tangent plane of wo, with its Jacobian
// sin(rho) / rho). The rule follows the lobe's width against the cone
// (AnisoConeRules below): the 7-point degree-5 rule (centre 1/4, six points
// at radius sqrt(2/3) gamma, 1/8 each), 19 points (the centre and two rings
// of 9 at the Gauss-Radau radii of t = rho^2 / gamma^2, exact in t to degree
// 4, in the azimuth to harmonic 8), or a product rule with points per axis
// set by the lobe's scale.
//
// LOD: the path's blur sigma_L (radians, capped at 2 alpha_max) widens the
// NDF per axis, alpha_k^2 + (sigma_L / 2)^2 (as the sampling lobe already
// widens), instead of the isotropic tables' blurred levels. Energy: as the
// isotropic levels, P is scaled per wi so that the reflected energy of the
// estimator, Int W(wi, wo) P(wi, wo) / sigma dwo, equals that of the unblurred
// estimator capped at the smooth anisotropic albedo (+0.1 %). The scale is a
// small table over theta_i (1-degree nodes), phi_i (10-degree nodes folded to
// [0, 90]: D is symmetric about both tangent axes) and 5 blur levels
// t = sigma_L / (2 alpha_max) in {0, 1/4, 1/2, 3/4, 1}, built when a material
// first needs it (~20 s on the loaded 2-core machine), shared by every
// instance of the process and cached on disk like the isotropic tables
// (glint_A_<key>.bin in host->cache_dir, HMAC-SHA256, atomic write; see
// glint_aniso_cache.cpp).
//
// The energies come from swapping the two integrals: with the cone
// indicator symmetric in (r, wo),
//   Int W(wo) Int_cone(wo) q(r) dr dwo / sigma = Int q(r) Wbar(r) dr,
// Wbar(r) the mean of W over the cone around r (7-point rule); q(r) dr is
// D cos(theta_h) dh, integrated on a 64 x 64 midpoint grid of the visible-
// normal sampler of the (widened) lobe with weight cos_i cos_h / (G1(wi) wi.h).
// The smooth albedo Int G2 D / (4 cos_i) dwo uses the same grid (integrand
// G2 / G1(wi) where the reflection is above the horizon).
#pragma once

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include "glimmer/closure_abi.h"
#include "glimmer/math.h"
#include "glimmer/microfacet.h"

namespace glimmer::plugin::glint {

namespace mfa = glimmer::microfacet;

// Reflected-direction density q(wi, r) of the anisotropic lobe.
inline float aniso_reflected_density(mfa::Distribution dist, float ax, float ay, const Vec3 &wi, const Vec3 &r) {
  const Vec3 s = wi + r;
  const float len2 = dot(s, s);
  if (!(len2 > 1e-18f)) return 0.0f;
  const Vec3 h = s * (1.0f / std::sqrt(len2));
  const float wi_h = dot(wi, h);
  if (!(h.z > 0.0f) || !(wi_h > 0.0f)) return 0.0f;
  const float d = mfa::D(dist, h, ax, ay);
  return std::isfinite(d) ? d * h.z / (4.0f * wi_h) : 0.0f;
}

// Orthonormal tangent basis of a direction (Duff et al. 2017's branchless
// form): continuous for every w with w.z > -1, so P has no seam where a
// case switch would change the rule's orientation.
inline void cone_basis(const Vec3 &w, Vec3 &e1, Vec3 &e2) {
  const float sign = std::copysign(1.0f, w.z);
  const float a = -1.0f / (sign + w.z);
  const float b = w.x * w.y * a;
  e1 = Vec3(1.0f + sign * w.x * w.x * a, sign * b, -sign * w.x);
  e2 = Vec3(b, sign + w.y * w.y * a, -w.y);
}

// One node of a disk rule: polar radius as a fraction of gamma, azimuth, weight.
struct DiskNode {
  float radius, psi, weight;
};

inline const std::array<DiskNode, 7> &disk_rule7() {
  static const std::array<DiskNode, 7> rule = [] {
    std::array<DiskNode, 7> r{};
    r[0] = {0.0f, 0.0f, 0.25f};
    for (int k = 0; k < 6; ++k)
      r[1 + k] = {static_cast<float>(std::sqrt(2.0 / 3.0)), static_cast<float>(k * M_PI / 3.0), 0.125f};
    return r;
  }();
  return rule;
}

inline const std::array<DiskNode, 19> &disk_rule19() {
  static const std::array<DiskNode, 19> rule = [] {
    std::array<DiskNode, 19> r{};
    const double s6 = std::sqrt(6.0);
    const double t1 = (6.0 - s6) / 10.0, t2 = (6.0 + s6) / 10.0;
    const double w1 = (16.0 + s6) / 36.0, w2 = (16.0 - s6) / 36.0;
    r[0] = {0.0f, 0.0f, static_cast<float>(1.0 / 9.0)};
    for (int k = 0; k < 9; ++k) {
      r[1 + k] = {static_cast<float>(std::sqrt(t1)), static_cast<float>(2.0 * M_PI * k / 9.0),
                  static_cast<float>(w1 / 9.0)};
      r[10 + k] = {static_cast<float>(std::sqrt(t2)), static_cast<float>(2.0 * M_PI * (k + 0.5) / 9.0),
                   static_cast<float>(w2 / 9.0)};
    }
    return r;
  }();
  return rule;
}

// A disk rule placed on the cone of half-angle gamma (radians): each node's
// offset along w (cos rho) and the tangent basis (sin rho cos psi, sin rho
// sin psi), and its weight times the area element sin(rho) / rho of the
// exponential map, renormalised so a constant is exact. Built once per gamma.
struct ConeRule {
  int count = 0;
  std::array<std::array<float, 4>, 19> nodes{};  // c, a, b, weight

  template <size_t N>
  static ConeRule place(const std::array<DiskNode, N> &rule, float gamma) {
    ConeRule out;
    out.count = static_cast<int>(N);
    double norm = 0.0;
    for (size_t k = 0; k < N; ++k) {
      const double rho = static_cast<double>(rule[k].radius) * gamma;
      const double s = std::sin(rho);
      const double jw = rule[k].weight * (rho > 0.0 ? s / rho : 1.0);
      out.nodes[k] = {static_cast<float>(std::cos(rho)), static_cast<float>(s * std::cos(rule[k].psi)),
                      static_cast<float>(s * std::sin(rule[k].psi)), static_cast<float>(jw)};
      norm += jw;
    }
    for (size_t k = 0; k < N; ++k) out.nodes[k][3] = static_cast<float>(out.nodes[k][3] / norm);
    return out;
  }

  // Mean of f(r) over the cone around w.
  template <typename F>
  float mean(const Vec3 &w, F &&f) const {
    Vec3 e1, e2;
    cone_basis(w, e1, e2);
    float sum = 0.0f;
    for (int k = 0; k < count; ++k) {
      const auto &n = nodes[k];
      sum += n[3] * f(w * n[0] + e1 * n[1] + e2 * n[2]);
    }
    return sum;
  }
};

// Rule choice by the lobe's width against the cone: across the plane of
// (wi, wo) q varies on the scale 2 alpha (wi.h) (the half-vector map divides
// a displacement of r by 2 wi.h there), along it on 2 alpha. With
// e = gamma / (alpha_min wi.h): the 7-point rule where e <= 1, the 19-point
// rule where e <= 2 (both measured <= 0.2 % there, see docs/glints.md), else
// a product rule with points per axis set by the scale (as the isotropic
// tables' interior rule). Along the plane of incidence the lobe's scale is
// 2 alpha_min, at most 24 points at gamma <= 10 degrees (kProductMaxPoints);
// across it the scale shrinks with wi.h (grazing incidence), and the
// Gauss-Chebyshev axis takes up to kProductMaxAcross points: with the old
// cap of 24 there, P was up to 38 % off at theta_i 85, gamma 4, alpha_min
// 0.0225 (docs/glints.md). 768 covers e <= 256 at 3 points per scale
// (theta_i <= 89 degrees at gamma 4 and the 0.0225 alpha floor: e <= 180).
inline constexpr float kSevenPointsUpTo = 1.0f, kNineteenPointsUpTo = 2.0f;
inline constexpr int kProductMaxPoints = 24, kProductMaxAcross = 768;

// Gauss-Legendre nodes and weights on [-1, 1] (Newton on P_n), n <= kProductMaxPoints.
struct GaussLegendre {
  std::array<std::array<float, kProductMaxPoints>, kProductMaxPoints + 1> x{}, w{};
  GaussLegendre() {
    for (int n = 1; n <= kProductMaxPoints; ++n)
      for (int i = 0; i < n; ++i) {
        double z = std::cos(M_PI * (i + 0.75) / (n + 0.5)), dp = 1.0;
        for (int it = 0; it < 100; ++it) {
          double p0 = 1.0, p1 = 0.0;
          for (int k = 1; k <= n; ++k) {
            const double p2 = p1;
            p1 = p0;
            p0 = ((2.0 * k - 1.0) * z * p1 - (k - 1.0) * p2) / k;
          }
          dp = n * (z * p0 - p1) / (z * z - 1.0);
          const double dz = p0 / dp;
          z -= dz;
          if (std::fabs(dz) < 1e-15) break;
        }
        x[n][i] = static_cast<float>(z);
        w[n][i] = static_cast<float>(2.0 / ((1.0 - z * z) * dp * dp));
      }
  }
  static const GaussLegendre &get() {
    static const GaussLegendre table;
    return table;
  }
};

// The two rules of one cone half-angle gamma (radians) and the product rule.
struct AnisoConeRules {
  float gamma = 0.0f;
  ConeRule seven, nineteen;
  explicit AnisoConeRules(float g = 0.0f)
      : gamma(g), seven(ConeRule::place(disk_rule7(), g)), nineteen(ConeRule::place(disk_rule19(), g)) {}

  // gamma / (alpha_min wi.h) at the query (h = normalize(wi + wo)).
  float narrowness(float ax, float ay, const Vec3 &wi, const Vec3 &wo) const {
    const Vec3 s = wi + wo;
    const float len2 = dot(s, s);
    const float wi_h = len2 > 1e-18f ? dot(wi, s) / std::sqrt(len2) : 1.0f;
    return gamma / (std::min(ax, ay) * std::max(wi_h, 1e-3f));
  }
  // Points the rule at (wi, wo) uses (7, 19 or the product's n_x n_y).
  int points(float ax, float ay, const Vec3 &wi, const Vec3 &wo) const {
    const float e = narrowness(ax, ay, wi, wo);
    if (e <= kSevenPointsUpTo) return 7;
    if (e <= kNineteenPointsUpTo) return 19;
    int nx, ny;
    product_points(ax, ay, wi, wo, nx, ny);
    return nx * ny;
  }
  // 3 points per lobe scale across the cone's diameter: 4..kProductMaxAcross
  // across the plane of incidence, 4..kProductMaxPoints along it.
  void product_points(float ax, float ay, const Vec3 &wi, const Vec3 &wo, int &nx, int &ny) const {
    const float along = 3.0f * gamma / std::min(ax, ay);
    const float across = std::min(3.0f * narrowness(ax, ay, wi, wo), static_cast<float>(kProductMaxAcross));
    nx = std::clamp(static_cast<int>(std::ceil(across)), 4, kProductMaxAcross);
    ny = std::clamp(static_cast<int>(std::ceil(along)), 4, kProductMaxPoints);
  }

  // Product rule on the cone's disk: (x, y) = gamma (u, s sqrt(1 - u^2)),
  // x across the plane of (wi, wo); Gauss-Chebyshev of the second kind in u
  // (its weight is the chord), Gauss-Legendre in s; the area element
  // sin(rho) / rho of the exponential map in the weights.
  template <typename F>
  float product_mean(const Vec3 &wi, const Vec3 &wo, int nx, int ny, F &&f) const {
    Vec3 ex = cross(wi, wo), ey;
    const float l2 = dot(ex, ex);
    if (l2 > 1e-12f) {
      ex = ex * (1.0f / std::sqrt(l2));
      ey = cross(wo, ex);
    } else {
      cone_basis(wo, ex, ey);
    }
    const GaussLegendre &gl = GaussLegendre::get();
    float sum = 0.0f, norm = 0.0f;
    for (int i = 1; i <= nx; ++i) {
      const double t = M_PI * i / (nx + 1);
      const float u = static_cast<float>(std::cos(t)), su = static_cast<float>(std::sin(t));
      const float wu = su * su;  // Gauss-Chebyshev (2nd kind) weight up to a constant
      for (int j = 0; j < ny; ++j) {
        const float x = gamma * u, y = gamma * gl.x[ny][j] * su;
        const float rho = std::sqrt(x * x + y * y);
        const float sr = std::sin(rho), cr = std::cos(rho);
        const float k = rho > 0.0f ? sr / rho : 1.0f;
        const float w = wu * gl.w[ny][j] * k;
        sum += w * f(wo * cr + (ex * x + ey * y) * (k));
        norm += w;
      }
    }
    return sum / norm;
  }

  // Mean of q over the query cone: P_gamma / sigma (sigma the cone's solid angle).
  float cone_mean_q(mfa::Distribution dist, float ax, float ay, const Vec3 &wi, const Vec3 &wo) const {
    auto q = [&](const Vec3 &r) { return aniso_reflected_density(dist, ax, ay, wi, r); };
    const float e = narrowness(ax, ay, wi, wo);
    if (e <= kSevenPointsUpTo) return seven.mean(wo, q);
    if (e <= kNineteenPointsUpTo) return nineteen.mean(wo, q);
    int nx, ny;
    product_points(ax, ay, wi, wo, nx, ny);
    return product_mean(wi, wo, nx, ny, q);
  }
};

// W(wi, wo) with F = 1: G2 (wi.h) / (cos_i cos_h) (tables/glint_common.h's glint_weight).
// `lambda_i` is Lambda(wi) (mfa::lambda at |wi.z|): G2 = 1 / (1 + Lambda(wi)
// + Lambda(wo)) with the operations of mfa::G2, so hoisting Lambda(wi) out of
// a loop over wo gives the same floats.
inline float aniso_white_weight(mfa::Distribution dist, float ax, float ay, const Vec3 &wi, float lambda_i,
                                const Vec3 &wo) {
  if (!(wi.z > 0.0f) || !(wo.z > 0.0f)) return 0.0f;
  Vec3 h;
  if (!mfa::half_vector_reflect(wi, wo, h)) return 0.0f;
  const float wi_h = dot(wi, h);
  if (!(wi_h > 0.0f) || !(h.z > 0.0f)) return 0.0f;
  const float lo = mfa::lambda(dist, Vec3(wo.x, wo.y, std::fabs(wo.z)), ax, ay);
  const float s = 1.0f + lambda_i + lo;
  const float g2 = std::isfinite(s) ? 1.0f / s : 0.0f;
  return g2 * wi_h / (wi.z * h.z);
}
inline float aniso_white_weight(mfa::Distribution dist, float ax, float ay, const Vec3 &wi, const Vec3 &wo) {
  return aniso_white_weight(dist, ax, ay, wi, mfa::lambda(dist, Vec3(wi.x, wi.y, std::fabs(wi.z)), ax, ay), wo);
}

struct AnisoSpec {
  mfa::Distribution distribution = mfa::Distribution::GGX;
  float alpha_x = 0.16f, alpha_y = 0.16f, gamma_deg = 2.0f;
  bool operator<(const AnisoSpec &o) const {
    return std::tie(distribution, alpha_x, alpha_y, gamma_deg) <
           std::tie(o.distribution, o.alpha_x, o.alpha_y, o.gamma_deg);
  }
  float alpha_max() const { return std::max(alpha_x, alpha_y); }
  // The lobe widened by the LOD blur sigma (radians) per axis.
  void widened(float sigma, float &ax, float &ay) const {
    const float w2 = 0.25f * sigma * sigma;
    ax = std::sqrt(alpha_x * alpha_x + w2);
    ay = std::sqrt(alpha_y * alpha_y + w2);
  }
};

// Energy scale of P per (theta_i, phi_i, blur level); see the file comment.
class AnisoEnergyTable {
 public:
  static constexpr int kTheta = 91, kPhi = 10, kLevels = 5, kGrid = 64;
  static constexpr float kPhiStepDeg = 10.0f;
  static constexpr double kEnergyResolution = 1e-3;  // the cap: smooth albedo + 0.1 %, as the isotropic level 0

  AnisoSpec spec;
  std::vector<float> scale;  // [(level * kTheta + ti) * kPhi + pi]
  double build_seconds = 0.0;  // 0 when loaded from the disk cache
  bool loaded_from_cache = false;

  // Reflected energies at one wi for the unblurred lobe: the smooth albedo
  // and the estimator's; and the estimator's at blur level t. For tests too.
  // (G1(wi) and Lambda(wi) are loop invariants: hoisted, same floats.)
  static double smooth_albedo(const AnisoSpec &s, const Vec3 &wi) {
    const float g1 = mfa::G1(s.distribution, wi, s.alpha_x, s.alpha_y);
    if (!(g1 > 0.0f)) return 0.0;
    const float li = mfa::lambda(s.distribution, Vec3(wi.x, wi.y, std::fabs(wi.z)), s.alpha_x, s.alpha_y);
    double sum = 0.0;
    for (int a = 0; a < kGrid; ++a)
      for (int b = 0; b < kGrid; ++b) {
        const Vec3 h = mfa::sample_visible_normal(s.distribution, wi, s.alpha_x, s.alpha_y, (a + 0.5f) / kGrid,
                                                  (b + 0.5f) / kGrid);
        const Vec3 r = mfa::reflect_about(wi, h);
        if (!(r.z > 0.0f)) continue;
        const float lo = mfa::lambda(s.distribution, Vec3(r.x, r.y, std::fabs(r.z)), s.alpha_x, s.alpha_y);
        const float sum_l = 1.0f + li + lo;
        sum += (std::isfinite(sum_l) ? 1.0f / sum_l : 0.0f) / g1;
      }
    return sum / (kGrid * kGrid);
  }
  static double estimator_energy(const AnisoSpec &s, const Vec3 &wi, float t) {
    float ax, ay;
    s.widened(t * 2.0f * s.alpha_max(), ax, ay);
    const ConeRule rule = ConeRule::place(disk_rule7(), s.gamma_deg * 0.017453292519943295f);
    const float g1 = mfa::G1(s.distribution, wi, ax, ay);
    if (!(g1 > 0.0f) || !(wi.z > 0.0f)) return 0.0;
    const float li = mfa::lambda(s.distribution, Vec3(wi.x, wi.y, std::fabs(wi.z)), s.alpha_x, s.alpha_y);
    double sum = 0.0;
    for (int a = 0; a < kGrid; ++a)
      for (int b = 0; b < kGrid; ++b) {
        const Vec3 h = mfa::sample_visible_normal(s.distribution, wi, ax, ay, (a + 0.5f) / kGrid, (b + 0.5f) / kGrid);
        const float wi_h = dot(wi, h);
        if (!(wi_h > 0.0f) || !(h.z > 0.0f)) continue;
        const Vec3 r = mfa::reflect_about(wi, h);
        const float wbar = rule.mean(r, [&](const Vec3 &wo) {
          return aniso_white_weight(s.distribution, s.alpha_x, s.alpha_y, wi, li, wo);
        });
        sum += static_cast<double>(wbar) * h.z * wi.z / (g1 * wi_h);
      }
    return sum / (kGrid * kGrid);
  }

  static Vec3 node_direction(int ti, int pi) {
    const double theta = std::min(static_cast<double>(ti), 89.9) * (M_PI / 180.0);
    const double phi = pi * kPhiStepDeg * (M_PI / 180.0);
    return Vec3(static_cast<float>(std::sin(theta) * std::cos(phi)),
                static_cast<float>(std::sin(theta) * std::sin(phi)), static_cast<float>(std::cos(theta)));
  }

  void build_node(int ti, int pi) {
    const Vec3 wi = node_direction(ti, pi);
    const double smooth = smooth_albedo(spec, wi);
    const double e0 = estimator_energy(spec, wi, 0.0f);
    const double target = std::min(e0, smooth * (1.0 + kEnergyResolution));
    for (int l = 0; l < kLevels; ++l) {
      const double e = l == 0 ? e0 : estimator_energy(spec, wi, static_cast<float>(l) / (kLevels - 1));
      scale[(static_cast<size_t>(l) * kTheta + ti) * kPhi + pi] = e > 0.0 ? static_cast<float>(target / e) : 1.0f;
    }
  }

  // Nodes are independent (each writes only its own entries), handed out
  // one at a time from an atomic counter: the values do not depend on the
  // thread count or the order (GlintAnisoCache.BuildIsIndependentOfThreadCount).
  static std::unique_ptr<AnisoEnergyTable> build(const AnisoSpec &s, int threads) {
    auto table = std::make_unique<AnisoEnergyTable>();
    table->spec = s;
    table->scale.assign(static_cast<size_t>(kLevels) * kTheta * kPhi, 1.0f);
    const auto start = std::chrono::steady_clock::now();
    std::atomic<int> next{0};
    auto work = [&table, &next] {
      for (int node = next++; node < kTheta * kPhi; node = next++) table->build_node(node / kPhi, node % kPhi);
    };
    threads = std::max(1, std::min(threads, 8));
    std::vector<std::thread> pool;
    for (int w = 1; w < threads; ++w) pool.emplace_back(work);
    work();
    for (auto &t : pool) t.join();
    table->build_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return table;
  }

  // Scale at (theta_i, phi_i folded to [0, 90]) in degrees and blur level t in [0, 1]:
  // bilinear over the nodes, linear between levels.
  float lookup(float theta_i_deg, float phi_i_deg, float t) const {
    const float fi = theta_i_deg > 0.0f ? (theta_i_deg < 90.0f ? theta_i_deg : 90.0f) : 0.0f;
    const float fp0 = phi_i_deg * (1.0f / kPhiStepDeg);
    const float fp = fp0 > 0.0f ? (fp0 < kPhi - 1.0f ? fp0 : kPhi - 1.0f) : 0.0f;
    const float fl0 = t * (kLevels - 1);
    const float fl = fl0 > 0.0f ? (fl0 < kLevels - 1.0f ? fl0 : kLevels - 1.0f) : 0.0f;
    const int i0 = std::min(static_cast<int>(fi), kTheta - 2), p0 = std::min(static_cast<int>(fp), kPhi - 2);
    const int l0 = std::min(static_cast<int>(fl), kLevels - 2);
    const float di = fi - i0, dp = fp - p0, dl = fl - l0;
    auto at = [&](int l) {
      const float *v = scale.data() + (static_cast<size_t>(l) * kTheta + i0) * kPhi + p0;
      const float a = v[0] + (v[1] - v[0]) * dp, b = v[kPhi] + (v[kPhi + 1] - v[kPhi]) * dp;
      return a + (b - a) * di;
    };
    const float a = at(l0);
    return dl > 0.0f ? a + (at(l0 + 1) - a) * dl : a;
  }
};

// Disk cache (glint_aniso_cache.cpp; the isotropic tables' scheme): files
// glint_A_<key>.bin, 0600 in the private cache folder, written atomically,
// HMAC-SHA256 keyed by the folder's secret. load returns nullptr and sets
// `problem` when the entry is missing, not a regular file (removed),
// truncated, fails its MAC, is for other parameters, holds non-finite or
// out-of-range scales, or disagrees with nodes recomputed on load.
uint64_t aniso_energy_key(const AnisoSpec &spec);
std::string aniso_energy_cache_path(const std::string &cache_dir, const AnisoSpec &spec);
bool save_aniso_energy(const std::string &path, const AnisoEnergyTable &table, std::string &problem);
std::unique_ptr<AnisoEnergyTable> load_aniso_energy(const std::string &path, const AnisoSpec &spec,
                                                    std::string &problem, int spot_checks = 3);

// Process-wide provider: one table per spec, shared by instances (weakly
// held), loaded from / written to host->cache_dir, built on first use; a
// corrupt entry is rebuilt with a warning through host->log.
std::shared_ptr<const AnisoEnergyTable> acquire_aniso_energy(const AnisoSpec &spec, const GlimmerHostServices *host);

}  // namespace glimmer::plugin::glint
