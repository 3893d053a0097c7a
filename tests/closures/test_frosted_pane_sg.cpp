// frosted_glass method=sg through thin panes (thin = 1, issue 12; the paper's
// thin-object case, closures/frosted_glass_sg.h "Thin panes"):
//  - accuracy: the light that enters a pane and leaves it (through the far
//    face, T, and back through the entry face after reflections between the
//    faces, R_int), lit by a smooth environment, for 8 incidence angles
//    0..70 deg: sg vs method=path (the pane's exact random walk, itself
//    validated against a path-traced slab in test_frosted_pane.cpp) at 16384
//    paths per angle, computed in the same test; mean relative error per
//    configuration. Both estimators share the front event (same random
//    numbers, same interface), and the front reflection (exact in both) is
//    left out: what is compared is what the SG replaces. Negative control: sg
//    without the refraction at the exit face (the lobe keeps the internal axis);
//  - white furnace: a lossless sg pane returns all the light (R + T = 1 within
//    the interface's own compensation error): the reflection between the
//    faces is carried, not dropped;
//  - consistency: every non-singular sample (the front reflection) equals
//    eval() at its direction (f cos and pdf); eval() has no transmission;
//  - stress: no NaN / Inf / negative raw outputs over 1e6 calls (1e8 under
//    make stress), IOR 2.4 and grazing included, thickness 1e-6..1e6.
#include <gtest/gtest.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <limits>
#include <vector>

#include "closures/angle_bands.h"
#include "closures/frosted_glass.h"
#include "closures/raw_output_checks.h"
#include "glimmer/exit_lobe.h"
#include "glimmer/rng.h"
#include "host/closure_instance.h"
#include "test_support.h"

