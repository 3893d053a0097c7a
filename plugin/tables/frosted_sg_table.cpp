// Spherical-Gaussian fit of the frosted_glass front-interface BTDF and its
// table (see frosted_sg_table.h for the recipe and the parameterisation).
#include "tables/frosted_sg_table.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <mutex>
#include <thread>
#include <type_traits>

#include <xmmintrin.h>

#include "core/dielectric_lobe.h"
#include "core/microfacet_lobe_params.h"
#include "glimmer/cache_blob.h"
#include "glimmer/microfacet.h"
#include "tables/checked_stamp.h"

namespace glimmer::plugin::frosted {

namespace {

constexpr double kDegToRad = 3.14159265358979323846 / 180.0;

// Polar angle below the interface of the smooth refraction of theta_i (pi / 2 in TIR).
double snell_angle(double theta_i, double eta) { return std::asin(std::min(1.0, std::sin(theta_i) / eta)); }

// The interface of frosted_glass (white), seen from the wi side with relative IOR eta.
DielectricLobe interface_lobe(float eta, float roughness) {
  DielectricLobe lobe;
  lobe.build(MicrofacetLobeParams::make(kMultiGgx, roughness, 0.0f), eta, false, true);
  return lobe;
}

// Calls visit(wo, weight, g) for each transmitted direction of the BTDF's
// visible-normal sampling (the spherical-cap form of sample_ggx_visible_normal,
// here in double) on a strata x strata midpoint grid in (u1, v): weight = g / p
// times the Jacobian of the map below, p the density of wo, so that
// Int h g = mean over the grid of h(wo) weight.
//  - The tail: the cap's height runs linearly in u2, and u2 -> 1 are the facets
//    near the horizon (slopes -> infinity). GGX's slope tail is heavy: the part
//    of 1 - |M| (which sets the moment kappa) coming from slopes in [s, 2 s] is
//    about the same for every s between alpha and 1, and on a uniform grid all
//    slopes beyond ~7 alpha fell into the last row, where total internal
//    reflection cuts the lobe. So u2 = 1 - (1 - v)^kTailPower, v uniform: row
//    j from the end spans slopes alpha (strata / j)^(kTailPower / 2), about a
//    factor 2 per row at the end (the last row starts beyond 300 alpha).
//  - The edge: a cell whose corners disagree on whether the path transmits
//    (total internal reflection at the facet, or wo above the interface) holds
//    the edge of the lobe, where g has a square-root kink (Fresnel at the
//    critical angle): it is integrated on a kEdgeRefine^2 sub-grid instead of
//    its midpoint. Without this the sums jumped whenever a midpoint crossed the
//    edge as theta_i, eta or the roughness changed. 16 (8 before fit version
//    9): at roughness ~0.05 the TIR cut lies at slopes ~370 alpha, and with 8
//    ln kappa still zig-zagged by ~0.03 from one roughness to the next.
//  - The inside of the lobe: a cell whose corners all transmit is integrated by 3 x 3 Gauss-Legendre points
//    (fit version 10; its midpoint before). Small lobes (past the onset of TIR at grazing, energy ~1e-3) come
//    from a sliver of the slope tail a few cells wide; with one midpoint per cell ln E and ln kappa zig-zagged
//    by ~0.01 from one roughness to the next (second differences over steps of 0.017 in ln roughness; ior 1.85,
//    theta 81-85 deg), which the table's interpolation check saw as ~0.7 % energy errors at cell centres.
//    3 x 3 points: 0.001, for 2.2x the fit's CPU (32 x 32 edge cells: unchanged; 96 strata: 0.005-0.008).
inline constexpr int kEdgeRefine = 16;
inline constexpr double kGaussNode[3] = {0.5 - 0.3872983346207417, 0.5, 0.5 + 0.3872983346207417};  // 0.5 +- sqrt(0.15)
inline constexpr double kGaussWeight[3] = {5.0 / 18.0, 8.0 / 18.0, 5.0 / 18.0};
inline constexpr int kTailPower = 3;

// A direction in double (the quadrature's wo, normalised in double: the moment kappa of a sharp lobe is
// 1 / (1 - |M|), and a float wo's length error of 6e-8 is 1 % of 1 - |M| at kappa 1.5e5).
struct Direction {
  double x, y, z;
};

// What a grid coordinate x in [0, 1] gives both axes of the quadrature: cos and sin of phi = 2 pi x (the u1
// axis), the cap height w = 1 - u2 = (1 - x)^kTailPower and the Jacobian du2 / dx (the v axis). The coordinates
// repeat over the grid (corners a / strata, Gauss points (a + node) / strata, edge sub-cells (a + (s + 1/2) /
// kEdgeRefine) / strata), so they are computed once per node instead of once per point (sincos and pow were
// ~17 % of the fit's CPU) by the same expressions: the same bits.
struct GridCoordinate {
  double cos_phi, sin_phi, w, jacobian;
};
GridCoordinate grid_coordinate(double x) {
  const double phi = 2.0 * M_PI * x;
  return {std::cos(phi), std::sin(phi), std::max(std::pow(1.0 - x, double(kTailPower)), 1e-12),
          kTailPower * std::pow(1.0 - x, double(kTailPower - 1))};
}

template <typename Visit>
void for_each_transmitted(const Vec3 &wi, float eta, float roughness, int strata, Visit &&visit) {
  namespace mf = glimmer::microfacet;
  const DielectricLobe lobe = interface_lobe(eta, roughness);
  // The stretched incident direction (isotropic GGX: ax = ay).
  const double ax = lobe.ax, ay = lobe.ay;
  double sx = ax * wi.x, sy = ay * wi.y, sz = wi.z;
  const double sl = std::sqrt(sx * sx + sy * sy + sz * sz);
  sx /= sl, sy /= sl, sz /= sl;
  // The visible normal at (u1, w = 1 - u2): a point of the cap z in [-sz, 1], plus the stretched wi, unstretched.
  auto normal_at = [&](const GridCoordinate &u1, double w) {
    const double z = w * (1.0 + sz) - sz;
    const double st = std::sqrt(std::max(0.0, 1.0 - z * z));
    const double hx = ax * (st * u1.cos_phi + sx), hy = ay * (st * u1.sin_phi + sy), hz = std::max(z + sz, 0.0);
    const double len = std::sqrt(hx * hx + hy * hy + hz * hz);
    if (!(len > 1e-300)) return Vec3(0.0f, 0.0f, 1.0f);
    return Vec3(float(hx / len), float(hy / len), float(hz / len));
  };
  auto transmits = [&](const GridCoordinate &u1, const GridCoordinate &v, Vec3 &m, Vec3 &wo) {
    m = normal_at(u1, v.w);
    return mf::refract(wi, m, eta, wo) && wo.z < 0.0f;
  };
  auto point = [&](const GridCoordinate &u1, const GridCoordinate &v, double scale) {
    Vec3 m, wo;
    if (!transmits(u1, v, m, wo)) return;  // TIR at this microfacet, or wo above the interface
    const double len = std::sqrt(double(wo.x) * wo.x + double(wo.y) * wo.y + double(wo.z) * wo.z);
    const Direction dir{wo.x / len, wo.y / len, wo.z / len};
    wo = normalize(wo);
    const LocalEval e = lobe.eval_local(wi, wo, eta);
    // e.pdf = (1 - F) p(wo): the transmitted share of the sampling density.
    const float F = mf::fresnel_dielectric(dot(wi, m), eta);
    const double p = double(e.pdf) / std::max(1.0 - double(F), 1e-12);
    if (!(p > 0.0) || !(e.f_cos.x > 0.0f)) return;
    visit(dir, scale * v.jacobian * double(e.f_cos.x) / p, double(e.f_cos.x));
  };
  // The grid's coordinates: corners, 3 Gauss points per cell, kEdgeRefine sub-cell midpoints per cell.
  std::vector<GridCoordinate> corners(size_t(strata) + 1), gauss(size_t(strata) * 3),
      edges(size_t(strata) * kEdgeRefine);
  for (int a = 0; a <= strata; ++a) corners[size_t(a)] = grid_coordinate(double(a) / strata);
  for (int a = 0; a < strata; ++a) {
    for (int i = 0; i < 3; ++i) gauss[size_t(a) * 3 + i] = grid_coordinate((a + kGaussNode[i]) / strata);
    for (int sa = 0; sa < kEdgeRefine; ++sa)
      edges[size_t(a) * kEdgeRefine + sa] = grid_coordinate((a + (sa + 0.5) / kEdgeRefine) / strata);
  }
  // Transmission at the grid's corners.
  std::vector<char> corner(size_t(strata + 1) * (strata + 1));
  for (int a = 0; a <= strata; ++a)
    for (int b = 0; b <= strata; ++b) {
      Vec3 m, wo;
      corner[size_t(a) * (strata + 1) + b] = transmits(corners[size_t(a)], corners[size_t(b)], m, wo) ? 1 : 0;
    }
  for (int a = 0; a < strata; ++a)
    for (int b = 0; b < strata; ++b) {
      auto c = [&](int da, int db) { return corner[size_t(a + da) * (strata + 1) + (b + db)]; };
      const bool edge = c(0, 0) != c(1, 0) || c(0, 0) != c(0, 1) || c(0, 0) != c(1, 1);
      if (!edge) {  // 3 x 3 Gauss-Legendre points (a midpoint aliased with the integrand's shape: see above)
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j)
            point(gauss[size_t(a) * 3 + i], gauss[size_t(b) * 3 + j], kGaussWeight[i] * kGaussWeight[j]);
        continue;
      }
      for (int sa = 0; sa < kEdgeRefine; ++sa)
        for (int sb = 0; sb < kEdgeRefine; ++sb)
          point(edges[size_t(a) * kEdgeRefine + sa], edges[size_t(b) * kEdgeRefine + sb],
                1.0 / (kEdgeRefine * kEdgeRefine));
    }
}

Vec3 incident(float cos_theta_i) {
  const float c = std::clamp(cos_theta_i, 1e-4f, 1.0f);
  return Vec3(std::sqrt(std::max(0.0f, 1.0f - c * c)), 0.0f, c);
}

}  // namespace

