// `glimmer lab ...`: the closure laboratory on the command line.
//
//   glimmer lab furnace --closure diffuse --param color=1,1,1 --wi 0.3,0,0.95 --samples 1e6
//   glimmer lab chi2    --closure NAME [--param k=v]... [--wi x,y,z] [--samples N] [--seed S] [--test-count K]
//                       [--axis x,y,z --theta-exponent K]   (cells refined toward an axis: near-delta lobes)
//   glimmer lab consistency | stress | bench  (same options)
//   glimmer lab plot    --closure NAME ... -o lobe.png
//
// furnace/chi2/consistency/stress/bench print one JSON object on stdout.
// Unknown closures or parameters exit 1, plugin problems exit 2.
#include <cmath>
#include <functional>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "cli/commands.h"
#include "cli/json_number.h"
#include "host/closure_instance.h"
#include "lab/closure_lab.h"
#include "render/image_output.h"
#include "scene/parse_number.h"

namespace glimmer::cli {

namespace {

struct LabOptions {
  std::string closure;
  std::vector<std::string> params;
  std::string wi = "0,0,1";
  double footprint = 0.0;  // uv area of the pixel footprint (0: a point)
  double samples = 1e6;
  uint64_t seed = 1;
  int test_count = 1;
  int theta_bins = 80;
  int phi_bins = 160;
  std::string axis = "0,0,1";
  double theta_exponent = 1.0;
  double iterations = 2e5;
  int repetitions = 5;
  std::string output;
  int width = 512;
  int height = 256;
};

// --wi / --axis x,y,z: three strict numbers (parse_number.h), a direction of
// length in [1e-6, 1e6] (a huge or tiny vector would under/overflow when normalised).
Vec3 parse_direction(const std::string &text, const std::string &option) {
  std::vector<float> v;
  try {
    v = scene::parse_float_list(text);
  } catch (const scene::NumberError &e) {
    throw CliError(kExitBadInput, option + " '" + text + "': " + e.what());
  }
  if (v.size() != 3) throw CliError(kExitBadInput, option + " '" + text + "' must be three numbers x,y,z");
  const double len = std::sqrt(double(v[0]) * v[0] + double(v[1]) * v[1] + double(v[2]) * v[2]);
  if (!(len >= 1e-6 && len <= 1e6))
    throw CliError(kExitBadInput, option + " '" + text + "': length must be in [1e-6, 1e6] (a direction; zero, huge " +
                                      "and tiny vectors are refused)");
  return normalize(Vec3(v[0], v[1], v[2]));
}

uint64_t positive_count(double value, const char *option) {
  if (!(value >= 1.0) || value > 1e12 || value != std::floor(value))
    throw CliError(kExitBadInput, std::string(option) + " must be a whole number between 1 and 1e12");
  return static_cast<uint64_t>(value);
}

// The closure instance and shading context the options describe.
struct LabSetup {
  std::unique_ptr<host::ClosureInstance> instance;
  GlimmerShadingContext ctx;
  Vec3 wi;
  nlohmann::json header;
};

LabSetup make_setup(CliContext &cli, const LabOptions &o) {
  auto &plugin = cli.plugin();  // PluginError -> exit 2
  const GlimmerClosureType *type = plugin.find(o.closure);
  if (type == nullptr) {
    std::string known;
    for (const auto *t : plugin.closures()) known += (known.empty() ? "" : ", ") + std::string(t->name);
    throw CliError(kExitBadInput, "unknown closure '" + o.closure + "' (known: " + known + ")");
  }
  host::ParamList params;
  nlohmann::json param_json = nlohmann::json::object();
  for (const auto &assignment : o.params) {
    params.set_assignment(*type, assignment);  // ClosureError -> exit 1
    const auto eq = assignment.find('=');
    if (param_json.contains(assignment.substr(0, eq)))
      throw CliError(kExitBadInput, "--param " + assignment.substr(0, eq) + " given more than once");
    param_json[assignment.substr(0, eq)] = assignment.substr(eq + 1);
  }
  LabSetup setup;
  setup.wi = parse_direction(o.wi, "--wi");
  setup.instance = std::make_unique<host::ClosureInstance>(*type, params);
  setup.ctx = host::make_local_context(setup.wi);
  if (!(o.footprint >= 0.0 && o.footprint <= 1e12))
    throw CliError(kExitBadInput, "--footprint must be a uv area between 0 and 1e12 (0: a point)");
  if (o.footprint > 0.0) {  // a square footprint: what a pixel covers in uv (the glint closures count particles in it)
    const float side = static_cast<float>(std::sqrt(o.footprint));
    setup.ctx.duv_dx[0] = side, setup.ctx.duv_dx[1] = 0.0f;
    setup.ctx.duv_dy[0] = 0.0f, setup.ctx.duv_dy[1] = side;
  }
  setup.header = {{"closure", o.closure}, {"params", param_json}, {"wi", json_vec3(setup.wi)}};
  if (o.footprint > 0.0) setup.header["footprint"] = o.footprint;
  return setup;
}

void add_common_options(CLI::App *cmd, LabOptions &o) {
  cmd->add_option("--closure", o.closure, "closure type name (see `glimmer describe`)")->required();
  cmd->add_option("--param", o.params, "closure parameter name=value (repeatable)");
  cmd->add_option("--wi", o.wi, "direction toward the viewer x,y,z in the local frame (outward normal +z; a wi below it arrives from the back, as in the renderer: N turned toward wi, backfacing), default 0,0,1");
  cmd->add_option("--seed", o.seed, "random seed (results are deterministic for a seed)");
  cmd->add_option("--footprint", o.footprint,
                  "uv area a pixel covers (a square; default 0: a point). Footprint-dependent closures need it: a "
                  "glint at a point holds about one particle, so its furnace albedo is mostly 0");
}

// Adds `glimmer lab NAME`: the common options, the test's own options
// (`add_options`), and `run`, called with the closure instance and context the
// options describe.
void add_lab_test(CLI::App *lab, CliContext &ctx, const std::string &name, const std::string &description,
                  const std::function<void(CLI::App *, LabOptions &)> &add_options,
                  std::function<void(const LabSetup &, const LabOptions &)> run) {
  auto o = std::make_shared<LabOptions>();
  auto *cmd = lab->add_subcommand(name, description);
  add_common_options(cmd, *o);
  add_options(cmd, *o);
  cmd->callback([&ctx, o, run = std::move(run)] { run(make_setup(ctx, *o), *o); });
}

}  // namespace

void add_lab_command(CLI::App &app, CliContext &ctx) {
  auto *lab = app.add_subcommand("lab", "closure laboratory: furnace, chi2, consistency, stress, bench, plot");
  lab->require_subcommand(1);

  add_lab_test(
      lab, ctx, "furnace", "white-furnace albedo: mean of sample weights eval/pdf (JSON)",
      [](CLI::App *cmd, LabOptions &o) {
        cmd->add_option("--samples", o.samples, "number of samples (default 1e6)");
      },
      [](const LabSetup &s, const LabOptions &o) {
        const uint64_t n = positive_count(o.samples, "--samples");
        const lab::FurnaceResult r = lab::furnace(*s.instance, s.ctx, n, o.seed);
        nlohmann::json out = s.header;
        out["test"] = "furnace";
        out["samples"] = r.samples;
        out["seed"] = o.seed;
        out["albedo"] = json_vec3(r.albedo);
        out["standard_error"] = json_vec3(r.standard_error);
        out["absorbed"] = r.absorbed_count;
        out["invalid"] = r.invalid_count;
        out["singular"] = r.singular_count;
        out["transmission"] = r.transmission_count;
        std::cout << out.dump(2) << "\n";
      });

  add_lab_test(
      lab, ctx, "chi2", "Mitsuba-style chi-square test of sample() against pdf (JSON)",
      [](CLI::App *cmd, LabOptions &o) {
        cmd->add_option("--samples", o.samples, "number of samples (default 1e6)");
        cmd->add_option("--test-count", o.test_count, "number of tests in the family, for the Sidak correction");
        cmd->add_option("--theta-bins", o.theta_bins, "cells in theta over [0, pi] (default 80)");
        cmd->add_option("--phi-bins", o.phi_bins, "cells in phi over [-pi, pi] (default 160)");
        cmd->add_option("--axis", o.axis, "binning axis x,y,z in the shading frame (default 0,0,1 = N)");
        cmd->add_option("--theta-exponent", o.theta_exponent,
                        "theta = pi t^K over cells uniform in t: K > 1 refines the cells near the axis (default 1)");
      },
      [](const LabSetup &s, const LabOptions &o) {
        if (o.test_count < 1) throw CliError(kExitBadInput, "--test-count must be >= 1");
        if (o.theta_bins < 2 || o.theta_bins % 2 || o.phi_bins < 1 ||
            static_cast<int64_t>(o.theta_bins) * o.phi_bins > lab::kMaxChi2Cells)
          throw CliError(kExitBadInput, "--theta-bins must be even and >= 2, --phi-bins >= 1 (at most 4e6 cells)");
        if (!(o.theta_exponent >= 1.0 && o.theta_exponent <= 16.0))
          throw CliError(kExitBadInput, "--theta-exponent must be in [1, 16]");
        lab::Chi2Options options;
        options.axis = parse_direction(o.axis, "--axis");
        options.theta_exponent = o.theta_exponent;
        options.samples = positive_count(o.samples, "--samples");
        options.seed = o.seed;
        options.test_count = o.test_count;
        options.theta_bins = o.theta_bins;
        options.phi_bins = o.phi_bins;
        const lab::Chi2Result r = lab::chi2_test(*s.instance, s.ctx, options);
        nlohmann::json out = s.header;
        out["test"] = "chi2";
        out["samples"] = r.samples;
        out["seed"] = o.seed;
        out["theta_bins"] = options.theta_bins;
        out["phi_bins"] = options.phi_bins;
        out["axis"] = json_vec3(options.axis);
        out["theta_exponent"] = options.theta_exponent;
        out["chi2"] = r.chi2;
        out["dof"] = r.dof;
        out["p_value"] = r.p_value;
        out["significance"] = r.significance;
        out["test_count"] = options.test_count;
        out["passed"] = r.passed;
        out["cells"] = r.cells;
        out["pooled_cells"] = r.pooled_cells;
        out["pdf_integral"] = r.pdf_integral;
        out["sampled_fraction"] = r.sampled_fraction;
        out["singular"] = r.singular_count;
        out["invalid"] = r.invalid_count;
        out["samples_in_zero_pdf_cells"] = r.samples_in_zero_pdf_cells;
        out["message"] = r.message;
        std::cout << out.dump(2) << "\n";
      });

  add_lab_test(
      lab, ctx, "consistency", "sample()'s eval/pdf against eval() at the same direction (JSON)",
      [](CLI::App *cmd, LabOptions &o) {
        cmd->add_option("--samples", o.samples, "number of samples (default 1e6)");
      },
      [](const LabSetup &s, const LabOptions &o) {
        const lab::ConsistencyResult r =
            lab::consistency(*s.instance, s.ctx, positive_count(o.samples, "--samples"), o.seed);
        nlohmann::json out = s.header;
        out["test"] = "consistency";
        out["samples"] = r.samples;
        out["checked"] = r.checked;
        out["mismatches"] = r.mismatches;
        out["max_relative_eval_difference"] = r.max_relative_eval_difference;
        out["max_relative_pdf_difference"] = r.max_relative_pdf_difference;
        std::cout << out.dump(2) << "\n";
      });

  add_lab_test(
      lab, ctx, "stress", "NaN/Inf/negative hunt over extreme inputs (JSON; --wi is ignored)",
      [](CLI::App *cmd, LabOptions &o) {
        cmd->add_option("--samples", o.samples, "number of calls (default 1e6)");
      },
      [](const LabSetup &s, const LabOptions &o) {
        lab::StressOptions options;
        options.calls = positive_count(o.samples, "--samples");
        options.seed = o.seed;
        const lab::StressResult r = lab::stress(*s.instance, options);
        nlohmann::json out = s.header;
        out.erase("wi");
        out["test"] = "stress";
        out["calls"] = r.calls;
        out["invalid"] = r.total_invalid();
        out["eval"] = {{"nan", r.eval_nan}, {"inf", r.eval_inf}, {"negative", r.eval_negative}};
        out["sample"] = {{"nan", r.sample_nan},
                         {"inf", r.sample_inf},
                         {"negative", r.sample_negative},
                         {"bad_direction", r.sample_bad_direction}};
        out["albedo_emit_invalid"] = r.other_invalid;
        out["first_failure"] = r.first_failure;
        std::cout << out.dump(2) << "\n";
      });

  add_lab_test(
      lab, ctx, "bench", "ns per eval and per sample, single-threaded median (JSON)",
      [](CLI::App *cmd, LabOptions &o) {
        cmd->add_option("--iterations", o.iterations, "calls per repetition (default 2e5)");
        cmd->add_option("--repetitions", o.repetitions, "repetitions; the median is reported (default 5)");
      },
      [](const LabSetup &s, const LabOptions &o) {
        if (o.repetitions < 1) throw CliError(kExitBadInput, "--repetitions must be >= 1");
        const lab::BenchResult r =
            lab::bench(*s.instance, s.ctx, positive_count(o.iterations, "--iterations"), o.repetitions);
        nlohmann::json out = s.header;
        out["test"] = "bench";
        out["iterations"] = r.iterations;
        out["repetitions"] = r.repetitions;
        out["ns_per_eval"] = r.ns_per_eval;
        out["ns_per_sample"] = r.ns_per_sample;
        std::cout << out.dump(2) << "\n";
      });

  add_lab_test(
      lab, ctx, "plot", "lobe picture (PNG): eval | pdf | sampled density, lat-long layout",
      [](CLI::App *cmd, LabOptions &o) {
        cmd->add_option("--samples", o.samples, "samples for the sampled-density panel (default 1e6)");
        cmd->add_option("-o,--output", o.output, "output PNG path")->required();
        cmd->add_option("--width", o.width, "panel width in pixels (default 512)");
        cmd->add_option("--height", o.height, "panel height in pixels (default 256)");
      },
      [](const LabSetup &s, const LabOptions &o) {
        if (o.width < 8 || o.height < 4 || o.width > 8192 || o.height > 8192)
          throw CliError(kExitBadInput, "--width must be in [8, 8192] and --height in [4, 8192]");
        try {
          render::check_output_path(o.output);  // before the sampling work
        } catch (const std::exception &e) {
          throw CliError(kExitBadInput, e.what());
        }
        lab::PlotOptions options;
        options.width = o.width;
        options.height = o.height;
        options.samples = positive_count(o.samples, "--samples");
        options.seed = o.seed;
        lab::plot_lobe(*s.instance, s.ctx, o.output, options);
        std::cerr << "glimmer: wrote " << o.output << "\n";
      });
}

}  // namespace glimmer::cli
