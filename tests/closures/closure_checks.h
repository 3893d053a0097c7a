// GoogleTest harness every closure's tests use: loads the DSO from
// GLIMMER_TEST_PLUGIN_PATH, creates instances from "name=value" parameters,
// and wraps the closure laboratory (bridge/lab/closure_lab.h) in assertion
// helpers with messages that say what failed and where.
//
// Typical use (see test_diffuse.cpp):
//   auto diffuse = glimmer::test::make_closure("diffuse", {{"color", "1,1,1"}});
//   EXPECT_CLOSURE_FURNACE(*diffuse, Vec3(0.3f, 0, 0.95f), Spectrum(1.0f), 1e-4);
//   EXPECT_CLOSURE_FURNACE_MATCHES_QUADRATURE(*closure, wi, 1e-4);  // no closed form
//   glimmer::test::expect_chi2_family({{"normal", diffuse, Vec3(0, 0, 1)}, ...});
//   EXPECT_CLOSURE_CONSISTENT(*diffuse, wi);
//   EXPECT_CLOSURE_STRESS_CLEAN({diffuse.get(), ...});
//
// Thresholds are statistical, never hand-tuned per closure:
//  - furnace: |albedo - expected| <= 5 standard errors + an absolute
//    allowance the caller states (quadrature or table error of the reference);
//  - chi2: Mitsuba's 1e6 samples, pooling to >= 5 expected, p >= Sidak-corrected
//    0.01 over the family of configurations tested together;
//  - stress: zero NaN/Inf/negative results.
// GLIMMER_STRESS=1 (make stress) scales stress call counts by 100 (1e6 -> 1e8).
#pragma once

#include <gtest/gtest.h>

#include <cstdlib>
#include <initializer_list>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "glimmer/math.h"
#include "host/closure_instance.h"
#include "host/plugin_library.h"
#include "lab/closure_lab.h"
#include "test_support.h"

