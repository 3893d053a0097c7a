// Acceptance of the farm pieces on a real Slurm (docs/farm.md): a private
// single-node cluster (tests/bridge/local_slurm.h) runs `glimmer farm slurm` jobs
// of the demo scene, 4 tiles and 4 sample splits, through sbatch; the merged images
// equal the one-machine render (tiles bit for bit, splits within 1e-6 relative).
// Skipped, saying why, only where the Slurm/munge packages are not installed.
#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <ctime>
#include <regex>
#include <vector>

#include "exr_compare.h"
#include "local_slurm.h"
#include "render_test_util.h"

namespace glimmer::test {
namespace {

namespace fs = std::filesystem;

const std::string kDemo = std::string(GLIMMER_TEST_SOURCE_DIR) + "/examples/demo.xml";
const std::string kSize = " --width 48 --height 32 --samples 8";

struct FarmRun {
  std::string output, render_id, merge_id;
};

// Submits `glimmer farm slurm` and waits for its merge job.
FarmRun run_farm_job(LocalSlurm &slurm, const std::string &name, const std::string &split,
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
  if (!submitted) return {output, "", ""};
  const std::string render_id = m[1], merge_id = m[2];
  const std::string state = slurm.wait(merge_id, 3600);
  std::string logs;
  for (const auto &e : fs::directory_iterator(work / "logs")) logs += e.path().string() + ":\n" + read_text(e.path());
  EXPECT_EQ(state, "COMPLETED") << "merge job " << merge_id << "\n" << logs;
  const std::string tasks = slurm.job_state(render_id);
  EXPECT_EQ(tasks, "COMPLETED COMPLETED COMPLETED COMPLETED") << logs;
  return {output, render_id, merge_id};
}

// Seconds since the epoch of every `key`=YYYY-MM-DDTHH:MM:SS in scontrol's one-line job records.
std::vector<long> job_times(const std::string &id, const std::string &key) {
  const std::string text = LocalSlurm::capture("scontrol -o show job " + id + " 2>/dev/null");
  std::vector<long> times;
  const std::regex re(key + R"(=(\d+)-(\d+)-(\d+)T(\d+):(\d+):(\d+))");
  for (auto it = std::sregex_iterator(text.begin(), text.end(), re); it != std::sregex_iterator(); ++it) {
    std::tm t{};
    t.tm_year = std::stoi((*it)[1]) - 1900;
    t.tm_mon = std::stoi((*it)[2]) - 1;
    t.tm_mday = std::stoi((*it)[3]);
    t.tm_hour = std::stoi((*it)[4]);
    t.tm_min = std::stoi((*it)[5]);
    t.tm_sec = std::stoi((*it)[6]);
    times.push_back(static_cast<long>(timegm(&t)));
  }
  return times;
}

TEST(Slurm, TilesAndSampleSplitsThroughSbatchEqualTheOneMachineRender) {
  LocalSlurm slurm(temp_dir() / "slurm");
  if (slurm.missing_packages) GTEST_SKIP() << "local Slurm unavailable: " << slurm.problem;
  ASSERT_EQ(slurm.problem, "");
  const std::string reference = (temp_dir() / "one_machine.exr").string();
  std::string out;
  ASSERT_EQ(0, run_cli("render '" + kDemo + "' -o '" + reference + "'" + kSize + " --quiet", out)) << out;
  const Exr ref = read_exr(reference);

  const Exr tiles = read_exr(run_farm_job(slurm, "slurm_tiles", "--tiles 4").output);
  EXPECT_TRUE(bit_identical(tiles, ref)) << "4 tiles merged differ from the one-machine render";

  const Exr splits = read_exr(run_farm_job(slurm, "slurm_splits", "--sample-splits 4").output);
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
  const std::string size = env ? env : " --width 640 --height 400 --samples 240";
  using Clock = std::chrono::steady_clock;
  auto one_process = [&](const std::string &name) {
    const auto t0 = Clock::now();
    std::string out;
    EXPECT_EQ(0, run_cli("render '" + kDemo + "' -o '" + (temp_dir() / name).string() + "'" + size + " --threads " +
                             std::to_string(slurm.cpus()) + " --quiet",
                         out))
        << out;
    return std::chrono::duration<double>(Clock::now() - t0).count();
  };
  // The same 4 parts as plain local processes (as many at once as Slurm runs: one per core) and a merge:
  // Slurm's own cost (scheduling, job launch, the dependent merge job) is the difference to this.
  auto local_parts = [&] {
    const auto t0 = Clock::now();
    const std::string dir = temp_dir().string(), cli = GLIMMER_TEST_CLI_PATH;
    const std::string cmd = "printf '0\\n1\\n2\\n3\\n' | xargs -P " + std::to_string(slurm.cpus()) + " -I{} '" + cli +
                            "' render '" + kDemo + "' -o '" + dir + "/bench_local_{}.exr'" + size +
                            " --sample-split {}/4 --threads 1 --quiet && '" + cli + "' merge '" + dir +
                            "/bench_local_0.exr' '" + dir + "/bench_local_1.exr' '" + dir + "/bench_local_2.exr' '" +
                            dir + "/bench_local_3.exr' -o '" + dir + "/bench_local.exr' --quiet";
    EXPECT_EQ(0, std::system(cmd.c_str()));
    return std::chrono::duration<double>(Clock::now() - t0).count();
  };
  // Repetitions in turn (one process, Slurm, local parts); the minimum of each is the estimate least
  // disturbed by other work on a shared machine.
  const char *reps_env = std::getenv("GLIMMER_FARM_BENCH_REPS");
  const int reps = reps_env ? std::max(1, std::atoi(reps_env)) : 2;
  std::vector<double> ones, farms, locals;
  for (int r = 0; r < reps; ++r) {
    ones.push_back(one_process("bench_one.exr"));
    const auto t0 = Clock::now();
    const FarmRun run = run_farm_job(slurm, "bench_slurm_" + std::to_string(r), "--sample-splits 4", size);
    farms.push_back(std::chrono::duration<double>(Clock::now() - t0).count());
    // Slurm's own waits from its job records (1 s resolution): submission to the first task's start,
    // the last task's end to the merge job's start, and the merge job itself.
    const auto submit = job_times(run.render_id, "SubmitTime"), start = job_times(run.render_id, "StartTime"),
               end = job_times(run.render_id, "EndTime"), merge_start = job_times(run.merge_id, "StartTime"),
               merge_end = job_times(run.merge_id, "EndTime");
    if (!submit.empty() && !start.empty() && !end.empty() && !merge_start.empty() && !merge_end.empty())
      std::printf(
          "farm bench Slurm waits: submit -> first task %ld s, last task -> merge start %ld s, merge job %ld s\n",
          *std::min_element(start.begin(), start.end()) - *std::min_element(submit.begin(), submit.end()),
          merge_start[0] - *std::max_element(end.begin(), end.end()), merge_end[0] - merge_start[0]);
    locals.push_back(local_parts());
    std::printf(
        "farm bench repetition %d: one process %.1f s, 4-way split on Slurm %.1f s, 4 local parts + merge "
        "%.1f s\n",
        r + 1, ones.back(), farms.back(), locals.back());
  }
  const double one = *std::min_element(ones.begin(), ones.end());
  const double farm = *std::min_element(farms.begin(), farms.end());
  const double local = *std::min_element(locals.begin(), locals.end());
  std::printf(
      "farm bench (%s, %d cores, best of %d): one process %.1f s; 4-way split on Slurm %.1f s (%+.1f %% vs "
      "one process); 4 local parts + merge %.1f s (Slurm %+.1f %% vs them)\n",
      size.c_str(), slurm.cpus(), reps, one, farm, 100.0 * (farm / one - 1.0), local, 100.0 * (farm / local - 1.0));
  EXPECT_GE(one, 60.0) << "the benchmark render should take at least 60 s; raise --samples";
}

}  // namespace
}  // namespace glimmer::test