double SphericalGaussian::eval(const Vec3 &w) const { return eval(w.x, w.y, w.z); }

namespace {
// The axis of g normalised in double: a float axis has |p| = 1 +- 6e-8, which at kappa ~1e5 moved
// exp(kappa (p . w - 1)) and the inner product below by several per cent.
void unit_axis(const SphericalGaussian &g, double p[3]) {
  const double x = g.axis.x, y = g.axis.y, z = g.axis.z, len = std::sqrt(x * x + y * y + z * z);
  const double inv = len > 0.0 ? 1.0 / len : 0.0;
  p[0] = x * inv, p[1] = y * inv, p[2] = z * inv;
}
}  // namespace

double SphericalGaussian::eval(double x, double y, double z) const {
  // kappa (p . w - 1) = -kappa |p - w|^2 / 2 for unit p and w, without the cancellation of 1 - p . w.
  double p[3];
  unit_axis(*this, p);
  const double len = std::sqrt(x * x + y * y + z * z), inv = len > 0.0 ? 1.0 / len : 0.0;
  const double dx = p[0] - x * inv, dy = p[1] - y * inv, dz = p[2] - z * inv;
  return double(amplitude) * std::exp(-0.5 * double(sharpness) * (dx * dx + dy * dy + dz * dz));
}
double SphericalGaussian::integral() const {
  const double k = sharpness;
  return 2.0 * M_PI * double(amplitude) * -std::expm1(-2.0 * k) / k;
}
double SphericalGaussian::integral_squared() const { return sg_inner_product(*this, *this); }

