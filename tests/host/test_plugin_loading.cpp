// Loading the closure DSO: ABI version check, broken DSOs, search order
// (--plugin, then $GLIMMER_PLUGIN_PATH, then next to the executable), and the
// exit code 2 the CLI gives for every plugin problem.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "host/cli_runner.h"
#include "host/plugin_library.h"

namespace glimmer::test {
namespace {

namespace fs = std::filesystem;

const std::string kHostVersion = std::to_string(GLIMMER_ABI_VERSION);

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
