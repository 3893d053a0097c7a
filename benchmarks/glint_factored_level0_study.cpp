// Session 42 (fact42): would a coarse level 0 of the glint table be accurate enough if an analytic lobe were factored
// out? A measurement tool only: nothing in plugin/ uses it.
//
// Level 0 (tables/glint_tables.h) stores P_gamma(theta_i, theta_o, dphi) on a 1-degree grid (91 x 91 x 181 u16,
// ~3 MB), read trilinearly. Candidate: store R = P / A on a coarser grid and read P' = A(query) R_trilinear(query),
//   A(wi, wo) = sigma D_a(h) cos(theta_h) / (4 wi.h),  h = normalize(wi + wo),  sigma = 2 pi (1 - cos gamma),
// the small-cone limit of P (equation (1) of glint_tables.h), with D at the table's alpha (a' = alpha) or at a
// widened alpha a'^2 = alpha^2 + k (gamma_rad / 2)^2. Factor "none" is plain subsampling of P (A = 1).
// Coarse nodes: R_node = P_node / A_node with P_node the built table's fp32 level-0 value at that (integer-degree)
// node, rounded up to 12 significant bits like the halves (glint_tables.h, "Storage"), nodes below 2^-28 of the
// peak read 0. A step that does not divide the axis (4 degrees on theta: 0, 4, .., 88, 90) ends in a short cell.
//
// Truth: directional_probability_reference (dense ring quadrature of (1), `rings` rings of 4 rings points) times
// the slice's energy-cap scale s(theta_i) (step 4 of the build scales a whole theta_i slice of level 0 by s <= 1):
// s at integer theta_i is the median of level0 / reference over nodes near the mirror direction, linear between.
// Every variant (today's lookup included) is compared with that scaled truth, so the cap is not counted as error.
// Queries: theta_i uniform in [0, 85] degrees; half with wo uniform on the hemisphere (z uniform), half near the
// lobe (half-vector slope ~ normal, std 1.5 sqrt(alpha^2 + (gamma/2)^2) per axis, wo = reflect(wi, h), above the
// horizon). Counted: truth > 1e-3 of the slice's peak (the table's peak over the slice, linear between slices).
// "today": LodLevel::lookup of the built level 0 (the halves, 1-degree trilinear, as the closure reads it; the
// closure's fast_acos_deg coordinates are not modelled: every variant gets the exact angles).
//
// build:  cmake --build build --target glint_factored_level0_study
// usage:  build/benchmarks/glint_factored_level0_study [queries=20000] [rings=48] [spec index 0..3 or -1 = all]
//         [threads=2]; GLINT_STUDY_CACHE=<dir> loads / saves the built tables there (load_table / save_table).
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "glimmer/microfacet.h"
#include "tables/glint_tables.h"