double sg_inner_product(const SphericalGaussian &g1, const SphericalGaussian &g2) {
  const double k1 = g1.sharpness, k2 = g2.sharpness;
  double p1[3], p2[3];
  unit_axis(g1, p1);
  unit_axis(g2, p2);
  // d = |k1 p1 + k2 p2|, d^2 = (k1 + k2)^2 - k1 k2 |p1 - p2|^2; d - k1 - k2 = -k1 k2 |p1 - p2|^2 / (d + k1 + k2)
  // (no cancellation when the axes are close and kappa large).
  const double s = (p1[0] - p2[0]) * (p1[0] - p2[0]) + (p1[1] - p2[1]) * (p1[1] - p2[1]) + (p1[2] - p2[2]) * (p1[2] - p2[2]);
  const double d = std::sqrt(std::max(0.0, (k1 + k2) * (k1 + k2) - k1 * k2 * s));
  const double a = double(g1.amplitude) * g2.amplitude;
  // sinh(d) exp(-k1 - k2) / d written without overflow; -> exp(-k1 - k2) as d -> 0.
  if (d < 1e-6) return 4.0 * M_PI * a * std::exp(-k1 - k2);
  return 2.0 * M_PI * a * std::exp(-k1 * k2 * s / (d + k1 + k2)) * -std::expm1(-2.0 * d) / d;
}

SphericalGaussian TransmissionLobe::sg(float cos_theta_i, float eta) const {
  SphericalGaussian g;
  const double theta_i = std::acos(std::clamp(double(cos_theta_i), 0.0, 1.0));
  if (eta >= 1.0f) {
    const double theta_axis = snell_angle(theta_i, eta) + axis_offset;
    g.axis = Vec3(float(-std::sin(theta_axis)), 0.0f, float(-std::cos(theta_axis)));
  } else {
    const double s = std::clamp(std::sin(theta_i) / eta + axis_offset, -1.0, 1.0);
    g.axis = Vec3(float(-s), 0.0f, float(-std::sqrt(std::max(0.0, 1.0 - s * s))));
  }
  g.sharpness = std::exp(log_sharpness);
  // a = E kappa / (2 pi (1 - exp(-2 kappa))): the SG's integral is the lobe's energy.
  const double k = g.sharpness;
  g.amplitude = float(double(std::max(energy, 0.0f)) * k / (2.0 * M_PI * -std::expm1(-2.0 * k)));
  return g;
}

double sharpness_from_mean_length(double r) {
  r = std::clamp(r, 1e-9, 1.0 - 1e-12);
  if (r < 1e-4) return 3.0 * r;                // coth k - 1/k = k/3 + O(k^3)
  if (r > 1.0 - 1e-6) return 1.0 / (1.0 - r);  // = 1 - 1/k + O(exp(-2k))
  double lo = std::log(1e-5), hi = std::log(2e6);
  for (int it = 0; it < 100; ++it) {  // bisection in ln(kappa): the mean length increases with kappa
    const double mid = 0.5 * (lo + hi), k = std::exp(mid);
    const double len = 1.0 / std::tanh(k) - 1.0 / k;
    (len < r ? lo : hi) = mid;
  }
  return std::exp(0.5 * (lo + hi));
}

TransmissionLobe fit_transmission_lobe(float cos_theta_i, float eta, float roughness, int strata, SharpnessFit how) {
  const Vec3 wi = incident(cos_theta_i);
  struct Sample {
    Direction wo;
    double weight;
  };
  std::vector<Sample> samples;  // for the L2 sharpness only (the table's moment fit needs the sums)
  if (how == SharpnessFit::kL2) samples.reserve(size_t(strata) * strata);
  double energy = 0.0, mx = 0.0, my = 0.0, mz = 0.0;
  for_each_transmitted(wi, eta, roughness, strata, [&](const Direction &wo, double weight, double) {
    if (how == SharpnessFit::kL2) samples.push_back({wo, weight});
    energy += weight;
    mx += weight * wo.x;
    my += weight * wo.y;
    mz += weight * wo.z;
  });
  const double n = double(strata) * strata;
  TransmissionLobe lobe;
  lobe.energy = float(energy / n);
  if (!(energy > 0.0)) return lobe;  // total internal reflection: no lobe (kappa 1, offset 0)
  // Scale and mean: the lobe's energy and mean direction.
  const double len = std::sqrt(mx * mx + my * my + mz * mz) / energy;
  const double theta_i = std::acos(double(wi.z));
  const double theta_axis = std::atan2(-mx, -mz);
  lobe.axis_offset = eta >= 1.0f ? float(theta_axis - snell_angle(theta_i, eta))
                                 : float(std::sin(theta_axis) - std::sin(theta_i) / eta);
  // Sharpness: the vMF match of the mean length (the variance)...
  const double kappa_moments = sharpness_from_mean_length(len);
  lobe.log_sharpness = float(std::log(kappa_moments));
  if (how == SharpnessFit::kMoments) return lobe;
  // ... or, keeping scale and mean, the kappa minimising Int (G - g)^2 = Int G^2 - 2 Int G g + const:
  // the variance is dominated by GGX's long tails and gives a far too wide lobe.
  auto l2 = [&](double log_k) {
    TransmissionLobe trial = lobe;
    trial.log_sharpness = float(log_k);
    const SphericalGaussian g = trial.sg(float(wi.z), eta);
    double cross = 0.0;
    for (const Sample &s : samples) cross += s.weight * g.eval(s.wo.x, s.wo.y, s.wo.z);
    return g.integral_squared() - 2.0 * cross / n;
  };
  // Golden-section search on ln(kappa) from the moment match up to 1000x sharper.
  const double phi = 0.5 * (std::sqrt(5.0) - 1.0);
  double a = std::log(kappa_moments), b = a + std::log(1000.0);
  double c = b - phi * (b - a), d = a + phi * (b - a), fc = l2(c), fd = l2(d);
  while (b - a > 1e-4) {
    if (fc < fd) {
      b = d, d = c, fd = fc;
      c = b - phi * (b - a), fc = l2(c);
    } else {
      a = c, c = d, fc = fd;
      d = a + phi * (b - a), fd = l2(d);
    }
  }
  lobe.log_sharpness = float(0.5 * (a + b));
  return lobe;
}