namespace {

using namespace glimmer;
using namespace glimmer::plugin;
using glimmer::test::angle_band;
using glimmer::test::BandSums;
using glimmer::test::degrees_between;
using glimmer::test::stress_scale;

struct PaneConfig {
  float roughness, ior;
  Vec3 absorb{1.0f};     // absorption colour at distance `thickness` (one normal crossing)
  float thickness = 0.05f;
  Vec3 tint{1.0f};  // the closure's colour (transmission tint per interface crossing)
};

std::unique_ptr<FrostedGlassClosure> create_pane(const PaneConfig &c, const char *method, bool thin = true) {
  const GlimmerParamValue values[] = {{"roughness", {c.roughness, 0, 0}, nullptr},
                                      {"color", {c.tint.x, c.tint.y, c.tint.z}, nullptr},
                                      {"ior", {c.ior, 0, 0}, nullptr},
                                      {"absorption_color", {c.absorb.x, c.absorb.y, c.absorb.z}, nullptr},
                                      {"absorption_distance", {c.thickness, 0, 0}, nullptr},
                                      {"thin", {thin ? 1.0f : 0.0f, 0, 0}, nullptr},
                                      {"thickness", {c.thickness, 0, 0}, nullptr},
                                      {"method", {0, 0, 0}, method}};
  ParamReader reader(FrostedGlassClosure::kName, FrostedGlassClosure::params(), values);
  auto closure = FrostedGlassClosure::create(reader);
  closure->prepare(host::default_host_services());
  return closure;
}

// Sky above the pane (a gradient), a broad bright lobe and a gradient below it (behind the pane).
Spectrum environment(const Vec3 &d) {
  const Vec3 c = normalize(Vec3(0.35f, 0.1f, -1.0f));
  const float lobe = 1.5f * std::exp(6.0f * (dot(d, c) - 1.0f));
  return Spectrum(0.3f + 0.25f * (d.x + 1.0f) + lobe, 0.35f + 0.2f * (d.y + 1.0f) + 0.2f * std::max(0.0f, d.z) + lobe,
                  0.5f + 0.3f * std::max(0.0f, -d.z) + lobe);
}

// The pane is the plane z = 0 (normal +z) at the origin, seen from above at incidence theta (degrees).
GlimmerShadingContext pane_context(float theta_deg) {
  const float th = theta_deg * float(M_PI) / 180.0f;
  GlimmerShadingContext ctx = host::make_local_context(Vec3(-std::sin(th), 0.0f, std::cos(th)));
  ctx.P = Vec3(0.0f);
  ctx.N = ctx.Ng = Vec3(0.0f, 0.0f, 1.0f);
  ctx.T = Vec3(1.0f, 0.0f, 0.0f);
  return ctx;
}

using Sampler = std::function<bool(const ShadingPoint &, const Vec3 &, LocalSample &)>;

// The samplers a comparison runs: `path`'s and `sg`'s own sample, and sg's pane estimator in `variant` (a
// negative control or an older form).
struct PaneSamplers {
  Sampler path, sg, variant;
};
PaneSamplers pane_samplers(const FrostedGlassClosure &path, const FrostedGlassClosure &sg, frosted::SgVariant variant) {
  return {[&path](const ShadingPoint &sp, const Vec3 &r, LocalSample &s) { return path.sample(sp, r, s); },
          [&sg](const ShadingPoint &sp, const Vec3 &r, LocalSample &s) { return sg.sample(sp, r, s); },
          [&sg, variant](const ShadingPoint &sp, const Vec3 &r, LocalSample &s) {
            return sg.pane_sample_sg(sp, r, s, variant);
          }};
}

// One path entering the pane at `theta_deg` (numbers from `rng`): false when the front event (the solid closure's
// first interface, same numbers) reflects, a reflection there being left out, or when `sample` fails; else its
// sample `s` and world direction `wo`.
bool entering_sample(const FrostedGlassClosure &front, const Sampler &sample, float theta_deg, Pcg32 &rng,
                     LocalSample &s, Vec3 &wo) {
  static const auto schema = FrostedGlassClosure::params();
  GlimmerShadingContext ctx = pane_context(theta_deg);
  ctx.path_seed = rng.next_u32();
  const ShadingPoint sp(&ctx, schema);
  const Vec3 rand(rng.next_float(), rng.next_float(), rng.next_float());
  LocalSample f;
  if (!front.sample(sp, rand, f) || !(f.label & GLIMMER_LABEL_TRANSMIT)) return false;
  if (!sample(sp, rand, s) || !(s.pdf > 0.0f)) return false;
  wo = normalize(sp.frame.to_world(s.wo));
  return true;
}

// Per angle: the mean luminance leaving through the far face (T) and back through the entry face after entering
// (R_int), with standard errors.
struct AngleEstimate {
  double T = 0.0, R = 0.0, se_T = 0.0, se_R = 0.0;
};
constexpr int kAngles = 8;

std::vector<AngleEstimate> estimate(const FrostedGlassClosure &front, const Sampler &sample, long paths,
                                    uint64_t seed) {
  std::vector<AngleEstimate> out(kAngles);
  tbb::parallel_for(0, kAngles, [&](int a) {
    Pcg32 rng(seed, 31 + uint64_t(a));
    double sum[2] = {0, 0}, sum2[2] = {0, 0};
    for (long i = 0; i < paths; ++i) {
      LocalSample s;
      Vec3 wo;
      if (!entering_sample(front, sample, 10.0f * float(a), rng, s, wo)) continue;
      const double L = average(s.f_cos / s.pdf * environment(wo));
      const int side = wo.z < 0.0f ? 0 : 1;
      sum[side] += L;
      sum2[side] += L * L;
    }
    AngleEstimate &e = out[a];
    e.T = sum[0] / paths;
    e.R = sum[1] / paths;
    e.se_T = std::sqrt(std::max(0.0, sum2[0] / paths - e.T * e.T) / paths);
    e.se_R = std::sqrt(std::max(0.0, sum2[1] / paths - e.R * e.R) / paths);
  });
  return out;
}

// Mean over angles of |est - ref| / ref for T, R_int and their sum; the reference's mean relative standard error.
struct PaneError {
  double T = 0.0, R = 0.0, total = 0.0, se_T = 0.0, se_R = 0.0;
};
PaneError compare(const std::vector<AngleEstimate> &est, const std::vector<AngleEstimate> &ref) {
  PaneError e;
  for (int a = 0; a < kAngles; ++a) {
    e.T += std::fabs(est[a].T - ref[a].T) / ref[a].T;
    e.R += std::fabs(est[a].R - ref[a].R) / ref[a].R;
    e.total += std::fabs(est[a].T + est[a].R - ref[a].T - ref[a].R) / (ref[a].T + ref[a].R);
    e.se_T += ref[a].se_T / ref[a].T;
    e.se_R += ref[a].se_R / ref[a].R;
  }
  for (double *v : {&e.T, &e.R, &e.total, &e.se_T, &e.se_R}) *v /= kAngles;
  return e;
}

constexpr double kGoal = 0.05;  // issue 12's goal for convex objects
constexpr long kReferencePaths = 16384, kSgPaths = 4096;

struct PaneCase {
  PaneConfig config;
  double bound_T, bound_R;  // the goal where met, else the measured error + ~30 % (a regression fails)
  bool control;             // the negative control must fail here (it measured > 2x the goal)
  // The control: sg without the exit refraction; at roughness > 0.4 the single SG that was the default there
  // before the twelfth session (3-7 % of T missing, the wrong shape).
  frosted::SgVariant control_variant = frosted::SgVariant::kNoExitRefraction;
  // Paths x this (reference and sg): R_int is a few % of the light, so at 16384 / 4096 paths its mean relative
  // error is mostly noise (reference se 0.047 at roughness 0.1); the rows whose R_int is asserted near the goal
  // take more.
  long scale = 1;
  // R_int's negative control (fifteenth session): the mixture with its axis roulette, the default at roughness
  // <= 0.4 before, must fail bound_R.
  bool r_control = false;
};

void check_pane(const PaneCase &c) {
  auto path = create_pane(c.config, "path"), sg = create_pane(c.config, "sg");
  auto solid = create_pane(c.config, "path", false);  // its first event is the pane's front event
  const auto [path_sampler, sg_sampler, control_sampler] = pane_samplers(*path, *sg, c.control_variant);
  const long ref_paths = kReferencePaths * c.scale, sg_paths = kSgPaths * c.scale;
  const auto ref = estimate(*solid, path_sampler, ref_paths, 1);
  const auto est = estimate(*solid, sg_sampler, sg_paths, 2);
  const PaneError e = compare(est, ref);
  const auto est_ctl = estimate(*solid, control_sampler, sg_paths, 2);
  const PaneError ctl = compare(est_ctl, ref);
  // Noise per path of T, sg over path: the mean relative se, each scaled to one path.
  double noise_sg = 0.0, noise_path = 0.0, noise_ctl = 0.0;
  for (int a = 0; a < kAngles; ++a) {
    noise_sg += est[a].se_T / est[a].T * std::sqrt(double(sg_paths));
    noise_ctl += est_ctl[a].se_T / est_ctl[a].T * std::sqrt(double(sg_paths));
    noise_path += ref[a].se_T / ref[a].T * std::sqrt(double(ref_paths));
  }
  std::printf("[frosted sg pane] roughness %.2f ior %.2f%s: mean relative error sg T %.4f, R_int %.4f, T + R_int "
              "%.4f (%s: T %.4f R_int %.4f); reference se T %.4f R_int %.4f (%ld / %ld paths per angle)\n",
              double(c.config.roughness), double(c.config.ior), c.config.absorb.x < 1.0f ? " absorbing" : "", e.T,
              e.R, e.total,
              c.control_variant == frosted::SgVariant::kNoExitRefraction ? "no exit refraction" : "single SG",
              ctl.T, ctl.R, e.se_T, e.se_R, ref_paths, sg_paths);
  std::printf("[frosted sg pane] noise of T per path over path's: sg %.3f, control %.3f\n", noise_sg / noise_path,
              noise_ctl / noise_path);
  // Printed for the rule's next step: the walk with one SG at the exit (the default above 0.4) at this roughness,
  // and where R_int has a control, the mixture with its axis roulette (the default up to 0.4 before), its negative
  // control.
  const auto print_variant = [&](frosted::SgVariant v, const char *what) {
    const Sampler sampler = [&sg, v](const ShadingPoint &sp, const Vec3 &r, LocalSample &s) {
      return sg->pane_sample_sg(sp, r, s, v);
    };
    const auto est_v = estimate(*solid, sampler, sg_paths, 2);
    const PaneError w = compare(est_v, ref);
    double noise_v = 0.0;
    for (int a = 0; a < kAngles; ++a) noise_v += est_v[a].se_T / est_v[a].T * std::sqrt(double(sg_paths));
    std::printf("[frosted sg pane] %s here: T %.4f, R_int %.4f, noise of T per path over path's %.3f\n", what, w.T,
                w.R, noise_v / noise_path);
    return w;
  };
  print_variant(frosted::SgVariant::kPaneWalk, "kPaneWalk");
  if (c.r_control) {
    const PaneError m = print_variant(frosted::SgVariant::kMixture, "kMixture (R_int control)");
    EXPECT_GT(m.R, c.bound_R) << "R_int negative control passed: roughness " << c.config.roughness;
  }
  EXPECT_LT(e.T, c.bound_T) << "roughness " << c.config.roughness << " ior " << c.config.ior;
  EXPECT_LT(e.R, c.bound_R) << "roughness " << c.config.roughness << " ior " << c.config.ior;
  if (c.control) {
    EXPECT_GT(ctl.T, 2.0 * kGoal) << "negative control passed: roughness " << c.config.roughness;
  }
}

TEST(FrostedGlassSgPane, MatchesThePathReference) {
  // Measured (fit version 10), mean relative error T / R_int / T + R_int: 0.1, 1.33: 0.0062 / 0.110 / 0.0047;
  // 0.3, 1.5: 0.029 / 0.211 / 0.011 (the mixture with the heavy tail). Above roughness 0.4 the pane's default is
  // the exact walk between the faces with the leaving table's SG (kPaneWalk, twelfth session): 0.5, 1.7: 0.0099 /
  // 0.037 / 0.008; 0.5, 1.5 absorbing: 0.011 / 0.039 / 0.010; 0.8, 1.5: 0.015 / 0.040 / 0.012 (the single SG before:
  // 0.125 / 0.147, 0.058 / 0.708, 0.119 / 0.108; reference se T 0.006-0.009, R_int 0.026-0.034). Fifteenth
  // session: up to 0.4 the default is the walk's split with the mixture's exit for the light that crosses without a
  // reflection (kPaneWalkMixture); those two rows take 16x the paths (262144 / 65536; at 1x R_int's error was mostly
  // noise, reference se 0.047 at 0.1): T / R_int 0.0018 / 0.0270 at 0.1, 1.33 and 0.0132 / 0.0103 at 0.3, 1.5
  // (reference se R_int 0.0116 / 0.0081); the mixture with its axis roulette (the default before): 0.0018 / 0.0425
  // and 0.0241 / 0.174. R_int bounds: the goal at 0.1 (the old default is within it there, so no control), 0.03 at
  // 0.3 with the old default as the control (it must fail). The goal is met for T and R_int at every roughness.
  const PaneCase cases[] = {
      {{0.1f, 1.33f}, kGoal, kGoal, true, frosted::SgVariant::kNoExitRefraction, 16, false},
      {{0.3f, 1.5f}, kGoal, 0.03, true, frosted::SgVariant::kNoExitRefraction, 16, true},
      {{0.5f, 1.7f}, kGoal, kGoal, true, frosted::SgVariant::kTracedCone},
      {{0.5f, 1.5f, Vec3(0.7f, 0.85f, 0.95f)}, kGoal, kGoal, false, frosted::SgVariant::kTracedCone},
      {{0.8f, 1.5f}, kGoal, kGoal, true, frosted::SgVariant::kTracedCone},
  };
  for (const PaneCase &c : cases) check_pane(c);
}

// ---- The exit lobe's shape: the angular distribution of the transmitted light (issue 12, eleventh session) ----
// The light that enters at incidence theta and leaves through the far face, binned by its angle off the incident
// direction continued (a pane's exit axis): the fraction of the transmitted energy per angular band, method=path's
// exact walk (the reference, validated against a path-traced slab in test_frosted_pane.cpp) vs sg's exit mixture
// as sampled (one lobe picked by its weight, the redraw rule). Both share the front event (the solid closure's
// first interface, same numbers). What the small light behind a pane needs is the mass 20-60 deg off axis.
constexpr int kBands = 8;
constexpr double kBandEdge[kBands + 1] = {0, 2, 5, 10, 20, 30, 45, 60, 90};  // degrees

struct BandMass {
  double mass[kBands] = {}, se[kBands] = {};  // fraction of the transmitted energy per band, its standard error
  double total = 0.0;                          // transmitted energy per entering path
  double reflected = 0.0;                      // energy per entering path leaving back through the entry face
  double reflected_se = 0.0;                   // its standard error
};

BandMass band_mass(const FrostedGlassClosure &front, const Sampler &sample, float theta_deg, long paths,
                   uint64_t seed) {
  constexpr int kChunks = 16;
  const float th = theta_deg * float(M_PI) / 180.0f;
  const Vec3 axis(std::sin(th), 0.0f, -std::cos(th));  // -wi: the incident direction continued
  struct Sums {
    BandSums<kBands> through;  // through the far face
    double reflected = 0.0;    // back through the entry face
    double reflected2 = 0.0;   // its sum of squares
  };
  std::vector<Sums> acc(kChunks);
  tbb::parallel_for(0, kChunks, [&](int chunk) {
    Pcg32 rng(seed, 97 + uint64_t(chunk));
    auto &a = acc[size_t(chunk)];
    for (long i = chunk; i < paths; i += kChunks) {
      LocalSample s;
      Vec3 wo;
      if (!entering_sample(front, sample, theta_deg, rng, s, wo)) continue;
      const double w = average(s.f_cos / s.pdf);
      if (!(wo.z < 0.0f)) {  // back through the entry face: not in the bands, its energy apart
        a.reflected += w;
        a.reflected2 += w * w;
        continue;
      }
      a.through.add(angle_band(kBandEdge, degrees_between(wo, axis)), w);
    }
  });
  BandSums<kBands> sum;
  BandMass out;
  double reflected2 = 0.0;
  for (const auto &a : acc) {
    sum += a.through;
    out.reflected += a.reflected;
    reflected2 += a.reflected2;
  }
  sum.fractions(double(paths), out.mass, out.se);
  out.total = sum.total / double(paths);
  out.reflected /= paths;
  out.reflected_se = std::sqrt(std::max(0.0, reflected2 / paths - out.reflected * out.reflected) / paths);
  return out;
}

// The reference: method=path's exact walk through the pane, its front event the solid closure's first interface.
BandMass path_band_mass(const FrostedGlassClosure &solid, const PaneConfig &config, float theta_deg, long paths) {
  auto path = create_pane(config, "path");
  return band_mass(
      solid, [&](const ShadingPoint &sp, const Vec3 &r, LocalSample &s) { return path->sample(sp, r, s); }, theta_deg,
      paths, 1);
}

// Relative error of the mass 20-60 deg off axis (bands 4..6), sg vs path; the reference's relative se of it.
double tail_error(const BandMass &sg, const BandMass &ref) {
  double a = 0.0, r = 0.0;
  for (int b = 4; b <= 6; ++b) a += sg.mass[b], r += ref.mass[b];
  return (a - r) / r;
}
double tail_se(const BandMass &ref) {
  double r = 0.0, v = 0.0;
  for (int b = 4; b <= 6; ++b) r += ref.mass[b], v += ref.se[b] * ref.se[b];
  return std::sqrt(v) / r;
}
// Total variation between the band distributions: sum |sg - path| over the bands.
double band_l1(const BandMass &sg, const BandMass &ref) {
  double d = 0.0;
  for (int b = 0; b < kBands; ++b) d += std::fabs(sg.mass[b] - ref.mass[b]);
  return d;
}

void print_bands(const char *what, const BandMass &m) {
  std::printf("  %-24s T %.4f |", what, m.total);
  for (int b = 0; b < kBands; ++b) std::printf(" %.2e", m.mass[b]);
  std::printf("\n");
}

// The pane's heavy tail (frosted_glass_sg.h, PaneTail) against the exact walk. Measured (fit of PaneTail: 4e6 / 1e6
// paths; 1e6 / 2.5e5 here): the mass 20-60 deg off axis, relative error now / with the tenth session's kappa / 4
// tails: roughness 0.2 IOR 1.5 at 0 / 10 deg +0.006 / -0.972 and -0.001 / -0.965; 0.3 1.5 at 0 / 40 deg
// -0.003 / -0.040 and -0.172 / -0.003 (reference relative se 0.014 / 0.014 / 0.006 / 0.005). Bound 0.3 where the ladder reaches the band; the tenth session's mixture (the control) must miss
// it at roughness 0.2 (the small light's pane). At roughness 0.1 (IOR 1.33) the band holds 1e-4 of the light and
// the ladder's widest lobe (kappa / 256) is still narrower than 20 deg: printed, not asserted.
// The ladder is validated once, at compile time for the default (frosted_glass_sg.h); invalid tails give no tail.
static_assert(frosted::kPaneLadder.valid && frosted::kPaneLadder.total > 0.146f && frosted::kPaneLadder.total < 0.147f);
static_assert(!frosted::make_pane_ladder({0.5f, 4, 1.0f, 5.0f}).valid);  // sum t_j 2 > 0.9
static_assert(!frosted::make_pane_ladder({0.12f, 6, 0.18f, 5.0f}).valid);  // 5 cores + 6 > the ABI's 10 lobes
static_assert(!frosted::make_pane_ladder({std::numeric_limits<float>::quiet_NaN(), 4, 0.18f, 5.0f}).valid);
static_assert(!frosted::make_pane_ladder({0.12f, 4, 0.18f, std::numeric_limits<float>::infinity()}).valid);
static_assert(frosted::make_pane_ladder({0.0f, 0, 0.0f, 1.0f}).valid);  // no tail at all is a valid ladder

TEST(FrostedGlassSgPane, ExitLobeShapeAgainstThePath) {
  const long ref_paths = stress_scale() > 1 ? 8000000 : 1000000, sg_paths = ref_paths / 4;
  struct ShapeCase {
    PaneConfig config;
    float theta;
    bool reached, control;  // the 20-60 deg band asserted; the control asserted to miss it
  };
  const ShapeCase cases[] = {{{0.2f, 1.5f, Vec3(1.0f), 0.02f}, 0.0f, true, true},   // the small light's pane
                             {{0.2f, 1.5f, Vec3(1.0f), 0.02f}, 10.0f, true, true},  // its view's edge
                             {{0.1f, 1.33f}, 0.0f, false, false},
                             {{0.3f, 1.5f}, 0.0f, true, false},
                             {{0.3f, 1.5f}, 40.0f, true, false}};
  constexpr double kBound = 0.3;
  for (const ShapeCase &c : cases) {
    auto path = create_pane(c.config, "path"), sg = create_pane(c.config, "sg");
    auto solid = create_pane(c.config, "path", false);
    const auto [path_sampler, sg_sampler, old_sampler] =
        pane_samplers(*path, *sg, frosted::SgVariant::kMixtureShortTail);
    const BandMass ref = band_mass(*solid, path_sampler, c.theta, ref_paths, 1);
    const BandMass now = band_mass(*solid, sg_sampler, c.theta, sg_paths, 2);
    const BandMass old = band_mass(*solid, old_sampler, c.theta, sg_paths, 2);
    std::printf("[frosted sg pane shape] roughness %.2f ior %.2f theta %.0f: fraction of T per band (deg) 0-2 2-5 "
                "5-10 10-20 20-30 30-45 45-60 60-90\n",
                double(c.config.roughness), double(c.config.ior), double(c.theta));
    print_bands("path (reference)", ref);
    std::printf("  %-24s          |", "path se");
    for (int b = 0; b < kBands; ++b) std::printf(" %.2e", ref.se[b]);
    std::printf("\n");
    print_bands("sg (PaneTail)", now);
    print_bands("sg, kappa/4 tails (s10)", old);
    std::printf("  mass 20-60 deg: relative error sg %+.3f, kappa/4 tails %+.3f (reference relative se %.3f); "
                "band L1 sg %.3f, kappa/4 tails %.3f\n",
                tail_error(now, ref), tail_error(old, ref), tail_se(ref), band_l1(now, ref), band_l1(old, ref));
    // The reference resolves the band (its own relative se well under the bound), the energy is the same.
    EXPECT_NEAR(now.total, ref.total, 0.02 * ref.total);
    if (c.reached) {
      EXPECT_LT(tail_se(ref), 0.1 * kBound);
      EXPECT_LT(std::fabs(tail_error(now, ref)), kBound) << "roughness " << c.config.roughness;
    }
    if (c.control) {
      EXPECT_GT(std::fabs(tail_error(old, ref)), kBound) << "control passed: " << c.config.roughness;
    }
  }
}

// ---- Rough panes (twelfth session): where sg's error at roughness 0.5-0.8 came from ----------------------------
// Per (roughness 0.5 / 0.65 / 0.8, IOR 1.33 / 1.5 / 1.7, incidence 0 / 40 / 70 deg): the transmitted energy T, the
// energy back through the entry face R_int and the band distribution of T (ExitLobeShapeAgainstThePath's bands),
// path's exact walk vs (a) the single SG that was the default above 0.4 (the negative control), (b) the mixture
// with the heavy-tail ladder (tried: no better), (c) the default now, kPaneWalk (the exact walk between the faces,
// the leaving table's SG at the last internal direction). Measured at 40000 / 20000 paths: (a) mean band L1 0.308,
// mean |dT| 0.027 (worst 0.060, T always short: R_int 5-34 % too high); (b) 0.343 / 0.027; (c) 0.073 / 0.004
// (worst 0.011). GLIMMER_PANE_TAIL="first,ratio,core,levels" overrides the ladder of (b); GLIMMER_PANE_BANDS=1
// prints the bands.
TEST(FrostedGlassSgPane, RoughPaneShapeAndEnergyAgainstThePath) {
  frosted::PaneTail tail;
  if (const char *t = std::getenv("GLIMMER_PANE_TAIL"))
    std::sscanf(t, "%f,%f,%f,%d", &tail.first, &tail.ratio, &tail.core_scale, &tail.levels);
  const frosted::PaneLadder ladder = frosted::make_pane_ladder(tail);  // validated once
  ASSERT_TRUE(ladder.valid);
  // 80000 since session 30 (40000 before): the default's face pick ~ sqrt(t_F) (frosted::pane_branch_level 2) makes T
  // noisier at 70 deg; at 40000 its worst |dT| read 0.0216 (noise: 0.0063 at 200000, 0.0169 at 80000).
  long ref_paths = stress_scale() > 1 ? 400000 : 80000;
  if (const char *n = std::getenv("GLIMMER_PANE_PATHS")) ref_paths = std::atol(n);
  constexpr int kEstimators = 3;
  const char *names[kEstimators] = {"single SG (control)", "ladder", "walk (default)"};
  const frosted::SgVariant variants[kEstimators] = {frosted::SgVariant::kTracedCone, frosted::SgVariant::kMixture,
                                                    frosted::SgVariant::kPaneWalk};
  double sum_l1[kEstimators] = {}, sum_dt[kEstimators] = {}, worst_dt[kEstimators] = {}, worst_l1[kEstimators] = {};
  int n_cases = 0;
  for (float roughness : {0.5f, 0.65f, 0.8f})
    for (float ior : {1.33f, 1.5f, 1.7f})
      for (float theta : {0.0f, 40.0f, 70.0f}) {
        const PaneConfig config{roughness, ior};
        auto sg = create_pane(config, "sg"), solid = create_pane(config, "path", false);
        const BandMass ref = path_band_mass(*solid, config, theta, ref_paths);
        std::printf("[rough pane] r %.2f ior %.2f theta %2.0f | path T %.4f R_int %.4f |", double(roughness),
                    double(ior), double(theta), ref.total, ref.reflected);
        BandMass est[kEstimators];
        for (int k = 0; k < kEstimators; ++k) {
          const frosted::SgVariant v = variants[k];
          est[k] = band_mass(
              *solid,
              [&](const ShadingPoint &sp, const Vec3 &r, LocalSample &s) { return sg->pane_sample_sg(sp, r, s, v, ladder); },
              theta, ref_paths / 2, 2);
          const double dt = est[k].total / ref.total - 1.0, l1 = band_l1(est[k], ref);
          sum_l1[k] += l1;
          sum_dt[k] += std::fabs(dt);
          worst_dt[k] = std::max(worst_dt[k], std::fabs(dt));
          worst_l1[k] = std::max(worst_l1[k], l1);
          std::printf(" %s dT %+.3f dR %+.3f L1 %.3f |", k == 0 ? "single" : k == 1 ? "ladder" : "walk", dt,
                      est[k].reflected / ref.reflected - 1.0, l1);
        }
        std::printf("\n");
        if (std::getenv("GLIMMER_PANE_BANDS")) {
          print_bands("path", ref);
          for (int k = 0; k < kEstimators; ++k) print_bands(names[k], est[k]);
        }
        ++n_cases;
      }
  for (int k = 0; k < kEstimators; ++k)
    std::printf("[rough pane] %d cases, %s: band L1 mean %.3f worst %.3f, |T / T_path - 1| mean %.4f worst %.4f\n",
                n_cases, names[k], sum_l1[k] / n_cases, worst_l1[k], sum_dt[k] / n_cases, worst_dt[k]);
  // The default: the energy through the far face within 2 % everywhere (measured worst 1.1 %; the reference's own
  // relative se ~0.3 %), the shape within a band L1 of 0.1 on average (measured 0.073).
  EXPECT_LT(worst_dt[2], 0.02);
  EXPECT_LT(sum_l1[2] / n_cases, 0.1);
  // The control (the single SG that was the default here) fails both.
  EXPECT_GT(worst_dt[0], 0.02);
  EXPECT_GT(sum_l1[0] / n_cases, 0.1);
}

// ---- Panes at roughness 0.1-0.4 (fifteenth session): the light reflected back (R_int) ------------------------
// The harness above, at roughness 0.1 / 0.2 / 0.3 / 0.4 (IOR 1.33 / 1.5 / 1.7, incidence 0 / 40 / 70 deg): path's
// exact walk vs (a) the mixture with the heavy-tail ladder that was the default here until the fifteenth session
// (its axis roulette sets the T / R_int split: the negative control), (b) kPaneWalk (the walk with one SG at the
// exit, printed), (c) the default now, kPaneWalkMixture (the walk's split, the mixture's shape after the walk's
// reflections). Per estimator: |T / T_path - 1|, |R_int / R_int,path - 1| and band L1 of T, mean and worst.
// GLIMMER_PANE_PATHS overrides the reference's paths (each estimator takes half); GLIMMER_PANE_BANDS=1 prints bands.
// Measured at 200000 / 100000 paths (reference relative se of R_int 0.009 mean, 0.017 worst): band L1 mean / worst,
// |dT| mean / worst, |dR_int| mean / worst: (a) 0.134 / 0.239, 0.027 / 0.095, 0.140 / 0.341; (b) 0.219 / 0.449,
// 0.0020 / 0.0099, 0.016 / 0.039; (c) 0.127 / 0.213, 0.0020 / 0.0099, 0.016 / 0.039 (the walk's energies: (b) and
// (c) differ in the exit direction only). make test's 60000 / 30000: (a) 0.136 / 0.231, 0.027 / 0.097, 0.139 / 0.334;
// (c) 0.129 / 0.215, 0.0040 / 0.016, 0.027 / 0.067. Bounds: mean |dR_int| < 0.05 (the goal), worst |dT| < 0.03,
// band L1 mean and worst below the control's; the control must fail both energy bounds. Per roughness (200000):
// the shape is slightly worse than the mixture's at 0.1 only (band L1 mean 0.107 against 0.096).
TEST(FrostedGlassSgPane, SmoothPaneShapeAndEnergyAgainstThePath) {
  long ref_paths = stress_scale() > 1 ? 400000 : 60000;
  if (const char *n = std::getenv("GLIMMER_PANE_PATHS")) ref_paths = std::atol(n);
  constexpr int kEstimators = 3;
  const char *names[kEstimators] = {"mixture (before; control)", "walk, one SG", "walk + mixture (default)"};
  const frosted::SgVariant variants[kEstimators] = {frosted::SgVariant::kMixture, frosted::SgVariant::kPaneWalk,
                                                    frosted::SgVariant::kPaneWalkMixture};
  double sum_l1[kEstimators] = {}, sum_dt[kEstimators] = {}, worst_dt[kEstimators] = {}, worst_l1[kEstimators] = {};
  double sum_dr[kEstimators] = {}, worst_dr[kEstimators] = {}, sum_se_r = 0.0, worst_se_r = 0.0;
  int n_cases = 0;
  for (float roughness : {0.1f, 0.2f, 0.3f, 0.4f})
    for (float ior : {1.33f, 1.5f, 1.7f})
      for (float theta : {0.0f, 40.0f, 70.0f}) {
        const PaneConfig config{roughness, ior};
        auto sg = create_pane(config, "sg"), solid = create_pane(config, "path", false);
        const BandMass ref = path_band_mass(*solid, config, theta, ref_paths);
        const double se_r = ref.reflected_se / ref.reflected;
        sum_se_r += se_r;
        worst_se_r = std::max(worst_se_r, se_r);
        std::printf("[smooth pane] r %.2f ior %.2f theta %2.0f | path T %.4f R_int %.4f (se %.3f) |", double(roughness),
                    double(ior), double(theta), ref.total, ref.reflected, se_r);
        BandMass est[kEstimators];
        for (int k = 0; k < kEstimators; ++k) {
          const frosted::SgVariant v = variants[k];
          est[k] = band_mass(
              *solid, [&](const ShadingPoint &sp, const Vec3 &r, LocalSample &s) { return sg->pane_sample_sg(sp, r, s, v); },
              theta, ref_paths / 2, 2);
          const double dt = est[k].total / ref.total - 1.0, dr = est[k].reflected / ref.reflected - 1.0;
          const double l1 = band_l1(est[k], ref);
          sum_l1[k] += l1;
          sum_dt[k] += std::fabs(dt);
          sum_dr[k] += std::fabs(dr);
          worst_dt[k] = std::max(worst_dt[k], std::fabs(dt));
          worst_dr[k] = std::max(worst_dr[k], std::fabs(dr));
          worst_l1[k] = std::max(worst_l1[k], l1);
          std::printf(" %s dT %+.3f dR %+.3f L1 %.3f |", k == 0 ? "mixture" : k == 1 ? "walk" : "default", dt, dr, l1);
        }
        std::printf("\n");
        if (std::getenv("GLIMMER_PANE_BANDS")) {
          print_bands("path", ref);
          for (int k = 0; k < kEstimators; ++k) print_bands(names[k], est[k]);
        }
        ++n_cases;
      }
  std::printf("[smooth pane] %d cases, %ld / %ld paths: the reference's relative se of R_int mean %.4f worst %.4f\n",
              n_cases, ref_paths, ref_paths / 2, sum_se_r / n_cases, worst_se_r);
  for (int k = 0; k < kEstimators; ++k)
    std::printf("[smooth pane] %d cases, %s: band L1 mean %.3f worst %.3f, |T / T_path - 1| mean %.4f worst %.4f, "
                "|R_int / R_int,path - 1| mean %.4f worst %.4f\n",
                n_cases, names[k], sum_l1[k] / n_cases, worst_l1[k], sum_dt[k] / n_cases, worst_dt[k],
                sum_dr[k] / n_cases, worst_dr[k]);
  // The default: R_int and T the walk's (their error is the two runs' noise), the shape no worse than the mixture's.
  EXPECT_LT(sum_dr[2] / n_cases, 0.05);
  EXPECT_LT(worst_dt[2], 0.03);
  EXPECT_LT(sum_l1[2] / n_cases, sum_l1[0] / n_cases);
  EXPECT_LT(worst_l1[2], worst_l1[0]);
  // The control (the mixture with its axis roulette) fails the energy bounds.
  EXPECT_GT(sum_dr[0] / n_cases, 0.05);
  EXPECT_GT(worst_dt[0], 0.03);
}

// ---- White furnace: nothing dropped between the faces ------------------------------
TEST(FrostedGlassSgPane, WhiteFurnaceKeepsTheReflectionBetweenTheFaces) {
  const auto schema = FrostedGlassClosure::params();
  double worst = 0.0, worst_z = 0.0, max_internal = 0.0;
  for (float roughness : {0.1f, 0.5f, 1.0f})
    for (float ior : {1.33f, 1.7f, 2.4f})
      for (float mu : {1.0f, 0.5f, 0.1f}) {
        auto sg = create_pane({roughness, ior}, "sg");
        const long n = 200000;
        Pcg32 rng(7, uint64_t(roughness * 100 + ior * 10 + mu * 1000));
        double sum = 0.0, sum2 = 0.0, internal = 0.0;
        for (long i = 0; i < n; ++i) {
          GlimmerShadingContext ctx = host::make_local_context(Vec3(std::sqrt(1.0f - mu * mu), 0.0f, mu));
          ctx.path_seed = rng.next_u32();
          const ShadingPoint sp(&ctx, schema);
          LocalSample s;
          if (!sg->sample(sp, Vec3(rng.next_float(), rng.next_float(), rng.next_float()), s) || !(s.pdf > 0.0f))
            continue;
          const double w = average(s.f_cos / s.pdf);
          sum += w;
          sum2 += w * w;
          if (s.moved && s.wo.z > 0.0f) internal += w;  // left back through the entry face
        }
        const double mean = sum / n, se = std::sqrt(std::max(0.0, sum2 / n - mean * mean) / n);
        worst = std::max(worst, std::fabs(1.0 - mean));
        worst_z = std::max(worst_z, std::fabs(1.0 - mean) / std::max(se, 1e-12));
        if (std::getenv("GLIMMER_PANE_FURNACE_CASES"))
          std::printf("  roughness %.1f ior %.2f mu %.1f: R + T %.5f (se %.5f)\n", double(roughness), double(ior),
                      double(mu), mean, se);
        max_internal = std::max(max_internal, internal / n);
        // The bound of method=path's furnace (the interface's compensation error), plus 5 standard errors.
        EXPECT_LT(std::fabs(1.0 - mean), 0.005 + 5.0 * se) << "roughness " << roughness << " ior " << ior << " mu "
                                                           << mu;
      }
  EXPECT_GT(max_internal, 0.05);  // the reflection between the faces carries real energy in this set
  std::printf("[frosted sg pane furnace] 27 cases (roughness 0.1/0.5/1, IOR 1.33/1.7/2.4, mu 1/0.5/0.1): max |1 - "
              "(R + T)| %.5f (%.1f se); light leaving back through the entry face after entering: up to %.3f\n",
              worst, worst_z, max_internal);
}

// ---- Consistency: non-singular samples are eval()'s; no transmission in eval() ----------
TEST(FrostedGlassSgPane, SampleAgreesWithEval) {
  const auto schema = FrostedGlassClosure::params();
  long checked = 0, singular = 0, mismatched = 0, transmitting_eval = 0;
  for (float roughness : {0.2f, 0.6f})
    for (float ior : {1.5f, 2.4f}) {
      auto sg = create_pane({roughness, ior}, "sg");
      Pcg32 rng(11);
      for (int i = 0; i < 20000; ++i) {
        float z = rng.next_float();
        if (i & 1) z = -z;  // both sides of the pane
        const float phi = 2.0f * float(M_PI) * rng.next_float(), st = std::sqrt(std::max(0.0f, 1.0f - z * z));
        GlimmerShadingContext ctx = host::make_local_context(Vec3(st * std::cos(phi), st * std::sin(phi), z));
        ctx.path_seed = rng.next_u32();
        const ShadingPoint sp(&ctx, schema);
        LocalSample s;
        if (!sg->sample(sp, Vec3(rng.next_float(), rng.next_float(), rng.next_float()), s)) continue;
        // A direction on the far side of the pane (mirror of wi): eval() has no transmission.
        const LocalEval through = sg->eval(sp, Vec3(-sp.wi.x, -sp.wi.y, -sp.wi.z));
        if (through.pdf != 0.0f || !is_zero(through.f_cos)) ++transmitting_eval;
        if (s.label & GLIMMER_LABEL_SINGULAR) {
          ++singular;
          continue;
        }
        const LocalEval e = sg->eval(sp, s.wo);
        ++checked;
        const double tol = 1e-4 * std::max(1.0, double(s.pdf));
        if (std::fabs(e.pdf - s.pdf) > tol || std::fabs(e.f_cos.x - s.f_cos.x) > 1e-4 * std::max(1.0f, s.f_cos.x))
          ++mismatched;
      }
    }
  EXPECT_GT(checked, 1000);
  EXPECT_GT(singular, 1000);
  EXPECT_EQ(mismatched, 0);
  EXPECT_EQ(transmitting_eval, 0);
  std::printf("[frosted sg pane consistency] %ld front reflections equal eval() (f cos and pdf), %ld singular exit "
              "samples; eval() transmission: %ld non-zero\n",
              checked, singular, transmitting_eval);
}

// ---- The rough pane's split sample (seventeenth session) ------------------------------------------------------
// kPaneWalk carries kPaneWalkSplit walks per sample (frosted_glass_sg.h): the same expectation as one walk, less
// variance. What the host's lamp integral sees of a sample is its weight times its exit mixture's density toward the
// lamp, so per incidence angle the estimate of E[weight x p(w_j)] toward 5 fixed directions (3 through the far face,
// 2 back through the entry face; a front reflection counts 0) is compared between the split and one walk (split =
// 1, bit-identical to the unsplit sample, checked below) on independent numbers: every (angle, direction) within
// 4.5 standard errors, and the sums over them within 4 (pooled). Negative control: the split that counts the
// extra front samples that reflect in n (biased low by ~the front's reflectance) must be > 6 pooled standard errors
// off. The per-sample variance of the split over one walk's is printed and bounded by what was measured.
// Session 37 (frostedpool37): every (config, angle) draws its own numbers (one walk Pcg32(8080 + 16 config + 2
// angle, 7), the split and its control + 1, paired). The old version restarted seeds 101 / 202 at every angle and
// config: its angles' offsets correlated up to 0.76 and the configs' 0.58-0.78, and its pooled se (cells added as if
// independent) was 1.25 / 1.52 / 1.49x too small (docs/history/frosted_glass_sessions.md "Session 37 (frostedpool37)").
// The pooled variance is now each draw's sum over the directions (their covariance counted), the angles independent.
// Per angle, that sum within 4.5 se (angle_z); its control, +3 % injected at 0 deg and the opposite at 60 deg (the
// pooled sum unmoved), must be > 6 se at one angle at least.
// The five probe directions of the split and exact-exit tests: 3 through the far face, 2 back through the entry face.
const Vec3 kPaneProbeDirections[5] = {Vec3(0.0f, 0.0f, -1.0f), normalize(Vec3(0.5f, 0.0f, -1.0f)),
                                      normalize(Vec3(-0.4f, 0.3f, -1.0f)), Vec3(0.0f, 0.0f, 1.0f),
                                      normalize(Vec3(0.6f, 0.0f, 1.0f))};

// One draw of the split and exact-exit tests: the pane's context at theta_deg with a fresh path seed, its shading
// point, and the closure's three numbers.
struct PaneDraw {
  GlimmerShadingContext ctx;
  ShadingPoint sp;
  Vec3 rand;
  // diffuse_bounce: the context's diffuse bounces before the pane (1: the pane seen after a bounce, e.g. from the
  // bench's floor; session 35).
  template <typename Schema>
  PaneDraw(float theta_deg, Pcg32 &rng, const Schema &schema, int diffuse_bounce = 0)
      : ctx(seeded(pane_context(theta_deg), rng.next_u32(), diffuse_bounce)), sp(&ctx, schema) {
    rand = Vec3(rng.next_float(), rng.next_float(), rng.next_float());
  }
  static GlimmerShadingContext seeded(GlimmerShadingContext ctx, uint32_t seed, int diffuse_bounce = 0) {
    ctx.path_seed = seed;
    ctx.diffuse_bounce = diffuse_bounce;
    return ctx;
  }
};

// A LocalSample wired to its own exit-mixture and exit-state buffers (ABI 2.7 / 2.8), as the host hands them.
struct WiredSample {
  GlimmerExitMixture buffer{};
  GlimmerExitState state{};
  LocalSample s;
  WiredSample() {
    s.mixture_out = &buffer;
    s.state_out = &state;
  }
  WiredSample(const WiredSample &) = delete;
  WiredSample &operator=(const WiredSample &) = delete;
};

// The exit lobe a pane sample hands the host (its ABI 2.7 mixture, else its single SG), normalised.
ExitLobeMixture sampled_exit_mixture(const LocalSample &s, const GlimmerExitMixture &buffer) {
  const Vec3 n = normalize(s.origin_Ng);
  ExitLobeMixture m;
  if (s.exit_mixture) {
    for (uint32_t k = 0; k < buffer.count; ++k) {
      m.lobe[m.count] = ExitLobe::make(normalize(Vec3(buffer.axis[k])), buffer.sharpness[k], n);
      m.weight[m.count++] = buffer.weight[k];
    }
  } else {
    m.lobe[0] = ExitLobe::make(normalize(s.lobe_axis), s.lobe_sharpness, n);
    m.weight[0] = 1.0;
    m.count = 1;
  }
  m.normalize();
  return m;
}

struct SplitSums {
  static constexpr int kDirs = 5;
  double sum[kDirs] = {}, sum2[kDirs] = {};
  double pooled = 0.0, pooled2 = 0.0;  // each sample's sum over the directions (its variance counts their covariance)
  long samples = 0;
  void add(const double (&v)[kDirs]) {
    double p = 0.0;
    for (int j = 0; j < kDirs; ++j) sum[j] += v[j], sum2[j] += v[j] * v[j], p += v[j];
    pooled += p, pooled2 += p * p;
    ++samples;
  }
};
// One split sample at `draw` toward the probe directions: v[j] = its weight x its exit mixture's density (0 toward
// every direction where the front reflects or there is no sample). True when it handed the host a mixture.
bool split_values(const FrostedGlassClosure &pane, const PaneDraw &draw, int split, bool count_rejected, int branch,
                  int front_grid, double (&v)[SplitSums::kDirs]) {
  GlimmerExitMixture buffer{};
  LocalSample s;
  s.mixture_out = &buffer;
  std::fill(v, v + SplitSums::kDirs, 0.0);
  if (!pane.pane_sample_sg_split(draw.sp, draw.rand, s, split, count_rejected, branch, -1, -1, front_grid) ||
      !(s.label & GLIMMER_LABEL_SINGULAR) || !s.exit_lobe)
    return false;
  const ExitLobeMixture m = sampled_exit_mixture(s, buffer);
  const double w = average(s.f_cos / s.pdf);
  for (int j = 0; j < SplitSums::kDirs; ++j) v[j] = w * m.pdf(kPaneProbeDirections[j]);
  return s.exit_mixture;
}
// Adds n draws' mean (sum / n) to `mean` and the variance of that mean to `var` (sums over independent sets).
void mean_var(double sum, double sum2, double n, double &mean, double &var) {
  mean += sum / n;
  var += std::max(0.0, sum2 / n - (sum / n) * (sum / n)) / n;
}
// z of the difference of two independent means from their sums and sums of squares over n samples each; `var_a`
// gets a's variance per sample.
double mean_difference_z(double sum_a, double sum2_a, double sum_b, double sum2_b, long n, double *var_a = nullptr) {
  const double ma = sum_a / double(n), mb = sum_b / double(n);
  const double va = std::max(0.0, sum2_a / double(n) - ma * ma), vb = std::max(0.0, sum2_b / double(n) - mb * mb);
  if (var_a) *var_a = va;
  return (ma - mb) / std::sqrt(std::max((va + vb) / double(n), 1e-300));
}
// The split tests' per-angle check and its injected control (session 37, frostedpool37). The draws' sum over the
// directions or cones (SplitSums::pooled, ConeSums::pooled_rgb: their covariance counted; sums and sums of squares
// over n draws) of an estimate against a reference (independent numbers) at one
// angle: the z is added to `worst`. The control: the same estimate with a known bias `bias` (relative) injected, its
// z added to `worst_injected`; the tests inject +kInjectedBias at 0 deg and the opposite amount at 60 deg (relative
// to their own means, so the pooled sum over the angles does not move): a weight that is right on average over the
// angles and wrong per angle, which a pooled sum cannot see (the coloured-Beer continued-path test injects 5 %).
struct AngleCheck {
  double worst = 0.0, worst_injected = 0.0, injected = 0.0, var_injected = 0.0;  // the control pooled
};
constexpr double kInjectedBias = 0.03;
double angle_z(double sum, double sum2, double ref_sum, double ref_sum2, double n, double bias, AngleCheck &check) {
  double m = 0.0, v = 0.0, mr = 0.0, vr = 0.0;
  mean_var(sum, sum2, n, m, v);
  mean_var(ref_sum, ref_sum2, n, mr, vr);
  const double z = (m - mr) / std::sqrt(v + vr), k = 1.0 + bias;
  const double zi = (k * m - mr) / std::sqrt(k * k * v + vr);
  check.worst = std::max(check.worst, std::fabs(z));
  check.worst_injected = std::max(check.worst_injected, std::fabs(zi));
  check.injected += k * m, check.var_injected += k * k * v;
  return z;
}
SplitSums split_estimate(const FrostedGlassClosure &pane, float theta_deg, int split, bool count_rejected,
                         uint64_t seed, long samples, long *mixtures = nullptr, int branch = -1, int diffuse_bounce = 0,
                         int front_grid = -1) {
  static const auto schema = FrostedGlassClosure::params();
  SplitSums out;
  Pcg32 rng(seed, 7);
  for (long i = 0; i < samples; ++i) {
    const PaneDraw draw(theta_deg, rng, schema, diffuse_bounce);
    double v[SplitSums::kDirs];
    if (split_values(pane, draw, split, count_rejected, branch, front_grid, v) && mixtures) ++*mixtures;
    out.add(v);
  }
  return out;
}

TEST(FrostedGlassSgPane, RoughPaneSplitSameExpectationLessNoise) {
  const PaneConfig configs[] = {{0.5f, 1.5f}, {0.8f, 1.5f}, {0.6f, 1.7f, Vec3(0.7f), 0.05f}};
  const float angles[] = {0.0f, 30.0f, 60.0f};
  constexpr long kSamples = 32768;
  long mixtures = 0;
  for (int ci = 0; ci < int(std::size(configs)); ++ci) {
    const PaneConfig &c = configs[ci];
    auto pane = create_pane(c, "sg");
    double pooled_split = 0.0, pooled_one = 0.0, pooled_ctl = 0.0, var_split = 0.0, var_one = 0.0, var_ctl = 0.0;
    double sample_var_split = 0.0, sample_var_one = 0.0, worst_z = 0.0, first = 0.0;
    AngleCheck check;
    for (int a = 0; a < int(std::size(angles)); ++a) {
      const float theta = angles[a];
      const uint64_t seed = 8080 + 16 * uint64_t(ci) + 2 * uint64_t(a);  // own numbers per (config, angle)
      const SplitSums one = split_estimate(*pane, theta, 1, false, seed, kSamples);
      // main's split (branch level 0; session 30's levels: RoughPaneSplitBranchesSameExpectationAsOneWalk below);
      // the control on the split's draws
      const SplitSums split =
          split_estimate(*pane, theta, frosted::kPaneWalkSplit, false, seed + 1, kSamples, &mixtures, 0);
      const SplitSums ctl = split_estimate(*pane, theta, frosted::kPaneWalkSplit, true, seed + 1, kSamples, nullptr, 0);
      for (int j = 0; j < SplitSums::kDirs; ++j) {
        double m1 = 0.0, v1 = 0.0, ms = 0.0, vs = 0.0;
        mean_var(one.sum[j], one.sum2[j], kSamples, m1, v1);
        mean_var(split.sum[j], split.sum2[j], kSamples, ms, vs);
        const double z = (ms - m1) / std::sqrt(std::max(v1 + vs, 1e-300));
        worst_z = std::max(worst_z, std::fabs(z));
        EXPECT_LT(std::fabs(z), 4.5) << "roughness " << c.roughness << " ior " << c.ior << " theta " << theta
                                     << " direction " << j << ": split " << ms << " one walk " << m1;
        sample_var_one += v1 * kSamples, sample_var_split += vs * kSamples;
      }
      if (a == 0) first = split.pooled / kSamples;
      const double bias = a == 0 ? kInjectedBias : a == 2 ? -kInjectedBias * first / (split.pooled / kSamples) : 0.0;
      EXPECT_LT(std::fabs(angle_z(split.pooled, split.pooled2, one.pooled, one.pooled2, kSamples, bias, check)), 4.5)
          << "roughness " << c.roughness << " theta " << theta;
      mean_var(one.pooled, one.pooled2, kSamples, pooled_one, var_one);
      mean_var(split.pooled, split.pooled2, kSamples, pooled_split, var_split);
      mean_var(ctl.pooled, ctl.pooled2, kSamples, pooled_ctl, var_ctl);
    }
    const double z_split = (pooled_split - pooled_one) / std::sqrt(var_one + var_split);
    const double z_ctl = (pooled_ctl - pooled_one) / std::sqrt(var_one + var_ctl);
    const double z_injected = (check.injected - pooled_one) / std::sqrt(var_one + check.var_injected);
    const double ratio = sample_var_split / sample_var_one;
    std::printf(
        "[frosted sg pane split] roughness %.2f ior %.2f%s: %d walks vs 1, pooled z %.2f (worst |z| %.2f over "
        "15, %.2f over 3 angles); control (rejected counted) z %.1f (%.4f vs %.4f); injected +-%.0f %% per "
        "angle: pooled z %.2f, worst over 3 angles %.1f; variance per sample split / one walk %.3f\n",
        double(c.roughness), double(c.ior), c.absorb.x < 1.0f ? " grey Beer" : "", frosted::kPaneWalkSplit, z_split,
        worst_z, check.worst, z_ctl, pooled_ctl, pooled_one, 100.0 * kInjectedBias, z_injected, check.worst_injected,
        ratio);
    EXPECT_LT(std::fabs(z_split), 4.0) << "roughness " << c.roughness;
    EXPECT_LT(z_ctl, -6.0) << "negative control passed: roughness " << c.roughness;
    EXPECT_GT(check.worst_injected, 6.0) << "injected per-angle bias passed: roughness " << c.roughness;
    EXPECT_LT(ratio, 0.5) << "roughness " << c.roughness;  // measured 0.35-0.40
  }
  EXPECT_GT(mixtures, 10000);  // the split samples do hand the host a mixture
}

// Session 30 (frostedpane30): the camera-seen split with both branches of each walk's first event at the far face
// (frosted::pane_branch_level 1) and with the face picked ~ sqrt(t_F) as well (2, the default) against one walk (the
// brute force, unbiased on its own numbers) and main's split (0). Per configuration, 3 angles x 5 directions (3
// through, 2 back) of E[weight x the exit mixture's density]: levels 1 and 2 within 4.5 se of one walk per (angle,
// direction) and 4 se pooled; the back directions' variance per sample (the light that reflected at the far face:
// the lamp above the bench's pane) below main's split's. Negative control: kPaneBranchControl (both branches at
// full weight, F not applied) must be > 6 se off one walk pooled in every configuration.
// Session 37 (frostedpool37): own numbers per (config, angle, level) (one walk Pcg32(9090 + 16 config + 5 angle,
// 7), level l the seed + 1 + l; the old seeds 303 / 404 + l at every angle and config gave a pooled se 1.25-1.54x
// too small); pooled over each draw's sum over the directions; per angle levels 1 and 2 within 4.5 se (angle_z);
// the injected control (+3 % into level 2 at 0 deg, the opposite at 60 deg) > 6 se at one angle at least.
TEST(FrostedGlassSgPane, RoughPaneSplitBranchesSameExpectationAsOneWalk) {
  const PaneConfig configs[] = {{0.5f, 1.5f}, {0.8f, 1.5f}, {0.6f, 1.7f, Vec3(0.7f), 0.05f}};
  const float angles[] = {0.0f, 30.0f, 60.0f};
  constexpr long kSamples = 32768;
  const int levels[] = {0, 1, 2, frosted::kPaneBranchControl};
  for (int ci = 0; ci < int(std::size(configs)); ++ci) {
    const PaneConfig &c = configs[ci];
    auto pane = create_pane(c, "sg");
    double pooled_one = 0.0, var_one = 0.0, pooled[4] = {}, var[4] = {}, back_var[4] = {}, through_var[4] = {};
    double worst[4] = {}, first[4] = {};
    AngleCheck check[4];
    for (int a = 0; a < int(std::size(angles)); ++a) {
      const float theta = angles[a];
      const uint64_t seed = 9090 + 16 * uint64_t(ci) + 5 * uint64_t(a);  // own numbers per (config, angle, level)
      const SplitSums one = split_estimate(*pane, theta, 1, false, seed, kSamples);
      mean_var(one.pooled, one.pooled2, kSamples, pooled_one, var_one);
      for (int l = 0; l < 4; ++l) {
        const SplitSums e =
            split_estimate(*pane, theta, frosted::kPaneWalkSplit, false, seed + 1 + l, kSamples, nullptr, levels[l]);
        for (int j = 0; j < SplitSums::kDirs; ++j) {
          double m1 = 0.0, v1 = 0.0, m = 0.0, v = 0.0;
          mean_var(one.sum[j], one.sum2[j], kSamples, m1, v1);
          mean_var(e.sum[j], e.sum2[j], kSamples, m, v);
          const double z = (m - m1) / std::sqrt(std::max(v1 + v, 1e-300));
          if (l == 1 || l == 2) {
            worst[l] = std::max(worst[l], std::fabs(z));
            EXPECT_LT(std::fabs(z), 4.5) << "level " << levels[l] << " roughness " << c.roughness << " theta " << theta
                                         << " direction " << j << ": " << m << " one walk " << m1;
          }
          (j < 3 ? through_var : back_var)[l] += v * kSamples;
        }
        if (a == 0) first[l] = e.pooled / kSamples;
        const double bias = a == 0 ? kInjectedBias : a == 2 ? -kInjectedBias * first[l] / (e.pooled / kSamples) : 0.0;
        const double z = angle_z(e.pooled, e.pooled2, one.pooled, one.pooled2, kSamples, bias, check[l]);
        if (l == 1 || l == 2) {
          EXPECT_LT(std::fabs(z), 4.5) << "level " << levels[l] << " theta " << theta;
        }
        mean_var(e.pooled, e.pooled2, kSamples, pooled[l], var[l]);
      }
    }
    double z[4];
    for (int l = 0; l < 4; ++l) z[l] = (pooled[l] - pooled_one) / std::sqrt(var_one + var[l]);
    std::printf(
        "[frosted sg pane branches] roughness %.2f ior %.2f%s: pooled z main split %.2f, level 1 %.2f, 2 %.2f "
        "(worst |z| %.2f / %.2f over 15, %.2f / %.2f over 3 angles); control z %.1f; injected +-%.0f %% per "
        "angle into level 2: worst over 3 angles %.1f; variance per sample / main split's, back directions: "
        "level 1 %.3f, 2 %.3f; through: %.3f, %.3f\n",
        double(c.roughness), double(c.ior), c.absorb.x < 1.0f ? " grey Beer" : "", z[0], z[1], z[2], worst[1], worst[2],
        check[1].worst, check[2].worst, z[3], 100.0 * kInjectedBias, check[2].worst_injected, back_var[1] / back_var[0],
        back_var[2] / back_var[0], through_var[1] / through_var[0], through_var[2] / through_var[0]);
    for (int l = 0; l < 3; ++l) EXPECT_LT(std::fabs(z[l]), 4.0) << "level " << levels[l] << " roughness " << c.roughness;
    EXPECT_GT(std::fabs(z[3]), 6.0) << "negative control passed: roughness " << c.roughness;
    EXPECT_GT(check[2].worst_injected, 6.0) << "injected per-angle bias passed: roughness " << c.roughness;
    EXPECT_LT(back_var[1], back_var[0]) << "roughness " << c.roughness;
    EXPECT_LT(back_var[2], back_var[0]) << "roughness " << c.roughness;
  }
}

// Session 35 (frostedgrid35, frostedgridexact35; rewritten in session 36, frostedgrid36): the pane seen after a
// bounce (the context's diffuse_bounce 1: the bench's floor under the pane), where frosted::pane_front_grid_level
// puts the split's 3 extra front samples on a 2 x 2 grid with the primary's microfacet numbers (x, y): level 1 (each
// extra keeps its own transmit coin) and kPaneFrontGridExact (3: no coin, walk k weighted 4 p_k / (p_0 + ... + p_3)).
// Both are exactly unbiased (level 1: frosted_glass_sg.h; level 3: FrostedGlassClosure::pane_front_grid_exact_walks).
// E[weight x the exit mixture's density] toward the 5 probe directions at 4 angles up to 75 deg. Every (pane, angle)
// draws its own numbers: session 35's version drew the same numbers at every angle and every pane, so its pooled z
// added correlated terms as if independent and its panes' shared +0.3..0.5 % (grid - main split) was one draw's
// fluctuation seen three times (docs/history/frosted_glass_sessions.md "Session 36 (frostedgrid36)"). (1) Against one
// walk (split 1, independent numbers): levels 1 and 3 within 4.5 se per (angle, direction), main's split and both
// levels within 4 se pooled (each draw's sum over the directions; the angles independent); its negative control
// kPaneFrontGridExactControl > 6 se pooled. (2) Paired, the same draws (the primary and
// its walk shared): each level minus main's split (level 0) within 4.5 of its own se per angle and 4 pooled.
// Negative controls, paired against main's split: kPaneFrontGridControl (level 1's shifted numbers not uniform) and
// kPaneFrontGridExactControl (the normaliser without p_0) > 6 se pooled at every pane; the Fresnel weight alone
// (kPaneFrontGridNoFresnelControl, kPaneFrontGridReflectControl) > 6 se at one angle at least, at the pane flagged
// `fresnel_controls` (r 0.6, IOR 1.7, strong Beer: F over one orbit's facets varies most at 60-75 deg and the walk's
// value with it; their bias changes sign between 0 and 60 deg, so the pooled sum hides it).
// IOR 2.4 (the walk's tail index ~1.7: infinite variance, sample se too small) is checked by a median of means:
// RoughPaneFrontGridAfterABounceHighIorMedianOfMeans below.
struct FrontGridPane {
  PaneConfig config;
  long samples;           // draws per angle
  bool fresnel_controls;  // also the Fresnel-weight controls (5, 6)
};
struct FrontGridSums {
  // main's split (0), the grid (1), its control (9), the exact grid (3), its controls (7; 5 and 6: the Fresnel weight)
  static constexpr int kLevels = 7;
  static constexpr int kLevel[kLevels] = {0,
                                          1,
                                          frosted::kPaneFrontGridControl,
                                          frosted::kPaneFrontGridExact,
                                          frosted::kPaneFrontGridExactControl,
                                          frosted::kPaneFrontGridNoFresnelControl,
                                          frosted::kPaneFrontGridReflectControl};
  SplitSums one, est[kLevels];                       // one walk; each level on the shared draws
  double d[kLevels - 1] = {}, d2[kLevels - 1] = {};  // per draw, pooled over the directions: level l + 1 - main
};
// One (pane, angle): one walk on Pcg32(seed, 7), the first `levels` of kLevel on the shared draws Pcg32(seed + 1, 7).
void front_grid_sums(const FrostedGlassClosure &pane, float theta, long samples, uint64_t seed, int levels,
                     FrontGridSums &out) {
  static const auto schema = FrostedGlassClosure::params();
  out.one = split_estimate(pane, theta, 1, false, seed, samples, nullptr, -1, 1, 0);
  Pcg32 rng(seed + 1, 7);
  for (long i = 0; i < samples; ++i) {
    const PaneDraw draw(theta, rng, schema, 1);
    double v[FrontGridSums::kLevels][SplitSums::kDirs], p[FrontGridSums::kLevels] = {};
    for (int l = 0; l < levels; ++l) {
      split_values(pane, draw, frosted::kPaneWalkSplit, false, -1, FrontGridSums::kLevel[l], v[l]);
      out.est[l].add(v[l]);
      for (double x : v[l]) p[l] += x;
    }
    for (int l = 0; l + 1 < levels; ++l)
      out.d[l] += p[l + 1] - p[0], out.d2[l] += (p[l + 1] - p[0]) * (p[l + 1] - p[0]);
  }
}
TEST(FrostedGlassSgPane, RoughPaneFrontGridAfterABounceSameExpectationAsOneWalk) {
  const FrontGridPane panes[] = {{{0.5f, 1.5f}, 32768, false},
                                 {{0.8f, 1.5f}, 65536, false},
                                 {{0.6f, 1.7f, Vec3(0.7f), 0.05f}, 32768, false},
                                 {{0.6f, 1.7f, Vec3(0.3f), 0.05f}, 32768, true}};
  const float angles[] = {0.0f, 35.0f, 60.0f, 75.0f};
  constexpr int kL = FrontGridSums::kLevels;
  for (int pi = 0; pi < int(std::size(panes)); ++pi) {
    const PaneConfig &c = panes[pi].config;
    const long samples = panes[pi].samples;
    const int levels = panes[pi].fresnel_controls ? kL : 5;
    auto pane = create_pane(c, "sg");
    double one = 0.0, var_one = 0.0, pooled[kL] = {}, var[kL] = {}, d[kL - 1] = {}, var_d[kL - 1] = {};
    double sample_var[kL] = {}, worst[kL] = {}, worst_paired[kL] = {};
    for (int a = 0; a < int(std::size(angles)); ++a) {
      FrontGridSums g;
      front_grid_sums(*pane, angles[a], samples, 5050 + 16 * pi + 2 * a, levels, g);  // own seeds per (pane, angle)
      mean_var(g.one.pooled, g.one.pooled2, samples, one, var_one);
      for (int l = 0; l < levels; ++l) mean_var(g.est[l].pooled, g.est[l].pooled2, samples, pooled[l], var[l]);
      for (int l = 1; l < levels; ++l) {  // paired, this angle: level l - main split
        double m = 0.0, v = 0.0;
        mean_var(g.d[l - 1], g.d2[l - 1], samples, m, v);
        worst_paired[l] = std::max(worst_paired[l], std::fabs(m) / std::sqrt(v));
        if (l == 1 || l == 3) {
          EXPECT_LT(std::fabs(m) / std::sqrt(v), 4.5) << "level " << FrontGridSums::kLevel[l] << " - main split, "
                                                      << "roughness " << c.roughness << " theta " << angles[a];
        }
        d[l - 1] += m, var_d[l - 1] += v;
      }
      for (int j = 0; j < SplitSums::kDirs; ++j) {
        double m1 = 0.0, v1 = 0.0;
        mean_var(g.one.sum[j], g.one.sum2[j], samples, m1, v1);
        for (int l : {0, 1, 3}) {  // main's split (the sample variance), the grid, the exact grid
          double m = 0.0, v = 0.0;
          mean_var(g.est[l].sum[j], g.est[l].sum2[j], samples, m, v);
          sample_var[l] += v;
          if (l == 0) continue;
          const double z = (m - m1) / std::sqrt(v1 + v);
          worst[l] = std::max(worst[l], std::fabs(z));
          EXPECT_LT(std::fabs(z), 4.5) << "level " << FrontGridSums::kLevel[l] << ", roughness " << c.roughness
                                       << " ior " << c.ior << " theta " << angles[a] << " direction " << j << ": " << m
                                       << " one walk " << m1;
        }
      }
    }
    const auto z_one = [&](int l) { return (pooled[l] - one) / std::sqrt(var_one + var[l]); };
    const auto z_d = [&](int l) { return d[l - 1] / std::sqrt(var_d[l - 1]); };
    EXPECT_LT(std::fabs(z_one(0)), 4.0) << "main split, roughness " << c.roughness << " ior " << c.ior;
    std::printf("[frosted sg pane front grid] roughness %.2f ior %.2f: control 7 against one walk pooled z %.1f\n",
                double(c.roughness), double(c.ior), z_one(4));
    EXPECT_GT(std::fabs(z_one(4)), 6.0) << "negative control of the one-walk check passed: roughness " << c.roughness;
    for (int l : {1, 3}) {
      std::printf(
          "[frosted sg pane front grid] level %d, roughness %.2f ior %.2f%s, after a bounce, %ld draws: vs one "
          "walk pooled z main split %.2f, level %.2f (worst |z| %.2f over 20); paired level - main split "
          "%+.5f (relative %+.4f, se %.4f) z %.2f (worst |z| %.2f over 4 angles); control z %.1f; variance per "
          "sample level / main split %.3f\n",
          FrontGridSums::kLevel[l], double(c.roughness), double(c.ior), c.absorb.x < 1.0f ? " grey Beer" : "", samples,
          z_one(0), z_one(l), worst[l], d[l - 1], d[l - 1] / pooled[0], std::sqrt(var_d[l - 1]) / pooled[0], z_d(l),
          worst_paired[l], z_d(l + 1), sample_var[l] / sample_var[0]);
      EXPECT_LT(std::fabs(z_one(l)), 4.0)
          << "level " << FrontGridSums::kLevel[l] << ", roughness " << c.roughness << " ior " << c.ior;
      EXPECT_LT(std::fabs(z_d(l)), 4.0) << "level " << FrontGridSums::kLevel[l] << " - main split, roughness "
                                        << c.roughness << " ior " << c.ior;
      EXPECT_GT(std::fabs(z_d(l + 1)), 6.0) << "negative control of level " << FrontGridSums::kLevel[l]
                                            << " passed: roughness " << c.roughness << " ior " << c.ior;
    }
    for (int l = 5; l < levels; ++l) {  // caught per angle (their pooled sum cancels: low at 0 deg, high at 60-75)
      std::printf(
          "[frosted sg pane front grid] Fresnel-weight control %d, roughness %.2f ior %.2f: paired - main "
          "split pooled relative %+.4f, z %.1f; worst |z| over the 4 angles %.1f\n",
          FrontGridSums::kLevel[l], double(c.roughness), double(c.ior), d[l - 1] / pooled[0], z_d(l), worst_paired[l]);
      EXPECT_GT(worst_paired[l], 6.0) << "Fresnel-weight control " << FrontGridSums::kLevel[l] << " passed";
    }
  }
}

// IOR 2.4 (r 0.8, after a bounce): the walk's throughput has a tail of index ~1.7 (frostedsplit35): infinite
// variance, so a sample se is too small and a z bound on it is not calibrated. Here each level minus main's split on
// shared draws is checked by a median of means: 16 independent blocks (own seeds), each block's paired difference
// pooled over 4 angles x 5 directions; z = the blocks' median over its robust se (1.2533 x 1.4826 x their median
// absolute deviation / sqrt(16), a normal law's): levels 1 and 3 within 4, the control 7 beyond 6. Calibrated on 40
// replications with other seeds (frostedgrid36; docs "Session 36 (frostedgrid36)"): levels 1 / 3 sd 1.13 / 1.20,
// worst |z| 2.17 / 2.71; control 7 12.3..59.3. The control 9 (-7 %) is printed, not asserted: |z| 3.2..12.8 over
// the replications, below 4 in 3 of 40 (it is asserted above, at 50+ se, on the other panes).
struct HighIorGrid {
  static constexpr int kLevels = 5;  // FrontGridSums::kLevel's first five: 0, 1, 9, 3, 7
  double median_z[kLevels] = {}, plain_z[kLevels] = {}, relative[kLevels] = {};
};
HighIorGrid high_ior_grid(const FrostedGlassClosure &pane, uint64_t seed, int blocks, long draws) {
  static const auto schema = FrostedGlassClosure::params();
  constexpr int kL = HighIorGrid::kLevels;
  const float angles[] = {0.0f, 35.0f, 60.0f, 75.0f};
  std::vector<double> block[kL];
  double sum[kL] = {}, var[kL] = {};
  for (int b = 0; b < blocks; ++b) {
    double m[kL] = {};
    for (int a = 0; a < 4; ++a) {
      Pcg32 rng(seed + 8 * uint64_t(b) + uint64_t(a), 7);
      double s[kL] = {}, s2[kL] = {};
      for (long i = 0; i < draws; ++i) {
        const PaneDraw draw(angles[a], rng, schema, 1);
        double v[SplitSums::kDirs], p[kL] = {};
        for (int l = 0; l < kL; ++l) {
          split_values(pane, draw, frosted::kPaneWalkSplit, false, -1, FrontGridSums::kLevel[l], v);
          for (double x : v) p[l] += x;
          const double x = l == 0 ? p[0] : p[l] - p[0];  // main's value; the other levels' paired difference
          s[l] += x, s2[l] += x * x;
        }
      }
      for (int l = 0; l < kL; ++l) mean_var(s[l], s2[l], double(draws), m[l], var[l]);
    }
    for (int l = 0; l < kL; ++l) block[l].push_back(m[l]), sum[l] += m[l];
  }
  const double main_mean = sum[0] / blocks;
  const auto median = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    const size_t h = v.size() / 2;
    return v.size() % 2 ? v[h] : 0.5 * (v[h - 1] + v[h]);
  };
  HighIorGrid out;
  for (int l = 1; l < kL; ++l) {
    std::vector<double> &x = block[l];
    const double med = median(x);
    std::vector<double> dev;
    for (double y : x) dev.push_back(std::fabs(y - med));
    const double se = 1.2533 * 1.4826 * median(dev) / std::sqrt(double(blocks));
    out.median_z[l] = med / se;
    out.plain_z[l] = (sum[l] / blocks) / std::sqrt(var[l] / (double(blocks) * blocks));
    out.relative[l] = med / main_mean;
  }
  return out;
}
TEST(FrostedGlassSgPane, RoughPaneFrontGridAfterABounceHighIorMedianOfMeans) {
  auto pane = create_pane({0.8f, 2.4f}, "sg");
  const HighIorGrid g = high_ior_grid(*pane, 7070, 16, 2048);
  for (int l = 1; l < HighIorGrid::kLevels; ++l)
    std::printf(
        "[frosted sg pane front grid, IOR 2.4] level %d - main split: median of 16 blocks relative %+.4f, "
        "z %.2f (the plain sample-se z %.2f)\n",
        FrontGridSums::kLevel[l], g.relative[l], g.median_z[l], g.plain_z[l]);
  EXPECT_LT(std::fabs(g.median_z[1]), 4.0) << "level 1";
  EXPECT_LT(std::fabs(g.median_z[3]), 4.0) << "level 3";
  EXPECT_GT(std::fabs(g.median_z[4]), 6.0) << "negative control 7 passed";
}

