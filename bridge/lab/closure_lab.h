// The closure laboratory: numerical checks and measurements that work on ANY
// closure type of the DSO through the C ABI (host::ClosureInstance + a
// GlimmerShadingContext, usually host::make_local_context(wi)).
//
//   furnace      white-furnace albedo: mean of sample() weights eval/pdf
//   chi2_test    Mitsuba-style chi-square test of sample() against eval()'s pdf
//                over the whole sphere (reflection and transmission)
//   consistency  sample()'s returned eval/pdf against eval() at the same wo
//   reciprocity  f(wi, wo) against f(wo, wi) (eta^2 scaled across an interface)
//   stress       NaN/Inf/negative hunt over extreme inputs
//   bench        ns per eval and per sample
//   plot_lobe    PNG of eval, pdf and the sampled density over the sphere
//
// Every routine is deterministic for a given seed: the random numbers of sample
// i are a pure function of (seed, i) (see sample_random3), and multi-threaded
// sums are reduced in a fixed block order, so results do not depend on the
// thread count. All directions passed in and reported are world space; the
// histogram/plot frame is the context's local shading frame (z = N, x = T).
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "glimmer/closure_abi.h"
#include "glimmer/math.h"
#include "host/closure_instance.h"

namespace glimmer::lab {

// ---- Random numbers --------------------------------------------------------
// The three uniform numbers in [0, 1) handed to sample() for sample `index`
// of a run seeded with `seed` (splitmix64-style hash of (seed, index, dim)).
void sample_random3(uint64_t seed, uint64_t index, float out[3]);
// A uniform double in [0, 1) from (seed, index, dimension).
double random_unit(uint64_t seed, uint64_t index, uint32_t dimension);

// True for NaN, +-Inf or a negative value (what a closure must never return).
inline bool is_invalid_value(float v) { return !std::isfinite(v) || v < 0.0f; }

// ---- White furnace ---------------------------------------------------------
struct FurnaceResult {
  // (1/N) sum over samples of eval/pdf (singular samples: eval, their pdf is 1);
  // absorbed samples (label 0) and samples with invalid numbers count as 0.
  Spectrum albedo{0.0f};
  Spectrum standard_error{0.0f};  // per channel, sqrt(variance / N)
  uint64_t samples = 0;
  uint64_t absorbed_count = 0;       // sample() returned label 0
  uint64_t invalid_count = 0;        // NaN/Inf/negative eval or pdf, or a non-unit wo
  uint64_t singular_count = 0;       // samples with the SINGULAR label
  uint64_t transmission_count = 0;   // samples with the TRANSMIT label
};
FurnaceResult furnace(const host::ClosureInstance &instance, const GlimmerShadingContext &ctx,
                      uint64_t samples, uint64_t seed);

// Reference for the furnace that does not use sample(): the integral of
// eval() (f * |cos|) over the whole sphere by composite Simpson quadrature in
// (theta, phi) with theta_steps x phi_steps intervals (both made even). Exact
// to quadrature error for smooth lobes; a lobe narrower than a few grid steps
// needs more steps.
Spectrum albedo_quadrature(const host::ClosureInstance &instance, const GlimmerShadingContext &ctx,
                           int theta_steps = 512, int phi_steps = 1024);

// ---- Chi-square test of sample() against pdf ------------------------------
// The sphere is split into theta_bins x phi_bins cells about `axis` (shading
// frame coordinates, z = N; the default bins about N with phi measured from T):
// cells uniform in t over [0, 1] with theta = pi t^theta_exponent (1: uniform in
// theta, upper and lower hemisphere, theta_bins should then be even so the
// horizon is a cell boundary; > 1 refines the cells near the axis, for
// near-delta lobes, e.g. exponent 4 about -wi for transmission at IOR ~1) and
// phi uniform over [-pi, pi].
// Defaults follow pbrt-v4's bsdfs_test (80 x 160) and Mitsuba 3's chi2.py
// (1e6 samples, pooling to >= 5 expected, Sidak correction).
// Expected counts are samples * integral of the pdf over each cell: 4x4-point
// Gauss-Legendre on rectangles of the cell (in cos(theta)^(1/3) for exponent 1,
// which puts nodes near the horizon for grazing lobes; in t otherwise) split
// in four adaptively, up to max_depth times, until a split changes the estimate
// by at most integration_tolerance expected samples. Cells whose integral is 0
// while samples landed in them are re-integrated on a fine uniform grid before
// they fail the test.
// Most theta x phi cells chi2_test accepts (std::invalid_argument past it).
constexpr int64_t kMaxChi2Cells = 4000000;

struct Chi2Options {
  int theta_bins = 80;
  int phi_bins = 160;
  uint64_t samples = 1000000;
  uint64_t seed = 1;
  double significance = 0.01;  // alpha before the Sidak correction
  int test_count = 1;          // number of chi2 tests in the family (Sidak)
  double min_expected = 5.0;   // cells below this are pooled
  Vec3 axis{0.0f, 0.0f, 1.0f};  // binning axis in the shading frame (need not be unit length)
  double theta_exponent = 1.0;  // >= 1; theta = pi t^theta_exponent
  double integration_tolerance = 1e-3;  // expected samples per cell
  int max_depth = 7;                    // adaptive splits per cell
  // The test also fails when the pdf integrates to more than 1 + this, or
  // when the fraction of non-absorbed, non-singular samples differs from the
  // pdf's integral by more than 5 binomial sigmas + this (the statistic itself
  // is nearly blind to a wrong normalisation).
  double pdf_integral_tolerance = 1e-3;
};

struct Chi2Cell {
  int theta_bin = 0, phi_bin = 0;  // -1 for a pooled cell
  double observed = 0.0, expected = 0.0;
  double contribution = 0.0;  // (observed - expected)^2 / expected
};

struct Chi2Result {
  double chi2 = 0.0;
  int dof = 0;
  double p_value = 0.0;
  double significance = 0.0;  // Sidak-corrected alpha' = 1 - (1 - alpha)^(1 / test_count)
  bool passed = false;
  int cells = 0;         // cells entering the statistic (after pooling)
  int pooled_cells = 0;  // original cells merged into pools
  // Integral of the pdf over the sphere (must be <= 1 + eps) and the fraction
  // of sample() calls that returned a (non-singular) direction; the two agree
  // for a correct sampler.
  double pdf_integral = 0.0;
  double sampled_fraction = 0.0;
  uint64_t samples = 0;
  uint64_t singular_count = 0;  // singular samples are not histogrammed
  uint64_t invalid_count = 0;   // NaN/Inf/non-unit wo from sample()
  uint64_t samples_in_zero_pdf_cells = 0;
  std::vector<Chi2Cell> worst_cells;  // up to 8 largest contributions
  std::string message;                // one-paragraph verdict incl. the worst cells
};
Chi2Result chi2_test(const host::ClosureInstance &instance, const GlimmerShadingContext &ctx,
                     const Chi2Options &options = {});

// Regularized upper incomplete gamma Q(a, x) and the chi-square survival
// function P(X >= chi2) for `dof` degrees of freedom (exposed for tests).
double regularized_gamma_q(double a, double x);
double chi2_survival(double chi2, double dof);
// Sidak correction: 1 - (1 - alpha)^(1 / test_count).
double sidak_significance(double alpha, int test_count);

// ---- eval/pdf consistency --------------------------------------------------
struct ConsistencyResult {
  uint64_t samples = 0;
  uint64_t checked = 0;      // non-singular samples compared
  uint64_t mismatches = 0;   // relative difference above tolerance (eval or pdf)
  double max_relative_eval_difference = 0.0;  // max over channels
  double max_relative_pdf_difference = 0.0;
  Vec3 worst_wo{0.0f};  // world-space wo of the worst mismatch
};
// Relative difference |a - b| / max(|a|, |b|), 0 when both are 0.
double relative_difference(double a, double b);
ConsistencyResult consistency(const host::ClosureInstance &instance, const GlimmerShadingContext &ctx,
                              uint64_t samples, uint64_t seed, double tolerance = 1e-4);

// ---- Reciprocity -----------------------------------------------------------
// Builds the shading context for a given wi (world space); the default is
// host::make_local_context.
using ContextBuilder = std::function<GlimmerShadingContext(const Vec3 &wi)>;

struct ReciprocityOptions {
  uint64_t pairs = 10000;
  uint64_t seed = 1;
  bool transmission = false;  // also draw wo below the surface
  // Relative IOR below/above the surface (1 = compare without scaling).
  // With wi toward the viewer, the radiance BSDF across an interface obeys
  // (Veach 1997, sec. 5.2; Walter et al. 2007, eq. 21)
  //   f(wi, wo) / eta(wi)^2 = f(wo, wi) / eta(wo)^2,
  // eta(x) being the IOR on x's side: 1 above the surface, `eta` below.
  double eta = 1.0;
  double min_abs_cos = 1e-3;  // skip pairs this close to grazing (division by cos)
  double tolerance = 1e-4;    // relative error counted as a failure
};
struct ReciprocityResult {
  uint64_t pairs = 0;
  uint64_t compared = 0;  // pairs where at least one side is non-zero
  uint64_t failures = 0;  // relative error > tolerance
  double max_relative_error = 0.0;
  Vec3 worst_wi{0.0f}, worst_wo{0.0f};
};
ReciprocityResult reciprocity(const host::ClosureInstance &instance, const ContextBuilder &builder,
                              const ReciprocityOptions &options = {});
ReciprocityResult reciprocity(const host::ClosureInstance &instance, const ReciprocityOptions &options = {});

// ---- Numerical stress ------------------------------------------------------
// `calls` rounds per instance, each: one eval and one sample (plus albedo and
// emit when present) at an extreme or random wi (grazing 1e-6 and 1e-3,
// below the horizon, exactly normal, exactly tangent, random), random or
// extreme wo, random numbers including 0 and the largest float below 1, and a
// footprint that is zero, tiny (1e-12), huge (1e6) or random, with random
// uv/P and spread angles.
struct StressOptions {
  uint64_t calls = 1000000;  // per instance
  uint64_t seed = 1;
};
struct StressResult {
  uint64_t calls = 0;
  uint64_t eval_nan = 0, eval_inf = 0, eval_negative = 0;        // eval() values and pdf
  uint64_t sample_nan = 0, sample_inf = 0, sample_negative = 0;  // sample() eval/pdf/roughness/eta
  uint64_t sample_bad_direction = 0;  // non-finite or non-unit wo with a non-zero label
  uint64_t other_invalid = 0;         // albedo()/emit() NaN/Inf/negative
  uint64_t total_invalid() const {
    return eval_nan + eval_inf + eval_negative + sample_nan + sample_inf + sample_negative +
           sample_bad_direction + other_invalid;
  }
  std::string first_failure;  // description of the first invalid result (inputs included)
};
StressResult stress(std::span<const host::ClosureInstance *const> instances, const StressOptions &options = {});
StressResult stress(const host::ClosureInstance &instance, const StressOptions &options = {});

// ---- Timing ----------------------------------------------------------------
struct BenchResult {
  double ns_per_eval = 0.0;    // median over repetitions
  double ns_per_sample = 0.0;  // median over repetitions
  uint64_t iterations = 0;
  int repetitions = 0;
};
// Single-threaded; inputs are generated before timing.
BenchResult bench(const host::ClosureInstance &instance, const GlimmerShadingContext &ctx, uint64_t iterations,
                  int repetitions = 5);

// ---- Lobe picture ----------------------------------------------------------
struct PlotOptions {
  int width = 512;   // per panel; the image has three panels side by side
  int height = 256;  // latitude-longitude layout: theta 0..pi top to bottom, phi -pi..pi
  uint64_t samples = 1000000;  // for the sampled-density panel (0 = no panel)
  uint64_t seed = 1;
};
// Writes a PNG with panels [eval (average of RGB f*|cos|) | pdf | sampled
// density], all in solid-angle density units, tone-mapped with the same scale
// (sqrt of value / max of the pdf panel) through a perceptual colour map.
// Written atomically (temporary file + rename). Throws std::runtime_error on
// I/O failure.
void plot_lobe(const host::ClosureInstance &instance, const GlimmerShadingContext &ctx, const std::string &path,
               const PlotOptions &options = {});

}  // namespace glimmer::lab
