// Acceptance of the farm pieces on a real Slurm (docs/farm.md): a private
// single-node cluster (tests/bridge/local_slurm.h) runs `glimmer farm slurm` jobs
// of the demo scene, 4 tiles and 4 sample splits, through sbatch; the merged images
// equal the one-machine render (tiles bit for bit, splits within 1e-6 relative).
// Skipped, saying why, only where the Slurm/munge packages are not installed.
#include <chrono>
#include <cstdlib>
#include <regex>

#include "exr_compare.h"
#include "local_slurm.h"
#include "render_test_util.h"

namespace glimmer::test {
namespace {

namespace fs = std::filesystem;

const std::string kDemo = std::string(GLIMMER_TEST_SOURCE_DIR) + "/examples/demo.xml";
const std::string kSize = " --width 48 --height 32 --samples 8";

// Submits `glimmer farm slurm` and waits for its merge job; returns the merged image path.
std::string run_farm_job(LocalSlurm &slurm, const std::string &name, const std::string &split,
                         const std::string &size = kSize) {
  const fs::path work = temp_dir() / name;
  const std::string output = (temp_dir() / (name + ".exr")).string();
  fs::remove(output);
  std::string out;
  EXPECT_EQ(0, run_cli("farm slurm '" + kDemo + "' -o '" + output + "' " + split + size + " --workdir '" +
                           work.string() + "'",
                       out))
      << out;
  std::smatch m;
  const bool submitted = std::regex_search(out, m, std::regex(R"(render job (\d+)[^\n]*\nmerge job (\d+))"));
  EXPECT_TRUE(submitted) << out;
  if (!submitted) return output;
  const std::string render_id = m[1], merge_id = m[2];
  const std::string state = slurm.wait(merge_id, 3600);
  std::string logs;
  for (const auto &e : fs::directory_iterator(work / "logs"))
    logs += e.path().string() + ":\n" + LocalSlurm::read(e.path());
  EXPECT_EQ(state, "COMPLETED") << "merge job " << merge_id << "\n" << logs;
  const std::string tasks = slurm.job_state(render_id);
  EXPECT_EQ(tasks, "COMPLETED COMPLETED COMPLETED COMPLETED") << logs;
  return output;
}

TEST(Slurm, TilesAndSampleSplitsThroughSbatchEqualTheOneMachineRender) {
  LocalSlurm slurm(temp_dir() / "slurm");
  if (slurm.missing_packages) GTEST_SKIP() << "local Slurm unavailable: " << slurm.problem;
  ASSERT_EQ(slurm.problem, "");
  const std::string reference = (temp_dir() / "one_machine.exr").string();
  std::string out;
  ASSERT_EQ(0, run_cli("render '" + kDemo + "' -o '" + reference + "'" + kSize + " --quiet", out)) << out;
  const Exr ref = read_exr(reference);

  const Exr tiles = read_exr(run_farm_job(slurm, "slurm_tiles", "--tiles 4"));
  EXPECT_TRUE(bit_identical(tiles, ref)) << "4 tiles merged differ from the one-machine render";

  const Exr splits = read_exr(run_farm_job(slurm, "slurm_splits", "--sample-splits 4"));
  ASSERT_EQ(splits.pixels.size(), ref.pixels.size());
  const double rel = max_relative_difference(splits, ref);
  EXPECT_LE(rel, 1e-6);
  std::printf("slurm 4 sample splits: max |merged - one machine| / max |one machine| = %.3g\n", rel);
  slurm.stop();
}

// The overhead benchmark (tools/farm_bench.sh; not part of `make test`): wall time of a
// render of >= 60 s as 4 sample splits through the local Slurm (tasks of 1 CPU on this
// node's cores, submit -> merged image) against one process with every core, measured
// one-process / Slurm / one-process so that a change of machine load shows.
TEST(Slurm, DISABLED_BenchFourWaySplitOverheadVsOneProcess) {
  LocalSlurm slurm(temp_dir() / "slurm_bench");
  if (slurm.missing_packages) GTEST_SKIP() << "local Slurm unavailable: " << slurm.problem;
  ASSERT_EQ(slurm.problem, "");
  const char *env = std::getenv("GLIMMER_FARM_BENCH_ARGS");
  const std::string size = env ? env : " --width 640 --height 400 --samples 96";
  using Clock = std::chrono::steady_clock;
  auto one_process = [&](const std::string &name) {
    const auto t0 = Clock::now();
    std::string out;
    EXPECT_EQ(0, run_cli("render '" + kDemo + "' -o '" + (temp_dir() / name).string() + "'" + size +
                             " --threads " + std::to_string(slurm.cpus()) + " --quiet", out)) << out;
    return std::chrono::duration<double>(Clock::now() - t0).count();
  };
  const double first = one_process("bench_one_a.exr");
  const auto t0 = Clock::now();
  run_farm_job(slurm, "bench_slurm", "--sample-splits 4", size);
  const double farm = std::chrono::duration<double>(Clock::now() - t0).count();
  const double second = one_process("bench_one_b.exr");
  const double one = 0.5 * (first + second);
  std::printf("farm bench (%s, %d cores): one process %.1f s and %.1f s, 4-way split on Slurm %.1f s: "
              "overhead %+.1f %%\n", size.c_str(), slurm.cpus(), first, second, farm, 100.0 * (farm / one - 1.0));
  EXPECT_GE(one, 60.0) << "the benchmark render should take at least 60 s; raise --samples";
}

}  // namespace
}  // namespace glimmer::test