double transmission_fit_error(float cos_theta_i, float eta, float roughness, const SphericalGaussian &sg,
                              int strata) {
  const Vec3 wi = incident(cos_theta_i);
  double cross = 0.0, g2 = 0.0;
  for_each_transmitted(wi, eta, roughness, strata, [&](const Direction &wo, double weight, double g) {
    cross += weight * sg.eval(wo.x, wo.y, wo.z);
    g2 += weight * g;
  });
  const double n = double(strata) * strata;
  cross /= n;
  g2 /= n;
  if (!(g2 > 0.0)) return 0.0;
  return std::sqrt(std::max(0.0, sg.integral_squared() - 2.0 * cross + g2) / g2);
}

// Entering: theta_i = theta_max t (2 - t), t uniform: 2x the uniform spacing at normal incidence, crowding
// toward grazing (spacing proportional to sqrt(theta_max - theta_i)), where the lobe's axis offset and
// sharpness change fastest at low roughness; a function smooth in theta_max - theta_i is smooth in t.
float TransmissionSgTable::theta_at(int i) {
  const double t = double(i) / (kThetaNodes - 1);
  return float(kThetaMaxDeg * kDegToRad * t * (2.0 - t));
}

namespace {
// Past the onset of TIR the leaving side's first coordinate follows theta_i itself, from the critical angle
// theta_c = asin(1 / ior) to 89.5 deg (a sine is flat at grazing: over it, E(x) had a square-root kink at
// x = ior and the last interval spanned 78.6..89.5 deg, energy errors up to 70 %).
double critical_angle(float ior) { return std::asin(1.0 / double(ior)); }
double theta_max() { return TransmissionSgTable::kThetaMaxDeg * kDegToRad; }
// Past the onset the nodes crowd at both ends: s(t) = t^2 + 2 t^3 - 2 t^4 is t^2 at the onset (where the energy
// of a sharp lobe falls by decades within a fraction of a degree) and 1 - 5 (1 - t)^2 at grazing (where the
// energy goes to 0 and ln E curves most); s' = 2 t (1 - t) (1 + 4 t) >= 0.
double onset_to_grazing(double t) { return t * t * (1.0 + 2.0 * t - 2.0 * t * t); }
double inverse_onset_to_grazing(double s) {
  s = std::clamp(s, 0.0, 1.0);
  double t = s < 0.5 ? std::sqrt(s) * 0.85 : 1.0 - std::sqrt((1.0 - s) / 5.0);  // near the ends s ~ t^2, 1 - 5 (1-t)^2
  for (int it = 0; it < 40; ++it) {  // safeguarded Newton (s' vanishes at both ends)
    const double f = onset_to_grazing(t) - s, df = 2.0 * t * (1.0 - t) * (1.0 + 4.0 * t);
    const double next = df > 1e-12 ? std::clamp(t - f / df, 0.0, 1.0) : t;
    if (std::fabs(next - t) < 1e-12) break;
    t = next;
  }
  return t;
}
}  // namespace

float TransmissionSgTable::sine_at(int i, float ior) {
  const int half = (kSineNodes - 1) / 2;
  if (i <= half) {
    const float t = float(i) / half;
    return 1.0f - (1.0f - t) * (1.0f - t);
  }
  const double t = double(i - half) / half, tc = critical_angle(ior);
  return float(ior * std::sin(tc + (theta_max() - tc) * onset_to_grazing(t)));
}

namespace {
// Continuous node coordinate of the leaving side at (theta_i, ior) (inverse of sine_at).
float sine_coordinate(float theta, float ior) {
  const int half = (TransmissionSgTable::kSineNodes - 1) / 2;
  const double x = ior * std::sin(double(theta));
  if (x <= 1.0) return float((1.0 - std::sqrt(std::max(0.0, 1.0 - x))) * half);
  // Only past the onset of TIR (no asin before it). A material's lookups share one ior: this thread's last ior and its
  // critical angle are kept (the same asin of the same input: the same bits; session 32, frostedtime32: 40 % of the
  // caustic bench's sine_coordinate calls are past the onset, ~17 instructions per camera path).
  thread_local float kept_ior = std::numeric_limits<float>::quiet_NaN();
  thread_local double kept_tc = 0.0;
  if (!(ior == kept_ior)) kept_tc = critical_angle(ior), kept_ior = ior;
  const double tc = kept_tc;
  const double t = inverse_onset_to_grazing(std::clamp((theta - tc) / (theta_max() - tc), 0.0, 1.0));
  return float((1.0 + t) * half);
}
}  // namespace

float TransmissionSgTable::roughness_at(int j) {
  return std::exp(std::log(kRoughnessMin) * (1.0f - float(j) / (kRoughnessNodes - 1)));
}
float TransmissionSgTable::ior_at(int k) { return kIorMin + (kIorMax - kIorMin) * k / (kIorNodes - 1); }

TransmissionLobe TransmissionSgTable::fit_node(size_t idx) {
  const int k = int(idx % kIorNodes), j = int(idx / kIorNodes % kRoughnessNodes);
  const int first = int(idx / (size_t(kIorNodes) * kRoughnessNodes));  // theta nodes, then sine nodes
  const int side = first < kThetaNodes ? 0 : 1;
  const float ior = ior_at(k);
  float cos_theta;
  if (side == 0) {
    cos_theta = std::cos(theta_at(first));
  } else {
    const float sin_max = std::sin(float(kThetaMaxDeg * kDegToRad));
    const float sin_theta = std::min(sine_at(first - kThetaNodes, ior) / ior, sin_max);
    cos_theta = std::sqrt(1.0f - sin_theta * sin_theta);
  }
  return fit_transmission_lobe(cos_theta, side == 0 ? ior : 1.0f / ior, roughness_at(j));
}

