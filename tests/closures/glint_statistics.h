// Statistics harness for glint models (issue 10): the statistics an artist
// sees, measured the same way on `glint` and on the reference
// `glint_jakob14` (the exact discrete model, itself checked against brute
// force in test_glint_hierarchy.cpp).
//
// A configuration is (distribution, roughness, gamma, particles per
// footprint n, incidence theta_i). Footprints are squares of side
// kFootprintSide at random uv positions; the density parameter is
// n / side^2. wo1 is the mirror direction of wi (the lobe peak).
//
// - lit_correlation(d): Pearson correlation, across footprints, of the BRDF
//   at wo and at wo moved d radians across the plane of incidence, averaged
//   over 16 base directions wo within a gamma of wo1 (each over its own
//   footprints, `footprints` in all).
//   For a fixed direction f = W K / (N a sigma) with W the same for every
//   footprint, so this is the correlation of the lit counts K (of the lit
//   sets, for sparse glints). Reference: the overlap of the two cones.
// - albedo_cv: coefficient of variation across footprints of the albedo
//   under a uniform white sky, Int f cos dwo. Monte Carlo with the closure's
//   own sampler: two independent estimates of S samples per footprint, the
//   variance across footprints their covariance (free of the Monte Carlo
//   noise; see albedo_cv).
// - reference_albedo_cv: the same for the exact particle set, in closed form
//   per footprint: every particle k of the footprint (enumerated by brute
//   force from the Jakob hierarchy) reflects wi to r_k and adds
//   Int_cone(r_k) W / (N a sigma) ~= W(wi, r_k) / (N a) (W varies little over
//   a cone of a few degrees; zero when r_k is below the horizon).
// - doubling: footprints of side s 2^(-1/32) and s 2^(1/32) around the same
//   centre (area ratio 2^(1/8)), s a power of two so that the two straddle a
//   node-level boundary of glint: correlation of the lit counts K (f a) and
//   the fraction of footprints whose count drops while the footprint grows.
//   Reference: nested footprints, corr = sqrt(a1 / a2) = 0.958, no drops.
// - mean_ratio: mean of f at wo1 over footprints divided by its exact
//   expectation W P_gamma / sigma (P_gamma by brute-force cone quadrature).
#pragma once

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "closures/closure_checks.h"
#include "closures/glint_test_util.h"
#include "sample_statistics.h"
#include "glimmer/microfacet.h"
#include "glimmer/rng.h"
#include "tables/glint_common.h"
#include "tables/glint_hierarchy.h"

namespace glimmer::test::glint_stats {

inline constexpr double kFootprintSide = 1.0 / 128.0;  // a power of two (level boundary for `doubling`)

struct Config {
  mf::Distribution dist = mf::Distribution::GGX;
  double roughness = 0.5;
  double gamma_deg = 2.0;
  double per_footprint = 100.0;  // particles per footprint
  double theta_i_deg = 0.0;
  uint32_t seed = 11;

