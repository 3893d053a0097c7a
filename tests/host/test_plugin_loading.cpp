// Loading the closure DSO: ABI version check, broken DSOs, search order
// (--plugin, then $GLIMMER_PLUGIN_PATH, then next to the executable), and the
// exit code 2 the CLI gives for every plugin problem.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <tuple>

#include "host/cli_runner.h"
#include "host/closure_instance.h"
#include "host/plugin_library.h"

namespace glimmer::test {
namespace {

namespace fs = std::filesystem;

const std::string kHostVersion = host::abi_version_name(GLIMMER_ABI_VERSION);  // "2.10"

TEST(PluginLoading, LoadsTheClosureDso) {
  const auto library = host::PluginLibrary::load(GLIMMER_TEST_PLUGIN_PATH);
  EXPECT_EQ(library->info().abi_version, GLIMMER_ABI_VERSION);
  EXPECT_NE(library->find("diffuse"), nullptr);
  EXPECT_NE(library->find("emission"), nullptr);
  EXPECT_EQ(library->find("no_such_closure"), nullptr);
  // A folder holding the DSO works too.
  EXPECT_NO_THROW(host::PluginLibrary::load(fs::path(GLIMMER_TEST_PLUGIN_PATH).parent_path().string()));
}

TEST(PluginLoading, RefusesOtherAbiVersionNamingBoth) {
  try {
    host::PluginLibrary::load(GLIMMER_TEST_FIXTURE_ABI999);
    FAIL() << "a DSO built for ABI 999 was accepted";
  } catch (const host::PluginError &e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("ABI version 999"), std::string::npos) << what;
    EXPECT_NE(what.find("ABI version " + kHostVersion), std::string::npos) << what;
  }
}

TEST(PluginLoading, RefusesAbi1Abi3AndANewerMinorNamingBothVersions) {
  EXPECT_EQ(kHostVersion, std::to_string(GLIMMER_ABI_MAJOR) + "." + std::to_string(GLIMMER_ABI_MINOR));
  const std::pair<const char *, const char *> fixtures[] = {
      {GLIMMER_TEST_FIXTURE_ABI1, "1"}, {GLIMMER_TEST_FIXTURE_ABI3_0, "3.0"}, {GLIMMER_TEST_FIXTURE_ABI2_11, "2.11"}};
  for (const auto &[path, version] : fixtures) {
    try {
      host::PluginLibrary::load(path);
      ADD_FAILURE() << "a DSO built for ABI " << version << " was accepted";
    } catch (const host::PluginError &e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("built for Glimmer ABI version " + std::string(version) + ","), std::string::npos) << what;
      EXPECT_NE(what.find("this host uses ABI version " + kHostVersion), std::string::npos) << what;
    }
  }
}

// The params fixture is compiled against ABI 2.0 (GLIMMER_ABI_MINOR=0: its
// GlimmerParamSpec has no flags field and its contexts no varying fields). It
// loads in this 2.2 host, its schema is read with its own stride, and its
// closure creates, evaluates and samples with a 2.2 context that lists varying
// values (which a 2.0 plugin never reads).
TEST(PluginLoading, Abi20PluginLoadsAndRendersInAbi22Host) {
  const auto library = host::PluginLibrary::load(GLIMMER_TEST_FIXTURE_PARAMS);
  EXPECT_EQ(host::abi_version_name(library->info().abi_version), "2.0");
  const GlimmerClosureType *type = library->find("fixture_params");
  ASSERT_NE(type, nullptr);
  EXPECT_LT(type->param_spec_size, sizeof(GlimmerParamSpec));  // the 2.0 layout, really
  ASSERT_EQ(type->param_count, 7u);
  EXPECT_STREQ(host::param_at(*type, 4).name, "mode");  // stride of the plugin's specs
  EXPECT_STREQ(host::param_at(*type, 5).default_string, "none");
  for (uint32_t i = 0; i < type->param_count; ++i) EXPECT_EQ(host::param_flags(*type, host::param_at(*type, i)), 0u);
  host::ParamList params;
  params.set_number("color", 0.25f, 0.5f, 0.75f);
  const host::ClosureInstance instance(*type, params);
  GlimmerShadingContext ctx = host::make_local_context(Vec3(0.0f, 0.0f, 1.0f));
  const GlimmerVaryingValue varying{0u, {1.0f, 1.0f, 1.0f}};
  ctx.varying_count = 1;
  ctx.varying = &varying;
  Spectrum f;
  float pdf = 0.0f;
  instance.eval(ctx, Vec3(0.0f, 0.0f, 1.0f), f, pdf);
  EXPECT_NEAR(f.y, 0.5f / kPi, 1e-6f);  // the constant colour: a 2.0 closure has no varying parameters
  EXPECT_NEAR(pdf, 1.0f / kPi, 1e-6f);
  GlimmerSample s{};
  const float r3[3] = {0.3f, 0.6f, 0.5f};
  EXPECT_NE(instance.sample(ctx, r3, s), 0u);
}

