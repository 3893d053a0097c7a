// `glimmer describe --json`, parameter validation messages (through the CLI
// and through host::ClosureInstance) and the `glimmer lab` command line.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <regex>
#include <string>

#include "host/cli_runner.h"
#include "host/closure_instance.h"
#include "host/plugin_library.h"

namespace glimmer::test {
namespace {

bool contains(const std::string &text, const std::string &part) { return text.find(part) != std::string::npos; }

TEST(Describe, JsonListsDiffuseWithItsColourParameter) {
  const CliRun run = run_cli({"describe", "--json"});
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const nlohmann::json j = nlohmann::json::parse(run.out);
  EXPECT_EQ(j["plugin"]["abi_version"].get<uint32_t>(), GLIMMER_ABI_VERSION);
  const nlohmann::json *diffuse = nullptr;
  for (const auto &c : j["closures"])
    if (c["name"] == "diffuse") diffuse = &c;
  ASSERT_NE(diffuse, nullptr) << run.out;
  const nlohmann::json *color = nullptr;
  for (const auto &p : (*diffuse)["params"])
    if (p["name"] == "color") color = &p;
  ASSERT_NE(color, nullptr) << run.out;
  EXPECT_EQ((*color)["type"], "color");
  EXPECT_EQ((*color)["default"], nlohmann::json::parse("[0.8, 0.8, 0.8]"));
  EXPECT_EQ((*color)["min"].get<double>(), 0.0);
  EXPECT_EQ((*color)["max"].get<double>(), 1.0);
  EXPECT_FALSE((*color)["doc"].get<std::string>().empty());
}

TEST(Describe, PrintsFloatsInShortestForm) {
  const CliRun run = run_cli({"describe", "--json"});
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_TRUE(contains(run.out, "0.8")) << run.out;
  EXPECT_FALSE(contains(run.out, "0.800000011920929")) << run.out;
  const CliRun text = run_cli({"describe"});
  EXPECT_FALSE(contains(text.out, "0.800000011920929")) << text.out;
  // An int parameter's range in integers; a float's as before.
  EXPECT_TRUE(contains(text.out, "seed (int, default 0, range [0, 2147483648])")) << text.out;
  EXPECT_TRUE(contains(text.out, "gamma (float, default 2.0, range [0.1, 10.0])")) << text.out;
}

TEST(Describe, ListsEveryParameterTypeOfTheFixturePlugin) {
  const CliRun run = run_cli({"describe", "--json", "--plugin", GLIMMER_TEST_FIXTURE_PARAMS});
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const nlohmann::json j = nlohmann::json::parse(run.out);
  ASSERT_EQ(j["closures"].size(), 2u);  // sorted by name: fixture_params, fixture_side (normal convention)
  ASSERT_EQ(j["closures"][0]["name"], "fixture_params");
  const auto &params = j["closures"][0]["params"];
  ASSERT_EQ(params.size(), 7u);
  EXPECT_EQ(params[4]["name"], "mode");
  EXPECT_EQ(params[4]["choices"], nlohmann::json::parse(R"(["alpha", "beta"])"));
  EXPECT_EQ(params[4]["default"], "alpha");
  EXPECT_EQ(params[2]["default"], 3);
  EXPECT_EQ(params[3]["default"], false);
}

// Each bad value exits 1 with a message naming the closure, the parameter and why.
struct BadParam {
  std::string assignment;
  std::vector<std::string> message_parts;
};

TEST(ParameterValidation, CliNamesTheParameterAndTheReason) {
  const std::vector<BadParam> cases = {
      {"nosuch=1", {"fixture_params", "unknown parameter 'nosuch'", "known: color, roughness"}},
      {"roughness=2", {"'roughness'", "outside [0, 1]"}},
      {"roughness=-0.5", {"'roughness'", "outside [0, 1]"}},
      {"roughness=abc", {"'roughness'", "not a number"}},
      {"roughness=nan", {"'roughness'", "not a finite number"}},
      {"color=1,2", {"'color'", "expects 3 number(s)"}},
      {"color=0.5,1.5,0.5", {"'color'", "outside [0, 1]"}},
      {"count=1.5", {"'count'", "whole number"}},
      {"count=11", {"'count'", "outside [0, 10]"}},
      {"mode=gamma", {"'mode'", "'gamma' is not one of: alpha|beta"}},
      {"roughness", {"'roughness'", "name=value"}},
  };
  for (const auto &c : cases) {
    const CliRun run = run_cli({"lab", "furnace", "--plugin", GLIMMER_TEST_FIXTURE_PARAMS, "--closure",
                                "fixture_params", "--param", c.assignment, "--samples", "1000"});
    EXPECT_EQ(run.exit_code, 1) << c.assignment << ": " << run.err;
    EXPECT_TRUE(run.out.empty()) << c.assignment << ": " << run.out;
    for (const auto &part : c.message_parts) EXPECT_TRUE(contains(run.err, part)) << c.assignment << ": " << run.err;
  }
}

TEST(ParameterValidation, GoodValuesOfEveryTypeAreAccepted) {
  const CliRun run = run_cli({"lab", "furnace", "--plugin", GLIMMER_TEST_FIXTURE_PARAMS, "--closure",
                              "fixture_params", "--param", "color=0.25", "--param", "roughness=1", "--param",
                              "count=10", "--param", "flag=true", "--param", "mode=beta", "--param", "label=x y",
                              "--samples", "20000"});
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const nlohmann::json j = nlohmann::json::parse(run.out);
  // Grey colour 0.25 given as one number: the furnace returns it.
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(j["albedo"][c].get<double>(), 0.25, 1e-5);
}

TEST(ParameterValidation, ClosureInstanceThrowsNamingTheParameter) {
  const auto library = host::PluginLibrary::load(GLIMMER_TEST_FIXTURE_PARAMS);
  const GlimmerClosureType &type = *library->find("fixture_params");
  host::ParamList params;
  params.set_string("mode", "delta");
  try {
    host::ClosureInstance instance(type, params);
    FAIL() << "bad enum accepted";
  } catch (const host::ClosureError &e) {
    EXPECT_TRUE(contains(e.what(), "'mode'")) << e.what();
  }
  host::ParamList unknown;
  EXPECT_THROW(unknown.set_from_text(type, "bogus", "1"), host::ClosureError);
}

TEST(LabCli, AcceptanceFurnaceOfWhiteDiffuseIsOne) {
  const CliRun run = run_cli({"lab", "furnace", "--closure", "diffuse", "--param", "color=1,1,1", "--wi",
                              "0.3,0,0.95", "--samples", "1000000"});
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const nlohmann::json j = nlohmann::json::parse(run.out);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(j["albedo"][c].get<double>(), 1.0, 0.002) << run.out;
  EXPECT_EQ(j["samples"].get<uint64_t>(), 1000000u);
  EXPECT_EQ(j["invalid"].get<uint64_t>(), 0u);
}

TEST(LabCli, Chi2AndBenchPrintJson) {
  const CliRun chi2 = run_cli({"lab", "chi2", "--closure", "diffuse", "--wi", "0,0,1", "--test-count", "2"});
  ASSERT_EQ(chi2.exit_code, 0) << chi2.err;
  const nlohmann::json c = nlohmann::json::parse(chi2.out);
  EXPECT_TRUE(c["passed"].get<bool>()) << chi2.out;
  EXPECT_GE(c["p_value"].get<double>(), c["significance"].get<double>());
  EXPECT_NEAR(c["significance"].get<double>(), 1.0 - std::sqrt(0.99), 1e-12);
  // Cells refined toward an axis (near-delta transmission at IOR 1.001 about -wi).
  const CliRun warped = run_cli({"lab", "chi2", "--closure", "microfacet_dielectric", "--param", "ior=1.001",
                                 "--param", "roughness=0.1", "--wi", "0,0.6,0.8", "--axis", "0,-0.6,-0.8",
                                 "--theta-exponent", "4", "--samples", "200000"});
  ASSERT_EQ(warped.exit_code, 0) << warped.err;
  const nlohmann::json w = nlohmann::json::parse(warped.out);
  EXPECT_TRUE(w["passed"].get<bool>()) << warped.out;
  EXPECT_EQ(w["theta_exponent"].get<double>(), 4.0);
  EXPECT_NEAR(w["axis"][2].get<double>(), -0.8, 1e-6);
  // The uniform cells about N cannot resolve that lobe (its pdf integral comes out wrong): the refinement matters.
  const CliRun plain = run_cli({"lab", "chi2", "--closure", "microfacet_dielectric", "--param", "ior=1.001", "--param",
                                "roughness=0.1", "--wi", "0,0.6,0.8", "--samples", "200000"});
  ASSERT_EQ(plain.exit_code, 0) << plain.err;
  EXPECT_FALSE(nlohmann::json::parse(plain.out)["passed"].get<bool>()) << plain.out;
  EXPECT_EQ(run_cli({"lab", "chi2", "--closure", "diffuse", "--theta-exponent", "0.5"}).exit_code, 1);
  const CliRun bench = run_cli({"lab", "bench", "--closure", "emission", "--iterations", "10000"});
  ASSERT_EQ(bench.exit_code, 0) << bench.err;
  const nlohmann::json b = nlohmann::json::parse(bench.out);
  EXPECT_GT(b["ns_per_eval"].get<double>(), 0.0);
  EXPECT_GT(b["ns_per_sample"].get<double>(), 0.0);
}

// Every lab sub-command on the microfacet closures (issue 4: "glimmer lab works for all of these").
TEST(LabCli, EverySubcommandWorksForTheMicrofacetClosures) {
  struct Config {
    std::vector<std::string> params;
    double albedo;  // expected furnace albedo (energy-conserving configurations)
  };
  const std::vector<std::pair<std::string, Config>> configs = {
      {"microfacet_conductor", {{"distribution=multi_ggx", "roughness=1"}, 1.0}},
      {"microfacet_conductor", {{"distribution=multi_ggx", "roughness=0.7", "bounce_tint=0.8,0.5,0.2"}, -1.0}},
      {"microfacet_conductor", {{"distribution=beckmann", "roughness=0.4", "anisotropy=0.5", "f0=0.9,0.6,0.3"}, -1.0}},
      {"microfacet_dielectric", {{"distribution=multi_ggx", "roughness=0.6", "ior=1.5"}, 1.0}},
      {"microfacet_dielectric", {{"distribution=ggx", "roughness=0.3", "ior=0.6667"}, -1.0}},
      {"microfacet_random_walk", {{"type=dielectric", "roughness=0.8", "ior=1.5"}, 1.0}},
  };
  const std::string plot = (std::filesystem::path(GLIMMER_TEST_BINARY_DIR) / "cli_runs" / "microfacet_lab.png").string();
  for (const auto &[closure, config] : configs) {
    std::vector<std::string> base = {"--closure", closure, "--wi", "0.5,0,0.8"};
    for (const auto &p : config.params) base.insert(base.end(), {"--param", p});
    SCOPED_TRACE(closure + " " + config.params[0] + " " + config.params[1]);
    auto run = [&](const std::string &sub, std::vector<std::string> extra) {
      std::vector<std::string> args = {"lab", sub};
      args.insert(args.end(), base.begin(), base.end());
      args.insert(args.end(), extra.begin(), extra.end());
      const CliRun r = run_cli(args);
      EXPECT_EQ(r.exit_code, 0) << sub << ": " << r.err << r.out;
      return r.exit_code == 0 && sub != "plot" ? nlohmann::json::parse(r.out) : nlohmann::json();
    };
    const nlohmann::json furnace = run("furnace", {"--samples", "100000"});
    if (!furnace.is_null()) {
      EXPECT_EQ(furnace["invalid"].get<uint64_t>(), 0u);
      if (config.albedo > 0.0) {
        EXPECT_NEAR(furnace["albedo"][0].get<double>(), config.albedo,
                    0.006 + 5.0 * furnace["standard_error"][0].get<double>());
      }
    }
    if (closure != "microfacet_random_walk") {  // stochastic eval: no exact pdf to test against
      const nlohmann::json chi2 = run("chi2", {"--samples", "200000", "--test-count", "5"});
      if (!chi2.is_null()) {
        EXPECT_TRUE(chi2["passed"].get<bool>()) << chi2.dump();
      }
      const nlohmann::json consistency = run("consistency", {"--samples", "20000"});
      if (!consistency.is_null()) {
        EXPECT_EQ(consistency["mismatches"].get<uint64_t>(), 0u);
      }
    }
    const nlohmann::json stress = run("stress", {"--samples", "20000"});
    if (!stress.is_null()) {
      EXPECT_EQ(stress["invalid"].get<uint64_t>(), 0u);
      EXPECT_EQ(stress["eval"]["nan"].get<uint64_t>() + stress["sample"]["nan"].get<uint64_t>(), 0u);
    }
    const nlohmann::json bench = run("bench", {"--iterations", "2000", "--repetitions", "1"});
    if (!bench.is_null()) {
      EXPECT_GT(bench["ns_per_eval"].get<double>(), 0.0);
    }
    std::filesystem::remove(plot);
    run("plot", {"-o", plot});
    EXPECT_TRUE(std::filesystem::exists(plot));
  }
}

TEST(LabCli, BadInputExitsOne) {
  const CliRun unknown = run_cli({"lab", "furnace", "--closure", "velvet"});
  EXPECT_EQ(unknown.exit_code, 1);
  EXPECT_TRUE(contains(unknown.err, "unknown closure 'velvet'")) << unknown.err;
  EXPECT_TRUE(contains(unknown.err, "diffuse")) << unknown.err;
  for (const auto &wi : {"0,0", "0,0,0", "a,b,c"}) {
    const CliRun run = run_cli({"lab", "furnace", "--closure", "diffuse", "--wi", wi});
    EXPECT_EQ(run.exit_code, 1) << wi;
    EXPECT_TRUE(contains(run.err, "--wi")) << run.err;
  }
  const CliRun samples = run_cli({"lab", "furnace", "--closure", "diffuse", "--samples", "0"});
  EXPECT_EQ(samples.exit_code, 1);
  EXPECT_TRUE(contains(samples.err, "--samples")) << samples.err;
  const CliRun plot = run_cli({"lab", "plot", "--closure", "diffuse"});  // no -o
  EXPECT_EQ(plot.exit_code, 1);
}

// A mistyped sub-command or option is named (CLI11 alone said "A subcommand is required" / "scene is required").
TEST(Cli, UnknownSubcommandsAndArgumentsAreNamed) {
  const CliRun typo = run_cli({"rendr", "scene.xml", "-o", "out.exr"});
  EXPECT_EQ(typo.exit_code, 1);
  EXPECT_TRUE(contains(typo.err, "unknown sub-command 'rendr' (one of: describe lab render")) << typo.err;
  const CliRun lab = run_cli({"lab", "furnance", "--closure", "diffuse"});
  EXPECT_EQ(lab.exit_code, 1);
  EXPECT_TRUE(contains(lab.err, "unknown sub-command 'furnance' (one of: furnace chi2")) << lab.err;
  const CliRun option = run_cli({"render", "--sampels"});
  EXPECT_EQ(option.exit_code, 1);
  EXPECT_TRUE(contains(option.err, "scene is required; not understood: '--sampels'")) << option.err;
  const CliRun version = run_cli({"--verison"});
  EXPECT_EQ(version.exit_code, 1);
  EXPECT_TRUE(contains(version.err, "not understood: '--verison'")) << version.err;
  // Nothing mistyped: CLI11's own message, unchanged.
  const CliRun none = run_cli({});
  EXPECT_EQ(none.exit_code, 1);
  EXPECT_TRUE(contains(none.err, "A subcommand is required\n")) << none.err;
}

// `glimmer --version` (a farm task's log records what rendered it): the host's version and closure ABI, then the
// plugin it loads; a plugin that does not load is named, and --version still succeeds (it is not a render).
TEST(Cli, VersionNamesTheHostAbiAndThePlugin) {
  const std::regex host_line("^glimmer [0-9]+\\.[0-9]+\\.[0-9]+ \\(closure ABI " +
                             host::abi_version_name(GLIMMER_ABI_VERSION) + "\\)\n");
  const CliRun version = run_cli({"--version"});
  EXPECT_EQ(version.exit_code, 0) << version.err;
  EXPECT_TRUE(std::regex_search(version.out, host_line)) << version.out;
  EXPECT_TRUE(contains(version.out, "\nplugin glimmer_closures ")) << version.out;
  EXPECT_TRUE(contains(version.out, "libglimmer_closures.so")) << version.out;
  const CliRun missing = run_cli({"--plugin", "/nonexistent/libglimmer_closures.so", "--version"});
  EXPECT_EQ(missing.exit_code, 0) << missing.err;
  EXPECT_TRUE(std::regex_search(missing.out, host_line)) << missing.out;
  EXPECT_TRUE(contains(missing.out, "plugin: none loaded (")) << missing.out;
  EXPECT_TRUE(contains(missing.out, "/nonexistent")) << missing.out;
}

// `glimmer lab --footprint` (session 40): a glint at a point (the default) holds about one particle, so its furnace
// albedo is 0 at most wi; over a footprint of 1 uv (10^6 particles: the filtered switch) it is the smooth GGX lobe,
// within 1 % of microfacet_conductor's albedo at the same wi. A negative footprint is refused naming the option.
TEST(Cli, LabFootprintReachesTheGlint) {
  auto albedo = [](const std::vector<std::string> &args) {
    std::vector<std::string> all = {"lab", "furnace", "--wi", "0.3,0,0.95", "--samples", "100000"};
    all.insert(all.end(), args.begin(), args.end());
    const CliRun run = run_cli(all);
    EXPECT_EQ(run.exit_code, 0) << run.err;
    return run.exit_code == 0 ? nlohmann::json::parse(run.out)["albedo"][0].get<double>() : -1.0;
  };
  const double point = albedo({"--closure", "glint"});
  const double wide = albedo({"--closure", "glint", "--footprint", "1"});
  const double smooth = albedo({"--closure", "microfacet_conductor", "--param", "roughness=0.4"});
  std::printf("[lab footprint] glint furnace albedo: point %.4f, footprint 1 uv %.4f; GGX conductor %.4f\n", point,
              wide, smooth);
  EXPECT_LT(point, 0.05);
  EXPECT_NEAR(wide, smooth, 0.01 * smooth);
  const CliRun bad = run_cli({"lab", "furnace", "--closure", "glint", "--footprint", "-1"});
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_TRUE(contains(bad.err, "--footprint")) << bad.err;
}

}  // namespace
}  // namespace glimmer::test