  // The closures' alpha: roughness^2, at least the particle field's floor.
  double alpha() const {
    return std::max(roughness * roughness, static_cast<double>(plugin::glint::ParticleField::kMinAlpha));
  }
  double density() const { return per_footprint / (kFootprintSide * kFootprintSide); }
  double gamma() const { return gamma_deg * M_PI / 180.0; }
  Vec3 wi() const { return spherical_dir(theta_i_deg, 0.0); }
  Vec3 wo1() const { return spherical_dir(theta_i_deg, 180.0); }
  // Direction `d` radians from `from` along the great circle perpendicular
  // to the plane of incidence (the xz plane): stays above the horizon, and
  // is defined at normal incidence.
  static Vec3 across(const Vec3 &from, double d) {
    const Vec3 t = normalize(cross(from, Vec3(1.0f, 0.0f, 0.0f)));  // in the tangent plane at `from`
    const Vec3 y = t.y >= 0.0f ? t : -t;
    return normalize(static_cast<float>(std::cos(d)) * from + static_cast<float>(std::sin(d)) * y);
  }
  // Direction `d` radians from `from` inside the plane of incidence (toward the normal).
  static Vec3 along(const Vec3 &from, double d) {
    const double theta = std::acos(std::clamp(static_cast<double>(from.z), -1.0, 1.0));
    const double phi = std::atan2(from.y, from.x);
    const double t = theta - d;
    return Vec3(static_cast<float>(std::sin(t) * std::cos(phi)), static_cast<float>(std::sin(t) * std::sin(phi)),
                static_cast<float>(std::cos(t)));
  }
  Vec3 wo_at(double d) const { return across(wo1(), d); }
  // Base directions of the lit-set correlation: wo1 moved by up to gamma
  // in and across the plane of incidence (fixed pseudo-random offsets), so
  // a model's direction cells are met at many phases.
  std::vector<Vec3> base_directions() const {
    Pcg32 rng(77);
    std::vector<Vec3> dirs;
    for (int k = 0; k < kBaseDirections; ++k) {
      const double in_plane = 2.0 * rng.next_double() - 1.0, across_plane = 2.0 * rng.next_double() - 1.0;
      dirs.push_back(across(along(wo1(), in_plane * gamma()), across_plane * gamma()));
    }
    return dirs;
  }
  static constexpr int kBaseDirections = 16;
  std::string name() const {
    char buf[128];
    std::snprintf(buf, sizeof(buf), "%s r=%.2g n=%g theta_i=%g", dist == mf::Distribution::GGX ? "ggx" : "beckmann",
                  roughness, per_footprint, theta_i_deg);
    return buf;
  }
  Params params(bool reference) const {
    Params p{{"distribution", dist == mf::Distribution::GGX ? "ggx" : "beckmann"},
             {"roughness", std::to_string(roughness)},
             {"gamma", std::to_string(gamma_deg)},
             {"density", std::to_string(density())},
             {"seed", std::to_string(seed)}};
    // Glint mode everywhere: the filtered switch is a separate feature.
    if (!reference) p.push_back({"filter_threshold", "1e9"});
    return p;
  }
};

// Footprint centres: uniform in [0, 64)^2, the same for every model.
inline std::vector<std::pair<double, double>> centres(int n, uint64_t seed = 5) {
  Pcg32 rng(seed);
  std::vector<std::pair<double, double>> c(static_cast<size_t>(n));
  for (auto &p : c) p = {64.0 * rng.next_double(), 64.0 * rng.next_double()};
  return c;
}

inline GlimmerShadingContext square_context(const Vec3 &wi, double u, double v, double side) {
  return footprint_context(wi, u, v, side, 0.0, 0.0, side);
}

inline double f_at(const host::ClosureInstance &c, const GlimmerShadingContext &ctx, const Vec3 &wo) {
  Spectrum f;
  float pdf;
  c.eval(ctx, wo, f, pdf);
  return f.x;
}

// Mean over the base directions of the correlation between wo and wo moved
// by d across the plane of incidence.
inline double lit_correlation(const host::ClosureInstance &c, const Config &cfg, double d, int footprints) {
  const Vec3 wi = cfg.wi();
  const auto bases = cfg.base_directions();
  const int per_base = std::max(footprints / static_cast<int>(bases.size()), 8);
  double sum = 0.0;
  for (size_t k = 0; k < bases.size(); ++k) {
    const Vec3 wo2 = Config::across(bases[k], d);
    std::vector<double> a, b;
    for (const auto &[u, v] : centres(per_base, 1000 + k)) {
      const GlimmerShadingContext ctx = square_context(wi, u, v, kFootprintSide);
      a.push_back(f_at(c, ctx, bases[k]));
      b.push_back(f_at(c, ctx, wo2));
    }
    sum += correlation(a, b);
  }
  return sum / static_cast<double>(bases.size());
}

struct Doubling {
  double correlation = 0.0;
  double drop_fraction = 0.0;  // footprints whose count drops as the footprint grows
};

inline Doubling doubling(const host::ClosureInstance &c, const Config &cfg, int footprints) {
  const double s1 = kFootprintSide * std::exp2(-1.0 / 32.0), s2 = kFootprintSide * std::exp2(1.0 / 32.0);
  const Vec3 wi = cfg.wi(), wo = cfg.wo1();
  Spectrum weight;
  if (!plugin::glint::glint_weight(cfg.dist, static_cast<float>(cfg.alpha()), Spectrum(1.0f), wi, wo, weight))
    return {};
  const double to_count = cfg.density() * 2.0 * M_PI * (1.0 - std::cos(cfg.gamma())) / weight.x;
  std::vector<double> k1, k2;
  int drops = 0;
  for (const auto &[u, v] : centres(footprints)) {
    k1.push_back(std::round(f_at(c, square_context(wi, u, v, s1), wo) * s1 * s1 * to_count));
    k2.push_back(std::round(f_at(c, square_context(wi, u, v, s2), wo) * s2 * s2 * to_count));
    drops += k2.back() < k1.back();
  }
  return {correlation(k1, k2), static_cast<double>(drops) / footprints};
}

// White-furnace albedo of a closure at one footprint by its own sampler:
// the mean of f cos / pdf over side^2 samples, stratified in the first two
// numbers (sample s uses the running index first_index + s), and the
// per-sample variance.
struct AlbedoEstimate {
  double mean = 0.0, variance = 0.0;
  int samples = 0;
  double standard_error() const { return std::sqrt(variance / (samples - 1)); }
};

inline AlbedoEstimate sampled_albedo(const host::ClosureInstance &c, const GlimmerShadingContext &ctx, int side,
                                     uint32_t first_index = 0) {
  double sum = 0.0, sum2 = 0.0;
  const int samples = side * side;
  for (int s = 0; s < samples; ++s) {
    const uint32_t index = first_index + static_cast<uint32_t>(s);
    const float r3[3] = {static_cast<float>(((s % side) + uint_to_unit_float(hash_u32(2 * index))) / side),
                         static_cast<float>(((s / side) + uint_to_unit_float(hash_u32(2 * index + 1))) / side),
                         uint_to_unit_float(hash_u32x2(index, 7u))};
    GlimmerSample out{};
    double w = 0.0;
    if (c.sample(ctx, r3, out) && out.pdf > 0.0f) w = out.eval[0] / out.pdf;
    sum += w;
    sum2 += w * w;
  }
  const double mean = sum / samples;
  return {mean, std::max(sum2 / samples - mean * mean, 0.0), samples};
}

// Coefficient of variation of the per-footprint albedo by Monte Carlo with
// the closure's own sampler. SplitHalf (the default): two independent
// stratified estimates A1, A2 per footprint (`samples` each, a square; the
// second continues the sample index), and Var(albedo) = Cov(A1, A2) across
// footprints: the two halves' Monte Carlo errors are independent of each
// other and of the footprint, so the covariance is unbiased whatever the
// sampling. SubtractedVariance (the estimator until issue 10's statistics
// session glintstats14; kept as the negative control of
// GlintStatistics.AlbedoCvEstimatorIsUnbiased): one estimate of `samples`,
// between-footprint variance minus the mean per-footprint variance of the
// mean computed as for i.i.d. samples. The samples are stratified, so that
// over-estimates the Monte Carlo variance and the CV comes out low where
// the Monte Carlo noise is comparable to the footprints' spread (glint at
// roughness 0.2, theta_i 80, 1000 particles, 200 footprints, two seeds:
// 0.011 / 0.000 at 1024 samples, 0.025 at 4096, 0.028 at 16384; split
// half, 2 x 4096: 0.029).
enum class AlbedoCvEstimator { SplitHalf, SubtractedVariance };

inline double albedo_cv(const host::ClosureInstance &c, const Config &cfg, int footprints, int samples,
                        AlbedoCvEstimator estimator = AlbedoCvEstimator::SplitHalf) {
  const Vec3 wi = cfg.wi();
  const int side = static_cast<int>(std::lround(std::sqrt(static_cast<double>(samples))));
  std::vector<double> a1, a2;
  double mc_var = 0.0;
  uint32_t index = 0;
  for (const auto &[u, v] : centres(footprints)) {
    const GlimmerShadingContext ctx = square_context(wi, u, v, kFootprintSide);
    const AlbedoEstimate e1 = sampled_albedo(c, ctx, side, index);
    index += static_cast<uint32_t>(e1.samples);
    a1.push_back(e1.mean);
    mc_var += e1.variance / (e1.samples - 1);
    if (estimator == AlbedoCvEstimator::SplitHalf) {
      const AlbedoEstimate e2 = sampled_albedo(c, ctx, side, index);
      index += static_cast<uint32_t>(e2.samples);
      a2.push_back(e2.mean);
    }
  }
  const double n = footprints;
  double m1 = 0, m2 = 0;
  for (double a : a1) m1 += a / n;
  if (estimator == AlbedoCvEstimator::SubtractedVariance) {
    double v = 0;
    for (double a : a1) v += (a - m1) * (a - m1);
    v /= n - 1;
    return std::sqrt(std::max(v - mc_var / n, 0.0)) / m1;
  }
  for (double a : a2) m2 += a / n;
  double cov = 0;
  for (size_t k = 0; k < a1.size(); ++k) cov += (a1[k] - m1) * (a2[k] - m2);
  cov /= n - 1;
  return std::sqrt(std::max(cov, 0.0)) / (0.5 * (m1 + m2));
}

// Closed-form per-footprint albedo of the exact particle set (see above).
inline double reference_albedo_cv(const Config &cfg, int footprints) {
  namespace pg = plugin::glint;
  const pg::ParticleHierarchy hierarchy(cfg.dist, cfg.alpha(), cfg.density(), cfg.seed);
  const Vec3 wi = cfg.wi();
  const float alpha = static_cast<float>(cfg.alpha());
  std::vector<double> albedo;
  std::vector<pg::HierarchyNode> stack;
  for (const auto &[u, v] : centres(footprints)) {
    pg::Footprint fp;
    fp.cx = u, fp.cy = v, fp.ax = kFootprintSide, fp.by = kFootprintSide;
    const pg::ParticleQuery q = pg::ParticleQuery::make(fp, wi, Vec3(0, 0, 1), cfg.gamma());
    double sum = 0.0;
    int64_t i0, i1, j0, j1;
    pg::ParticleHierarchy::unit_cells(fp, i0, i1, j0, j1);
    for (int64_t j = j0; j <= j1; ++j)
      for (int64_t i = i0; i <= i1; ++i) {
        stack.push_back(hierarchy.root(i, j));
        while (!stack.empty()) {
          const pg::HierarchyNode n = stack.back();
          stack.pop_back();
          if (n.count == 0 || !pg::ParticleHierarchy::box_overlaps(q, n)) continue;  // particles lie in their box
          if (!pg::ParticleHierarchy::is_leaf(n)) {
            pg::HierarchyNode a, b;
            pg::ParticleHierarchy::split(n, a, b);
            stack.push_back(a);
            stack.push_back(b);
            continue;
          }
          for (uint32_t p = 0; p < n.count; ++p) {
            const pg::HierarchyParticle particle = pg::ParticleHierarchy::leaf_particle(n, p);
            if (!q.inside_footprint(particle.x, particle.y)) continue;
            const double theta = hierarchy.code_theta(particle.u), phi = 2.0 * M_PI * particle.v;
            const Vec3 m(static_cast<float>(std::sin(theta) * std::cos(phi)),
                         static_cast<float>(std::sin(theta) * std::sin(phi)), static_cast<float>(std::cos(theta)));
            const Vec3 r = 2.0f * dot(wi, m) * m - wi;
            Spectrum weight;
            if (pg::glint_weight(cfg.dist, alpha, Spectrum(1.0f), wi, r, weight)) sum += weight.x;
          }
        }
      }
    albedo.push_back(sum / (cfg.density() * fp.area()));
  }
  double m = 0, v = 0;
  for (double a : albedo) m += a;
  m /= footprints;
  for (double a : albedo) v += (a - m) * (a - m);
  v /= footprints - 1;
  return std::sqrt(v) / m;
}

struct MeanRatio {
  double ratio = 0.0;
  double standard_error = 0.0;  // of the ratio
};

inline MeanRatio mean_ratio(const host::ClosureInstance &c, const Config &cfg, int footprints) {
  const Vec3 wi = cfg.wi(), wo = cfg.wo1();
  Spectrum weight;
  if (!plugin::glint::glint_weight(cfg.dist, static_cast<float>(cfg.alpha()), Spectrum(1.0f), wi, wo, weight))
    return {};
  // E[f] = W P / sigma = W * (mean of q over the cone).
  const double expected = weight.x * cone_mean_reflected_density(cfg.dist, cfg.alpha(), wi, wo, cfg.gamma_deg, 32);
  double sum = 0, sum2 = 0;
  for (const auto &[u, v] : centres(footprints)) {
    const double f = f_at(c, square_context(wi, u, v, kFootprintSide), wo);
    sum += f;
    sum2 += f * f;
  }
  const double mean = sum / footprints;
  const double se = std::sqrt(std::max(sum2 / footprints - mean * mean, 0.0) / footprints);
  return {mean / expected, se / expected};
}

}  // namespace glimmer::test::glint_stats