// ABI 2.3's normal convention: the host hands N toward wi and `backfacing`; a
// TRANSMISSIVE closure of an older plugin took the side from dot(wi, N) with the
// front-face N, and the host hands it that. Both builds of the fixture's
// fixture_side closure see wi inside for a path arriving at the back.
Spectrum echoed_side(const char *plugin_path, bool through_host) {
  const auto library = host::PluginLibrary::load(plugin_path);
  const GlimmerClosureType *type = library->find("fixture_side");
  EXPECT_NE(type, nullptr);
  if (type == nullptr) return Spectrum(-1.0f);
  const host::ClosureInstance instance(*type, host::ParamList{});
  const GlimmerShadingContext ctx = host::make_local_context(Vec3(0.3f, 0.0f, -0.9f));  // from the back
  EXPECT_EQ(ctx.backfacing, 1u);
  EXPECT_GT(dot(Vec3(ctx.wi), Vec3(ctx.N)), 0.0f);  // N toward wi
  if (through_host) return instance.albedo(ctx);
  float rgb[3];
  type->albedo(instance.handle(), &ctx, rgb);  // the context as is, without the host's adaptation
  return {rgb[0], rgb[1], rgb[2]};
}

TEST(PluginLoading, TransmissiveClosuresOfAnOlderPluginGetTheFrontFaceNormal) {
  auto sees_inside = [](const Spectrum &echo) { return echo.x == 1.0f && echo.y == 0.0f; };
  auto sees_outside = [](const Spectrum &echo) { return echo.x == 0.0f && echo.y == 1.0f; };
  EXPECT_TRUE(sees_inside(echoed_side(GLIMMER_TEST_FIXTURE_PARAMS, true)));          // 2.0 plugin, host adapts
  EXPECT_TRUE(sees_inside(echoed_side(GLIMMER_TEST_FIXTURE_PARAMS_CURRENT, true)));  // 2.3 plugin reads backfacing
  // Negative control: without the adaptation the 2.0 closure would take the back for the front.
  EXPECT_TRUE(sees_outside(echoed_side(GLIMMER_TEST_FIXTURE_PARAMS, false)));
}

// ABI 2.2: an INT parameter's exact value reaches a 2.2 plugin (the decimal
// text in GlimmerParamValue.string); the fixture's albedo() echoes `seed` as
// (seed >> 16, seed & 0xffff, 0), exact in floats.
Spectrum echoed_seed(const GlimmerClosureType &type, const std::string &seed) {
  host::ParamList params;
  params.set_from_text(type, "seed", seed);
  const host::ClosureInstance instance(type, params);
  return instance.albedo(host::make_local_context(Vec3(0.0f, 0.0f, 1.0f)));
}

TEST(PluginLoading, IntegerParametersReachAnAbi22PluginExactly) {
  const auto library = host::PluginLibrary::load(GLIMMER_TEST_FIXTURE_PARAMS_CURRENT);
  const GlimmerClosureType *type = library->find("fixture_params");
  ASSERT_NE(type, nullptr);
  EXPECT_EQ(host::closure_abi_version(*type), GLIMMER_ABI_VERSION);
  // 2^24 + 1 is not a float: through value[0] it would arrive as 2^24 (256, 0).
  ASSERT_NE(static_cast<int64_t>(static_cast<float>(16777217)), 16777217);
  for (const auto &[text, hi, lo] : {std::tuple{"16777217", 256.0f, 1.0f}, std::tuple{"2147483647", 32767.0f, 65535.0f},
                                     std::tuple{"2147483648", 32768.0f, 0.0f}, std::tuple{"1e3", 0.0f, 1000.0f}}) {
    const Spectrum echo = echoed_seed(*type, text);
    EXPECT_EQ(echo.x, hi) << text;
    EXPECT_EQ(echo.y, lo) << text;
  }
  // The range is checked on the integer, exactly (2^31 + 1 is the float 2^31, inside the range).
  try {
    echoed_seed(*type, "2147483649");
    ADD_FAILURE() << "seed 2^31 + 1 outside [0, 2^31] was accepted";
  } catch (const host::ClosureError &e) {
    EXPECT_NE(std::string(e.what()).find("'seed' = 2147483649 is outside [0, 2147483648]"), std::string::npos)
        << e.what();
  }
  EXPECT_THROW(echoed_seed(*type, "3.5"), host::ClosureError);
  EXPECT_THROW(echoed_seed(*type, "99999999999999999999"), host::ClosureError);
}