TransmissionSgTable::TransmissionSgTable(Empty) : nodes_(node_count()) {}

std::vector<TransmissionLobe> TransmissionSgTable::fit_nodes(const std::vector<size_t> &indices, unsigned threads) {
  std::vector<TransmissionLobe> out(indices.size());
  if (threads == 0) threads = std::max(1u, std::thread::hardware_concurrency());
  threads = unsigned(std::min<size_t>(threads, std::max<size_t>(1, indices.size())));
  // Dynamic chunks instead of a fixed share per thread: a thread that drew cheap nodes takes more, so all
  // threads finish together. Which thread fits a node changes nothing in its result.
  constexpr size_t kChunk = 16;
  std::atomic<size_t> next{0};
  auto work = [&] {
    for (size_t begin; (begin = next.fetch_add(kChunk)) < indices.size();)
      for (size_t n = begin; n < std::min(begin + kChunk, indices.size()); ++n) out[n] = fit_node(indices[n]);
  };
  std::vector<std::thread> pool;
  for (unsigned w = 1; w < threads; ++w) pool.emplace_back(work);
  work();
  for (auto &t : pool) t.join();
  return out;
}

TransmissionSgTable::TransmissionSgTable(unsigned threads) : TransmissionSgTable(Empty{}) {
  std::vector<size_t> all(nodes_.size());
  for (size_t i = 0; i < all.size(); ++i) all[i] = i;
  nodes_ = fit_nodes(all, threads);
  derive_interpolated();
}

void TransmissionSgTable::derive_interpolated() {
  log_energy_.resize(nodes_.size());
  for (size_t i = 0; i < nodes_.size(); ++i) log_energy_[i] = std::log(std::max(nodes_[i].energy, 0.0f) + kEnergyFloor);
  lookup_nodes_.resize(nodes_.size());
  for (size_t i = 0; i < nodes_.size(); ++i)
    lookup_nodes_[i] = {log_energy_[i], nodes_[i].log_sharpness, nodes_[i].axis_offset, 0.0f};
}

bool TransmissionSgTable::operator==(const TransmissionSgTable &o) const {
  if (nodes_.size() != o.nodes_.size()) return false;
  for (size_t i = 0; i < nodes_.size(); ++i)
    if (nodes_[i].energy != o.nodes_[i].energy || nodes_[i].log_sharpness != o.nodes_[i].log_sharpness ||
        nodes_[i].axis_offset != o.nodes_[i].axis_offset)
      return false;
  return true;
}

// ---- Disk cache ----
namespace {

constexpr char kCacheMagic[8] = {'G', 'L', 'M', 'F', 'R', 'S', 'G', 'T'};
constexpr uint32_t kCacheFormat = 1;
// Bump when the fit itself changes (the grid and fit constants are hashed below).
constexpr uint32_t kFitVersion = 10;  // 2: leaving side over the Snell sine, axis as a sine offset; 3: edge refinement;
                                     // 4: the sine's upper segment ends at grazing for each ior; 5: the upper
                                     // segment over theta_i, the leaving fit's tail row always refined; 6: the
                                     // fit's grid warped toward the slope tail; 7: node placement (entering toward
                                     // grazing, leaving at both ends of the upper segment); 8: directions in
                                     // double, the upper segment's s(t); 9: edge cells refined 16 x 16;
                                     // 10: 3 x 3 Gauss-Legendre points inside the lobe

// The first 8 bytes of SHA-256 over the format, the grid and the fit's constants.
uint64_t cache_key() {
  using T = TransmissionSgTable;
  const float grid[] = {float(kCacheFormat),     float(T::kThetaNodes), T::kThetaMaxDeg,       float(T::kSineNodes),
                        float(T::kRoughnessNodes), T::kRoughnessMin,    float(T::kIorNodes),   T::kIorMin,
                        T::kIorMax,                float(kFitStrata),   float(int(kTableFit)), float(kFitVersion)};
  const Digest256 d = sha256(grid, sizeof(grid));
  uint64_t key;
  std::memcpy(&key, d.data(), sizeof(key));
  return key;
}

}  // namespace

std::string TransmissionSgTable::cache_path(const std::string &cache_dir) {
  return cache_entry_path(cache_dir, "frosted_sg_", cache_key());
}

// File: magic, format, key, node count, then (E, ln kappa, axis offset) per node, then the MAC (cache_blob.h).
std::string TransmissionSgTable::save(const std::string &path) const {
  ByteWriter out;
  out.put_header(kCacheMagic, kCacheFormat, cache_key());
  out.put(uint64_t(nodes_.size()));
  for (const TransmissionLobe &n : nodes_) {
    out.put(n.energy);
    out.put(n.log_sharpness);
    out.put(n.axis_offset);
  }
  return write_cache_blob(path, std::move(out.bytes));
}

// ---- The check nodes' stamp (session 32, frostedtime32; tables/checked_stamp.h since session 39) ----
// load() re-fits 16 check nodes (~380 M instructions, ~0.1 s CPU: a fixed cost of every render with frosted glass,
// which the error-vs-time ladder's process CPU clock counts at every rung). Once they pass, the entry's checked stamp
// (checked_stamp.h: this plugin build's id and the FNV-1a hash of the entry's payload) lets a later load by the same
// build of the same bytes skip the re-fits.
namespace {
CheckedStampKind stamp_kind() {
  CheckedStampKind kind{{'G', 'L', 'M', 'F', 'S', 'G', 'C', 'K'}, 2u, cache_key()};  // format: checked_stamp.h
  return kind;
}
}  // namespace

std::string TransmissionSgTable::stamp_path(const std::string &entry_path) { return checked_stamp_path(entry_path); }

const std::string &TransmissionSgTable::build_id() { return plugin_build_id(); }