// split = 1 is the unsplit sample bit for bit; coloured Beer keeps one walk (the split would be biased there).
TEST(FrostedGlassSgPane, RoughPaneSplitOfOneIsTheWalk) {
  const auto schema = FrostedGlassClosure::params();
  long compared = 0, differing = 0, coloured_same = 0, coloured = 0;
  for (const PaneConfig &c : {PaneConfig{0.6f, 1.5f}, PaneConfig{0.9f, 2.4f}, PaneConfig{0.5f, 1.5f, Vec3(0.9f, 0.5f, 0.2f)}}) {
    auto pane = create_pane(c, "sg");
    const bool coloured_beer = c.absorb.x != c.absorb.y;
    Pcg32 rng(5);
    for (int i = 0; i < 4000; ++i) {
      GlimmerShadingContext ctx = pane_context(70.0f * rng.next_float());
      ctx.path_seed = rng.next_u32();
      const ShadingPoint sp(&ctx, schema);
      const Vec3 rand(rng.next_float(), rng.next_float(), rng.next_float());
      LocalSample a, b;
      // A sample of zero weight (a walk absorbed to 0 by Beer) is the split's "no sample": both count 0.
      const bool ok_a = pane->pane_sample_sg_split(sp, rand, a, 1, false) && max_component(a.f_cos) > 0.0f;
      const bool ok_b = pane->pane_sample_sg(sp, rand, b, frosted::SgVariant::kPaneWalk, frosted::kPaneLadder,
                                             coloured_beer ? frosted::kPaneWalkSplit : 1) &&
                        max_component(b.f_cos) > 0.0f;
      const bool same = ok_a == ok_b && (!ok_a || (a.wo.x == b.wo.x && a.wo.y == b.wo.y && a.wo.z == b.wo.z &&
                                                   a.f_cos.x == b.f_cos.x && a.f_cos.z == b.f_cos.z &&
                                                   a.label == b.label && a.lobe_sharpness == b.lobe_sharpness));
      if (coloured_beer) {
        ++coloured;
        coloured_same += same;
      } else {
        ++compared;
        differing += !same;
      }
    }
  }
  EXPECT_EQ(differing, 0) << "of " << compared;
  EXPECT_EQ(coloured_same, coloured);
}

