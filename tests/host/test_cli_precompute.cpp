// `glimmer precompute energy`: the generator of plugin/tables/microfacet_energy_data.cpp.
// A tiny run (2x2 strata, 64 walks) must write a source with exactly the arrays,
// sizes and header lines of the committed table, and record its own command line;
// bad counts and an unwritable output are clear errors with exit code 1.
#include <gtest/gtest.h>

#include <filesystem>
#include <map>
#include <regex>
#include <string>

#include "host/cli_runner.h"

namespace glimmer::test {
namespace {

namespace fs = std::filesystem;

// Array name -> number of values in its initializer.
std::map<std::string, size_t> array_sizes(const std::string &source) {
  std::map<std::string, size_t> sizes;
  const std::regex decl(R"(const float (\w+)(\[[^=]*\])\s*=\s*\{)");
  for (std::sregex_iterator it(source.begin(), source.end(), decl), end; it != end; ++it) {
    const size_t open = size_t(it->position(0) + it->length(0));
    const size_t close = source.find("};", open);
    size_t values = 0;
    for (size_t i = open; i < close; ++i) values += source[i] == ',';
    sizes[(*it)[1].str() + (*it)[2].str()] = values;
  }
  return sizes;
}

TEST(PrecomputeEnergy, TinyRunMatchesTheCommittedTableLayoutAndRecordsItsCommand) {
  const fs::path dir = fs::path(GLIMMER_TEST_BINARY_DIR) / "precompute_test";
  fs::create_directories(dir);
  const fs::path out = dir / "energy.cpp";
  fs::remove(out);
  const CliRun run = run_cli({"precompute", "energy", "--strata", "2", "--walks", "64", "--seed", "3", "-o", out.string()});
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const std::string generated = read_text(out);
  EXPECT_NE(generated.find("// Command: glimmer precompute energy --strata 2 --walks 64 --seed 3"), std::string::npos);
  EXPECT_NE(generated.find("E_Fms cells use 64 Heitz 2016 random walks"), std::string::npos);
  EXPECT_FALSE(fs::exists(out.string() + ".tmp"));

  const std::string committed = read_text(fs::path(GLIMMER_TEST_SOURCE_DIR) / "plugin/tables/microfacet_energy_data.cpp");
  EXPECT_NE(committed.find("// Command: glimmer precompute energy --strata "), std::string::npos);
  const auto expected = array_sizes(committed), got = array_sizes(generated);
  EXPECT_EQ(expected.size(), 8u);
  EXPECT_EQ(got, expected);
  // Energies are finite numbers (no "nan"/"inf" text).
  EXPECT_EQ(generated.find("nan"), std::string::npos);
  EXPECT_EQ(generated.find("inf"), std::string::npos);
}

TEST(PrecomputeEnergy, BadCountsAndUnwritableOutputAreErrors) {
  const fs::path dir = fs::path(GLIMMER_TEST_BINARY_DIR) / "precompute_test";
  fs::create_directories(dir);
  CliRun run = run_cli({"precompute", "energy", "--strata", "1", "-o", (dir / "never.cpp").string()});
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find("--strata must be >= 2"), std::string::npos) << run.err;
  EXPECT_FALSE(fs::exists(dir / "never.cpp"));
  run = run_cli({"precompute", "energy", "--strata", "2", "--walks", "16", "-o", "/nonexistent-dir/x.cpp"});
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find("cannot write --output"), std::string::npos) << run.err;
  run = run_cli({"precompute", "energy"});
  EXPECT_NE(run.exit_code, 0);
  EXPECT_NE(run.err.find("output"), std::string::npos) << run.err;
}

}  // namespace
}  // namespace glimmer::test