std::array<std::array<int, 3>, 16> TransmissionSgTable::check_nodes() {
  std::array<std::array<int, 3>, 16> nodes{};
  const int firsts = kThetaNodes + kSineNodes;
  for (int n = 0; n < 16; ++n)  // spread over both sides, every roughness and ior range
    nodes[n] = {(n * 37 + 5) % firsts, (n * 11 + 3) % kRoughnessNodes, (n * 5 + 1) % kIorNodes};
  return nodes;
}

std::unique_ptr<TransmissionSgTable> TransmissionSgTable::load(const std::string &path, std::string &problem) {
  return load(path, problem, build_id());
}

std::unique_ptr<TransmissionSgTable> TransmissionSgTable::load(const std::string &path, std::string &problem,
                                                                const std::string &build_id) {
  std::vector<unsigned char> bytes;
  problem = read_cache_blob(path, bytes);
  if (!problem.empty()) return nullptr;
  auto table = std::unique_ptr<TransmissionSgTable>(new TransmissionSgTable(Empty{}));
  ByteReader in{bytes};
  auto get = [&](void *p, size_t n) { return in.get(p, n); };
  uint64_t count = 0;
  if (!in.get_header(kCacheMagic, kCacheFormat, cache_key()) || !get(&count, 8) || count != table->nodes_.size()) {
    problem = "bad header (not a frosted SG table of this grid and fit)";
    return nullptr;
  }
  for (TransmissionLobe &n : table->nodes_)
    if (!get(&n.energy, 4) || !get(&n.log_sharpness, 4) || !get(&n.axis_offset, 4)) {
      problem = "truncated";
      return nullptr;
    }
  if (!in.at_end()) {
    problem = "trailing bytes";
    return nullptr;
  }
  for (const TransmissionLobe &n : table->nodes_)
    if (!std::isfinite(n.energy) || !std::isfinite(n.log_sharpness) || !std::isfinite(n.axis_offset) ||
        n.energy < 0.0f || n.energy > 1.1f || std::fabs(n.axis_offset) > 3.2f) {
      problem = "non-finite or out-of-range values";
      return nullptr;
    }
  const bool stamped = checked_stamp_matches(path, stamp_kind(), bytes, build_id);
  for (const auto &c : check_nodes()) {
    if (stamped) break;  // this build checked these bytes before
    const size_t idx = (size_t(c[0]) * kRoughnessNodes + c[1]) * kIorNodes + c[2];
    const TransmissionLobe fit = table->fit_node(idx), &stored = table->nodes_[idx];
    if (std::fabs(fit.energy - stored.energy) > 1e-4f || std::fabs(fit.log_sharpness - stored.log_sharpness) > 1e-3f ||
        std::fabs(fit.axis_offset - stored.axis_offset) > 1e-4f) {
      problem = "node " + std::to_string(idx) + " differs from its fit";
      return nullptr;
    }
  }
  if (!stamped) table->stamp_not_written_ = write_checked_stamp(path, stamp_kind(), bytes, build_id);
  table->derive_interpolated();
  table->loaded_from_cache_ = true;
  table->refitted_check_nodes_ = !stamped;
  return table;
}

namespace {
// A frosted_sg_*.bin in cache_dir other than `current` (an entry of an older fit or grid: the key is in the
// name), or "".
std::string other_cache_entry(const std::string &cache_dir, const std::string &current) {
  std::error_code ec;
  for (const auto &entry : std::filesystem::directory_iterator(cache_dir, ec)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind("frosted_sg_", 0) == 0 && name.size() > 4 && name.compare(name.size() - 4, 4, ".bin") == 0 &&
        entry.path().string() != current)
      return entry.path().string();
  }
  return "";
}
}  // namespace