namespace {

namespace pg = glimmer::plugin::glint;
namespace mf = glimmer::microfacet;
using glimmer::Vec3;

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

struct StudySpec {
  const char *name;
  pg::BaseDistribution dist;
  float roughness;
  float gamma_deg;
};
// alpha = max(roughness^2, kMinAlpha = 0.15^2) in float, as ParticleField::alpha (tables/glint_common.h), which is
// the TableSpec's alpha (closures/glint.cpp).
const StudySpec kSpecs[] = {
    {"GGX r0.35 (alpha 0.1225) gamma 2 (GI car-paint flakes)", pg::BaseDistribution::GGX, 0.35f, 2.0f},
    {"Beckmann r0.5 (alpha 0.25) gamma 3 (GI floor)", pg::BaseDistribution::Beckmann, 0.5f, 3.0f},
    {"GGX r0.4 (alpha 0.16) gamma 2 (per-eval benchmark)", pg::BaseDistribution::GGX, 0.4f, 2.0f},
    {"GGX r0.2 (alpha 0.04) gamma 2 (narrow lobe)", pg::BaseDistribution::GGX, 0.2f, 2.0f},
};

double sq_d(double x) { return x * x; }

struct D3 {
  double x, y, z;
};
D3 spherical(double theta, double phi) {
  return {std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
}

// D(h) of the isotropic base in double from cos(theta_h) (the same formulas as mf::ggx_D / mf::beckmann_D, without
// Beckmann's e < 80 cut-off).
double ndf(pg::BaseDistribution dist, double alpha, double c) {
  if (!(c > 0.0)) return 0.0;
  const double c2 = c * c, a2 = alpha * alpha;
  if (dist == pg::BaseDistribution::GGX) {
    const double k = (1.0 - c2) / a2 + c2;
    return 1.0 / (kPi * a2 * k * k);
  }
  return std::exp(-(1.0 - c2) / (c2 * a2)) / (kPi * a2 * c2 * c2);
}

// The factor A at angles in degrees (0 where h leaves the hemisphere), D at alpha'^2 = alpha^2 + widen ((1 - mix) +
// mix / (wi.h)^2): the cone's half-angle gamma moves h by gamma / 2 along the plane of (wi, wo) and by
// gamma / (2 wi.h) across it (glint_tables.cpp, ConeQuadrature), so mix > 0 widens more where wi.h is small.
double lobe_factor(pg::BaseDistribution dist, double alpha, double widen, double mix, double sigma, double ti,
                   double to, double dp) {
  const D3 wi = spherical(ti * kDeg, 0.0), wo = spherical(to * kDeg, dp * kDeg);
  D3 h{wi.x + wo.x, wi.y + wo.y, wi.z + wo.z};
  const double len = std::sqrt(h.x * h.x + h.y * h.y + h.z * h.z);
  if (!(len > 1e-12)) return 0.0;
  h = {h.x / len, h.y / len, h.z / len};
  const double wi_h = wi.x * h.x + wi.y * h.y + wi.z * h.z;
  if (!(wi_h > 0.0) || !(h.z > 0.0)) return 0.0;
  if (mix >= 2.0) {  // anisotropic widening: gamma / 2 along the plane of (wi, wo), gamma / (2 wi.h) across it
    D3 ep{wi.y * wo.z - wi.z * wo.y, wi.z * wo.x - wi.x * wo.z, wi.x * wo.y - wi.y * wo.x};
    double lp = std::sqrt(ep.x * ep.x + ep.y * ep.y + ep.z * ep.z);
    if (!(lp > 1e-9)) {  // wi = wo: any direction across h
      ep = {h.z, 0.0, -h.x};
      lp = std::sqrt(ep.x * ep.x + ep.z * ep.z);
      if (!(lp > 1e-9)) ep = {0.0, 1.0, 0.0}, lp = 1.0;
    }
    ep = {ep.x / lp, ep.y / lp, ep.z / lp};
    const D3 ea{h.y * ep.z - h.z * ep.y, h.z * ep.x - h.x * ep.z, h.x * ep.y - h.y * ep.x};
    auto slope_of = [&](const D3 &e, double &u, double &v) {
      u = (e.x * h.z - h.x * e.z) / (h.z * h.z);
      v = (e.y * h.z - h.y * e.z) / (h.z * h.z);
    };
    double pu, pv, au, av;
    slope_of(ep, pu, pv);
    slope_of(ea, au, av);
    const double k = widen;  // here: k (gamma_rad / 2)^2
    const double wp = k / (wi_h * wi_h), wa = k;
    const double sxx = alpha * alpha + wp * pu * pu + wa * au * au, syy = alpha * alpha + wp * pv * pv + wa * av * av,
                 sxy = wp * pu * pv + wa * au * av;
    const double det = sxx * syy - sxy * sxy;
    const double mx = h.x / h.z, my = h.y / h.z;
    const double q = (syy * mx * mx - 2.0 * sxy * mx * my + sxx * my * my) / det;
    const double c4 = h.z * h.z * h.z * h.z;
    const double d = dist == pg::BaseDistribution::GGX ? 1.0 / (kPi * std::sqrt(det) * c4 * (1.0 + q) * (1.0 + q))
                                                       : std::exp(-q) / (kPi * std::sqrt(det) * c4);
    return sigma * d * h.z / (4.0 * wi_h);
  }
  const double a = std::sqrt(alpha * alpha + widen * ((1.0 - mix) + mix / (wi_h * wi_h)));
  return sigma * ndf(dist, a, h.z) * h.z / (4.0 * wi_h);
}

// x rounded up to 12 significant bits (a half of the table's 16-bit format: 11 stored mantissa bits).
float round_up_12_bits(float x) {
  if (!(x > 0.0f)) return 0.0f;
  int e = 0;
  const double m = std::frexp(static_cast<double>(x), &e);  // [0.5, 1)
  return static_cast<float>(std::ldexp(std::ceil(std::ldexp(m, 12)), e - 12));
}

// One axis of a coarse grid: nodes 0, step, 2 step, .., and `last` if the step does not reach it exactly.
struct Axis {
  std::vector<int> nodes;
  int step = 1;
  Axis(int step_deg, int last) : step(step_deg) {
    for (int x = 0; x <= last; x += step) nodes.push_back(x);
    if (nodes.back() != last) nodes.push_back(last);
  }
  int size() const { return static_cast<int>(nodes.size()); }
  void locate(double x, int &i, double &t) const {
    x = std::clamp(x, 0.0, static_cast<double>(nodes.back()));
    i = std::min(static_cast<int>(x / step), size() - 2);
    t = (x - nodes[i]) / (nodes[i + 1] - nodes[i]);
  }
};

struct FactorKind {
  std::string name;
  bool factored = false;
  double alpha = 0.0;  // the base alpha
  double widen = 0.0;  // k (gamma_rad / 2)^2
  double mix = 0.0;    // the share of widen divided by (wi.h)^2
};

double kRCap = 4.0;  // set by GLINT_STUDY_RCAP (16 gave the same 2/2/2 rows, 64 and 1e6 worse maxima at 3+ deg)

// A coarse level 0 storing R = P / A (or P when not factored).
struct CoarseTable {
  Axis ai, ao, ap;
  FactorKind factor;
  pg::BaseDistribution dist;
  double sigma;
  std::vector<float> r;

  CoarseTable(const pg::DirectionalTable &table, int si, int so, int sp, const FactorKind &f)
      : ai(si, 90), ao(so, 90), ap(sp, 180), factor(f), dist(table.spec.distribution),
        sigma(table.cone_solid_angle()) {
    const pg::LodLevel &l0 = table.levels[0];
    r.resize(static_cast<size_t>(ai.size()) * ao.size() * ap.size());
    float peak = 0.0f;
    size_t k = 0;
    for (int ti : ai.nodes)
      for (int to : ao.nodes)
        for (int dp : ap.nodes) {
          const double p = l0.values[(static_cast<size_t>(ti) * l0.n_theta_o + to) * l0.n_phi + dp];
          double v = p;
          if (factor.factored) {
            const double a = lobe_factor(dist, factor.alpha, factor.widen, factor.mix, sigma, ti, to, dp);
            // R is capped (kRCap): it diverges where A -> 0 with P > 0 (theta_i = theta_o = 90: h.z -> 0; Beckmann's
            // far tails, where the cone's spread dominates D), and the 16-bit format's range is set by the peak.
            v = a > 0.0 ? std::min(p / a, kRCap) : kRCap;
            if (!(p > 0.0)) v = 0.0;
          }
          r[k++] = static_cast<float>(v);
          peak = std::max(peak, r[k - 1]);
        }
    for (float &x : r) x = x < std::ldexp(peak, -28) ? 0.0f : round_up_12_bits(x);
  }
  size_t bytes() const { return r.size() * sizeof(uint16_t); }
  double at(int i, int o, int p) const {
    return r[(static_cast<size_t>(i) * ao.size() + o) * ap.size() + p];
  }
  double eval(double ti, double to, double dp) const {
    int i, o, p;
    double u, v, w;
    ai.locate(ti, i, u);
    ao.locate(to, o, v);
    ap.locate(dp, p, w);
    auto lp = [&](int ii, int oo) { return at(ii, oo, p) + (at(ii, oo, p + 1) - at(ii, oo, p)) * w; };
    const double a = lp(i, o) + (lp(i, o + 1) - lp(i, o)) * v;
    const double b = lp(i + 1, o) + (lp(i + 1, o + 1) - lp(i + 1, o)) * v;
    const double rr = a + (b - a) * u;
    return factor.factored ? rr * lobe_factor(dist, factor.alpha, factor.widen, factor.mix, sigma, ti, to, dp) : rr;
  }
};

struct Query {
  double ti, to, dp;
  bool lobe;
  double truth = 0.0;  // reference x s(theta_i)
  double peak = 0.0;   // the slice's peak (of the truth's scale)
};

struct Stats {
  size_t n = 0;
  double mean = 0, rms = 0, p99 = 0, max = 0;
  double max_ti = 0, max_to = 0, max_dp = 0, max_signed = 0;
};

// The subset away from grazing: theta_i <= 80 and theta_o <= 85 degrees.
bool inner(const Query &q) { return q.ti <= 80.0 && q.to <= 85.0; }

template <class F>
Stats error_stats(const std::vector<Query> &qs, const F &approx, bool inner_only = false) {
  Stats s;
  std::vector<double> errs;
  double sum = 0, sum2 = 0;
  for (const Query &q : qs) {
    if (!(q.truth > 1e-3 * q.peak) || (inner_only && !inner(q))) continue;
    const double e = approx(q) / q.truth - 1.0;
    const double a = std::fabs(e);
    errs.push_back(a);
    sum += a;
    sum2 += e * e;
    if (a > s.max) {
      s.max = a;
      s.max_signed = e;
      s.max_ti = q.ti;
      s.max_to = q.to;
      s.max_dp = q.dp;
    }
  }
  s.n = errs.size();
  if (s.n == 0) return s;
  s.mean = sum / s.n;
  s.rms = std::sqrt(sum2 / s.n);
  std::sort(errs.begin(), errs.end());
  s.p99 = errs[std::min(errs.size() - 1, static_cast<size_t>(0.99 * errs.size()))];
  return s;
}

template <class F>
void print_row(const char *grid, size_t bytes, const std::string &factor, const std::vector<Query> &qs,
               const F &approx) {
  const Stats s = error_stats(qs, approx), t = error_stats(qs, approx, true);
  std::printf("| %-6s | %7zu | %-21s | %6.3f | %6.3f | %6.3f | %7.2f | (%4.1f, %4.1f, %5.1f) %+.1f | %6.3f | %6.3f | "
              "%6.3f | %6.2f | (%4.1f, %4.1f, %5.1f) |\n",
              grid, bytes, factor.c_str(), 100 * s.mean, 100 * s.rms, 100 * s.p99, 100 * s.max, s.max_ti, s.max_to,
              s.max_dp, 100 * s.max_signed, 100 * t.mean, 100 * t.rms, 100 * t.p99, 100 * t.max, t.max_ti, t.max_to,
              t.max_dp);
}

// The `n` worst counted queries of a variant: angles, truth / slice peak, signed error.
template <class F>
void print_worst(const char *what, const std::vector<Query> &qs, const F &approx, int n = 6) {
  std::vector<std::pair<double, const Query *>> e;
  for (const Query &q : qs)
    if (q.truth > 1e-3 * q.peak) e.push_back({approx(q) / q.truth - 1.0, &q});
  const size_t m = std::min(e.size(), static_cast<size_t>(n));
  std::partial_sort(e.begin(), e.begin() + static_cast<long>(m), e.end(),
                    [](const auto &a, const auto &b) { return std::fabs(a.first) > std::fabs(b.first); });
  std::printf("worst %zu of %s:", m, what);
  for (size_t i = 0; i < m; ++i)
    std::printf(" (%.1f, %.1f, %.1f; P/peak %.3f) %+.1f%%;", e[i].second->ti, e[i].second->to, e[i].second->dp,
                e[i].second->truth / e[i].second->peak, 100 * e[i].first);
  std::printf("\n");
}

template <class F>
void parallel_for(int n, int threads, const F &f) {
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t)
    pool.emplace_back([&, t] {
      for (int i = t; i < n; i += threads) f(i);
    });
  for (auto &th : pool) th.join();
}

std::unique_ptr<pg::DirectionalTable> get_table(const pg::TableSpec &spec, const pg::NdfFunction &nf, int threads) {
  const char *dir = std::getenv("GLINT_STUDY_CACHE");
  std::string problem;
  if (dir && *dir) {
    const std::string path = pg::table_cache_path(dir, spec);
    auto t = pg::load_table(path, spec, problem);
    if (t) {
      std::printf("table loaded from %s\n", path.c_str());
      return t;
    }
  }
  auto t = pg::build_directional_table(spec, nf, threads);
  std::printf("table built in %.1f s\n", t->build_seconds);
  if (dir && *dir && !pg::save_table(pg::table_cache_path(dir, spec), *t, problem))
    std::printf("(not cached: %s)\n", problem.c_str());
  return t;
}

void study(const StudySpec &ss, int n_queries, int rings, int threads) {
  pg::TableSpec spec;
  spec.distribution = ss.dist;
  spec.alpha = std::max(ss.roughness * ss.roughness, 0.15f * 0.15f);
  spec.gamma_deg = ss.gamma_deg;
  const mf::Distribution mdist = ss.dist == pg::BaseDistribution::GGX ? mf::Distribution::GGX
                                                                       : mf::Distribution::Beckmann;
  const float alpha_f = spec.alpha;
  const pg::NdfFunction nf = [mdist, alpha_f](double cos_m) {  // as closures/glint.cpp passes it
    const double c = std::min(std::max(cos_m, 0.0), 1.0);
    const Vec3 m(static_cast<float>(std::sqrt(1.0 - c * c)), 0.0f, static_cast<float>(c));
    return static_cast<double>(mf::D(mdist, m, alpha_f, alpha_f));
  };
  std::printf("\n## %s: alpha %.6g, gamma %g deg\n\n", ss.name, spec.alpha, spec.gamma_deg);
  // The double-precision D of the factor against mf::D (float).
  double worst_d = 0.0;
  for (double c = 0.3; c <= 1.0; c += 0.05) {
    const double ref = nf(c);
    if (ref > 1e-6) worst_d = std::max(worst_d, std::fabs(ndf(ss.dist, spec.alpha, c) / ref - 1.0));
  }
  std::printf("factor's D vs mf::D: max rel diff %.2e (cos_h 0.3..1, D > 1e-6)\n", worst_d);
  const auto table = get_table(spec, nf, threads);
  const pg::LodLevel &l0 = table->levels[0];
  const size_t slice = static_cast<size_t>(l0.n_theta_o) * l0.n_phi;

  // Energy-cap scale per integer theta_i (median of level0 / reference near the mirror) and slice peaks.
  std::vector<double> scale(91, 1.0), peak(91, 0.0);
  parallel_for(91, threads, [&](int ti) {
    double pk = 0.0;
    for (size_t i = 0; i < slice; ++i) pk = std::max(pk, static_cast<double>(l0.values[ti * slice + i]));
    std::vector<double> ratios;
    for (int d = -2; d <= 2; ++d)
      for (int dp : {180, 178, 176}) {
        const int to = std::clamp(ti + d, 0, 90);
        const double v = l0.values[ti * slice + static_cast<size_t>(to) * l0.n_phi + dp];
        if (!(v > 0.05 * pk)) continue;
        const double ref = pg::directional_probability_reference(nf, spec.gamma_deg, ti, to, dp, rings);
        if (ref > 0.0) ratios.push_back(v / ref);
      }
    std::sort(ratios.begin(), ratios.end());
    scale[ti] = ratios.empty() ? 1.0 : ratios[ratios.size() / 2];
    peak[ti] = pk / scale[ti];
  });
  std::printf("energy-cap scale s(theta_i) (median level0 / reference near the mirror), slices with |s - 1| > 5e-4:");
  int shown = 0;
  for (int ti = 0; ti <= 90; ++ti)
    if (std::fabs(scale[ti] - 1.0) > 5e-4) std::printf("%s %d:%.4f", shown++ % 10 ? "" : "\n ", ti, scale[ti]);
  if (!shown) std::printf(" none");
  double lo = 1e9, hi = 0;
  for (int ti = 0; ti <= 86; ++ti) lo = std::min(lo, scale[ti]), hi = std::max(hi, scale[ti]);
  std::printf("\n  (range over theta_i 0..86: %.5f .. %.5f)\n", lo, hi);

  // Queries.
  std::mt19937_64 rng(0x6c696d6d65720042ull + static_cast<uint64_t>(ss.dist) * 977 + ss.roughness * 1000);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::normal_distribution<double> normal(0.0, 1.0);
  const double gamma_rad = spec.gamma_deg * kDeg;
  const double lobe_std = 1.5 * std::sqrt(sq_d(spec.alpha) + sq_d(0.5 * gamma_rad));
  std::vector<Query> qs;
  while (static_cast<int>(qs.size()) < n_queries) {
    Query q;
    q.ti = 85.0 * u01(rng);
    const D3 wi = spherical(q.ti * kDeg, 0.0);
    D3 wo;
    q.lobe = qs.size() % 2 == 1;
    if (!q.lobe) {
      const double z = u01(rng), phi = 2 * kPi * u01(rng), s = std::sqrt(std::max(0.0, 1 - z * z));
      wo = {s * std::cos(phi), s * std::sin(phi), z};
    } else {
      const double sx = lobe_std * normal(rng), sy = lobe_std * normal(rng);
      const double inv = 1.0 / std::sqrt(sx * sx + sy * sy + 1.0);
      const D3 h{-sx * inv, -sy * inv, inv};
      const double d = wi.x * h.x + wi.y * h.y + wi.z * h.z;
      wo = {2 * d * h.x - wi.x, 2 * d * h.y - wi.y, 2 * d * h.z - wi.z};
      if (!(d > 0.0) || !(wo.z > 0.0)) continue;
    }
    q.to = std::acos(std::clamp(wo.z, -1.0, 1.0)) / kDeg;
    q.dp = std::atan2(std::fabs(wo.y), wo.x) / kDeg;  // folded to [0, 180]
    qs.push_back(q);
  }
  const auto t0 = std::chrono::steady_clock::now();
  parallel_for(static_cast<int>(qs.size()), threads, [&](int i) {
    Query &q = qs[i];
    const int k = std::min(static_cast<int>(q.ti), 89);
    const double f = q.ti - k;
    const double s = scale[k] + (scale[k + 1] - scale[k]) * f;
    q.truth = s * pg::directional_probability_reference(nf, spec.gamma_deg, q.ti, q.to, q.dp, rings);
    q.peak = peak[k] + (peak[k + 1] - peak[k]) * f;
  });
  const double ref_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  size_t counted = 0, counted_lobe = 0, counted_inner = 0;
  for (const Query &q : qs)
    if (q.truth > 1e-3 * q.peak) ++counted, counted_lobe += q.lobe, counted_inner += inner(q);
  std::printf("%zu queries (%.1f s of reference at %d rings), %zu counted (truth > 1e-3 slice peak; %zu of them "
              "near-lobe; %zu with theta_i <= 80 and theta_o <= 85)\n",
              qs.size(), ref_s, rings, counted, counted_lobe, counted_inner);

  // The reference's own accuracy: against the rim rule on a subset (where it applies) and at twice the rings.
  {
    double worst_rim = 0, worst_rings = 0;
    int n_rim = 0, n_cmp = 0;
    for (size_t i = 0; i < qs.size() && n_cmp < 200; i += 37) {
      const Query &q = qs[i];
      if (!(q.truth > 1e-3 * q.peak)) continue;
      ++n_cmp;
      const double r1 = pg::directional_probability_reference(nf, spec.gamma_deg, q.ti, q.to, q.dp, rings);
      const double r2 = pg::directional_probability_reference(nf, spec.gamma_deg, q.ti, q.to, q.dp, 2 * rings);
      worst_rings = std::max(worst_rings, std::fabs(r1 / r2 - 1));
      const double rim = pg::directional_probability_by_rim(ss.dist, spec.alpha, spec.gamma_deg, q.ti, q.to, q.dp);
      if (rim > 0) {
        ++n_rim;
        worst_rim = std::max(worst_rim, std::fabs(r1 / rim - 1));
      }
    }
    std::printf("truth check on %d counted queries: max |ref(%d rings) / ref(%d rings) - 1| = %.2e; vs the rim "
                "rule (%d applicable): %.2e\n\n",
                n_cmp, rings, 2 * rings, worst_rings, n_rim, worst_rim);
  }

  std::printf("Relative error of P' in %% (all counted queries | the subset theta_i <= 80, theta_o <= 85)\n\n");
  std::printf("| grid i/o/p | bytes L0 | factor | mean | rms | p99 | max | max at (ti, to, dphi) signed | "
              "inner mean | inner rms | inner p99 | inner max | inner max at |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  const auto today = [&](const Query &q) {
    return static_cast<double>(l0.lookup(static_cast<float>(q.ti), static_cast<float>(q.to), static_cast<float>(q.dp)));
  };
  print_row("1/1/1", l0.halves.size() * sizeof(uint16_t), "today (halves lookup)", qs, today);
  std::vector<FactorKind> factors = {{"none (subsample P)", false}, {"A(alpha)", true, spec.alpha}};
  for (double k : {1.0, 4.0}) {
    char name[64];
    std::snprintf(name, sizeof name, "A(alpha'), k=%.2g", k);
    factors.push_back({name, true, spec.alpha, k * sq_d(0.5 * gamma_rad), 0.0});
  }
  for (double mix : {0.5, 1.0})
    for (double k : {0.5, 0.75, 1.0, 1.5, 2.0}) {
      if (mix == 0.5 && k != 1.0) continue;
      char name[64];
      std::snprintf(name, sizeof name, "A(a'(wi.h)) m%.2g k%.2g", mix, k);
      factors.push_back({name, true, spec.alpha, k * sq_d(0.5 * gamma_rad), mix});
    }
  std::vector<std::array<int, 3>> grids = {{1, 2, 2}, {2, 2, 2}, {2, 3, 3}, {2, 4, 4}, {3, 3, 3}, {4, 4, 4}, {6, 6, 6}};
  if (std::getenv("GLINT_STUDY_QUICK")) {  // the best factor on the grids with 1-degree theta_o
    factors = {{"A(a'(wi.h)) m1 k1", true, spec.alpha, sq_d(0.5 * gamma_rad), 1.0}};
    for (double k : {0.25, 0.5, 1.0, 2.0}) {
      char name[64];
      std::snprintf(name, sizeof name, "A(aniso) k%.2g", k);
      factors.push_back({name, true, spec.alpha, k * sq_d(0.5 * gamma_rad), 2.0});
    }
    grids = {{2, 2, 2}};
  }
  for (const auto &g : grids) {
    char gname[32];
    std::snprintf(gname, sizeof gname, "%d/%d/%d", g[0], g[1], g[2]);
    for (const FactorKind &f : factors) {
      const CoarseTable ct(*table, g[0], g[1], g[2], f);
      print_row(gname, ct.bytes(), f.name, qs, [&](const Query &q) { return ct.eval(q.ti, q.to, q.dp); });
    }
  }
  std::printf("\n");
  print_worst("today", qs, today);
  for (const auto &g : {std::array<int, 3>{2, 2, 2}, std::array<int, 3>{2, 3, 3}}) {
    const FactorKind best{"m1 k1", true, spec.alpha, sq_d(0.5 * gamma_rad), 1.0};
    const CoarseTable ct(*table, g[0], g[1], g[2], best);
    char what[64];
    std::snprintf(what, sizeof what, "%d/%d/%d A(a'(wi.h)) m1 k1", g[0], g[1], g[2]);
    print_worst(what, qs, [&](const Query &q) { return ct.eval(q.ti, q.to, q.dp); });
  }
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char **argv) {
  const int n_queries = argc > 1 ? std::atoi(argv[1]) : 20000;
  const int rings = argc > 2 ? std::atoi(argv[2]) : 48;
  const int which = argc > 3 ? std::atoi(argv[3]) : -1;
  const int threads = argc > 4 ? std::atoi(argv[4]) : 2;
  if (const char *cap = std::getenv("GLINT_STUDY_RCAP")) kRCap = std::atof(cap);
  std::printf("R cap %g (R_node = min(P / A, cap); nodes with P = 0 read 0)\n", kRCap);
  for (int i = 0; i < 4; ++i)
    if (which < 0 || which == i) study(kSpecs[i], n_queries, rings, threads);
  return 0;
}