namespace glimmer::test {

// The closure type `name`; throws (failing the test) when the DSO lacks it.
inline const GlimmerClosureType &closure_type(const std::string &name) {
  const GlimmerClosureType *type = plugin().find(name);
  if (type == nullptr) throw std::runtime_error("the plugin has no closure '" + name + "'");
  return *type;
}

using Params = std::vector<std::pair<std::string, std::string>>;

// Creates an instance from textual parameters (as in XML / on the CLI).
inline std::shared_ptr<host::ClosureInstance> make_closure(const GlimmerClosureType &type, const Params &params = {}) {
  host::ParamList list;
  for (const auto &[name, value] : params) list.set_from_text(type, name, value);
  return std::make_shared<host::ClosureInstance>(type, list);
}
inline std::shared_ptr<host::ClosureInstance> make_closure(const std::string &name, const Params &params = {}) {
  return make_closure(closure_type(name), params);
}

// Direction in the local frame (N = +z) at `cos_theta` from the normal, in the xz plane.
inline Vec3 direction_at_cos(double cos_theta) {
  const double s = std::sqrt(std::max(0.0, 1.0 - cos_theta * cos_theta));
  return Vec3(static_cast<float>(s), 0.0f, static_cast<float>(cos_theta));
}

// Direction in the local frame (N = +z) at polar angle `theta_deg` and azimuth `phi_deg` (degrees).
inline Vec3 spherical_dir(double theta_deg, double phi_deg) {
  const double deg = M_PI / 180.0;
  const double t = theta_deg * deg, p = phi_deg * deg;
  return Vec3(static_cast<float>(std::sin(t) * std::cos(p)), static_cast<float>(std::sin(t) * std::sin(p)),
              static_cast<float>(std::cos(t)));
}

// Local context at `wi` with uv (u, v) and the uv footprint spanned by
// duv_dx = (ax, ay) and duv_dy = (bx, by) (closures with spatial detail: glint).
inline GlimmerShadingContext footprint_context(const Vec3 &wi, double u, double v, double ax, double ay, double bx,
                                               double by) {
  GlimmerShadingContext ctx = host::make_local_context(wi);
  ctx.uv[0] = static_cast<float>(u);
  ctx.uv[1] = static_cast<float>(v);
  ctx.duv_dx[0] = static_cast<float>(ax);
  ctx.duv_dx[1] = static_cast<float>(ay);
  ctx.duv_dy[0] = static_cast<float>(bx);
  ctx.duv_dy[1] = static_cast<float>(by);
  return ctx;
}

// Closures that precompute tables (glint) cache them in the build folder
// during tests, not in the user's home (an explicit GLIMMER_CACHE_DIR wins).
inline bool cache_tables_in_build_folder() {
  setenv("GLIMMER_CACHE_DIR", GLIMMER_TEST_BINARY_DIR "/test_cache", 0);
  return true;
}

// The viewing directions every closure is checked at: normal, 45 degrees,
// 75 degrees, grazing 1e-3 and grazing 1e-6 (cosines).
inline std::vector<std::pair<std::string, Vec3>> standard_wi() {
  return {{"normal", Vec3(0, 0, 1)},
          {"cos=0.95", Vec3(0.3f, 0.0f, 0.95f)},
          {"45deg", direction_at_cos(std::sqrt(0.5))},
          {"75deg", direction_at_cos(std::cos(75.0 * M_PI / 180.0))},
          {"grazing 1e-3", direction_at_cos(1e-3)},
          {"grazing 1e-6", direction_at_cos(1e-6)}};
}

// Direction pairs (wi, wo) for checking a closure's value against its formula: normal to grazing 88 degrees
// incidence, 5 to 89 degrees exitance, azimuths on both sides of the plane of incidence.
inline std::vector<std::pair<Vec3, Vec3>> value_check_pairs() {
  std::vector<std::pair<Vec3, Vec3>> pairs;
  for (const Vec3 &wi : {spherical_dir(0, 0), spherical_dir(30, 10), spherical_dir(70, 200), spherical_dir(88, 0)})
    for (const Vec3 &wo : {spherical_dir(5, 180), spherical_dir(40, 120), spherical_dir(80, 20), spherical_dir(89, 0),
                           spherical_dir(60, 200)})
      pairs.emplace_back(wi, wo);
  return pairs;
}

inline std::string format_vec(const Vec3 &v) {
  std::ostringstream s;
  s << "(" << v.x << ", " << v.y << ", " << v.z << ")";
  return s.str();
}

// ---- Furnace -------------------------------------------------------------------
// Passes when every channel of the sampled albedo lies within 5 standard
// errors + abs_tolerance of `expected`, and no sample was invalid.
inline ::testing::AssertionResult furnace_matches(const host::ClosureInstance &instance,
                                                  const GlimmerShadingContext &ctx, const Spectrum &expected,
                                                  double abs_tolerance, uint64_t samples = 1000000,
                                                  uint64_t seed = 1) {
  const Vec3 wi(ctx.wi);
  const lab::FurnaceResult r = lab::furnace(instance, ctx, samples, seed);
  std::ostringstream msg;
  msg << instance.type().name << " furnace at wi " << format_vec(wi) << ": albedo " << format_vec(r.albedo)
      << " +- " << format_vec(r.standard_error) << " (expected " << format_vec(expected) << ", allowance 5 se + "
      << abs_tolerance << "), " << r.invalid_count << " invalid, " << r.absorbed_count << " absorbed of "
      << r.samples;
  bool ok = r.invalid_count == 0;
  for (int c = 0; c < 3; ++c)
    ok = ok && std::fabs(double(r.albedo[c]) - double(expected[c])) <= 5.0 * r.standard_error[c] + abs_tolerance;
  return ok ? ::testing::AssertionSuccess() << msg.str() : ::testing::AssertionFailure() << msg.str();
}
inline ::testing::AssertionResult furnace_matches(const host::ClosureInstance &instance, const Vec3 &wi,
                                                  const Spectrum &expected, double abs_tolerance,
                                                  uint64_t samples = 1000000, uint64_t seed = 1) {
  return furnace_matches(instance, host::make_local_context(wi), expected, abs_tolerance, samples, seed);
}
// `where` is a wi (Vec3) or a full GlimmerShadingContext.
#define EXPECT_CLOSURE_FURNACE(instance, where, expected, abs_tolerance) \
  EXPECT_TRUE(::glimmer::test::furnace_matches((instance), (where), (expected), (abs_tolerance)))

// The sampled furnace against the quadrature of eval() (lab::albedo_quadrature):
// proves sample()'s weights are unbiased for closures without a closed-form
// albedo. `abs_tolerance` covers the quadrature error of narrow lobes.
inline ::testing::AssertionResult furnace_matches_quadrature(const host::ClosureInstance &instance,
                                                             const GlimmerShadingContext &ctx, double abs_tolerance,
                                                             int theta_steps = 512, int phi_steps = 1024) {
  const Spectrum reference = lab::albedo_quadrature(instance, ctx, theta_steps, phi_steps);
  return furnace_matches(instance, ctx, reference, abs_tolerance) << " (reference: quadrature of eval over "
                                                                  << theta_steps << " x " << phi_steps << ")";
}
inline ::testing::AssertionResult furnace_matches_quadrature(const host::ClosureInstance &instance, const Vec3 &wi,
                                                             double abs_tolerance) {
  return furnace_matches_quadrature(instance, host::make_local_context(wi), abs_tolerance);
}
#define EXPECT_CLOSURE_FURNACE_MATCHES_QUADRATURE(instance, where, abs_tolerance) \
  EXPECT_TRUE(::glimmer::test::furnace_matches_quadrature((instance), (where), (abs_tolerance)))

// ---- Chi-square ------------------------------------------------------------------
struct Chi2Config {
  std::string label;
  std::shared_ptr<host::ClosureInstance> instance;
  Vec3 wi;
  // Context override (backfacing, rotated frames, footprints); default:
  // host::make_local_context(wi).
  std::optional<GlimmerShadingContext> ctx = std::nullopt;
  bool stress_only = false;  // skipped unless `full` (expect_chi2_family): run by the test's *Stress twin
};

// Runs the chi2 test on every configuration with the Sidak correction for the
// whole family (test_count = configs.size()) and returns the results. Not `full`
// (`make test`): the configurations marked stress_only are skipped; the others keep
// the seed (first seed + index in the family) and the threshold of the full run, so
// every assertion of the short run is one of the full run's.
inline std::vector<lab::Chi2Result> expect_chi2_family(const std::vector<Chi2Config> &configs,
                                                       lab::Chi2Options options = {}, bool full = true) {
  options.test_count = static_cast<int>(configs.size());
  std::vector<lab::Chi2Result> results;
  const uint64_t first_seed = options.seed;
  for (size_t i = 0; i < configs.size(); ++i) {
    const Chi2Config &c = configs[i];
    if (!full && c.stress_only) continue;
    const GlimmerShadingContext ctx = c.ctx ? *c.ctx : host::make_local_context(c.wi);
    // Independent samples per configuration (a family of independent tests).
    options.seed = first_seed + i;
    const lab::Chi2Result r = lab::chi2_test(*c.instance, ctx, options);
    EXPECT_TRUE(r.passed) << c.instance->type().name << " [" << c.label << "] wi " << format_vec(c.wi) << ": "
                          << r.message;
    results.push_back(r);
  }
  return results;
}

// ---- eval/pdf consistency -------------------------------------------------------------
// `ctx` is a full context (footprints, spread); the Vec3 overload uses
// host::make_local_context(wi).
inline ::testing::AssertionResult consistent(const host::ClosureInstance &instance, const GlimmerShadingContext &ctx,
                                             double tolerance = 1e-4, uint64_t samples = 200000) {
  const lab::ConsistencyResult r = lab::consistency(instance, ctx, samples, 7, tolerance);
  std::ostringstream msg;
  msg << instance.type().name << " eval/pdf consistency at wi " << format_vec(Vec3(ctx.wi)) << ": " << r.mismatches
      << " mismatches of " << r.checked << " (tolerance " << tolerance << "), max relative eval difference "
      << r.max_relative_eval_difference << ", pdf " << r.max_relative_pdf_difference << ", worst wo "
      << format_vec(r.worst_wo);
  const bool ok = r.mismatches == 0 && r.checked > 0;
  return ok ? ::testing::AssertionSuccess() << msg.str() : ::testing::AssertionFailure() << msg.str();
}
inline ::testing::AssertionResult consistent(const host::ClosureInstance &instance, const Vec3 &wi,
                                             double tolerance = 1e-4, uint64_t samples = 200000) {
  return consistent(instance, host::make_local_context(wi), tolerance, samples);
}
#define EXPECT_CLOSURE_CONSISTENT(instance, wi) EXPECT_TRUE(::glimmer::test::consistent((instance), (wi)))

// ---- Reciprocity -------------------------------------------------------------------------
inline ::testing::AssertionResult reciprocal(const host::ClosureInstance &instance, lab::ReciprocityOptions options = {}) {
  const lab::ReciprocityResult r = lab::reciprocity(instance, options);
  std::ostringstream msg;
  msg << instance.type().name << " reciprocity: " << r.failures << " failures of " << r.compared
      << " compared pairs (tolerance " << options.tolerance << "), max relative error " << r.max_relative_error
      << " at wi " << format_vec(r.worst_wi) << ", wo " << format_vec(r.worst_wo);
  const bool ok = r.failures == 0 && r.compared > 0;
  return ok ? ::testing::AssertionSuccess() << msg.str() : ::testing::AssertionFailure() << msg.str();
}
#define EXPECT_CLOSURE_RECIPROCAL(instance, options) EXPECT_TRUE(::glimmer::test::reciprocal((instance), (options)))

// ---- Stress --------------------------------------------------------------------------------
// `total_calls` (default 1e6, x100 under make stress) spread over the instances.
inline ::testing::AssertionResult stress_clean(const std::vector<const host::ClosureInstance *> &instances,
                                               uint64_t total_calls = 1000000, uint64_t seed = 1) {
  lab::StressOptions options;
  options.calls = std::max<uint64_t>(1, total_calls * stress_scale() / std::max<size_t>(1, instances.size()));
  options.seed = seed;
  const lab::StressResult r = lab::stress(instances, options);
  std::ostringstream msg;
  msg << "stress over " << instances.size() << " instance(s), " << r.calls << " calls: eval NaN/Inf/neg "
      << r.eval_nan << "/" << r.eval_inf << "/" << r.eval_negative << ", sample NaN/Inf/neg " << r.sample_nan << "/"
      << r.sample_inf << "/" << r.sample_negative << ", bad directions " << r.sample_bad_direction
      << ", albedo/emit invalid " << r.other_invalid;
  if (!r.first_failure.empty()) msg << "; first: " << r.first_failure;
  const bool ok = r.total_invalid() == 0 && r.calls == options.calls * instances.size();
  return ok ? ::testing::AssertionSuccess() << msg.str() : ::testing::AssertionFailure() << msg.str();
}
#define EXPECT_CLOSURE_STRESS_CLEAN(...) EXPECT_TRUE(::glimmer::test::stress_clean(__VA_ARGS__))

// The stress check over owned instances (`total_calls` as in stress_clean), then wi and wo both at grazing cos 1e-6
// (opposite azimuths): each eval finite and non-negative (value and pdf).
inline void expect_stress_and_grazing_clean(const std::vector<std::shared_ptr<host::ClosureInstance>> &closures,
                                            uint64_t total_calls = 1000000) {
  std::vector<const host::ClosureInstance *> raw;
  for (const auto &c : closures) raw.push_back(c.get());
  EXPECT_CLOSURE_STRESS_CLEAN(raw, total_calls);
  const Vec3 grazing = direction_at_cos(1e-6);
  for (const auto &c : closures) {
    Spectrum f;
    float pdf = -1.0f;
    c->eval(host::make_local_context(grazing), Vec3(-grazing.x, -grazing.y, grazing.z), f, pdf);
    EXPECT_TRUE(std::isfinite(f[0]) && f[0] >= 0.0f && pdf >= 0.0f) << c->type().name;
  }
}

// ---- Tampering (negative controls) -----------------------------------------------------
// A copy of a closure type whose entry points can be replaced, so a test can
// prove that a check FAILS for a broken closure. The replacement functions
// reach the original through TamperedType::original(). One tampered type at a
// time: constructing another one redirects original() to its type.
class TamperedType {
 public:
  explicit TamperedType(const GlimmerClosureType &original) : type_(original) { original_ = &original; }
  GlimmerClosureType &type() { return type_; }
  static const GlimmerClosureType &original() { return *original_; }

 private:
  GlimmerClosureType type_;
  static inline const GlimmerClosureType *original_ = nullptr;
};

}  // namespace glimmer::test