// A 2.0 plugin reads integers from the float: values a float holds reach it,
// one it cannot hold is refused by the host (not silently rounded).
TEST(PluginLoading, IntegerBeyondFloatPrecisionIsRefusedForAnOlderPlugin) {
  const auto library = host::PluginLibrary::load(GLIMMER_TEST_FIXTURE_PARAMS);
  const GlimmerClosureType *type = library->find("fixture_params");
  ASSERT_NE(type, nullptr);
  EXPECT_EQ(host::closure_abi_version(*type), 0u);
  const Spectrum echo = echoed_seed(*type, "16777216");
  EXPECT_EQ(echo.x, 256.0f);
  EXPECT_EQ(echo.y, 0.0f);
  try {
    echoed_seed(*type, "16777217");
    ADD_FAILURE() << "16777217 was handed to an ABI 2.0 plugin as a float";
  } catch (const host::ClosureError &e) {
    EXPECT_NE(std::string(e.what()).find("cannot reach this plugin exactly"), std::string::npos) << e.what();
  }
}

// Schemas are validated when the plugin loads: defaults in range, enum
// defaults among the choices, unique names.
TEST(PluginLoading, SchemaValidationNamesTheParameterAndTheProblem) {
  GlimmerParamSpec specs[2] = {
      {"roughness", GLIMMER_PARAM_FLOAT, {0.5f, 0, 0}, 0.0f, 1.0f, nullptr, nullptr, "r", 0},
      {"distribution", GLIMMER_PARAM_ENUM, {0, 0, 0}, 0.0f, 0.0f, "ggx|beckmann", "ggx", "d", 0},
  };
  GlimmerClosureType type{};
  type.struct_size = sizeof(type);
  type.param_spec_size = sizeof(GlimmerParamSpec);
  type.name = "schema_test";
  type.param_count = 2;
  type.params = specs;
  EXPECT_EQ(host::validate_schema(type), "");
  specs[0].default_value[0] = 1.5f;
  EXPECT_NE(host::validate_schema(type).find("'roughness': default 1.5"), std::string::npos) << host::validate_schema(type);
  specs[0].default_value[0] = 0.5f;
  specs[1].default_string = "sharp";
  EXPECT_NE(host::validate_schema(type).find("'distribution': default 'sharp' is not one of its choices"),
            std::string::npos)
      << host::validate_schema(type);
  specs[1].default_string = "ggx";
  specs[1].name = "roughness";
  EXPECT_NE(host::validate_schema(type).find("declared twice"), std::string::npos);
  // INT: whole default and whole bounds.
  specs[1] = {"count", GLIMMER_PARAM_INT, {3, 0, 0}, 0.0f, 10.0f, nullptr, nullptr, "c", 0};
  EXPECT_EQ(host::validate_schema(type), "");
  specs[1].default_value[0] = 2.5f;
  EXPECT_NE(host::validate_schema(type).find("'count': default 2.5"), std::string::npos) << host::validate_schema(type);
  specs[1].default_value[0] = 3.0f;
  specs[1].max_value = 10.5f;
  EXPECT_NE(host::validate_schema(type).find("'count': integer range"), std::string::npos)
      << host::validate_schema(type);
  // Every closure of the real plugin passes (it loads).
  EXPECT_NO_THROW(host::PluginLibrary::load(GLIMMER_TEST_PLUGIN_PATH));
}

TEST(PluginLoading, CliRefusesOtherAbiVersionWithExitCode2) {
  const CliRun run = run_cli({"describe", "--plugin", GLIMMER_TEST_FIXTURE_ABI999});
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.err.find("999"), std::string::npos) << run.err;
  EXPECT_NE(run.err.find("this host uses ABI version " + kHostVersion), std::string::npos) << run.err;
  EXPECT_TRUE(run.out.empty()) << run.out;
}

TEST(PluginLoading, CliRefusesLibraryWithoutEntryPoint) {
  const CliRun run = run_cli({"describe", "--plugin", GLIMMER_TEST_FIXTURE_NO_ENTRY});
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.err.find("glimmer_plugin_entry"), std::string::npos) << run.err;
  EXPECT_NE(run.err.find(GLIMMER_TEST_FIXTURE_NO_ENTRY), std::string::npos) << run.err;
}