// ---- The rough pane's exact exit for the lamps (session 24, frostedpane24) -------------------------------------
// The split sample hands the host the picked face's walks (frosted::PaneSgExitState), and eval_exit gives the exact
// exit's value over the sample's weight, q(w) = sum_k (t_k / t_F) f_k(w) / E_k. So W q(w) (W the sample's weight) is
// an estimate of the pane's f cos toward w (the front reflection excluded), as method=path's exit state is
// (eval_exit = W_path T f_T(d, w) cos, checked in test_frosted_pane.cpp). Per incidence angle (0 / 30 / 60 deg)
// and 5 fixed directions (3 through the far face, 2 back through the entry face), the two estimates' means on
// independent numbers: every (angle, direction) within 4.5 standard errors and the sum over them within 4 (pooled).
// Negative control: the SG mixture the host integrated before (W x the mixture's density) must be > 6 standard
// errors off path in at least one (angle, direction) (at 32768 samples: worst |z| 46.8 at roughness 0.5, the
// mixture 25 % low toward the far face's off-axis direction at 30 deg; 5.7 at 0.8). Every split sample carries a
// state.
// Session 39 (frostedpane39): the old version drew sg's numbers from seed 303 and path's from 404 at every angle and
// pane and pooled the 15 cells as if independent: on its own draws (a lockstep, every angle restarted in step,
// benchmarks/frosted_pane_pooling_lockstep_s39.patch) it reproduces the old pooled z -1.44 / -3.13 (r 0.5 / 0.8) and
// gives -1.10 / -2.09 with every covariance counted: its se 1.31 / 1.49x too small (the shared angles 1.32 / 1.35x,
// the directions' covariance 0.99 / 1.11x); over 16 independent seed sets (16384 draws per angle) the sd of the old
// pooled z was 1.33 / 1.86 (all counted 1.01 / 1.25). Now own numbers per (pane, angle) (path Pcg32(3030 + 16 pane +
// 2 angle, 9), sg + 1), pooled over each draw's sum over the directions (ExitSums::pooled: their covariance
// counted), the angles independent; per angle that sum within 4.5 se (angle_z) and its injected control (+3 % at 0
// deg, the opposite at 60 deg: the pooled sum unmoved) > 6 se at one angle on each pane. Measured: pooled z +0.33 /
// -1.00, worst per angle 0.87 / 1.35, worst per cell 1.36 / 1.85, injected 61.3 / 16.0, SG mixture 91.9 / 13.5.
// Each draw's sum over the probe directions (grey and per channel): its variance counts their covariance.
struct DrawSums {
  double grey = 0.0, grey2 = 0.0, rgb[3] = {}, rgb2[3] = {};
  void add(double t, const double (&tc)[3]) {
    grey += t, grey2 += t * t;
    for (int ch = 0; ch < 3; ++ch) rgb[ch] += tc[ch], rgb2[ch] += tc[ch] * tc[ch];
  }
};
struct ExitSums {
  static constexpr int kDirs = 5;
  DrawSums pooled;  // each draw's sum over the directions
  double sum[kDirs] = {}, sum2[kDirs] = {}, ctl[kDirs] = {}, ctl2[kDirs] = {};
  double rgb[kDirs][3] = {}, rgb2[kDirs][3] = {};  // per channel (the state's value times the weight's channel)
  long samples = 0, exits = 0, states = 0;
};
ExitSums exact_exit_estimate(const FrostedGlassClosure &pane, bool sg, float theta_deg, uint64_t seed, long samples) {
  static const auto schema = FrostedGlassClosure::params();
  const auto &dirs = kPaneProbeDirections;
  ExitSums out;
  Pcg32 rng(seed, 9);
  for (long i = 0; i < samples; ++i) {
    const PaneDraw draw(theta_deg, rng, schema);
    const ShadingPoint &sp = draw.sp;
    const Vec3 &rand = draw.rand;
    WiredSample wired;
    LocalSample &s = wired.s;
    ++out.samples;
    if (!pane.sample(sp, rand, s) || !(s.label & GLIMMER_LABEL_SINGULAR)) continue;  // 0 toward every direction
    ++out.exits;
    out.states += s.exit_state;
    ExitLobeMixture m;
    if (sg && s.exit_lobe) m = sampled_exit_mixture(s, wired.buffer);
    const double w = average(s.f_cos / s.pdf);
    double t = 0.0, tc[3] = {};
    for (int j = 0; j < ExitSums::kDirs; ++j) {
      double v = 0.0, c = 0.0;
      if (s.exit_state) {
        const Spectrum f = pane.eval_exit(sp, wired.state, dirs[j]).f_cos;
        const double e = average(f);
        v = sg ? w * e : e;  // sg: the value over the weight; path: the walk's f cos estimate itself
        for (int ch = 0; ch < 3; ++ch) {
          const double vc = sg ? double(s.f_cos[ch] / s.pdf) * f[ch] : f[ch];
          out.rgb[j][ch] += vc, out.rgb2[j][ch] += vc * vc, tc[ch] += vc;
        }
      }
      if (sg && m.count > 0) c = w * m.pdf(dirs[j]);
      out.sum[j] += v, out.sum2[j] += v * v, t += v;
      out.ctl[j] += c, out.ctl2[j] += c * c;
    }
    out.pooled.add(t, tc);
  }
  return out;
}