const TransmissionSgTable &TransmissionSgTable::get(const GlimmerHostServices *host) {
  static std::mutex mutex;
  static std::unique_ptr<TransmissionSgTable> table;
  std::lock_guard<std::mutex> lock(mutex);
  if (table) return *table;
  auto log = [&](int level, const std::string &msg) {
    if (host != nullptr && host->log != nullptr) host->log(host->host_data, level, msg.c_str());
  };
  const bool use_cache = host != nullptr && host->cache_dir != nullptr && host->cache_dir[0] != '\0';
  const std::string path = use_cache ? cache_path(host->cache_dir) : std::string();
  if (use_cache) {
    std::string problem;
    table = load(path, problem);
    if (!table && problem != "missing")
      log(GLIMMER_LOG_WARNING, "frosted_glass: cached SG table " + path + " is unusable (" + problem + "); rebuilding");
    if (table && !table->stamp_not_written().empty())
      log(GLIMMER_LOG_WARNING, "frosted_glass: cannot record the SG table's check beside " + path + " (" +
                                   table->stamp_not_written() + "); every start will repeat its 16 re-fits");
    if (!table && problem == "missing")
      if (const std::string old = other_cache_entry(host->cache_dir, path); !old.empty())
        log(GLIMMER_LOG_WARNING, "frosted_glass: cached SG table " + old +
                                     " is for another grid or fit version; rebuilding (" + path + ")");
  }
  if (!table) {
    // Said before the fit (minutes on a small machine), so a first render does not look hung.
    log(GLIMMER_LOG_INFO, "frosted_glass: fitting the SG transmission table once" +
                              (use_cache ? " (cached as " + path + ")" : std::string(" (no cache folder)")) +
                              "; this takes minutes");
    const auto t0 = std::chrono::steady_clock::now();
    table = std::make_unique<TransmissionSgTable>();
    char msg[160];
    std::snprintf(msg, sizeof(msg), "frosted_glass: built the SG transmission table (%zu lobes) in %.1f s",
                  table->nodes_.size(), std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    log(GLIMMER_LOG_INFO, msg);
    if (use_cache)
      if (const std::string problem = table->save(path); !problem.empty())
        log(GLIMMER_LOG_WARNING, "frosted_glass: SG table cache not written: " + problem);
  }
  return *table;
}

namespace {

// Catmull-Rom weights of the 4 nodes around c on each axis (indices clamped at the ends). The first
// coordinate starts at normal incidence, where the lobe is symmetric: node -1 is node 1 mirrored (the energy
// and sharpness are even in theta_i, the axis offset odd), instead of a clamped node that puts a false slope
// into the first interval.
using Taps = TransmissionSgTable::Taps;
Taps catmull_rom_taps(float c, int nodes, bool mirror_at_zero) {
  const int i0 = std::clamp(int(std::floor(c)), 0, nodes - 2);
  const float t = std::clamp(c - float(i0), 0.0f, 1.0f), t2 = t * t, t3 = t2 * t;
  Taps k;
  const float w[4] = {0.5f * (-t3 + 2 * t2 - t), 0.5f * (3 * t3 - 5 * t2 + 2), 0.5f * (-3 * t3 + 4 * t2 + t),
                      0.5f * (t3 - t2)};
  for (int n = 0; n < 4; ++n) {
    const int i = i0 - 1 + n;
    const bool mirrored = mirror_at_zero && i < 0;
    k.index[n] = mirrored ? -i : std::clamp(i, 0, nodes - 1);
    k.weight[n] = w[n];
    k.parity[n] = mirrored ? -1.0f : 1.0f;
  }
  return k;
}

// lookup()'s continuous grid coordinates (lookup_energies uses the same): the roughness and IOR axes, and the
// first axis (entering: theta; leaving: the Snell sine).
using Table = TransmissionSgTable;
bool in_grid(float ior, float roughness) {
  return ior >= Table::kIorMin && ior <= Table::kIorMax && roughness >= Table::kRoughnessMin && roughness <= 1.0f;
}
float roughness_coordinate(float roughness) {
  return (1.0f - std::log(roughness) / std::log(Table::kRoughnessMin)) * (Table::kRoughnessNodes - 1);
}
float ior_coordinate(float ior) { return (ior - Table::kIorMin) / (Table::kIorMax - Table::kIorMin) * (Table::kIorNodes - 1); }
float first_coordinate(float theta, int side, float ior) {
  return side == 0 ? float((1.0 - std::sqrt(std::max(0.0, 1.0 - theta / theta_max()))) * (Table::kThetaNodes - 1))
                   : sine_coordinate(theta, ior);
}

}  // namespace

namespace {
// axes() and first_taps() inlined into the lookups (out of line they cost lookup() 366 -> 381 instructions per call
// on the caustic scene's sg render).
[[gnu::always_inline]] inline Table::Axes make_axes(float eta, float roughness) {
  Table::Axes ax;
  ax.eta = eta;
  ax.ior = eta >= 1.0f ? eta : 1.0f / eta;
  ax.side = eta >= 1.0f ? 0 : 1;
  ax.in_grid = in_grid(ax.ior, roughness);
  if (ax.in_grid) {
    ax.b = catmull_rom_taps(roughness_coordinate(roughness), Table::kRoughnessNodes, false);
    ax.c = catmull_rom_taps(ior_coordinate(ax.ior), Table::kIorNodes, false);
  }
  return ax;
}
[[gnu::always_inline]] inline bool make_first_taps(float cos_theta_i, const Table::Axes &ax, Taps &a) {
  if (!ax.in_grid) return false;
  const float theta = std::acos(std::clamp(cos_theta_i, 0.0f, 1.0f));
  if (!(theta <= float(Table::kThetaMaxDeg * kDegToRad))) return false;
  a = catmull_rom_taps(first_coordinate(theta, ax.side, ax.ior), ax.side == 0 ? Table::kThetaNodes : Table::kSineNodes,
                       true);
  return true;
}
}  // namespace

TransmissionSgTable::Axes TransmissionSgTable::axes(float eta, float roughness) { return make_axes(eta, roughness); }

bool TransmissionSgTable::first_taps(float cos_theta_i, const Axes &ax, Taps &a) {
  return make_first_taps(cos_theta_i, ax, a);
}

bool TransmissionSgTable::lookup(float cos_theta_i, float eta, float roughness, TransmissionLobe &out) const {
  return lookup(cos_theta_i, make_axes(eta, roughness), out);
}

bool TransmissionSgTable::lookup(float cos_theta_i, const Axes &ax, TransmissionLobe &out) const {
  Taps a;
  if (!make_first_taps(cos_theta_i, ax, a)) return false;
  const int side = ax.side;
  const Taps &b = ax.b, &c = ax.c;
  // The 64 taps, in x, y, z order, each summed into (ln(E + floor), ln kappa, axis offset) as one 4-lane product
  // and sum (lookup_nodes_): lane by lane the same float operations in the same order as the scalar sums
  //   energy += w * ln(E + floor), log_sharpness += w * ln kappa, axis_offset += (w * parity) * offset,
  //   w = (a.weight[x] * b.weight[y]) * c.weight[z]
  // (packed single-precision multiplies and adds round as the scalar ones: the same bits,
  // FrostedSgTable.LookupIsTheScalarTapSumBitForBit).
  // Per x, the IOR weights with the axis lane's parity folded in: (w_xy c_z) parity = w_xy (c_z parity) exactly
  // (parity is +-1). The IOR taps are 4 consecutive nodes except at the grid's ends (clamped indices): then fixed
  // offsets from the row.
  size_t b_offset[4];
  for (int y = 0; y < 4; ++y) b_offset[y] = size_t(b.index[y]) * kIorNodes + size_t(c.index[0]);
  const auto sum_taps = [&](auto contiguous) {
    size_t c_offset[4];
    for (int z = 0; z < 4; ++z) c_offset[z] = size_t(c.index[z] - c.index[0]);
    __m128 acc = _mm_setzero_ps();
    for (int x = 0; x < 4; ++x) {
      const float p = a.parity[x];
      const __m128 cw[4] = {_mm_setr_ps(c.weight[0], c.weight[0], c.weight[0] * p, c.weight[0]),
                            _mm_setr_ps(c.weight[1], c.weight[1], c.weight[1] * p, c.weight[1]),
                            _mm_setr_ps(c.weight[2], c.weight[2], c.weight[2] * p, c.weight[2]),
                            _mm_setr_ps(c.weight[3], c.weight[3], c.weight[3] * p, c.weight[3])};
      const std::array<float, 4> *plane = &lookup_nodes_[index(side, a.index[x], 0, 0)];
      for (int y = 0; y < 4; ++y) {
        const __m128 wxy = _mm_set1_ps(a.weight[x] * b.weight[y]);
        const std::array<float, 4> *row = plane + b_offset[y];
        for (int z = 0; z < 4; ++z) {
          const size_t at = decltype(contiguous)::value ? size_t(z) : c_offset[z];
          acc = _mm_add_ps(acc, _mm_mul_ps(_mm_mul_ps(wxy, cw[z]), _mm_loadu_ps(row[at].data())));
        }
      }
    }
    return acc;
  };
  const bool c_contiguous = c.index[1] == c.index[0] + 1 && c.index[2] == c.index[0] + 2 && c.index[3] == c.index[0] + 3;
  const __m128 acc = c_contiguous ? sum_taps(std::true_type{}) : sum_taps(std::false_type{});
  alignas(16) float sum[4];
  _mm_store_ps(sum, acc);
  TransmissionLobe lobe;
  lobe.energy = std::max(std::exp(sum[0]) - kEnergyFloor, 0.0f);  // interpolated ln(E + floor) -> E
  lobe.log_sharpness = sum[1];
  lobe.axis_offset = sum[2];
  out = lobe;
  return true;
}

bool TransmissionSgTable::lookup_scalar(float cos_theta_i, float eta, float roughness, TransmissionLobe &out) const {
  const Axes ax = make_axes(eta, roughness);
  Taps a;
  if (!make_first_taps(cos_theta_i, ax, a)) return false;
  const int side = ax.side;
  const Taps &b = ax.b, &c = ax.c;
  TransmissionLobe acc;
  for (int x = 0; x < 4; ++x)
    for (int y = 0; y < 4; ++y)
      for (int z = 0; z < 4; ++z) {
        const float w = a.weight[x] * b.weight[y] * c.weight[z];
        const TransmissionLobe &n = node(side, a.index[x], b.index[y], c.index[z]);
        acc.energy += w * log_energy_[index(side, a.index[x], b.index[y], c.index[z])];
        acc.log_sharpness += w * n.log_sharpness;
        acc.axis_offset += w * a.parity[x] * n.axis_offset;
      }
  acc.energy = std::max(std::exp(acc.energy) - kEnergyFloor, 0.0f);  // interpolated ln(E + floor) -> E
  out = acc;
  return true;
}

void TransmissionSgTable::lookup_energies(const float *cos_theta_i, int n, float eta, float roughness, float *energy,
                                          bool *valid) const {
  lookup_energies(cos_theta_i, n, make_axes(eta, roughness), energy, valid);
}

void TransmissionSgTable::lookup_energies(const float *cos_theta_i, int n, const Axes &ax, float *energy,
                                          bool *valid) const {
  n = std::clamp(n, 0, kMaxEnergyBatch);
  for (int i = 0; i < n; ++i) valid[i] = false, energy[i] = 0.0f;
  if (!ax.in_grid) return;
  const int side = ax.side;
  const Taps &b = ax.b, &c = ax.c;
  const __m128 c_weight = _mm_setr_ps(c.weight[0], c.weight[1], c.weight[2], c.weight[3]);
  // The IOR taps are 4 consecutive nodes except at the grid's ends (clamped indices).
  const bool c_contiguous =
      c.index[1] == c.index[0] + 1 && c.index[2] == c.index[0] + 2 && c.index[3] == c.index[0] + 3;
  size_t b_offset[4];  // from a first-coordinate plane to the row's first IOR tap
  for (int y = 0; y < 4; ++y) b_offset[y] = size_t(b.index[y]) * kIorNodes + size_t(c.index[0]);
  size_t c_offset[4];
  for (int z = 0; z < 4; ++z) c_offset[z] = size_t(c.index[z] - c.index[0]);
  // One incidence's sum: the same sums in the same order as lookup()'s energy lane,
  // e += ((a.weight[x] * b.weight[y]) * c.weight[z]) x ln(E + floor) tap by tap; a row's 4 products made as one
  // 4-lane product (the same roundings), then added in z order.
  const auto energy_sum = [&](const Taps &a, auto contiguous) {
    float e = 0.0f;
    for (int x = 0; x < 4; ++x) {
      const float *plane = &log_energy_[index(side, a.index[x], 0, 0)];
      for (int y = 0; y < 4; ++y) {
        const float *row = plane + b_offset[y];
        const __m128 values = decltype(contiguous)::value
                                  ? _mm_loadu_ps(row)
                                  : _mm_setr_ps(row[c_offset[0]], row[c_offset[1]], row[c_offset[2]], row[c_offset[3]]);
        const __m128 p = _mm_mul_ps(_mm_mul_ps(_mm_set1_ps(a.weight[x] * b.weight[y]), c_weight), values);
        e += _mm_cvtss_f32(p);
        e += _mm_cvtss_f32(_mm_shuffle_ps(p, p, _MM_SHUFFLE(1, 1, 1, 1)));
        e += _mm_cvtss_f32(_mm_movehl_ps(p, p));
        e += _mm_cvtss_f32(_mm_shuffle_ps(p, p, _MM_SHUFFLE(3, 3, 3, 3)));
      }
    }
    return e;
  };
  for (int i = 0; i < n; ++i) {
    Taps a;
    if (!make_first_taps(cos_theta_i[i], ax, a)) continue;
    const float e = c_contiguous ? energy_sum(a, std::true_type{}) : energy_sum(a, std::false_type{});
    energy[i] = std::max(std::exp(e) - kEnergyFloor, 0.0f);
    valid[i] = true;
  }
}

}  // namespace glimmer::plugin::frosted
