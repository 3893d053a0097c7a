// Small helpers for the glint tests over the closure laboratory
// (bridge/lab/closure_lab.h): plugin loading, instances from text
// parameters, chi2 families with the Sidak correction, consistency, stress.
#pragma once

#include <gtest/gtest.h>

#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "host/closure_instance.h"
#include "host/plugin_library.h"
#include "lab/closure_lab.h"

namespace glimmer::glint_test {

inline const host::PluginLibrary &plugin() {
  static const std::unique_ptr<host::PluginLibrary> library = host::PluginLibrary::load(GLIMMER_TEST_PLUGIN_PATH);
  return *library;
}

inline const GlimmerClosureType &closure_type(const std::string &name) {
  const GlimmerClosureType *type = plugin().find(name);
  if (type == nullptr) throw std::runtime_error("the plugin has no closure '" + name + "'");
  return *type;
}

using Params = std::vector<std::pair<std::string, std::string>>;

inline std::shared_ptr<host::ClosureInstance> make_closure(const std::string &name, const Params &params = {}) {
  const GlimmerClosureType &type = closure_type(name);
  host::ParamList list;
  for (const auto &[key, value] : params) list.set_from_text(type, key, value);
  return std::make_shared<host::ClosureInstance>(type, list);
}

struct Chi2Config {
  std::string label;
  std::shared_ptr<host::ClosureInstance> instance;
  GlimmerShadingContext ctx;
};

// Mitsuba-style chi2 over a family of configurations, Sidak-corrected.
inline std::vector<lab::Chi2Result> expect_chi2_family(const std::vector<Chi2Config> &configs,
                                                       lab::Chi2Options options = {}) {
  options.test_count = static_cast<int>(configs.size());
  std::vector<lab::Chi2Result> results;
  for (const auto &c : configs) {
    const lab::Chi2Result r = lab::chi2_test(*c.instance, c.ctx, options);
    EXPECT_TRUE(r.passed) << c.instance->type().name << " [" << c.label << "]: " << r.message;
    results.push_back(r);
  }
  return results;
}

inline ::testing::AssertionResult consistent(const host::ClosureInstance &instance, const GlimmerShadingContext &ctx,
                                             double tolerance = 1e-4, uint64_t samples = 100000) {
  const lab::ConsistencyResult r = lab::consistency(instance, ctx, samples, 7, tolerance);
  if (r.mismatches == 0 && r.checked > 0) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << instance.type().name << ": " << r.mismatches << " eval/pdf mismatches of "
                                       << r.checked << ", max rel eval diff " << r.max_relative_eval_difference
                                       << ", pdf " << r.max_relative_pdf_difference;
}

inline ::testing::AssertionResult stress_clean(const std::vector<const host::ClosureInstance *> &instances,
                                               uint64_t calls_per_instance) {
  lab::StressOptions options;
  options.calls = calls_per_instance;
  const lab::StressResult r = lab::stress(instances, options);
  if (r.total_invalid() == 0 && r.calls > 0) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << r.total_invalid() << " invalid results in " << r.calls
                                       << " calls; first: " << r.first_failure;
}

}  // namespace glimmer::glint_test