TEST(FrostedGlassSgPane, RoughPaneExactExitAgainstThePathsExitState) {
  const PaneConfig configs[] = {{0.5f, 1.5f}, {0.8f, 1.5f}};
  const float angles[] = {0.0f, 30.0f, 60.0f};
  constexpr long kSamples = 131072;
  for (int ci = 0; ci < int(std::size(configs)); ++ci) {
    const PaneConfig &c = configs[ci];
    auto sg = create_pane(c, "sg"), path = create_pane(c, "path");
    double pooled_sg = 0.0, pooled_path = 0.0, var_sg = 0.0, var_path = 0.0, worst_z = 0.0, worst_ctl = 0.0;
    double first = 0.0;
    AngleCheck check;  // each draw's sum over the directions per angle, and its injected control
    for (int ai = 0; ai < int(std::size(angles)); ++ai) {
      const float theta = angles[ai];
      const uint64_t seed = 3030 + 16 * uint64_t(ci) + 2 * uint64_t(ai);  // own numbers per (pane, angle)
      const ExitSums b = exact_exit_estimate(*path, false, theta, seed, kSamples);
      const ExitSums a = exact_exit_estimate(*sg, true, theta, seed + 1, kSamples);
      EXPECT_EQ(a.states, a.exits) << "roughness " << c.roughness << " theta " << theta;
      EXPECT_GT(a.states, kSamples / 2);
      for (int j = 0; j < ExitSums::kDirs; ++j) {
        const double z = mean_difference_z(a.sum[j], a.sum2[j], b.sum[j], b.sum2[j], kSamples);
        // the SG mixture shares sg's draws, not path's: independent of path's numbers
        const double z_ctl = mean_difference_z(a.ctl[j], a.ctl2[j], b.sum[j], b.sum2[j], kSamples);
        worst_z = std::max(worst_z, std::fabs(z));
        worst_ctl = std::max(worst_ctl, std::fabs(z_ctl));
        EXPECT_LT(std::fabs(z), 4.5) << "roughness " << c.roughness << " theta " << theta << " direction " << j
                                     << ": sg exact exit " << a.sum[j] / kSamples << ", path " << b.sum[j] / kSamples;
        std::printf(
            "[frosted sg pane exact exit] roughness %.1f theta %2.0f direction %d: path %.5f, sg exact "
            "%.5f (z %+.2f), SG mixture %.5f (z %+.2f)\n",
            double(c.roughness), double(theta), j, b.sum[j] / kSamples, a.sum[j] / kSamples, z, a.ctl[j] / kSamples,
            z_ctl);
      }
      // pooled over the directions by each draw's sum (their covariance counted), the angles independent
      mean_var(a.pooled.grey, a.pooled.grey2, kSamples, pooled_sg, var_sg);
      mean_var(b.pooled.grey, b.pooled.grey2, kSamples, pooled_path, var_path);
      if (ai == 0) first = a.pooled.grey / kSamples;
      const double bias = ai == 0 ? kInjectedBias : ai == 2 ? -kInjectedBias * first / (a.pooled.grey / kSamples) : 0.0;
      EXPECT_LT(std::fabs(angle_z(a.pooled.grey, a.pooled.grey2, b.pooled.grey, b.pooled.grey2, kSamples, bias, check)),
                4.5)
          << "roughness " << c.roughness << " theta " << theta;
    }
    const double z_pooled = (pooled_sg - pooled_path) / std::sqrt(var_sg + var_path);
    const double z_injected = (check.injected - pooled_path) / std::sqrt(check.var_injected + var_path);
    std::printf(
        "[frosted sg pane exact exit] roughness %.1f: pooled z %.2f, worst |z| %.2f over 15, %.2f over 3 "
        "angles; injected +-%.0f %% per angle: worst %.1f (pooled %.2f); the SG mixture's worst |z| %.1f "
        "(negative control)\n",
        double(c.roughness), z_pooled, worst_z, check.worst, 100.0 * kInjectedBias, check.worst_injected, z_injected,
        worst_ctl);
    EXPECT_LT(std::fabs(z_pooled), 4.0) << "roughness " << c.roughness;
    EXPECT_GT(check.worst_injected, 6.0) << "injected per-angle bias passed: roughness " << c.roughness;
    EXPECT_GT(worst_ctl, 6.0) << "negative control passed: roughness " << c.roughness;
  }
}