TEST(PluginLoading, CliReportsMissingPlugin) {
  const std::string missing = std::string(GLIMMER_TEST_BINARY_DIR) + "/no/such/libglimmer_closures.so";
  const CliRun run = run_cli({"describe", "--plugin", missing});
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.err.find("not found"), std::string::npos) << run.err;
  EXPECT_NE(run.err.find(missing), std::string::npos) << run.err;
  // The lab reports plugin problems the same way.
  const CliRun lab = run_cli({"lab", "furnace", "--closure", "diffuse", "--plugin", missing});
  EXPECT_EQ(lab.exit_code, 2);
}

TEST(PluginLoading, CliReportsFileThatIsNotALibrary) {
  const fs::path bogus = fs::path(GLIMMER_TEST_BINARY_DIR) / "not_a_library.so";
  {
    std::ofstream out(bogus);
    out << "this is not an ELF file\n";
  }
  const CliRun run = run_cli({"describe", "--plugin", bogus.string()});
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.err.find("cannot load closure plugin"), std::string::npos) << run.err;
  fs::remove(bogus);
}

// describe prints "... from <path>" naming the DSO it loaded.
std::string loaded_path(const CliRun &run) {
  const auto first_line = run.out.substr(0, run.out.find('\n'));
  const auto from = first_line.find(" from ");
  return from == std::string::npos ? std::string() : first_line.substr(from + 6);
}

TEST(PluginSearchOrder, ExplicitFlagWinsOverEnvironment) {
  const CliRun run = run_cli({"describe", "--plugin", GLIMMER_TEST_PLUGIN_PATH},
                             {std::string("GLIMMER_PLUGIN_PATH=") + GLIMMER_TEST_FIXTURE_ABI999});
  EXPECT_EQ(run.exit_code, 0) << run.err;
  EXPECT_EQ(loaded_path(run), GLIMMER_TEST_PLUGIN_PATH);
}

TEST(PluginSearchOrder, EnvironmentWinsOverExecutableFolder) {
  // The real DSO sits next to the executable, yet the environment is used.
  const CliRun broken = run_cli({"describe"}, {std::string("GLIMMER_PLUGIN_PATH=") + GLIMMER_TEST_FIXTURE_ABI999});
  EXPECT_EQ(broken.exit_code, 2);
  EXPECT_NE(broken.err.find("999"), std::string::npos) << broken.err;
  const CliRun params = run_cli({"describe"}, {std::string("GLIMMER_PLUGIN_PATH=") + GLIMMER_TEST_FIXTURE_PARAMS});
  EXPECT_EQ(params.exit_code, 0) << params.err;
  EXPECT_EQ(loaded_path(params), GLIMMER_TEST_FIXTURE_PARAMS);
  EXPECT_NE(params.out.find("fixture_params"), std::string::npos);
}

TEST(PluginSearchOrder, FallsBackToExecutableFolder) {
  const CliRun run = run_cli({"describe"});
  EXPECT_EQ(run.exit_code, 0) << run.err;
  const fs::path expected = fs::path(GLIMMER_TEST_CLI_PATH).parent_path() / host::PluginLibrary::kLibraryFileName;
  EXPECT_EQ(fs::weakly_canonical(loaded_path(run)), fs::weakly_canonical(expected));
}

TEST(PluginSearchOrder, ReportsEveryPlaceTriedWhenNothingIsFound) {
  // A copy of the executable in a folder without the DSO.
  const fs::path dir = fs::path(GLIMMER_TEST_BINARY_DIR) / "lonely_cli";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path exe = dir / "glimmer";
  fs::copy_file(GLIMMER_TEST_CLI_PATH, exe);
  fs::permissions(exe, fs::perms::owner_all, fs::perm_options::add);
  const CliRun run = run_cli({"describe"}, {}, exe.string());
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.err.find("not found; tried"), std::string::npos) << run.err;
  EXPECT_NE(run.err.find("GLIMMER_PLUGIN_PATH"), std::string::npos) << run.err;
  EXPECT_NE(run.err.find((dir / host::PluginLibrary::kLibraryFileName).string()), std::string::npos) << run.err;
  // The environment variable may name the DSO's folder.
  const CliRun via_env = run_cli({"describe"},
                                 {"GLIMMER_PLUGIN_PATH=" + fs::path(GLIMMER_TEST_PLUGIN_PATH).parent_path().string()},
                                 exe.string());
  EXPECT_EQ(via_env.exit_code, 0) << via_env.err;
  fs::remove_all(dir);
}

}  // namespace
}  // namespace glimmer::test
