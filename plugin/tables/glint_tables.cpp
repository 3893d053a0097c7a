// Directional probability tables of the separable glint model; see glint_tables.h.
#include "tables/glint_tables.h"

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <thread>

#include "glimmer/cache_blob.h"
#include "glimmer/microfacet.h"
#include "tables/checked_stamp.h"

namespace glimmer::plugin::glint {
namespace {

constexpr double kPiD = 3.14159265358979323846;
constexpr double kDeg = kPiD / 180.0;
constexpr uint32_t kFormatVersion = 7;  // 2: LOD levels normalised by their W-weighted energy; 3: HMAC-SHA256;
                                        // 4: P_gamma by a direct cone rule, 0.5-degree energy grid,
                                        //    level 0 <= the smooth albedo (+0.1 %);
                                        // 5: the rim rule where the interior rule would exceed its points;
                                        // 6: the factored level 0's slice scales (FactoredLevel0);
                                        // 7: the same over every theta_o (kMaxThetaODeg 85 -> 90). The scales
                                        //    depend on FactoredLevel0's constants and lobe: a change of them
                                        //    needs a new version (and the energy check recomputes them)
constexpr char kMagic[8] = {'G', 'L', 'M', 'G', 'L', 'N', 'T', 'P'};

struct D3 {
  double x, y, z;
};
inline D3 operator+(D3 a, D3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline D3 operator*(D3 a, double s) { return {a.x * s, a.y * s, a.z * s}; }
inline double sq(double v) { return v * v; }
inline double dot3(D3 a, D3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline D3 cross3(D3 a, D3 b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }
inline D3 normalized(D3 a) {
  const double l = std::sqrt(dot3(a, a));
  return l > 0 ? a * (1.0 / l) : D3{0, 0, 1};
}
inline D3 spherical(double theta, double phi) {
  return {std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
}

// Equation (1): density of the reflected direction r for particle normals
// distributed as D(m) cos(theta_m).
inline double reflected_density(const NdfFunction &ndf, D3 wi, D3 r) {
  const D3 s = wi + r;
  const double len = std::sqrt(dot3(s, s));
  if (!(len > 1e-9)) return 0.0;
  const D3 h = s * (1.0 / len);
  const double wi_h = dot3(wi, h);
  if (!(h.z > 0.0) || !(wi_h > 0.0)) return 0.0;
  return ndf(h.z) * h.z / (4.0 * wi_h);
}

// Tangent frame around a unit direction c.
inline void tangent_frame(D3 c, D3 &e1, D3 &e2) {
  const D3 a = std::fabs(c.z) < 0.9 ? D3{0, 0, 1} : D3{1, 0, 0};
  e1 = normalized(cross3(a, c));
  e2 = cross3(c, e1);
}
inline D3 cone_point(D3 c, D3 e1, D3 e2, double rho, double phi) {
  return c * std::cos(rho) + (e1 * std::cos(phi) + e2 * std::sin(phi)) * std::sin(rho);
}

inline double cone_solid_angle_d(double gamma_rad) { return 2.0 * kPiD * (1.0 - std::cos(gamma_rad)); }

// Gauss-Legendre nodes and weights on [-1, 1] (Newton on P_n from the
// Chebyshev-like first guess cos(pi (k - 1/4) / (n + 1/2))).
struct GaussLegendre {
  std::vector<double> x, w;
  explicit GaussLegendre(int n) : x(n), w(n) {
    for (int k = 0; k < n; ++k) {
      double z = std::cos(kPiD * (k + 0.75) / (n + 0.5)), dp = 1.0;
      for (int it = 0; it < 100; ++it) {
        double p_prev = 1.0, p = z;  // P_0, P_1, then the three-term recurrence up to P_n (n >= 2)
        for (int j = 2; j <= n; ++j) {
          const double p_next = ((2.0 * j - 1.0) * z * p - (j - 1.0) * p_prev) / j;
          p_prev = p;
          p = p_next;
        }
        dp = n * (z * p - p_prev) / (z * z - 1.0);
        const double dz = p / dp;
        z -= dz;
        if (std::fabs(dz) < 1e-15) break;
      }
      x[k] = z;
      w[k] = 2.0 / ((1.0 - z * z) * dp * dp);
    }
  }
};

// Steps 1-2: P_gamma(wi, wo) = Int_cone(wo, gamma) q(wi, r) dr, equation (1),
// by a product rule on the cone. Cone points are the exponential map of the
// disk of radius gamma in the tangent plane of wo, (x, y) = gamma (u,
// s sqrt(1 - u^2)), dr = sin(rho) / rho dx dy = gamma^2 sqrt(1 - u^2) du ds
// (sin(rho) / rho): Gauss-Chebyshev of the second kind in u (its weight is
// the chord sqrt(1 - u^2), so the disk's edge costs no accuracy) and
// Gauss-Legendre in s. x runs across the plane of (wi, wo), where q varies on
// the scale 2 alpha (wi.h) (the half-vector map divides a displacement of r
// across that plane by 2 wi.h, and D varies on the scale alpha), y along it
// (scale 2 alpha); each axis gets kPointsPerScale points per such scale,
// kMinPoints..kMaxPoints. (Before: P at gamma = 1 degree by a 7-point rule,
// then summed over a grid of 1-degree cones covering the gamma cone; that
// adds the 1-degree cone's spread to the gamma cone's, and the glint mean at
// the peak was 2.7..6.9 % low at roughness 0.2.)
class ConeQuadrature {
 public:
  static constexpr double kPointsPerScale = 3.0;
  static constexpr int kMinPoints = 4, kMaxPoints = 24;

  ConeQuadrature(double gamma_rad, double alpha) : gamma_(gamma_rad), alpha_(alpha) {
    for (int n = kMinPoints; n <= kMaxPoints; ++n) legendre_.emplace_back(n);
  }

  // False where the lobe is too narrow for the rule at (wi, wo): an axis
  // would need more than kMaxPoints (the rim rule is used there).
  bool resolves(D3 wi, D3 wo) const {
    return needed_points(across_scales(wi, wo)) <= kMaxPoints && needed_points(along_scales()) <= kMaxPoints;
  }

  double operator()(const NdfFunction &ndf, D3 wi, D3 wo) const {
    D3 across = cross3(wi, wo);
    if (!(dot3(across, across) > 1e-20)) {  // wi and wo collinear: any frame
      D3 e2;
      tangent_frame(wo, across, e2);
    }
    const D3 ex = normalized(across), ey = cross3(wo, ex);
    const int n_x = points(across_scales(wi, wo));
    const GaussLegendre &rule_y = legendre_[static_cast<size_t>(points(along_scales()) - kMinPoints)];
    double sum = 0.0;
    for (int k = 1; k <= n_x; ++k) {  // Gauss-Chebyshev (second kind) node u = cos(k pi / (n + 1))
      const double angle = k * kPiD / (n_x + 1);
      const double u = std::cos(angle), chord = std::sin(angle);
      const double x = gamma_ * u;
      double row = 0.0;
      for (size_t b = 0; b < rule_y.x.size(); ++b) {
        const double y = gamma_ * chord * rule_y.x[b];
        const double rho = std::sqrt(x * x + y * y);
        const double sinc = rho > 1e-12 ? std::sin(rho) / rho : 1.0;
        const D3 r = wo * std::cos(rho) + (ex * x + ey * y) * sinc;
        row += rule_y.w[b] * sinc * reflected_density(ndf, wi, r);
      }
      sum += chord * chord * row;  // weight pi / (n + 1) sin^2, applied below
    }
    return sum * gamma_ * gamma_ * kPiD / (n_x + 1);
  }

 private:
  // Lobe scales across the cone's diameter: 2 alpha (wi.h) across the plane of (wi, wo), 2 alpha along it.
  double across_scales(D3 wi, D3 wo) const {
    const D3 s = wi + wo;
    const double len = std::sqrt(dot3(s, s));
    const double wi_h = len > 1e-9 ? std::max(dot3(wi, s) / len, 0.0) : 0.0;
    return 2.0 * gamma_ / (2.0 * alpha_ * std::max(wi_h, 1e-3));
  }
  double along_scales() const { return 2.0 * gamma_ / (2.0 * alpha_); }
  static int needed_points(double scales) { return static_cast<int>(std::ceil(kPointsPerScale * scales)); }
  static int points(double scales) { return std::clamp(needed_points(scales), kMinPoints, kMaxPoints); }
  double gamma_, alpha_;
  std::vector<GaussLegendre> legendre_;
};

// P_gamma where the lobe is too narrow for the interior rule below
// (ConeQuadrature::resolves: an axis would need more than its 24 points, e.g.
// roughness 0.15 at gamma 5 degrees near grazing, where that rule was off by
// -10..+6 %), by the cone's boundary instead of its interior. The
// half-vector map h = normalize(wi + r) takes the cone onto a region R of
// half vectors, and D(h) cos(theta_h) dh is the slope distribution P22(s) ds
// (s = tan(theta_h) (cos phi_h, sin phi_h)), radially symmetric for an
// isotropic D with the closed-form radial CDF C(rho) = Pr[|s| <= rho]:
// GGX rho^2 / (alpha^2 + rho^2), Beckmann 1 - exp(-rho^2 / alpha^2). By
// Green's theorem in polar coordinates, Int_R P22 ds = (1 / 2 pi) Loop C(rho)
// dphi over the boundary of R, the image of the cone's rim r(psi). With
// (x, y, z) = wi + r(psi) (h unnormalised), dphi = (x y' - y x') / (x^2 + y^2)
// dpsi and rho^2 = (x^2 + y^2) / z^2, the integrand is
//   g(rho) (x y' - y x') / z^2,  g = C / rho^2 (GGX 1 / (alpha^2 + rho^2)),
// smooth even where the rim passes through the normal, and periodic in psi:
// the trapezoid rule converges geometrically once its points resolve g, which
// varies on the scale alpha in slope, i.e. alpha / |ds/dpsi| in psi. The
// interior rule (ConeQuadrature) needs points on the lobe's scale over the
// whole cone and capped at 24 per axis; this one only along the rim.
// Returns -1 when the rim's half vectors leave the upper hemisphere (then R
// is not a region of slopes; the caller uses the interior rule).
double slope_cdf_over_rho2(BaseDistribution dist, double alpha, double rho2) {
  const double a2 = alpha * alpha;
  if (dist == BaseDistribution::GGX) return 1.0 / (a2 + rho2);
  return rho2 > 1e-12 * a2 ? -std::expm1(-rho2 / a2) / rho2 : (1.0 - 0.5 * rho2 / a2) / a2;
}
double cone_probability_by_rim(BaseDistribution dist, double alpha, double gamma_rad, D3 wi, D3 wo) {
  D3 e1, e2;
  tangent_frame(wo, e1, e2);
  const double sin_g = std::sin(gamma_rad), cos_g = std::cos(gamma_rad);
  auto rim = [&](double psi) { return wi + wo * cos_g + (e1 * std::cos(psi) + e2 * std::sin(psi)) * sin_g; };
  // Points: g varies on the slope scale max(alpha, rho) (1 / (alpha^2 + rho^2)
  // for GGX), and the rim's image moves in slope at |ds/dpsi| <= |dp| (1 / z
  // + |p| / z^2) <= sin(gamma) (1 + 2 / z) / z (|dp/dpsi| = sin(gamma), |p| <= 2):
  // 8 points per that scale, with rho bounded below from a coarse pass.
  constexpr int kCoarse = 64;
  double z_min = 1e30, rho_min = 1e30;
  for (int k = 0; k < kCoarse; ++k) {
    const D3 p = rim(2.0 * kPiD * k / kCoarse);
    z_min = std::min(z_min, p.z);
    if (p.z > 0.0) rho_min = std::min(rho_min, std::sqrt(p.x * p.x + p.y * p.y) / p.z);
  }
  if (!(z_min > 0.05)) return -1.0;
  const double speed = sin_g * (1.0 + 2.0 / z_min) / z_min;
  const double scale = std::max(alpha, rho_min - speed * kPiD / kCoarse);  // rho within half a coarse step
  const int n = std::clamp(static_cast<int>(std::ceil(8.0 * 2.0 * kPiD * speed / scale)), kCoarse, 1 << 16);
  double sum = 0.0;
  for (int k = 0; k < n; ++k) {
    const double psi = 2.0 * kPiD * k / n;
    const D3 p = rim(psi);                                                    // wi + r(psi)
    const D3 dp = (e1 * -std::sin(psi) + e2 * std::cos(psi)) * sin_g;         // d/dpsi
    if (!(p.z > 0.0)) return -1.0;
    const double rho2 = (p.x * p.x + p.y * p.y) / (p.z * p.z);
    sum += slope_cdf_over_rho2(dist, alpha, rho2) * (p.x * dp.y - p.y * dp.x) / (p.z * p.z);
  }
  return std::fabs(sum / n);  // (1 / 2 pi) * (2 pi / n) * sum; the map may reverse the rim's orientation
}

template <typename Fn>
void parallel_for(int count, int threads, Fn fn) {
  threads = std::max(1, std::min(threads, count));
  if (threads == 1) {
    for (int i = 0; i < count; ++i) fn(i);
    return;
  }
  std::atomic<int> next{0};
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t)
    pool.emplace_back([&] {
      for (int i = next++; i < count; i = next++) fn(i);
    });
  for (auto &th : pool) th.join();
}

LodLevel make_level(int level, int n_theta_i_unused = kThetaICount) {
  (void)n_theta_i_unused;
  LodLevel l;
  l.sigma_deg = kLodSigmaDeg[level];
  l.set_step(kLodStepDeg[level]);
  l.values.assign(static_cast<size_t>(kThetaICount) * l.n_theta_o * l.n_phi, 0.0f);
  return l;
}

// Step 4 (energy): the W-weighted reflected energy of one theta_i slice of a
// level, E = Int W(wi, wo) P(wo) dwo (F = 1), by the midpoint rule on a
// 0.5-degree (theta_o, dphi) grid through the level's own trilinear lookup
// (what eval sees). `weight` holds W on that grid (weight_grid). (A 1-degree
// grid, used before, is 0.4 % off for a roughness-0.2 lobe, which the blurred
// levels then inherited; 0.5 degrees is within ~0.15 % of a 0.1-degree grid.)
constexpr int kEnergyCellsPerDegree = 2;
constexpr int kEnergyTheta = 90 * kEnergyCellsPerDegree, kEnergyPhi = 180 * kEnergyCellsPerDegree;
constexpr double kEnergyStepDeg = 1.0 / kEnergyCellsPerDegree;
// Relative accuracy of the level-0 energy on that grid: level 0 is capped at
// the smooth albedo times 1 + this (step 4).
constexpr double kEnergyResolution = 1e-3;
double slice_energy(const LodLevel &level, int ti, const std::vector<double> &weight) {
  double sum = 0.0;
  for (int t = 0; t < kEnergyTheta; ++t)
    for (int p = 0; p < kEnergyPhi; ++p)
      sum += weight[static_cast<size_t>(t) * kEnergyPhi + p] *
             level.lookup_exact(static_cast<float>(ti), static_cast<float>((t + 0.5) * kEnergyStepDeg),
                                static_cast<float>((p + 0.5) * kEnergyStepDeg));
  return sum;
}

// W(wi, wo) sin(theta_o) dtheta dphi (x 2 for the folded half) on the energy
// grid, W = G2 (wi.h) / (cos_i cos_h) as glint_weight (tables/glint_common.h).
std::vector<double> weight_grid(const TableSpec &spec, int ti) {
  const microfacet::Distribution dist =
      spec.distribution == BaseDistribution::GGX ? microfacet::Distribution::GGX : microfacet::Distribution::Beckmann;
  std::vector<double> w(static_cast<size_t>(kEnergyTheta) * kEnergyPhi, 0.0);
  const D3 wi_d = spherical(ti * kDeg, 0.0);
  const Vec3 wi(static_cast<float>(wi_d.x), static_cast<float>(wi_d.y), static_cast<float>(wi_d.z));
  if (!(wi.z > 0.0f)) return w;
  for (int t = 0; t < kEnergyTheta; ++t)
    for (int p = 0; p < kEnergyPhi; ++p) {
      const D3 wo_d = spherical((t + 0.5) * kEnergyStepDeg * kDeg, (p + 0.5) * kEnergyStepDeg * kDeg);
      const Vec3 wo(static_cast<float>(wo_d.x), static_cast<float>(wo_d.y), static_cast<float>(wo_d.z));
      Vec3 h;
      if (!microfacet::half_vector_reflect(wi, wo, h)) continue;
      const float wi_h = dot(wi, h);
      if (!(wi_h > 0.0f) || !(h.z > 0.0f)) continue;
      const double g2 = microfacet::G2(dist, wi, wo, spec.alpha, spec.alpha);
      w[static_cast<size_t>(t) * kEnergyPhi + p] =
          2.0 * g2 * wi_h / (wi.z * h.z) * std::sin((t + 0.5) * kEnergyStepDeg * kDeg) * sq(kEnergyStepDeg * kDeg);
    }
  return w;
}

// The smooth microfacet albedo Int F G2 D / (4 cos_i) dwo (F = 1) at theta_i:
// the smooth model's white furnace, which level 0 must not exceed (step 4).
// Over visible normals h ~ D_wi (Heitz 2014), f cos dwo = G2 / G1(wi) dD_wi
// where wo = reflect(wi, h) is above the horizon: a bounded integrand,
// integrated by the midpoint rule on the sampler's unit square (the horizon
// cut is the only discontinuity; 256^2 points resolve it to ~1e-4, where a
// 1-degree grid over wo is 2 % low at 89 degrees).
double smooth_albedo(const TableSpec &spec, int ti) {
  constexpr int kSide = 256;
  const microfacet::Distribution dist =
      spec.distribution == BaseDistribution::GGX ? microfacet::Distribution::GGX : microfacet::Distribution::Beckmann;
  const D3 wi_d = spherical(ti * kDeg, 0.0);
  const Vec3 wi(static_cast<float>(wi_d.x), static_cast<float>(wi_d.y), static_cast<float>(wi_d.z));
  if (!(wi.z > 0.0f)) return 0.0;
  const float g1 = microfacet::G1(dist, wi, spec.alpha, spec.alpha);
  if (!(g1 > 0.0f)) return 0.0;
  double sum = 0.0;
  for (int a = 0; a < kSide; ++a)
    for (int b = 0; b < kSide; ++b) {
      const float u1 = (a + 0.5f) / kSide, u2 = (b + 0.5f) / kSide;
      const Vec3 h = microfacet::sample_visible_normal(dist, wi, spec.alpha, spec.alpha, u1, u2);
      const Vec3 wo = microfacet::reflect_about(wi, h);
      if (wo.z > 0.0f) sum += microfacet::G2(dist, wi, wo, spec.alpha, spec.alpha) / g1;
    }
  return sum / (static_cast<double>(kSide) * kSide);
}

// Energy validation of a table read from disk, after its MAC: per theta_i,
// every LOD level keeps the W-weighted energy of level 0 (step 4 of the build
// scales each level to it, to float rounding), so values edited in some levels
// are caught even with a valid MAC.
bool plausible_energy(const DirectionalTable &table, const TableSpec &spec, int threads, std::string &problem) {
  constexpr double kEnergyTolerance = 1e-4;
  std::vector<int> bad_level(kThetaICount, 0);
  parallel_for(kThetaICount, threads, [&](int ti) {
    const std::vector<double> weight = weight_grid(spec, ti);
    const double level0_energy = slice_energy(table.levels[0], ti, weight);
    for (int l = 1; l < kLodCount && bad_level[ti] == 0; ++l) {
      const double energy = slice_energy(table.levels[l], ti, weight);
      if (!(energy > 0.0) || !(level0_energy > 0.0)) continue;  // left unscaled by the build
      if (std::fabs(energy - level0_energy) > kEnergyTolerance * level0_energy) bad_level[ti] = l;
    }
  });
  for (int ti = 0; ti < kThetaICount; ++ti)
    if (bad_level[ti] != 0) {
      problem = "LOD level " + std::to_string(bad_level[ti]) + " does not keep the energy of level 0 at theta_i " +
                std::to_string(ti);
      return false;
    }
  return true;
}

}  // namespace

namespace {
// A of (1) (glint_factored_level0.h) at the angles of a table node (degrees; wi in the xz plane, wo at azimuth dphi).
double lobe_at_angles(const Level0Lobe &lobe, double theta_i_deg, double theta_o_deg, double dphi_deg) {
  const D3 wi = spherical(theta_i_deg * kDeg, 0.0), wo = spherical(theta_o_deg * kDeg, dphi_deg * kDeg);
  const D3 s = wi + wo;
  const double len = std::sqrt(dot3(s, s));
  if (!(len > 1e-12)) return 0.0;
  return lobe.at(dot3(wi, s) / len, s.z / len);
}
}  // namespace

FactoredLevel0::FactoredLevel0(const LodLevel &level0, const TableSpec &spec, float sigma, bool normalise,
                               const std::vector<double> *scales)
    : lobe_(spec.distribution == BaseDistribution::GGX, spec.alpha, spec.gamma_deg * kDeg, sigma) {
  residual_.set_step(kStepDeg);
  residual_.lane_scale[0] = 1.0f / kStepDeg;  // theta_i at the same step (exact: a power of two)
  residual_.lane_last[0] = kNodesThetaI - 2;
  const size_t slice = static_cast<size_t>(residual_.n_theta_o) * residual_.n_phi;
  residual_.values.resize(kNodesThetaI * slice);
  for (int i = 0; i < kNodesThetaI; ++i)
    for (int o = 0; o < residual_.n_theta_o; ++o)
      for (int p = 0; p < residual_.n_phi; ++p) {
        const int ti = i * kStepDeg, to = o * kStepDeg, dp = p * kStepDeg;
        const double P = level0.values[(static_cast<size_t>(ti) * level0.n_theta_o + to) * level0.n_phi + dp];
        const double A = lobe_at_angles(lobe_, ti, to, dp);
        double r = 0.0;
        if (P > 0.0) r = A > 0.0 ? std::min(P / A, static_cast<double>(kResidualCap)) : kResidualCap;
        residual_.values[(static_cast<size_t>(i) * residual_.n_theta_o + o) * residual_.n_phi + p] =
            static_cast<float>(r);
      }
  if (normalise) {
    if (scales != nullptr && scales->size() == static_cast<size_t>(kNodesThetaI)) {
      scales_ = *scales;  // saved with the table (the same level 0, so the same scales)
    } else {
      scales_.assign(kNodesThetaI, 1.0);
      parallel_for(kNodesThetaI, static_cast<int>(std::max(1u, std::thread::hardware_concurrency())),
                   [&](int i) { scales_[static_cast<size_t>(i)] = slice_scale(level0, spec, i); });
    }
    for (double x : scales_)
      if (!(x > kMinScale && x < kMaxScale)) {  // not a small correction: the factored form is not used (inactive)
        scales_.clear();
        std::vector<float>().swap(residual_.values);  // no halves: active() is false
        return;
      }
    for (int i = 0; i < kNodesThetaI; ++i)
      for (size_t k = 0; k < slice; ++k) residual_.values[i * slice + k] *= static_cast<float>(scales_[i]);
  }
  residual_.pack_halves();
  std::vector<float>().swap(residual_.values);
}

// The factor that gives theta_i slice i of R (node theta_i = 2 i) level 0's W-weighted energy through the lookups
// that read it: E = Int W P dwo on step 4's 0.5-degree grid (weight_grid, slice_energy), P factored where covered
// (every theta_o while kMaxThetaODeg is 90) and level 0's 1-degree lookup elsewhere; returns (E_level0 - E_uncovered) /
// E_factored. Without it the factored slices read up to 0.17 % less energy than level 0 (GGX 0.35 at theta_i 80), which
// the blurred levels, normalised to level 0, then exceeded (Glint.LodBlurConservesEnergyAtEveryIncidence). (A 1-degree
// grid here left +0.055 % at theta_i 0 on the 0.5-degree one: GlintFactoredLevel0.SliceEnergyEqualsTheOneDegreeLevels.)
double FactoredLevel0::slice_scale(const LodLevel &level0, const TableSpec &spec, int i) const {
  const int ti = i * kStepDeg;
  const std::vector<double> weight = weight_grid(spec, ti);
  double e_uncovered = 0.0, e_factored = 0.0;
  for (int t = 0; t < kEnergyTheta; ++t) {
    const double to = (t + 0.5) * kEnergyStepDeg;
    const bool covered = covers(static_cast<float>(ti), static_cast<float>(to));
    for (int p = 0; p < kEnergyPhi; ++p) {
      const double w = weight[static_cast<size_t>(t) * kEnergyPhi + p];
      if (!(w > 0.0)) continue;
      const double dp = (p + 0.5) * kEnergyStepDeg;
      const float fi = static_cast<float>(ti), fo = static_cast<float>(to), fp = static_cast<float>(dp);
      if (covered)
        e_factored += w * lobe_at_angles(lobe_, ti, to, dp) * residual_.lookup_exact(fi, fo, fp);
      else
        e_uncovered += w * level0.lookup_exact(fi, fo, fp);
    }
  }
  const double e_level0 = slice_energy(level0, ti, weight);
  if (!(e_factored > 0.0) || !(e_level0 > e_uncovered)) return 1.0;
  return (e_level0 - e_uncovered) / e_factored;
}

float FactoredLevel0::lookup_angles(float theta_i_deg, float theta_o_deg, float dphi_deg) const {
  const float A = static_cast<float>(lobe_at_angles(lobe_, theta_i_deg, theta_o_deg, dphi_deg));
  return lookup(cell(_mm_setr_ps(theta_i_deg, theta_o_deg, dphi_deg, 0.0f)), A);
}

size_t DirectionalTable::byte_size() const {
  size_t s = 0;
  for (const auto &l : levels) s += l.values.size() * sizeof(float) + l.halves.size() * sizeof(uint16_t);
  return s + factored0.byte_size();
}

namespace {
// x >= 0 (finite, < 2^15) as LodLevel::halves stores it: exponent + 15 in bits 11..15, the 11 high mantissa bits
// below, rounded up (a carry into the exponent is the next power of two); 0 below the smallest normal (2^-14).
uint16_t half_rounded_up(float x) {
  uint32_t bits;
  std::memcpy(&bits, &x, sizeof bits);
  const int e = static_cast<int>(bits >> 23) - 127;
  if (e < -14) return 0;
  const uint32_t h = (static_cast<uint32_t>(e + 15) << 11) | ((bits >> 12) & 0x7ffu);
  return static_cast<uint16_t>(h + ((bits & 0xfffu) != 0));
}
}  // namespace

void LodLevel::pack_halves() {
  float peak = 0.0f;
  for (const float v : values) peak = std::max(peak, v);
  int e = 0;
  if (peak > 0.0f) std::frexp(peak, &e);  // peak < 2^e
  const int k = 15 - e;                   // peak 2^k < 2^15
  halves.resize(values.size());
  // x 2^k in double, then one rounding to float: ldexp's correctly rounded result without a libm call per value
  // (10 % of a warm-cache render's start).
  const double to_scaled = std::ldexp(1.0, k);
  for (size_t i = 0; i < values.size(); ++i)
    halves[i] = half_rounded_up(static_cast<float>(static_cast<double>(values[i]) * to_scaled));
  const float scale = std::ldexp(1.0f, 112 - k);
  for (float &s : half_scale) s = scale;
}

double directional_probability_by_rim(BaseDistribution dist, double alpha, double gamma_deg, double theta_i_deg,
                                      double theta_o_deg, double dphi_deg) {
  return cone_probability_by_rim(dist, alpha, gamma_deg * kDeg, spherical(theta_i_deg * kDeg, 0.0),
                                 spherical(theta_o_deg * kDeg, dphi_deg * kDeg));
}

double directional_probability_reference(const NdfFunction &ndf, double gamma_deg, double theta_i_deg,
                                         double theta_o_deg, double dphi_deg, int rings) {
  const D3 wi = spherical(theta_i_deg * kDeg, 0.0);
  const D3 wo = spherical(theta_o_deg * kDeg, dphi_deg * kDeg);
  D3 e1, e2;
  tangent_frame(wo, e1, e2);
  const double cos_g = std::cos(gamma_deg * kDeg);
  const int n_phi = 4 * rings;
  double sum = 0.0;
  for (int r = 0; r < rings; ++r) {  // rings of equal solid angle (uniform in cos rho)
    const double cos_rho = 1.0 - (r + 0.5) / rings * (1.0 - cos_g);
    const double rho = std::acos(cos_rho);
    for (int p = 0; p < n_phi; ++p)
      sum += reflected_density(ndf, wi, cone_point(wo, e1, e2, rho, (p + 0.5 * (r & 1)) * 2.0 * kPiD / n_phi));
  }
  return sum / (rings * n_phi) * cone_solid_angle_d(gamma_deg * kDeg);
}

namespace {
constexpr int kDirN = 91, kDirP = 181;  // the 1-degree base grid: theta_o 0..90, dphi 0..180
constexpr size_t kDirSliceSize = static_cast<size_t>(kDirN) * kDirP;

// Steps 1-2: P_gamma on the 1-degree grid, each node by the cone rule.
std::vector<double> cone_probability_grid(const TableSpec &spec, const NdfFunction &ndf, int threads) {
  const ConeQuadrature cone(static_cast<double>(spec.gamma_deg) * kDeg, static_cast<double>(spec.alpha));
  std::vector<double> pg(static_cast<size_t>(kThetaICount) * kDirSliceSize);
  parallel_for(kThetaICount, threads, [&](int ti) {
    const D3 wi = spherical(ti * kDeg, 0.0);
    for (int to = 0; to < kDirN; ++to)
      for (int p = 0; p < kDirP; ++p) {
        const D3 wo = spherical(to * kDeg, p * kDeg);
        const double rim = cone.resolves(wi, wo)
                               ? -1.0
                               : cone_probability_by_rim(spec.distribution, spec.alpha, spec.gamma_deg * kDeg, wi, wo);
        pg[ti * kDirSliceSize + static_cast<size_t>(to) * kDirP + p] = rim >= 0.0 ? rim : cone(ndf, wi, wo);
      }
  });
  return pg;
}

// Step 3 for one theta_i slice and one level l >= 1: P_gamma blurred by a Gaussian of sigma_L over wo, separably on
// the sphere with 1-degree taps (theta: through the pole, zero below the horizon; phi: sigma_L / sin(theta),
// periodic). kernel and pass1 are the caller's scratch.
void blur_slice(const double *slice, int ti, LodLevel &level, std::vector<double> &kernel, std::vector<double> &pass1) {
  auto src = [&](int t, int p) -> double {  // integer-degree sample with the sphere's topology
    if (t < 0) {
      t = -t;
      p = 180 - p;
    }
    if (t > 90) return 0.0;
    p = ((p % 360) + 360) % 360;
    if (p > 180) p = 360 - p;
    return slice[static_cast<size_t>(t) * kDirP + p];
  };
  const double sigma = level.sigma_deg;
  const int step = level.step_deg;
  // Pass 1 (theta): output theta nodes of this level x all 1-degree dphi nodes.
  const int half = static_cast<int>(std::ceil(std::min(3.0 * sigma, 180.0)));
  kernel.resize(2 * half + 1);
  double norm = 0.0;
  for (int k = -half; k <= half; ++k) norm += kernel[k + half] = std::exp(-0.5 * sq(k / sigma));
  for (auto &w : kernel) w /= norm;
  pass1.assign(static_cast<size_t>(level.n_theta_o) * kDirP, 0.0);
  for (int to = 0; to < level.n_theta_o; ++to)
    for (int p = 0; p < kDirP; ++p) {
      double sum = 0.0;
      for (int k = -half; k <= half; ++k) sum += kernel[k + half] * src(to * step + k, p);
      pass1[static_cast<size_t>(to) * kDirP + p] = sum;
    }
  // Pass 2 (phi): along the parallel, sigma_phi = sigma / sin(theta_o), periodic.
  float *out = level.values.data() + static_cast<size_t>(ti) * level.n_theta_o * level.n_phi;
  for (int to = 0; to < level.n_theta_o; ++to) {
    const double sin_t = std::max(std::sin(to * step * kDeg), std::sin(0.5 * kDeg));
    const double sigma_phi = sigma / sin_t;
    const int half_phi = static_cast<int>(std::ceil(std::min(3.0 * sigma_phi, 180.0)));
    kernel.resize(2 * half_phi + 1);
    double norm_phi = 0.0;
    for (int k = -half_phi; k <= half_phi; ++k) norm_phi += kernel[k + half_phi] = std::exp(-0.5 * sq(k / sigma_phi));
    const double *row = pass1.data() + static_cast<size_t>(to) * kDirP;
    for (int p = 0; p < level.n_phi; ++p) {
      double sum = 0.0;
      for (int k = -half_phi; k <= half_phi; ++k) {
        int q = ((p * step + k) % 360 + 360) % 360;
        if (q > 180) q = 360 - q;
        sum += kernel[k + half_phi] * row[q];
      }
      out[static_cast<size_t>(to) * level.n_phi + p] = static_cast<float>(sum / norm_phi);
    }
  }
}

// Step 4 for one theta_i slice: the blurred lobe weighted by the same W that eval multiplies it with must reflect
// the energy of the unblurred one (blurring P moves probability toward grazing wo, where W is large: without this
// the albedo grew to 2..4.7 at grazing incidence).
// Level 0 first: the cone estimator W(wo) P_gamma(wo) / sigma averages W over the cone (W is convex near the
// horizon) and is read through trilinear lookups, so its albedo can exceed the smooth model's (GGX 0.35: +0.6..1.0 %
// at 86..89 degrees; GGX 0.2: +0.7 % at normal incidence). Where it exceeds it by more than the energy grid resolves
// (kEnergyResolution), level 0 is scaled down to that bound; elsewhere it is left exact.
void normalise_slice_energy(const TableSpec &spec, int ti, DirectionalTable &table) {
  const std::vector<double> weight = weight_grid(spec, ti);
  double target_energy = slice_energy(table.levels[0], ti, weight);
  const double bound = smooth_albedo(spec, ti) * cone_solid_angle_d(spec.gamma_deg * kDeg) * (1.0 + kEnergyResolution);
  if (target_energy > bound && bound > 0.0) {
    const float s = static_cast<float>(bound / target_energy);
    float *out = table.levels[0].values.data() + static_cast<size_t>(ti) * kDirSliceSize;
    for (size_t i = 0; i < kDirSliceSize; ++i) out[i] *= s;
    target_energy = slice_energy(table.levels[0], ti, weight);
  }
  for (int l = 1; l < kLodCount; ++l) {
    LodLevel &level = table.levels[l];
    const double energy = slice_energy(level, ti, weight);
    if (!(energy > 0.0) || !(target_energy > 0.0)) continue;
    const float s = static_cast<float>(target_energy / energy);
    float *out = level.values.data() + static_cast<size_t>(ti) * level.n_theta_o * level.n_phi;
    for (size_t i = 0; i < static_cast<size_t>(level.n_theta_o) * level.n_phi; ++i) out[i] *= s;
  }
}
}  // namespace

std::unique_ptr<DirectionalTable> build_directional_table(const TableSpec &spec, const NdfFunction &ndf,
                                                          int threads) {
  const auto start = std::chrono::steady_clock::now();
  auto table = std::make_unique<DirectionalTable>();
  table->spec = spec;
  const std::vector<double> pg = cone_probability_grid(spec, ndf, threads);  // steps 1-2
  // Step 3: LOD levels. Level 0 is P_gamma itself (the 1-degree base; no blur, so camera rays see the exact lobe up
  // to the horizon). Levels 1..8 are P_gamma blurred (blur_slice), then normalised to the W-weighted energy of
  // P_gamma (step 4, normalise_slice_energy).
  for (int l = 0; l < kLodCount; ++l) table->levels[l] = make_level(l);
  parallel_for(kThetaICount, threads, [&](int ti) {
    const double *slice = pg.data() + ti * kDirSliceSize;
    std::vector<float> fslice(slice, slice + kDirSliceSize);
    std::copy(fslice.begin(), fslice.end(), table->levels[0].values.begin() + ti * kDirSliceSize);
    std::vector<double> kernel, pass1;
    for (int l = 1; l < kLodCount; ++l) blur_slice(slice, ti, table->levels[l], kernel, pass1);
    normalise_slice_energy(spec, ti, *table);
  });
  table->pack_halves();
  table->factor_level0();
  table->build_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return table;
}

uint64_t table_key(const TableSpec &spec) {
  return Fnv1a{}
      .add(kMagic)
      .add(kFormatVersion)
      .add(static_cast<int>(spec.distribution))
      .add(spec.alpha)
      .add(spec.gamma_deg)
      .add(kLodSigmaDeg)
      .add(kLodStepDeg)
      .h;
}

std::string table_cache_path(const std::string &cache_dir, const TableSpec &spec) {
  return cache_entry_path(cache_dir, "glint_P_", table_key(spec));
}

// File: magic, version, key, spec, then per level (n_theta_o, n_phi, values), the factored level 0's slice scales
// (count, doubles; count 0 where it does not apply: its nodes are recomputed from level 0 at load, ~10 ms),
// then HMAC-SHA256 of everything before it, keyed by the cache folder's
// secret (glimmer/cache_key.h).
bool save_table(const std::string &path, const DirectionalTable &table, std::string &problem) {
  ByteWriter out;
  out.put_header(kMagic, kFormatVersion, table_key(table.spec));
  out.put(static_cast<int>(table.spec.distribution));
  out.put(table.spec.alpha);
  out.put(table.spec.gamma_deg);
  for (const auto &l : table.levels) {
    out.put(l.n_theta_o);
    out.put(l.n_phi);
    out.put(l.values.data(), l.values.size() * sizeof(float));
  }
  const std::vector<double> &scales = table.factored0.slice_scales();
  out.put(static_cast<int>(scales.size()));
  out.put(scales.data(), scales.size() * sizeof(double));
  // One private cache folder, a MAC keyed by its secret, one atomic write
  // (random O_EXCL|O_NOFOLLOW temporary, fsync, rename): write_cache_blob.
  problem = write_cache_blob(path, std::move(out.bytes));
  return problem.empty();
}

namespace {
// The energy check's stamp (checked_stamp.h): this build checked these bytes of this spec's entry.
CheckedStampKind energy_stamp_kind(const TableSpec &spec) {
  CheckedStampKind kind{{'G', 'L', 'M', 'G', 'L', 'N', 'T', 'K'}, 2u, table_key(spec)};  // format: checked_stamp.h
  return kind;
}
}  // namespace

std::unique_ptr<DirectionalTable> load_table(const std::string &path, const TableSpec &spec, std::string &problem) {
  return load_table(path, spec, problem, plugin_build_id());
}

std::unique_ptr<DirectionalTable> load_table(const std::string &path, const TableSpec &spec, std::string &problem,
                                             const std::string &build_id) {
  // Junk at the entry path (a directory, a FIFO, a symlink) is removed so the rebuilt table can take its place.
  std::vector<unsigned char> bytes;
  problem = read_cache_file(path, bytes);
  if (!problem.empty()) return nullptr;
  ByteReader in{bytes};
  auto get = [&](void *p, size_t n) { return in.get(p, n); };
  int dist = -1;
  auto table = std::make_unique<DirectionalTable>();
  if (!in.get_header(kMagic, kFormatVersion, table_key(spec)) || !get(&dist, 4) || !get(&table->spec.alpha, 4) ||
      !get(&table->spec.gamma_deg, 4)) {
    problem = "bad header (not a glint table of this version and parameters)";
    return nullptr;
  }
  table->spec.distribution = static_cast<BaseDistribution>(dist);
  if (!(table->spec == spec)) {
    problem = "parameters differ from the requested table";
    return nullptr;
  }
  for (int l = 0; l < kLodCount; ++l) {
    LodLevel expected = make_level(l);
    LodLevel &level = table->levels[l];
    level = expected;
    int n_to = 0, n_phi = 0;
    if (!get(&n_to, 4) || !get(&n_phi, 4) || n_to != expected.n_theta_o || n_phi != expected.n_phi ||
        !get(level.values.data(), level.values.size() * sizeof(float))) {
      problem = "truncated or malformed level " + std::to_string(l);
      return nullptr;
    }
  }
  int n_scales = -1;  // 0: not factored (a narrow lobe, or scales out of range at the build)
  if (!get(&n_scales, 4) || (n_scales != 0 && n_scales != FactoredLevel0::kNodesThetaI) ||
      (n_scales != 0 && !FactoredLevel0::applies(spec))) {
    problem = "malformed factored level 0";
    return nullptr;
  }
  std::vector<double> scales(static_cast<size_t>(n_scales));
  if (n_scales > 0 && !get(scales.data(), scales.size() * sizeof(double))) {
    problem = "truncated factored level 0";
    return nullptr;
  }
  for (double x : scales)
    if (!(x > FactoredLevel0::kMinScale && x < FactoredLevel0::kMaxScale)) {
      problem = "factored level 0's slice scale out of range";
      return nullptr;
    }
  problem = check_cache_mac(path, bytes, in.pos);
  if (!problem.empty()) return nullptr;
  for (const auto &l : table->levels)
    for (float v : l.values)
      if (!std::isfinite(v) || v < 0.0f) {
        problem = "non-finite or negative values";
        return nullptr;
      }
  // The energy check (~1 s of CPU per table, most of a small render's start) once per build and entry bytes. The
  // stamp binds the entry's verified MAC, which binds its bytes (hashing the 14.5 MB again cost ~20 ms per load).
  const std::vector<unsigned char> mac(bytes.end() - static_cast<std::ptrdiff_t>(Digest256{}.size()), bytes.end());
  const CheckedStampKind stamp_kind = energy_stamp_kind(spec);
  table->energy_checked = !checked_stamp_matches(path, stamp_kind, mac, build_id);
  table->pack_halves();
  // The energy check also recomputes the factored level 0's scales (~0.1 s): a file whose scales differ from this
  // build's (edited, or written by code with other FactoredLevel0 constants) is rebuilt.
  table->factor_level0(table->energy_checked ? nullptr : &scales);
  if (table->energy_checked) {
    if (!plausible_energy(*table, spec, static_cast<int>(std::max(1u, std::thread::hardware_concurrency())), problem))
      return nullptr;
    if (table->factored0.slice_scales() != scales) {
      problem = "the factored level 0's slice scales differ from this build's";
      return nullptr;
    }
    table->stamp_not_written = write_checked_stamp(path, stamp_kind, mac, build_id);
  }
  table->loaded_from_cache = true;
  return table;
}

std::shared_ptr<const DirectionalTable> acquire_table(const TableSpec &spec, const NdfFunction &ndf,
                                                      const GlimmerHostServices *host) {
  static std::mutex mutex;
  static std::map<uint64_t, std::weak_ptr<const DirectionalTable>> shared;
  std::lock_guard<std::mutex> lock(mutex);
  const uint64_t key = table_key(spec);
  if (auto it = shared.find(key); it != shared.end())
    if (auto t = it->second.lock(); t && t->spec == spec) return t;

  auto log = [&](int level, const std::string &msg) {
    if (host != nullptr && host->log != nullptr) host->log(host->host_data, level, msg.c_str());
  };
  const bool use_cache = host != nullptr && host->cache_dir != nullptr && host->cache_dir[0] != '\0';
  std::string path;
  std::unique_ptr<DirectionalTable> table;
  if (use_cache) {
    path = table_cache_path(host->cache_dir, spec);
    std::string problem;
    table = load_table(path, spec, problem);
    if (!table && problem != "missing")
      log(GLIMMER_LOG_WARNING, "glint: cached table " + path + " is unusable (" + problem + "); recomputing");
    if (table && !table->stamp_not_written.empty())
      log(GLIMMER_LOG_WARNING, "glint: cannot record the table's energy check beside " + path + " (" +
                                   table->stamp_not_written + "); every start will repeat the check (~1 s of CPU)");
  }
  if (!table) {
    table = build_directional_table(spec, ndf, static_cast<int>(std::max(1u, std::thread::hardware_concurrency())));
    if (use_cache) {
      std::string problem;
      if (!save_table(path, *table, problem)) log(GLIMMER_LOG_WARNING, "glint: table cache not written: " + problem);
    }
    table->release_values();
    char msg[256];
    std::snprintf(msg, sizeof(msg),
                  "glint: precomputed directional table (%s, alpha %.4g, gamma %.3g deg, %.1f MB) in %.3f s",
                  spec.distribution == BaseDistribution::GGX ? "ggx" : "beckmann", spec.alpha, spec.gamma_deg,
                  table->byte_size() / 1048576.0, table->build_seconds);
    log(GLIMMER_LOG_INFO, msg);
  } else {
    table->release_values();
  }
  std::shared_ptr<const DirectionalTable> result(std::move(table));
  shared[key] = result;
  return result;
}

}  // namespace glimmer::plugin::glint