// Session 32 (frostedvar32): where the split sample writes the exact exit (PaneSgExitState), its continued direction
// is the picked end's own leaving direction (frosted::pane_exact_leaving_level 1, the default): the continued path's
// directions then follow method=path's walk. Per configuration, 3 angles x 5 cones (half-angle 25 deg about
// kPaneProbeDirections: 3 through the far face, 2 back through the entry face) of E[weight x 1{wo in the cone}] for
// sg (the split, its front reflections included) against path's pane sample (the brute force, independent numbers):
// every (angle, cone) within 4.5 se and the sum over them within 4 (pooled). Negative control: level 0 (the continued
// direction drawn from the face's SG mixture, main's) must be > 6 se off path in at least one (configuration, angle,
// cone).
// Session 38 (frostedpane38): the old version drew path's numbers from seed 505 and sg's from 606 at every angle and
// configuration and pooled the 15 cells as if independent: on its own draws (a lockstep: every angle restarted in
// step, each draw's sum over the angles and cones kept) its pooled se was 1.27 / 1.42 / 1.37x too small (shared
// angles 1.26-1.27x, overlapping cones 1.01-1.12x); 16 independent seed sets gave an sd of the old pooled z of 0.96 /
// 1.01 / 1.39 (0.76 / 0.71 / 1.01 with everything counted). Now own numbers per (configuration, angle) (path
// Pcg32(5050 + 16 config + 2 angle, 11), sg's two levels + 1, paired), pooled over each draw's sum over the cones
// (ConeSums::pooled: their covariance counted), the angles independent; per angle that sum within 4.5 se (angle_z);
// the injected control (+3 % at 0 deg, the opposite at 60 deg: the pooled sum unmoved) > 6 se at one angle on
// every configuration.
struct ConeSums {
  static constexpr int kCones = 5;
  double sum[kCones] = {}, sum2[kCones] = {};
  double rgb[kCones][3] = {}, rgb2[kCones][3] = {};  // per channel: the weight's channel x 1{wo in the cone}
  double pooled_rgb[3] = {}, pooled_rgb2[3] = {};    // per channel: each draw's sum over the cones (they overlap)
  double pooled = 0.0, pooled2 = 0.0;                // grey: each draw's sum over the cones
  long states = 0;
};
// both_faces: frosted::pane_both_faces_level's level for the sg split (-1: the knob's; session 35's coloured-Beer
// check passes kPaneOneColourState as its negative control).
ConeSums continued_cones(const FrostedGlassClosure &pane, bool sg, int level, float theta_deg, uint64_t seed,
                         long samples, int both_faces = -1) {
  static const auto schema = FrostedGlassClosure::params();
  const float cos_cone = std::cos(25.0f * kPi / 180.0f);
  ConeSums out;
  Pcg32 rng(seed, 11);
  for (long i = 0; i < samples; ++i) {
    const PaneDraw draw(theta_deg, rng, schema);
    WiredSample wired;
    LocalSample &s = wired.s;
    const bool ok =
        sg ? pane.pane_sample_sg_split(draw.sp, draw.rand, s, frosted::kPaneWalkSplit, false, -1, level, both_faces)
           : pane.sample(draw.sp, draw.rand, s);
    if (!ok || !(s.pdf > 0.0f)) continue;
    out.states += s.exit_state;
    const Spectrum W = s.f_cos / s.pdf;
    const double w = average(W);
    const Vec3 wo = normalize(s.wo);
    int cones = 0;  // the cones wo is in
    for (int j = 0; j < ConeSums::kCones; ++j) {
      const bool in = dot(wo, kPaneProbeDirections[j]) > cos_cone;
      cones += in;
      const double v = in ? w : 0.0;
      out.sum[j] += v, out.sum2[j] += v * v;
      for (int ch = 0; ch < 3; ++ch) {
        const double vc = in ? double(W[ch]) : 0.0;
        out.rgb[j][ch] += vc, out.rgb2[j][ch] += vc * vc;
      }
    }
    for (int ch = 0; ch < 3; ++ch) {
      const double t = cones * double(W[ch]);
      out.pooled_rgb[ch] += t, out.pooled_rgb2[ch] += t * t;
    }
    out.pooled += cones * w, out.pooled2 += cones * w * cones * w;
  }
  return out;
}

