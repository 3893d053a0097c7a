// Anisotropic base roughness of the glint closure (roughness_u / roughness_v;
// issue 10, docs/glints.md "Anisotropic base roughness"). References are
// computed by brute force here and checked themselves:
//  * P: the brute-force cone mean of the analytic reflected density (ring
//    quadrature, glint_test_util.h), checked against a closed form at
//    wi = wo = N (the anisotropic GGX slope mass of a disk, one smooth
//    periodic 1D integral) and for its own convergence (rings 48 vs 96);
//  * energy: the smooth anisotropic albedo by a visible-normal quadrature,
//    checked against a dense wo grid.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <vector>

#include "closures/closure_checks.h"
#include "closures/glint_statistics.h"
#include "closures/glint_test_util.h"
#include "glimmer/microfacet.h"
#include "glimmer/rng.h"
#include "tables/glint_aniso.h"

namespace glimmer::test {
namespace {

const bool kCacheDirSet = cache_tables_in_build_folder();

constexpr double kDeg = M_PI / 180.0;

namespace gl = plugin::glint;

std::string fmt(double x) {
  char b[32];
  std::snprintf(b, sizeof b, "%.6g", x);
  return b;
}

// A glint with base alphas (ax, ay) given as roughness = sqrt(alpha).
std::shared_ptr<host::ClosureInstance> aniso_glint(const char *dist, double ax, double ay, Params extra = {}) {
  Params p = {{"distribution", dist},
              {"roughness_u", fmt(std::sqrt(ax))},
              {"roughness_v", fmt(std::sqrt(ay))},
              {"gamma", "2"},
              {"density", "1e6"}};
  for (auto &e : extra) p.push_back(e);
  return make_closure("glint", p);
}

GlimmerShadingContext square_context(const Vec3 &wi, double u, double v, double side, float spread = 0.0f) {
  GlimmerShadingContext ctx = footprint_context(wi, u, v, side, 0.0, 0.0, side);
  ctx.spread_angle = spread;
  return ctx;
}

// ---- The brute-force reference, checked -------------------------------------
// Anisotropic GGX at wi = wo = N: the reflection of N is within gamma of N
// iff the half vector is within gamma / 2 of N, i.e. its slope within
// rho = tan(gamma / 2); the slope density 1 / (pi ax ay (1 + s^T A s)^2) has
// the radial integral (1 - 1 / (1 + rho^2 k)) / (2 k pi ax ay), k =
// cos^2 phi / ax^2 + sin^2 phi / ay^2, left: a smooth periodic integral in phi
// (trapezoid rule, converged at 4096 points).
double ggx_disk_mass(double ax, double ay, double gamma_rad) {
  const double rho2 = std::pow(std::tan(0.5 * gamma_rad), 2);
  const int n = 4096;
  double sum = 0.0;
  for (int j = 0; j < n; ++j) {
    const double phi = 2.0 * M_PI * j / n;
    const double k = std::pow(std::cos(phi) / ax, 2) + std::pow(std::sin(phi) / ay, 2);
    sum += (1.0 - 1.0 / (1.0 + rho2 * k)) / (2.0 * k * M_PI * ax * ay);
  }
  return sum * 2.0 * M_PI / n;
}

TEST(GlintAniso, BruteForceConeMeanMatchesClosedFormAndConverges) {
  const Vec3 n(0.0f, 0.0f, 1.0f);
  for (const auto &[ax, ay] : std::vector<std::pair<double, double>>{{0.25, 0.0625}, {0.36, 0.09}, {0.16, 0.0225}})
    for (const double gamma : {1.0, 2.0, 4.0}) {
      const double sigma = 2.0 * M_PI * (1.0 - std::cos(gamma * kDeg));
      const double closed = ggx_disk_mass(ax, ay, gamma * kDeg);
      const double brute = sigma * cone_mean_reflected_density(mf::Distribution::GGX, ax, ay, n, n, gamma, 48);
      EXPECT_NEAR(brute / closed, 1.0, 2e-3) << ax << " x " << ay << " gamma " << gamma;
      // Control: the swapped axes are the same disk mass at N, but a
      // wrong factor 2 (the normal within gamma instead of the reflection) is not.
      EXPECT_GT(std::fabs(ggx_disk_mass(ax, ay, 2.0 * gamma * kDeg) / closed - 1.0), 0.2);
    }
  // Convergence off the normal (48 vs 96 rings) where the tests below use it.
  for (const double theta_i : {40.0, 85.0}) {
    const Vec3 wi = spherical_dir(theta_i, 30.0), wo = spherical_dir(theta_i + 1.0, 212.0);
    const double a = cone_mean_reflected_density(mf::Distribution::GGX, 0.16, 0.0225, wi, wo, 4.0, 48);
    const double b = cone_mean_reflected_density(mf::Distribution::GGX, 0.16, 0.0225, wi, wo, 4.0, 96);
    EXPECT_NEAR(a / b, 1.0, 2e-3) << theta_i;
  }
  // At 85..89 degrees the lobe is 1/35..1/100 of the cone across the plane
  // of incidence: the rings the P test gives it (8 per lobe scale, capped at
  // 1024) against twice as many, at the mirror direction.
  for (const auto &[ax, ay, theta_i, gamma] : std::vector<std::array<double, 4>>{
           {0.16, 0.0225, 85.0, 4.0}, {0.0225, 1.0, 85.0, 4.0}, {0.25, 0.0625, 89.0, 1.0}}) {
    const Vec3 wi = spherical_dir(theta_i, 55.0), wo = spherical_dir(theta_i, 235.0);
    const gl::AnisoConeRules rules(static_cast<float>(gamma * kDeg));
    const int rings = std::clamp(
        static_cast<int>(std::ceil(8.0f * rules.narrowness(static_cast<float>(ax), static_cast<float>(ay), wi, wo))),
        48, 1024);
    const double a = cone_mean_reflected_density(mf::Distribution::GGX, ax, ay, wi, wo, gamma, rings);
    const double b = cone_mean_reflected_density(mf::Distribution::GGX, ax, ay, wi, wo, gamma, 2 * rings);
    EXPECT_GT(a, 0.0);
    EXPECT_NEAR(a / b, 1.0, 2e-3) << ax << " x " << ay << " rings " << rings;  // as the 48 vs 96 check above
  }
}

// ---- P per query vs the brute force over all azimuths -----------------------
// The closure's P / sigma (AnisoConeRules::cone_mean_q: the 7-point rule,
// the 19-point rule or the product rule, by the lobe's width against the
// cone) against the brute-force cone mean (48 rings, 8 per lobe scale where
// the lobe is narrower) over the lobe core (q >= 20 % of its peak on a 9 x 9
// grid of wo around the mirror direction, +-3 lobe widths), wi at 0, 40, 70,
// 85, 89 degrees and 8 azimuths (every 45 degrees + 10: all quadrants of the
// tangent frame), GGX and Beckmann, alpha pairs down to the 0.0225 floor x 1.
// Threshold: 0.5 % everywhere (set from the design note's 7-point figure,
// <= 0.14 % where gamma <= 0.6 alpha_min; 0.65..0.72 % at 0.8 alpha_min,
// before the rule choice was measured). Before the across axis of the product
// rule took up to kProductMaxAcross points (capped at 24 like the other
// axis) those queries were 1.3..38 % off at theta_i 85 and not asserted.
// Negative control: the isotropic stand-in sqrt(ax ay) fails the same
// comparison, its largest error over the lobe core above 10x the tolerance
// (5 %) in every configuration (design note, GGX: 88 % .. 1660 %).
struct RuleError {
  double worst = 0.0, worst_capped = 0.0, control = 0.0;
  int min_points = 1 << 30, max_points = 0, capped = 0, singular = 0, core = 0;
};

// Rings of the brute force: 48, or 8 per lobe scale across the plane of
// incidence where the lobe is narrower (grazing incidence; up to 1024,
// checked for convergence in BruteForceConeMeanMatchesClosedFormAndConverges;
// with 4 per scale the brute force itself was still 0.3..0.5 % off at
// theta_i 85..89).
int brute_rings(const gl::AnisoConeRules &rules, float ax, float ay, const Vec3 &wi, const Vec3 &wo) {
  return std::clamp(static_cast<int>(std::ceil(8.0f * rules.narrowness(ax, ay, wi, wo))), 48, 1024);
}

// The cone around wo contains (or nearly contains) r = -wi, where the half
// vector map is singular (every h with wi.h = 0 reflects wi into -wi; near
// grazing incidence that great circle passes within 90 - theta_i of the
// normal, so the lobe's mass piles up at r = -wi: q ~ 1 / |wi + r|). Only
// at theta_i > 90 - gamma near the mirror direction (89 degrees, gamma >= 2);
// neither the rule nor the ring brute force converges there (both 4..20 %
// apart, the brute force changing by 2..4 % with twice the rings): excluded
// within 1.5 gamma of -wi, counted and printed.
bool near_retro_singularity(const Vec3 &wi, const Vec3 &wo, double gamma_deg) {
  return std::acos(std::clamp(-static_cast<double>(dot(wi, wo)), -1.0, 1.0)) < 1.5 * gamma_deg * kDeg;
}

RuleError rule_error(mf::Distribution dist, double ax, double ay, double gamma_deg) {
  const gl::AnisoConeRules rules(static_cast<float>(gamma_deg * kDeg));
  const float fx = static_cast<float>(ax), fy = static_cast<float>(ay);
  RuleError e;
  const double a_geo = std::sqrt(ax * ay);
  for (const double theta_i : {0.0, 40.0, 70.0, 85.0, 89.0})
    for (int k = 0; k < 8; ++k) {
      const double phi_i = 45.0 * k + 10.0;
      const Vec3 wi = spherical_dir(theta_i, phi_i);
      const double span = 3.0 * 2.0 * std::max(ax, ay) / kDeg;
      struct Row {
        double q, brute, rule, iso;
        int points;
        bool capped;
      };
      std::vector<Row> rows;
      // The lobe's peak is at least q at the mirror direction (with alpha 1 x
      // 0.0225 the grid, spanned by alpha_max, can miss the narrow core: its
      // own largest q was 1e-14 for Beckmann at normal incidence).
      const Vec3 mirror(-wi.x, -wi.y, wi.z);
      double peak = reflected_density(dist, ax, ay, wi, mirror);
      // wo: the 9 x 9 grid and the mirror direction itself.
      std::vector<Vec3> wos = directions_around_mirror(theta_i, phi_i, span, 9, 89.5);
      if (theta_i < 89.5) wos.push_back(mirror);
      for (const Vec3 &wo : wos) {
        const double q = reflected_density(dist, ax, ay, wi, wo);
        if (!(q > 0.0)) continue;
        if (near_retro_singularity(wi, wo, gamma_deg)) {
          ++e.singular;
          continue;
        }
        peak = std::max(peak, q);
        int nx = 0, ny = 0;
        rules.product_points(fx, fy, wi, wo, nx, ny);
        const int points = rules.points(fx, fy, wi, wo);
        const bool capped = points > 19 && (nx == gl::kProductMaxAcross || ny == gl::kProductMaxPoints);
        rows.push_back({q,
                        cone_mean_reflected_density(dist, ax, ay, wi, wo, gamma_deg, brute_rings(rules, fx, fy, wi, wo)),
                        rules.cone_mean_q(dist, fx, fy, wi, wo),
                        cone_mean_reflected_density(dist, a_geo, wi, wo, gamma_deg, 24), points, capped});
      }
      for (const Row &r : rows) {
        if (r.q < 0.2 * peak) continue;
        ++e.core;
        const double err = std::fabs(r.rule / r.brute - 1.0);
        if (r.capped) {
          e.worst_capped = std::max(e.worst_capped, err);
          ++e.capped;
        } else {
          e.worst = std::max(e.worst, err);
        }
        e.min_points = std::min(e.min_points, r.points);
        e.max_points = std::max(e.max_points, r.points);
        e.control = std::max(e.control, std::fabs(r.iso / r.brute - 1.0));
      }
    }
  return e;
}

// 30 cases (both distributions, 5 roughness pairs, gamma 1 / 2 / 4 degrees). `make test` runs 12: the three most
// anisotropic pairs (0.16 x 0.0225 and the 44:1 pairs along either axis) at the narrowest and widest cone, both
// distributions; the *Stress twin (`make stress`) all 30, with the same bounds.
void expect_probability_matches_brute_force(bool full) {
  int run = 0;
  for (const auto dist : {mf::Distribution::GGX, mf::Distribution::Beckmann})
    for (const auto &[ax, ay] : std::vector<std::pair<double, double>>{
             {0.25, 0.0625}, {0.36, 0.09}, {0.16, 0.0225}, {0.0225, 1.0}, {1.0, 0.0225}})
      for (const double gamma : {1.0, 2.0, 4.0}) {
        if (!full && (ax == 0.25 || ax == 0.36 || gamma == 2.0)) continue;
        ++run;
        const RuleError e = rule_error(dist, ax, ay, gamma);
        std::printf("[aniso P] %s alpha %.4f x %.4f gamma %.0f: %d..%d points, max error %.5f; where the product "
                    "rule runs out of points (%d queries) %.4f; isotropic sqrt(ax ay) max error %.3f; %d queries "
                    "near r = -wi skipped; %d core queries\n",
                    dist == mf::Distribution::GGX ? "ggx" : "beckmann", ax, ay, gamma, e.min_points, e.max_points,
                    e.worst, e.capped, e.worst_capped, e.control, e.singular, e.core);
        EXPECT_LE(e.worst, 5e-3) << ax << " x " << ay << " gamma " << gamma;
        // Since the across axis takes up to kProductMaxAcross points no query of this domain is capped.
        EXPECT_EQ(e.capped, 0) << ax << " x " << ay << " gamma " << gamma;
        EXPECT_GT(e.control, 0.05) << "control: the isotropic stand-in must fail";
      }
  EXPECT_EQ(run, full ? 30 : 12);
}

TEST(GlintAniso, ProbabilityMatchesBruteForceConeMeanOverAllAzimuths) { expect_probability_matches_brute_force(false); }

TEST(GlintAniso, ProbabilityMatchesBruteForceConeMeanOverAllAzimuthsStress) {
  if (stress_scale() == 1) GTEST_SKIP() << "make stress only";
  expect_probability_matches_brute_force(true);
}

// ---- Isotropic path unchanged -------------------------------------------------
TEST(GlintAniso, EqualRoughnessIsTheIsotropicModelBitForBit) {
  auto base = make_closure("glint", {{"roughness", "0.5"}, {"density", "1e6"}});
  auto same = make_closure("glint", {{"roughness", "0.3"}, {"roughness_u", "0.5"}, {"roughness_v", "0.5"},
                                     {"density", "1e6"}});
  auto explicit_default = make_closure("glint", {{"roughness", "0.5"}, {"roughness_u", "-1"}, {"density", "1e6"}});
  auto other = make_closure("glint", {{"roughness", "0.5"}, {"roughness_v", "0.45"}, {"density", "1e6"}});
  Pcg32 rng(3);
  int lit = 0, differing = 0;
  for (int i = 0; i < 3000; ++i) {
    const double theta = 80.0 * rng.next_double(), phi = 360.0 * rng.next_double();
    const Vec3 wi = spherical_dir(theta, phi);
    const Vec3 wo = spherical_dir(std::min(89.0, theta + 30.0 * (rng.next_double() - 0.5)),
                                  phi + 180.0 + 30.0 * (rng.next_double() - 0.5));
    const double side = std::pow(10.0, -1.0 - 3.0 * rng.next_double());
    const GlimmerShadingContext ctx =
        square_context(wi, rng.next_double(), rng.next_double(), side, (i % 3) * 0.1f);
    float p0, p1, p2;
    const float f0 = eval_f(*base, ctx, wo, &p0), f1 = eval_f(*same, ctx, wo, &p1), f2 = eval_f(*explicit_default, ctx, wo, &p2);
    EXPECT_EQ(f0, f1);
    EXPECT_EQ(p0, p1);
    EXPECT_EQ(f0, f2);
    EXPECT_EQ(p0, p2);
    lit += f0 > 0.0f;
    differing += eval_f(*other, ctx, wo) != f0;
    const float r3[3] = {static_cast<float>(rng.next_double()), static_cast<float>(rng.next_double()), 0.5f};
    GlimmerSample s0{}, s1{};
    EXPECT_EQ(base->sample(ctx, r3, s0), same->sample(ctx, r3, s1));
    EXPECT_EQ(s0.eval[0], s1.eval[0]);
    EXPECT_EQ(s0.pdf, s1.pdf);
    EXPECT_EQ(s0.roughness, s1.roughness);
  }
  EXPECT_GT(lit, 300);
  EXPECT_GT(differing, lit / 2);  // control: a 10 % anisotropy changes the values
}

// ---- The tangent frame comes from ctx.T -----------------------------------------
// Rotating T by 90 degrees about N with the axes' roughness swapped is the
// same surface: equal values within the disk rule's error (its orientation
// follows wo's own frame, not T's). Control: the rotation alone changes them.
TEST(GlintAniso, TangentFrameFromContext) {
  auto uv = aniso_glint("ggx", 0.25, 0.0625, {{"filter_threshold", "0"}});
  auto vu = aniso_glint("ggx", 0.0625, 0.25, {{"filter_threshold", "0"}});
  Pcg32 rng(5);
  double worst = 0.0, control = 0.0;
  int compared = 0;
  for (int i = 0; i < 400; ++i) {
    const double theta = 70.0 * rng.next_double(), phi = 360.0 * rng.next_double();
    const Vec3 wi = spherical_dir(theta, phi);
    const Vec3 wo = spherical_dir(std::min(88.0, theta + 12.0 * (rng.next_double() - 0.5)),
                                  phi + 180.0 + 20.0 * (rng.next_double() - 0.5));
    GlimmerShadingContext a = square_context(wi, 0.5, 0.5, 0.01);
    GlimmerShadingContext b = a;
    b.T = Vec3(0.0f, 1.0f, 0.0f);
    const float fa = eval_f(*uv, a, wo), fb = eval_f(*vu, b, wo), fc = eval_f(*uv, b, wo);
    if (!(fa > 1e-3f)) continue;
    ++compared;
    worst = std::max(worst, std::fabs(double(fb) / fa - 1.0));
    control = std::max(control, std::fabs(double(fc) / fa - 1.0));
  }
  std::printf("[aniso frame] %d lit pairs: T rotated + axes swapped max rel. difference %.4f; rotated alone %.3f\n",
              compared, worst, control);
  EXPECT_GT(compared, 100);
  EXPECT_LE(worst, 5e-3);
  EXPECT_GT(control, 0.5);
}

// ---- White furnace vs the smooth anisotropic BRDF ---------------------------------
// Smooth albedo: smooth_albedo_vndf (glint_test_util.h), checked against a 0.1 x 0.2-degree wo grid at two wi.
double smooth_albedo_grid(mf::Distribution dist, double ax, double ay, const Vec3 &wi, int n_theta, int n_phi) {
  const float x = static_cast<float>(ax), y = static_cast<float>(ay);
  double sum = 0.0;
  for (int t = 0; t < n_theta; ++t) {
    const double theta = (t + 0.5) * 90.0 / n_theta;
    const double w = std::sin(theta * kDeg) * (90.0 / n_theta * kDeg) * (360.0 / n_phi * kDeg);
    for (int p = 0; p < n_phi; ++p) {
      const Vec3 wo = spherical_dir(theta, (p + 0.5) * 360.0 / n_phi);
      Vec3 h;
      if (!mf::half_vector_reflect(wi, wo, h)) continue;
      sum += w * mf::G2(dist, wi, wo, x, y) * mf::D(dist, h, x, y) / (4.0 * wi.z);
    }
  }
  return sum;
}

// Asserted: |albedo - smooth| <= 3 sigma + 1 % (the task's line) and albedo
// <= smooth + 3 sigma (issue 10's energy line; with the energy table's
// first 24 x 24 grid this was 4.1 sigma at the largest blur).
TEST(GlintAniso, WhiteFurnaceMatchesSmoothAnisotropicAlbedoAtEveryIncidenceAndBlur) {
  struct Case {
    const char *name;
    mf::Distribution d;
    double ax, ay;
  };
  double worst_sigmas = -1e9, worst_rel = 0.0;
  for (const Case &c : {Case{"ggx", mf::Distribution::GGX, 0.3, 0.05}, Case{"beckmann", mf::Distribution::Beckmann, 0.5, 0.1},
                        Case{"ggx", mf::Distribution::GGX, 0.1, 0.5}}) {
    for (const double theta_check : {0.0, 60.0}) {
      const Vec3 wi = spherical_dir(theta_check, 30.0);
      const double grid = smooth_albedo_grid(c.d, c.ax, c.ay, wi, 900, 1800);
      EXPECT_NEAR(smooth_albedo_vndf(c.d, c.ax, c.ay, wi), grid, 2e-3 * grid) << c.name << " " << theta_check;
    }
    // Large particle counts: the default filter_threshold switches to the mean.
    auto glint = aniso_glint(c.name, c.ax, c.ay, {{"density", "1e12"}});
    const double alpha_max = std::max(c.ax, c.ay);
    for (const double theta_i : {0.0, 30.0, 60.0, 75.0, 80.0, 85.0, 88.0, 89.0})
      for (const double phi_i : {0.0, 45.0, 90.0, 160.0}) {
        const Vec3 wi = spherical_dir(theta_i, phi_i);
        const double smooth = smooth_albedo_vndf(c.d, c.ax, c.ay, wi);
        for (const double blur : {0.0, 0.5, 1.0}) {
          const auto ctx = square_context(wi, 0.3, 0.6, 0.1, static_cast<float>(blur * 2.0 * alpha_max));
          const glint_stats::AlbedoEstimate a = glint_stats::sampled_albedo(*glint, ctx, 128);
          const double se = a.standard_error();
          worst_sigmas = std::max(worst_sigmas, (a.mean - smooth) / se);
          worst_rel = std::max(worst_rel, std::fabs(a.mean / smooth - 1.0));
          std::printf("[aniso furnace] %s %.2f x %.2f theta_i %4.1f phi_i %5.1f blur %.1f: albedo %.4f +- %.4f, "
                      "smooth %.4f\n", c.name, c.ax, c.ay, theta_i, phi_i, blur, a.mean, se, smooth);
          EXPECT_LE(std::fabs(a.mean - smooth), 3.0 * se + 0.01 * smooth)
              << c.name << " theta_i " << theta_i << " phi_i " << phi_i << " blur " << blur;
          // Issue 10's energy line: never above the smooth albedo + 3 sigma.
          EXPECT_LE(a.mean, smooth + 3.0 * se)
              << c.name << " theta_i " << theta_i << " phi_i " << phi_i << " blur " << blur;
        }
      }
  }
  std::printf("[aniso furnace] largest (albedo - smooth) / sigma %.2f, largest |albedo / smooth - 1| %.4f\n",
              worst_sigmas, worst_rel);
}

// ---- Sampling: chi2, eval/pdf consistency ------------------------------------------
// 18 configurations (Sidak-corrected over the 18). `make test` runs 8 with the seeds and the threshold of the full
// family: the more anisotropic 0.3 x 0.05 at normal incidence and at 70 degrees along both axes (phi 0 and 90), the
// 0.5 x 0.1 at 70 degrees diagonally (phi 45), and the widened spread and Beckmann of both;
// Chi2SamplerMatchesPdfStress (`make stress`) all 18.
void expect_aniso_sampler_matches_pdf(bool full) {
  std::vector<Chi2Config> configs;
  for (const auto &[ax, ay] : std::vector<std::pair<double, double>>{{0.3, 0.05}, {0.5, 0.1}}) {
    auto c = aniso_glint("ggx", ax, ay);
    const bool narrow = ax == 0.3;
    for (const double theta_i : {0.0, 40.0, 70.0})
      for (const double phi_i : {0.0, 45.0, 90.0}) {
        if (theta_i == 0.0 && phi_i > 0.0) continue;
        const Vec3 wi = spherical_dir(theta_i, phi_i);
        configs.push_back({"ggx " + fmt(ax) + "x" + fmt(ay) + " theta_i " + fmt(theta_i) + " phi_i " + fmt(phi_i), c,
                           wi, square_context(wi, 0.3, 0.3, 1e-3)});
        const bool kept =
            narrow ? theta_i == 0.0 || (theta_i == 70.0 && phi_i != 45.0) : theta_i == 70.0 && phi_i == 45.0;
        configs.back().stress_only = !kept;
      }
    const Vec3 wi = spherical_dir(30.0, 60.0);
    configs.push_back({"ggx " + fmt(ax) + "x" + fmt(ay) + " spread 10deg", c, wi,
                       square_context(wi, 0.3, 0.3, 1e-3, static_cast<float>(10.0 * kDeg))});
    auto b = aniso_glint("beckmann", ax, ay);
    const Vec3 wb = spherical_dir(50.0, 135.0);
    configs.push_back({"beckmann " + fmt(ax) + "x" + fmt(ay), b, wb, square_context(wb, 0.3, 0.3, 1e-3)});
  }
  ASSERT_EQ(configs.size(), 18u);
  size_t run = 0;
  for (const auto &c : configs) run += full || !c.stress_only;
  ASSERT_EQ(run, full ? 18u : 8u);
  expect_chi2_family(configs, {}, full);
}

TEST(GlintAniso, Chi2SamplerMatchesPdf) { expect_aniso_sampler_matches_pdf(false); }

TEST(GlintAniso, Chi2SamplerMatchesPdfStress) {
  if (stress_scale() == 1) GTEST_SKIP() << "make stress only";
  expect_aniso_sampler_matches_pdf(true);
}

TEST(GlintAniso, EvalPdfConsistentWithSample) {
  auto glint = aniso_glint("ggx", 0.3, 0.05);
  for (const double theta_i : {0.0, 40.0, 70.0, 85.0})
    for (const double side : {0.0, 1e-4, 1e-2})
      EXPECT_TRUE(consistent(*glint, square_context(spherical_dir(theta_i, 30.0), 0.4, 0.6, side), 1e-4, 50000));
  auto blurred = aniso_glint("beckmann", 0.5, 0.1);
  EXPECT_TRUE(consistent(*blurred, square_context(spherical_dir(50.0, 100.0), 0.4, 0.6, 1e-3, 0.3f), 1e-4, 50000));
}

// ---- Stress ---------------------------------------------------------------------------
TEST(GlintAniso, StressNoNanInfNegative) {
  std::vector<std::shared_ptr<host::ClosureInstance>> keep;
  for (const char *dist : {"ggx", "beckmann"})
    for (const auto &[ru, rv, gamma, density] : std::vector<std::array<const char *, 4>>{
             {"0.0001", "1", "0.1", "1"}, {"1", "0.0001", "10", "1e12"}, {"0.3", "0.9", "2", "1e6"},
             {"1", "0.2", "10", "1"}, {"0.0001", "0.5", "10", "1e12"}}) {
      keep.push_back(make_closure("glint", {{"distribution", dist}, {"roughness_u", ru}, {"roughness_v", rv},
                                            {"gamma", gamma}, {"density", density}, {"uv_scale", "1000"}}));
    }
  // 10000 calls per instance in `make test` (each of the stress inputs' extreme classes, bridge/lab/stress.cpp, is
  // drawn with probability >= 1/48 per call: >= ~200 calls each per instance), 1e7 under `make stress` (1e5 x 100).
  const uint64_t per_instance = stress_scale() == 1 ? 10000 : 100000;
  expect_stress_and_grazing_clean(keep, per_instance * keep.size());
  // Zero and huge footprints at grazing incidence.
  for (const auto &c : keep)
    for (const double side : {0.0, 1e30})
      for (const double cos_i : {1e-6, 1e-3, 0.5}) {
        const Vec3 wi = direction_at_cos(cos_i);
        for (const Vec3 &wo : {Vec3(-wi.x, 0.0f, wi.z), spherical_dir(60.0, 170.0), direction_at_cos(1e-6)}) {
          float pdf = -1.0f;
          const float f = eval_f(*c, square_context(wi, 0.2, 0.7, side, 0.5f), wo, &pdf);
          EXPECT_TRUE(std::isfinite(f) && f >= 0.0f && std::isfinite(pdf) && pdf >= 0.0f)
              << c->type().name << " side " << side << " cos_i " << cos_i;
        }
      }
}

// Negative control of the NaN hunt's call count in `make test` (10000 per instance, above): a glint whose eval returns
// NaN only at one of the rarest extreme inputs the hunt draws (bridge/lab/stress.cpp: duv_dx[0] = -3e38, probability
// 1/48 per call) fails it at that count.
void nan_at_negative_huge_differential(const GlimmerInstance *instance, const GlimmerShadingContext *ctx,
                                       GlimmerVec3 wo, float out_eval[3], float *out_pdf) {
  TamperedType::original().eval(instance, ctx, wo, out_eval, out_pdf);
  if (ctx->duv_dx[0] < -1e38f) out_eval[0] = std::numeric_limits<float>::quiet_NaN();
}

TEST(GlintAniso, NanHuntCallCountOfMakeTestReachesTheRarestExtremeInput) {
  TamperedType tampered(closure_type("glint"));
  tampered.type().eval = &nan_at_negative_huge_differential;
  const auto broken = make_closure(
      tampered.type(),
      {{"roughness_u", "0.3"}, {"roughness_v", "0.9"}, {"gamma", "2"}, {"density", "1e6"}, {"uv_scale", "1000"}});
  const ::testing::AssertionResult r = stress_clean({broken.get()}, 10000);
  std::printf("negative control: %s\n", r.message());
  EXPECT_FALSE(r);
}

TEST(GlintAniso, RejectsBadRoughnessWithItsName) {
  for (const auto &[name, value] : std::vector<std::pair<std::string, std::string>>{
           {"roughness_u", "1.5"}, {"roughness_v", "-2"}}) {
    try {
      make_closure("glint", {{name, value}});
      ADD_FAILURE() << name << "=" << value << " was accepted";
    } catch (const std::exception &e) {
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace glimmer::test