TEST(FrostedGlassSgPane, RoughPaneContinuedDirectionFollowsThePathsWalk) {
  const PaneConfig configs[] = {{0.5f, 1.5f}, {0.8f, 1.5f}, {0.6f, 1.7f, Vec3(0.7f), 0.05f}};
  const float angles[] = {0.0f, 30.0f, 60.0f};
  constexpr long kSamples = 262144;
  double worst_control = 0.0;
  for (int ci = 0; ci < int(std::size(configs)); ++ci) {
    const PaneConfig &c = configs[ci];
    auto sg = create_pane(c, "sg"), path = create_pane(c, "path");
    double pooled[2] = {}, var[2] = {}, pooled_path = 0.0, var_path = 0.0, worst[2] = {}, first = 0.0;
    AngleCheck check;  // level 1 (the default) against path per angle, and its injected control
    for (int a = 0; a < int(std::size(angles)); ++a) {
      const float theta = angles[a];
      const uint64_t seed = 5050 + 16 * uint64_t(ci) + 2 * uint64_t(a);  // own numbers per (config, angle)
      const ConeSums b = continued_cones(*path, false, 0, theta, seed, kSamples);
      for (int level = 0; level < 2; ++level) {
        const ConeSums e = continued_cones(*sg, true, level, theta, seed + 1, kSamples);  // the levels paired
        EXPECT_GT(e.states, kSamples / 2) << "roughness " << c.roughness << " theta " << theta;
        for (int j = 0; j < ConeSums::kCones; ++j) {
          const double z = mean_difference_z(e.sum[j], e.sum2[j], b.sum[j], b.sum2[j], kSamples);
          worst[level] = std::max(worst[level], std::fabs(z));
          if (level == 1) {
            EXPECT_LT(std::fabs(z), 4.5) << "roughness " << c.roughness << " theta " << theta << " cone " << j;
          }
        }
        mean_var(e.pooled, e.pooled2, kSamples, pooled[level], var[level]);
        if (level == 0) continue;
        mean_var(b.pooled, b.pooled2, kSamples, pooled_path, var_path);
        if (a == 0) first = e.pooled / kSamples;
        const double bias = a == 0 ? kInjectedBias : a == 2 ? -kInjectedBias * first / (e.pooled / kSamples) : 0.0;
        EXPECT_LT(std::fabs(angle_z(e.pooled, e.pooled2, b.pooled, b.pooled2, kSamples, bias, check)), 4.5)
            << "roughness " << c.roughness << " theta " << theta;
      }
    }
    const double z1 = (pooled[1] - pooled_path) / std::sqrt(var[1] + var_path);
    const double z0 = (pooled[0] - pooled_path) / std::sqrt(var[0] + var_path);
    std::printf(
        "[frosted sg pane continued direction] roughness %.2f ior %.2f%s: exact leaving pooled z %.2f, worst "
        "|z| %.2f over 15, %.2f over 3 angles; injected +-%.0f %% per angle: worst %.1f; SG draw (control) "
        "pooled z %.2f, worst |z| %.1f\n",
        double(c.roughness), double(c.ior), c.absorb.x < 1.0f ? " grey Beer" : "", z1, worst[1], check.worst,
        100.0 * kInjectedBias, check.worst_injected, z0, worst[0]);
    EXPECT_LT(std::fabs(z1), 4.0) << "roughness " << c.roughness;
    EXPECT_GT(check.worst_injected, 6.0) << "injected per-angle bias passed: roughness " << c.roughness;
    worst_control = std::max(worst_control, worst[0]);
  }
  EXPECT_GT(worst_control, 6.0) << "negative control passed";  // the SG's shape error is smallest at roughness 0.8
}

// Session 33 (frostedface33): the exit state with both faces' ends (frosted::pane_both_faces_level): the host's lamps
// see W q(w) toward every direction on either side of the pane in every sample, q summing the ends on w's side with
// c_k = (t_k / t_F) p_F / E_k. Per configuration (5 panes since session 34), 3 angles (0, 60 and 120 deg: seen from
// the back) x kPaneProbeDirections (3 through the far face, 2 back through the entry face) of E[W q(w_j)] for
// levels 1 (sqrt pick) and 2 (pick t_F / t) against method=path's
// exit state (the brute force, exact_exit_estimate, independent numbers): every (angle, direction) within 4.5 se, the
// sum over them within 4 (pooled); measured (session 34, 5 panes) pooled z +0.42 / -0.53 / -0.99 / +0.88 / +0.52.
// Negative control (kPaneBothFacesControl: c_k without p_F, the picked face's 1 / p_F kept for the other face's ends)
// must be > 6 se off on every pane (measured 76.5 / 85.9 / 81.6 / 73.0 / 68.0). Printed: each level's variance per
// sample over main's (level 0) toward the back and the through directions (level 1: back 0.598 / 0.599 / 0.653 /
// 0.169 / 0.663, through 0.542 / 0.646 / 0.658 / 0.506 / 0.598).
// Levels 1 and 2 give the same lamp values by construction: W c_k = t_k / (n E_k) does not depend on the face pick,
// so their rows here are one check run twice (identical figures); the pick's own effect (the continued direction's
// law at level 2) is not checked here (review 34, finding 5).
// Session 38 (frostedpane38): the old version drew path's numbers from seed 404 and sg's from 707 at every angle and
// pane and pooled the 15 cells as if independent: on its own draws (lockstep) its pooled se was 1.01 / 1.38 / 1.24 /
// 1.00 / 1.00x too small (r 0.5, r 0.8, r 0.6 Beer, r 0.15, tinted); 16 independent seed sets gave an sd of the old
// pooled z of 1.02 / 1.58 / 0.86 / 0.69 / 0.93 (1.02 / 1.16 / 0.70 / 0.69 / 0.94 with everything counted). Now own
// numbers per (pane, angle) (path Pcg32(seed_base + 2 angle, 9), sg's levels + 1, paired: 4040 + 16 pane here, 6060 +
// 16 pane in the coloured-Beer test), pooled over each draw's sum over the directions (DrawSums: their covariance
// counted, grey and per channel), the angles independent; level 1 per angle within 4.5 se (angle_z) and its injected
// control (+5 % at 0 deg, the opposite at 120 deg; 3 % gave 6.1 se at r 0.8) > 6 se at one angle on every pane.
struct BothFacesSums {
  static constexpr int kDirs = 5;
  double sum[kDirs] = {}, sum2[kDirs] = {};
  double rgb[kDirs][3] = {}, rgb2[kDirs][3] = {};  // per channel: W's channel x q(w_j)
  DrawSums pooled;                                 // each draw's sum over the directions
};
BothFacesSums both_faces_estimate(const FrostedGlassClosure &pane, int level, float theta_deg, uint64_t seed,
                                  long samples) {
  static const auto schema = FrostedGlassClosure::params();
  BothFacesSums out;
  Pcg32 rng(seed, 13);
  for (long i = 0; i < samples; ++i) {
    const PaneDraw draw(theta_deg, rng, schema);
    WiredSample wired;
    LocalSample &s = wired.s;
    if (!pane.pane_sample_sg_split(draw.sp, draw.rand, s, frosted::kPaneWalkSplit, false, -1, -1, level) ||
        !(s.label & GLIMMER_LABEL_SINGULAR) || !s.exit_state)
      continue;  // 0 toward every direction
    const Spectrum W = s.f_cos / s.pdf;
    const double w = average(W);
    double t = 0.0, tc[3] = {};
    for (int j = 0; j < BothFacesSums::kDirs; ++j) {
      const Spectrum q = pane.eval_exit(draw.sp, wired.state, kPaneProbeDirections[j]).f_cos;
      const double v = w * average(q);
      out.sum[j] += v, out.sum2[j] += v * v, t += v;
      for (int ch = 0; ch < 3; ++ch) {
        const double vc = double(W[ch]) * q[ch];
        out.rgb[j][ch] += vc, out.rgb2[j][ch] += vc * vc, tc[ch] += vc;
      }
    }
    out.pooled.add(t, tc);
  }
  return out;
}

// One pane of RoughPaneBothFacesLampsSameExpectationAsThePath: levels 0, 1, 2 and the control against path's exit
// state, 3 angles x 5 directions (levels 1 and 2 checked here; with a coloured tint or coloured Beer also per
// channel, each channel pooled over the 15). With coloured Beer the ends' colours differ, so pane_both_faces_scale's
// colour test falls back to the picked face's ends (levels 1 and the control then give level 0's sums bit for bit,
// checked) and the control is kPaneBothFacesNoColourGuard (the test bypassed), judged per channel. Returns the
// control's pooled |z| (with coloured Beer the worst channel's).
double check_both_faces(const PaneConfig &c, uint64_t seed_base, double *one_colour_worst = nullptr) {
  const float angles[] = {0.0f, 60.0f, 120.0f};  // 120: the pane seen from its back (the flipped frame)
  constexpr long kSamples = 32768;
  constexpr int kDirs = BothFacesSums::kDirs;
  const auto grey = [](const Vec3 &v) { return v.x == v.y && v.y == v.z; };
  const bool beer = !grey(c.absorb), coloured = beer || !grey(c.tint);
  const int levels[] = {
      0, 1, 2, frosted::kPaneBothFacesControl, frosted::kPaneBothFacesNoColourGuard, frosted::kPaneOneColourState};
  const int n_levels = beer ? 6 : 4;  // the guard's bypass and the old one-colour state only where colours differ
  auto sg = create_pane(c, "sg"), path = create_pane(c, "path");
  double pooled[6] = {}, var[6] = {}, pooled_path = 0.0, var_path = 0.0, worst[6] = {}, worst_rgb[6] = {};
  double back_var[6] = {}, through_var[6] = {};  // per sample, summed over the angles' directions
  double rgb_pooled[6][3] = {}, rgb_var[6][3] = {}, rgb_path[3] = {}, rgb_path_var[3] = {}, first = 0.0;
  bool as_level0[6] = {true, true, true, true, true, true};  // every sum bit for bit level 0's
  AngleCheck check;                                          // level 1 (grey) per angle, and its injected control
  constexpr double kInjected = 0.05;                         // 3 % reached 6.1 se only at r 0.8 (32768 draws per angle)
  for (int ai = 0; ai < 3; ++ai) {
    const float theta = angles[ai];
    const uint64_t seed = seed_base + 2 * uint64_t(ai);  // own numbers per (pane, angle); sg's levels paired
    const ExitSums b = exact_exit_estimate(*path, false, theta, seed, kSamples);
    BothFacesSums first_level;
    for (int l = 0; l < n_levels; ++l) {
      const BothFacesSums a = both_faces_estimate(*sg, levels[l], theta, seed + 1, kSamples);
      if (l == 0) first_level = a;
      for (int j = 0; j < kDirs; ++j)
        as_level0[l] = as_level0[l] && a.sum[j] == first_level.sum[j] && a.rgb[j][0] == first_level.rgb[j][0] &&
                       a.rgb[j][1] == first_level.rgb[j][1] && a.rgb[j][2] == first_level.rgb[j][2];
      const bool checked = l == 1 || l == 2;
      for (int j = 0; j < kDirs; ++j) {
        double ss = 0.0;
        const double z = mean_difference_z(a.sum[j], a.sum2[j], b.sum[j], b.sum2[j], kSamples, &ss);
        worst[l] = std::max(worst[l], std::fabs(z));
        if (checked) {
          EXPECT_LT(std::fabs(z), 4.5) << "level " << levels[l] << " theta " << theta << " direction " << j;
        }
        (kPaneProbeDirections[j].z > 0.0f ? back_var : through_var)[l] += ss;
        for (int ch = 0; ch < 3 && coloured; ++ch) {
          const double zc = mean_difference_z(a.rgb[j][ch], a.rgb2[j][ch], b.rgb[j][ch], b.rgb2[j][ch], kSamples);
          worst_rgb[l] = std::max(worst_rgb[l], std::fabs(zc));
          if (checked) {
            EXPECT_LT(std::fabs(zc), 4.5) << "level " << levels[l] << " theta " << theta << " ch " << ch;
          }
        }
      }
      // pooled over the directions by each draw's sum (their covariance counted), the angles independent
      mean_var(a.pooled.grey, a.pooled.grey2, kSamples, pooled[l], var[l]);
      for (int ch = 0; ch < 3 && coloured; ++ch)
        mean_var(a.pooled.rgb[ch], a.pooled.rgb2[ch], kSamples, rgb_pooled[l][ch], rgb_var[l][ch]);
      if (l != 1) continue;
      mean_var(b.pooled.grey, b.pooled.grey2, kSamples, pooled_path, var_path);
      for (int ch = 0; ch < 3 && coloured; ++ch)
        mean_var(b.pooled.rgb[ch], b.pooled.rgb2[ch], kSamples, rgb_path[ch], rgb_path_var[ch]);
      if (ai == 0) first = a.pooled.grey / kSamples;
      const double bias = ai == 0 ? kInjected : ai == 2 ? -kInjected * first / (a.pooled.grey / kSamples) : 0.0;
      EXPECT_LT(std::fabs(angle_z(a.pooled.grey, a.pooled.grey2, b.pooled.grey, b.pooled.grey2, kSamples, bias, check)),
                4.5)
          << "roughness " << c.roughness << " theta " << theta;
    }
  }
  double control = 0.0;
  for (int l = 0; l < n_levels; ++l) {
    const double z = (pooled[l] - pooled_path) / std::sqrt(var[l] + var_path);
    double zc[3] = {};
    for (int ch = 0; ch < 3 && coloured; ++ch)
      zc[ch] = (rgb_pooled[l][ch] - rgb_path[ch]) / std::sqrt(std::max(rgb_var[l][ch] + rgb_path_var[ch], 1e-300));
    std::printf("[frosted sg pane both faces] roughness %.2f ior %.2f%s%s level %d: pooled z %+.2f, worst |z| %.2f "
                "over 15; per channel pooled z %+.2f / %+.2f / %+.2f, worst |z| %.2f over 45; variance per sample / "
                "level 0's: back %.3f, through %.3f%s\n",
                double(c.roughness), double(c.ior), beer ? " coloured Beer" : c.absorb.x < 1.0f ? " grey Beer" : "",
                grey(c.tint) ? "" : " tinted", levels[l], z, worst[l], zc[0], zc[1], zc[2], worst_rgb[l],
                back_var[l] / back_var[0], through_var[l] / through_var[0],
                l > 0 && as_level0[l] ? " (level 0's sums bit for bit)" : "");
    if (l == 1 || l == 2) {
      EXPECT_LT(std::fabs(z), 4.0) << "level " << levels[l] << " roughness " << c.roughness;
      for (int ch = 0; ch < 3 && coloured; ++ch)
        EXPECT_LT(std::fabs(zc[ch]), 4.0) << "level " << levels[l] << " channel " << ch;
    }
    if (l == 3 && !beer) control = std::fabs(z);
    if (l == 4) control = std::max({std::fabs(zc[0]), std::fabs(zc[1]), std::fabs(zc[2])});
    if (l == 5 && one_colour_worst != nullptr) *one_colour_worst = worst_rgb[5];
  }
  std::printf(
      "[frosted sg pane both faces] roughness %.2f ior %.2f: level 1 worst |z| over 3 angles %.2f; injected "
      "+-%.0f %% per angle: worst %.1f\n",
      double(c.roughness), double(c.ior), check.worst, 100.0 * kInjected, check.worst_injected);
  EXPECT_GT(check.worst_injected, 6.0) << "injected per-angle bias passed: roughness " << c.roughness;
  // Without coloured Beer level 1 carries both faces (its sums differ from level 0's). With it (session 35) levels 0
  // and 1 are the one-end route alike (the both-faces state cannot carry the ends' colours): level 0's sums bit for
  // bit.
  if (!beer) {
    EXPECT_FALSE(as_level0[1]) << "roughness " << c.roughness;
  } else {
    EXPECT_TRUE(as_level0[1]) << "roughness " << c.roughness;
  }
  return control;
}

// Session 34 (frostedbudget34): two more panes, where the SG fits worst (roughness 0.15: the split's ends' E_k and
// the exit BTDF at a narrow lobe; in renders the split runs above kMixtureRoughnessMax, so this row checks the
// estimator, not a default route) and a coloured tint (0.9, 0.55, 0.25) per crossing (every end has the weight's
// colour, so both faces stay on; checked per channel); the negative control must fail on every pane. Session 34
// (frostedtestfix34): the per-channel checks only on coloured panes (they were vacuous, zc = 0, on grey ones); level 1
// must differ from level 0 on every pane here (the both-faces route ran).
TEST(FrostedGlassSgPane, RoughPaneBothFacesLampsSameExpectationAsThePath) {
  const PaneConfig configs[] = {{0.5f, 1.5f},
                                {0.8f, 1.5f},
                                {0.6f, 1.7f, Vec3(0.7f), 0.05f},
                                {0.15f, 1.5f},
                                {0.5f, 1.5f, Vec3(0.8f), 0.05f, Vec3(0.9f, 0.55f, 0.25f)}};
  for (int ci = 0; ci < int(std::size(configs)); ++ci) {
    const PaneConfig &c = configs[ci];
    const double control = check_both_faces(c, 4040 + 16 * uint64_t(ci));
    EXPECT_GT(control, 6.0) << "negative control passed: roughness " << c.roughness;
  }
}

// Session 34 (frostedtestfix34, review 34 finding 4) / session 35 (frostedbeer35): coloured Beer, so the ends'
// colours differ. Session 34 found the one-face state biased per channel (every end of the face in the face's weight's
// colour); session 35's one end per sample (frosted::kPaneOneColourState's comment) is exact per channel and turns the
// both-faces state off there (levels 0, 1, 2, 9 give the same sums bit for bit, checked). Two panes: r 0.5 Beer
// (0.9, 0.6, 0.3) and r 0.8 Beer (0.95, 0.5, 0.1). Measured (one end): per channel pooled z +0.81 / +0.96 / +1.01,
// worst |z| 1.24 over 45; +0.11 / +0.37 / +0.46, worst 1.64. Negative controls, both required on each pane: the old
// one-colour state (kPaneOneColourState, 65a01b6's code) worst per-cell |z| > 4.5 (measured 5.46 / 14.76: session
// 34's 5.46 to every digit) and kPaneBothFacesNoColourGuard's worst channel pooled |z| > 6 (13.32 / 23.04). ~15 s.
TEST(FrostedGlassSgPane, RoughPaneColouredBeerBothFacesPerChannel) {
  const PaneConfig configs[] = {{0.5f, 1.5f, Vec3(0.9f, 0.6f, 0.3f), 0.05f},
                                {0.8f, 1.5f, Vec3(0.95f, 0.5f, 0.1f), 0.05f}};
  for (int ci = 0; ci < int(std::size(configs)); ++ci) {
    const PaneConfig &c = configs[ci];
    double one_colour_worst = 0.0;
    EXPECT_GT(check_both_faces(c, 6060 + 16 * uint64_t(ci), &one_colour_worst), 6.0)
        << "negative control passed: roughness " << c.roughness;
    EXPECT_GT(one_colour_worst, 4.5) << "the old one-colour state passed: roughness " << c.roughness;
  }
}

// Session 35 (frostedbeer35): the continued path of the coloured-Beer split (one end per sample: the weight T_j / (n
// pi_j) carries end j's own colour, its leaving direction the continued one) per channel against method=path's pane
// sample (continued_cones: E[W_ch 1{wo in cone}], 3 angles x 5 cones x 3 channels, independent numbers): every cell
// within 4.5 se, each channel pooled over the 15 within 4. Negative control: kPaneOneColourState (the face's weight
// sum_{k in F} T_k / (n p_F) with an end picked by t_k / t_F: every end of the face in the face's colour) must be
// > 6 se off in some cell. Roughness 0.8, Beer (0.95, 0.5, 0.1): the more saturated of the two panes above.
// Session 37 (frostedpool37): the cones overlap (25 deg around directions 26-27 deg apart) and the old version drew
// the same numbers at every angle (path 505, sg 606): its pooled se was 1.41 / 1.44 / 1.59x too small per channel.
// Now own numbers per angle (path Pcg32(7070 + 2 angle, 11), sg's two levels + 1, paired), each channel pooled over
// each draw's sum over the cones (ConeSums::pooled_rgb: a draw in two cones counts twice, its covariance counted);
// per angle and channel that sum within 4.5 se; the injected control (+5 % at 0 deg, the opposite at 60 deg) > 6 se
// at one angle in every channel.
TEST(FrostedGlassSgPane, RoughPaneColouredBeerContinuedPathPerChannel) {
  const PaneConfig c{0.8f, 1.5f, Vec3(0.95f, 0.5f, 0.1f), 0.05f};
  const float angles[] = {0.0f, 30.0f, 60.0f};
  constexpr long kSamples = 131072;
  auto sg = create_pane(c, "sg"), path = create_pane(c, "path");
  double worst[2] = {}, pooled[2][3] = {}, var[2][3] = {}, pooled_path[3] = {}, var_path[3] = {}, first[3] = {};
  AngleCheck check[3];                // per channel, the default against path
  constexpr double kInjected = 0.05;  // the split tests' 3 % reached 5.6 se only in blue
  const int levels[] = {-1, frosted::kPaneOneColourState};
  for (int a = 0; a < int(std::size(angles)); ++a) {
    const float theta = angles[a];
    const uint64_t seed = 7070 + 2 * uint64_t(a);  // own numbers per angle (path; sg's two levels share theirs)
    const ConeSums b = continued_cones(*path, false, 0, theta, seed, kSamples);
    for (int l = 0; l < 2; ++l) {
      const ConeSums e = continued_cones(*sg, true, -1, theta, seed + 1, kSamples, levels[l]);
      EXPECT_GT(e.states, kSamples / 2) << "theta " << theta;
      for (int j = 0; j < ConeSums::kCones; ++j)
        for (int ch = 0; ch < 3; ++ch) {
          const double z = mean_difference_z(e.rgb[j][ch], e.rgb2[j][ch], b.rgb[j][ch], b.rgb2[j][ch], kSamples);
          worst[l] = std::max(worst[l], std::fabs(z));
          if (l == 0) {
            EXPECT_LT(std::fabs(z), 4.5) << "theta " << theta << " cone " << j << " channel " << ch;
          }
        }
      for (int ch = 0; ch < 3; ++ch) {
        mean_var(e.pooled_rgb[ch], e.pooled_rgb2[ch], kSamples, pooled[l][ch], var[l][ch]);
        if (l > 0) continue;
        mean_var(b.pooled_rgb[ch], b.pooled_rgb2[ch], kSamples, pooled_path[ch], var_path[ch]);
        const double m = e.pooled_rgb[ch] / kSamples;
        if (a == 0) first[ch] = m;
        const double bias = a == 0 ? kInjected : a == 2 ? -kInjected * first[ch] / m : 0.0;
        const double z = angle_z(e.pooled_rgb[ch], e.pooled_rgb2[ch], b.pooled_rgb[ch], b.pooled_rgb2[ch], kSamples,
                                 bias, check[ch]);
        EXPECT_LT(std::fabs(z), 4.5) << "theta " << theta << " channel " << ch;
      }
    }
  }
  for (int l = 0; l < 2; ++l) {
    double z[3];
    for (int ch = 0; ch < 3; ++ch) z[ch] = (pooled[l][ch] - pooled_path[ch]) / std::sqrt(var[l][ch] + var_path[ch]);
    std::printf(
        "[frosted sg pane coloured Beer continued path] roughness 0.80 %s: per channel pooled z %+.2f / %+.2f / "
        "%+.2f, worst |z| %.2f over 45\n",
        l == 0 ? "one end (default)" : "old one-colour state (control)", z[0], z[1], z[2], worst[l]);
    for (int ch = 0; ch < 3 && l == 0; ++ch) EXPECT_LT(std::fabs(z[ch]), 4.0) << "channel " << ch;
  }
  for (int ch = 0; ch < 3; ++ch) {
    std::printf(
        "[frosted sg pane coloured Beer continued path] channel %d: worst |z| over 3 angles %.2f; injected "
        "+-%.0f %% per angle: worst %.1f\n",
        ch, check[ch].worst, 100.0 * kInjected, check[ch].worst_injected);
    EXPECT_GT(check[ch].worst_injected, 6.0) << "injected per-angle bias passed: channel " << ch;
  }
  EXPECT_GT(worst[1], 6.0) << "negative control passed";
}

// ---- Stress --------------------------------------------------------------------------
TEST(FrostedGlassSgPane, StressRawOutputsFiniteNonNegative) {
  Pcg32 rng(23);
  const float roughs[] = {0.0f, 1e-3f, 0.04f, 0.1f, 0.5f, 1.0f};
  const float iors[] = {1.0f, 1.2f, 1.33f, 1.7f, 2.5f, 1e3f, 1.0f / 2.4f};
  const float thicknesses[] = {1e-6f, 1e-3f, 0.05f, 1.0f, 1e6f};
  std::vector<std::unique_ptr<FrostedGlassClosure>> pool;
  for (int i = 0; i < 60; ++i) {
    PaneConfig c{(i & 1) ? roughs[rng.next_u32() % 6] : rng.next_float(),
                 (i % 2 == 0) ? 2.4f : iors[rng.next_u32() % 7]};  // half TIR-heavy
    if (i % 4 == 1) c.absorb = Vec3(rng.next_float(), 0.0f, 1e-6f);
    c.thickness = thicknesses[rng.next_u32() % 5];
    pool.push_back(create_pane(c, (i % 3 == 0) ? "auto" : "sg"));
  }
  const auto schema = FrostedGlassClosure::params();
  const long blocks = 64;
  // GLIMMER_STRESS_BLOCKS="first,end": only blocks [first, end) of the 64. A block's queries depend on its index
  // alone, so runs over disjoint ranges together are exactly the whole run (a make-stress run split over processes
  // or sessions: 1e8 queries here cost ~1 CPU hour).
  long first = 0, end = blocks;
  if (const char *range = std::getenv("GLIMMER_STRESS_BLOCKS"))
    if (std::sscanf(range, "%ld,%ld", &first, &end) != 2 || !(0 <= first && first < end && end <= blocks))
      first = 0, end = blocks;
  const long calls = 1000000 * long(stress_scale()) / blocks * (end - first);
  std::atomic<long> bad_count{0}, moved{0}, samples{0}, host_queries{0}, host_mixtures{0};
  tbb::parallel_for(first, end, [&](long b) {
    Pcg32 r(700 + b);
    auto direction = [&](bool grazing) { return test::stress_direction(r, grazing, 2); };  // both sides of the pane
    for (long i = 0; i < calls / (end - first); ++i) {
      const FrostedGlassClosure &c = *pool[r.next_u32() % pool.size()];
      const bool grazing = (i % 4) == 0;
      GlimmerShadingContext ctx = host::make_local_context(direction(grazing));
      ctx.path_seed = r.next_u32();
      ctx.diffuse_bounce = int(r.next_u32() % 2);  // auto: both rules
      const ShadingPoint sp(&ctx, schema);
      const Vec3 wo = direction(grazing);
      const Vec3 rand(r.next_float(), r.next_float(), r.next_float());
      long n_bad = glimmer::test::stress_eval_and_sample(c, sp, wo, rand, samples, moved);
      // The same query through the C entry point into a 2.7 host's sample with its whole-mixture buffer: what the
      // renderer reads (the default rule writes the exit mixture up to roughness 0.4).
      long mixtures = 0;
      uint32_t flags = 0;
      n_bad += glimmer::test::bad_host_query(c, ctx, rand, r.next_float(), r.next_float(), flags, mixtures);
      host_queries.fetch_add(1, std::memory_order_relaxed);
      if (mixtures) host_mixtures.fetch_add(1, std::memory_order_relaxed);
      if (n_bad) bad_count.fetch_add(n_bad);
    }
  });
  EXPECT_EQ(bad_count.load(), 0);
  EXPECT_GT(moved.load(), calls / 20);  // the sg pane estimator really ran
  EXPECT_GT(host_mixtures.load(), calls / 40);  // and the whole exit mixture reached the host
  std::printf("[frosted sg pane stress] through the C entry point (2.7 host): %ld sample queries, %ld whole exit "
              "mixtures read (axes, sharpness, weights, host density at wo and a lamp-integral draw)\n",
              host_queries.load(), host_mixtures.load());
  std::printf("[frosted sg pane stress] blocks %ld..%ld of %ld: %ld eval + %ld sample calls (%ld sg exit samples), 1/4 "
              "grazing, half IOR 2.4, both sides, thickness 1e-6..1e6: %ld bad\n",
              first, end - 1, blocks, calls, samples.load(), moved.load(), bad_count.load());
}

}  // namespace
