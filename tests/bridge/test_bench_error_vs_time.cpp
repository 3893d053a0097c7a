// `glimmer bench error-vs-time`: argument errors exit with code 1 and a clear
// message; --from-csv re-plots a CSV into a PNG and reports equal-RMSE speed-ups;
// --reference own measures every method against its own converged render.
// frosted glass: the methods path / sg / auto render and are compared with path.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <sys/wait.h>

namespace {

int run(const std::string &args, std::string &output) {
  const std::string cmd = std::string(GLIMMER_TEST_CLI_PATH) + " " + args + " 2>&1";
  FILE *p = popen(cmd.c_str(), "r");
  char buf[512];
  output.clear();
  while (fgets(buf, sizeof(buf), p) != nullptr) output += buf;
  const int status = pclose(p);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// `glimmer bench error-vs-time <args>` must exit with code 1 and say `message`.
void expect_bad_input(const std::string &args, const std::string &message) {
  std::string out;
  const int code = run("bench error-vs-time " + args, out);
  EXPECT_EQ(code, 1) << out;
  EXPECT_NE(out.find(message), std::string::npos) << out;
}

// Re-plots `csv_text` (written to <build>/<folder>/in.csv) with `options`; the folder is returned for its PNG.
int replot(const std::string &folder, const std::string &csv_text, const std::string &options, std::string &out,
           std::filesystem::path &dir) {
  dir = std::filesystem::path(GLIMMER_TEST_BINARY_DIR) / folder;
  std::filesystem::create_directories(dir);
  const std::string csv = (dir / "in.csv").string();
  std::ofstream(csv) << csv_text;
  return run("bench error-vs-time --from-csv " + csv + " --out-dir " + dir.string() + " " + options, out);
}

// The rows of the plain CSV (frosted_error_vs_time.csv) a bench run wrote in `dir`: method, samples, seconds,
// rmse as written.
struct PlainCsvRow {
  std::string method, samples, seconds, rmse;
};
std::vector<PlainCsvRow> plain_csv_rows(const std::filesystem::path &dir) {
  std::ifstream csv(dir / "frosted_error_vs_time.csv");
  std::string line;
  std::getline(csv, line);  // the header
  std::vector<PlainCsvRow> rows;
  while (std::getline(csv, line)) {
    std::istringstream fields(line);
    PlainCsvRow r;
    std::getline(fields, r.method, ',');
    std::getline(fields, r.samples, ',');
    std::getline(fields, r.seconds, ',');
    std::getline(fields, r.rmse, ',');
    rows.push_back(r);
  }
  return rows;
}

TEST(BenchErrorVsTime, SceneWithoutGlintsIsABadInput) {
  // A scene of its own: the examples may gain glints at any time.
  const std::filesystem::path dir = std::filesystem::path(GLIMMER_TEST_BINARY_DIR) / "bench_evt_no_glints";
  std::filesystem::create_directories(dir);
  const std::string scene = (dir / "no_glints.xml").string();
  std::ofstream(scene) << "<cycles><camera width=\"8\" height=\"8\" />\n"
                          "<shader name=\"d\"><diffuse_bsdf name=\"b\" /><connect from=\"b bsdf\" to=\"output surface\" /></shader>\n"
                          "<state shader=\"d\"><mesh P=\"-1 -1 1  1 -1 1  1 1 1\" nverts=\"3\" verts=\"0 1 2\" /></state></cycles>\n";
  expect_bad_input(scene, "no <glint_bsdf>");
}

TEST(BenchErrorVsTime, UnknownMethodIsABadInput) {
  expect_bad_input(std::string(GLIMMER_TEST_SOURCE_DIR) +
                       "/examples/glint.xml --methods jakob14,phong --samples 1 --reference-samples 1",
                   "unknown method 'phong'");
}

TEST(BenchErrorVsTime, ReplotsACsvAndReportsSpeedUps) {
  std::filesystem::path dir;
  std::string out;
  const int code = replot("bench_evt_test",
                          "method,samples,seconds,rmse\n"
                          "jakob14,1,10,0.4\njakob14,4,40,0.2\n"
                          "dsm-filtered,1,0.1,0.4\ndsm-filtered,4,0.4,0.2\n",
                          "--name plot", out, dir);
  EXPECT_EQ(code, 0) << out;
  EXPECT_TRUE(std::filesystem::exists(dir / "plot.png")) << out;
  // Equal RMSE 0.4 and 0.2: 10 s vs 0.1 s and 40 s vs 0.4 s -> 100x.
  EXPECT_NE(out.find("speed-up 100.0x"), std::string::npos) << out;
  std::filesystem::remove_all(dir);
}

TEST(BenchErrorVsTime, OwnReferenceRendersOneConvergedImagePerMethod) {
  const std::filesystem::path dir = std::filesystem::path(GLIMMER_TEST_BINARY_DIR) / "bench_evt_own";
  std::filesystem::create_directories(dir);
  std::string out;
  const int code = run(std::string("bench error-vs-time ") + GLIMMER_TEST_SOURCE_DIR +
                           "/benchmarks/scenes/glint_direct.xml --reference own --methods jakob14,dsm-filtered "
                           "--samples 1 --reference-samples 2 --width 6 --height 6 --threads 1 --out-dir " +
                           dir.string() + " --name own",
                       out);
  EXPECT_EQ(code, 0) << out;
  EXPECT_NE(out.find("reference: jakob14 at 2 spp"), std::string::npos) << out;
  EXPECT_NE(out.find("reference: dsm-filtered at 2 spp"), std::string::npos) << out;
  EXPECT_NE(out.find("converged dsm-filtered vs converged jakob14: RMSE"), std::string::npos) << out;
  EXPECT_TRUE(std::filesystem::exists(dir / "own.csv")) << out;
  std::filesystem::remove_all(dir);
}

TEST(BenchErrorVsTime, FrostedUnknownMethodIsABadInput) {
  expect_bad_input(std::string(GLIMMER_TEST_SOURCE_DIR) +
                       "/examples/frosted_closeup.xml --methods path,phong --samples 1 --reference-samples 1",
                   "unknown method 'phong' for frosted");
}

TEST(BenchErrorVsTime, SceneWithBothMaterialsNeedsMaterialOption) {
  // examples/frosted.xml has a glint sphere behind the frosted slab.
  expect_bad_input(std::string(GLIMMER_TEST_SOURCE_DIR) + "/examples/frosted.xml --samples 1 --reference-samples 1",
                   "--material glint or --material frosted");
}

TEST(BenchErrorVsTime, FrostedCsvReportsTheSpeedUpAtThePathRmseOfAGivenTime) {
  std::filesystem::path dir;
  std::string out;
  const int code = replot("bench_evt_frosted_csv",
                          "method,samples,seconds,rmse\n"
                          "path,1,10,0.4\npath,4,40,0.2\n"
                          "sg,1,1,0.4\nsg,4,4,0.2\n"
                          "auto,1,5,0.5\nauto,4,20,0.3\n",
                          "--at-seconds 20", out, dir);
  EXPECT_EQ(code, 0) << out;
  EXPECT_TRUE(std::filesystem::exists(dir / "frosted_error_vs_time.png")) << out;
  // path at 20 s: log-log between (10 s, 0.4) and (40 s, 0.2) -> 0.4 / sqrt(2) = 0.28284; sg reaches it at 2 s.
  EXPECT_NE(out.find("at path's 20-s RMSE 0.28284: sg 2.000 s, speed-up 10.0x"), std::string::npos) << out;
  // auto's ladder ends at 0.3: a biased method's plateau is reported, not extrapolated.
  EXPECT_NE(out.find("at path's 20-s RMSE 0.28284: auto never reaches it on the ladder"), std::string::npos) << out;
  std::filesystem::remove_all(dir);
}

TEST(BenchErrorVsTime, FrostedMethodsRenderAgainstThePathReference) {
  const std::filesystem::path dir = std::filesystem::path(GLIMMER_TEST_BINARY_DIR) / "bench_evt_frosted_run";
  std::filesystem::create_directories(dir);
  std::string out;
  const int code = run(std::string("bench error-vs-time ") + GLIMMER_TEST_SOURCE_DIR +
                           "/examples/frosted_closeup.xml --methods path,sg,auto --samples 1,2 --reference-samples 4 "
                           "--width 12 --height 8 --threads 1 --clock cpu --out-dir " + dir.string(),
                       out);
  EXPECT_EQ(code, 0) << out;
  std::ifstream csv(dir / "frosted_error_vs_time.csv");
  std::string line;
  int rows = 0;
  std::getline(csv, line);
  EXPECT_EQ(line, "method,samples,seconds,rmse");
  while (std::getline(csv, line)) ++rows;
  EXPECT_EQ(rows, 6) << out;  // 3 methods x 2 rungs
  EXPECT_NE(out.find("reference: path at 4 spp"), std::string::npos) << out;
  std::filesystem::remove_all(dir);
}

TEST(BenchErrorVsTime, FrostedTwoReferenceSeedsRegionsAndPathStrategy) {
  // --path-strategy bsdf reaches the path renders (ladder and references), path-mis renders path with MIS,
  // --reference-seeds 2 renders two references on two seeds and subtracts their noise, --regions auto splits the
  // figures per shader of the scene's id pass.
  const std::filesystem::path dir = std::filesystem::path(GLIMMER_TEST_BINARY_DIR) / "bench_evt_frosted_regions";
  std::filesystem::create_directories(dir);
  std::string out;
  const int code = run(std::string("bench error-vs-time ") + GLIMMER_TEST_SOURCE_DIR +
                           "/examples/frosted_closeup.xml --methods path,path-mis,sg --samples 1,2 "
                           "--reference-samples 4 --reference-seeds 2 --regions auto --path-strategy bsdf "
                           "--width 12 --height 8 --threads 1 --clock cpu --at-seconds 1000 --out-dir " + dir.string(),
                       out);
  EXPECT_EQ(code, 0) << out;
  EXPECT_NE(out.find("reference: path at 4 spp, strategy bsdf (seed 7919)"), std::string::npos) << out;
  EXPECT_NE(out.find("reference: path at 4 spp, strategy bsdf (seed 8932)"), std::string::npos) << out;
  EXPECT_NE(out.find("reference: 2 images, RMS noise of their mean"), std::string::npos) << out;
  EXPECT_NE(out.find("(raw "), std::string::npos) << out;
  EXPECT_NE(out.find("path's 1000-s RMSE"), std::string::npos) << out;
  EXPECT_NE(out.find("is extrapolated from its last rungs"), std::string::npos) << out;
  std::ifstream csv(dir / "frosted_error_vs_time_regions.csv");
  std::string line, all;
  std::getline(csv, line);
  EXPECT_EQ(line, "method,samples,seconds,region,pixels,rmse,rmse_raw");
  while (std::getline(csv, line)) all += line + "\n";
  // The closeup's camera sees its floor and its frosted objects: regions named after their shaders.
  EXPECT_NE(all.find("path-mis,2,"), std::string::npos) << all;
  EXPECT_NE(all.find(",floor,"), std::string::npos) << all;
  EXPECT_NE(all.find(",frost"), std::string::npos) << all;
  // The whole image is in the regions CSV too (region "all"), with the plain CSV's RMSE and every pixel.
  const std::vector<PlainCsvRow> plain = plain_csv_rows(dir);
  for (const PlainCsvRow &r : plain)
    EXPECT_NE(all.find(r.method + "," + r.samples + "," + r.seconds + ",all,96," + r.rmse + ","), std::string::npos)
        << r.method << " " << r.samples << "\n" << all;
  EXPECT_EQ(plain.size(), 6u);
  EXPECT_NE(out.find("region floor: at path's 1000-s RMSE"), std::string::npos) << out;
  std::filesystem::remove_all(dir);
}

// The plain CSV's rmse of `method` at `samples` after a bench run in `dir` (-1 if absent).
double csv_rmse(const std::filesystem::path &dir, const std::string &method, int samples) {
  for (const PlainCsvRow &r : plain_csv_rows(dir))
    if (r.method == method && r.samples == std::to_string(samples)) return std::stod(r.rmse);
  return -1.0;
}

TEST(BenchErrorVsTime, FrostedLadderSeedsGiveIndependentImagesAndAverageTheirErrors) {
  // --seed: the same seed twice gives the same image (the same RMSE to the last digit), another seed another
  // image; --seeds 2 renders seeds 5 and 6 and its MSE is the mean of theirs (the 6 digits of the CSV), split
  // into noise and bias^2 in the log and the regions CSV.
  const std::filesystem::path base = std::filesystem::path(GLIMMER_TEST_BINARY_DIR) / "bench_evt_seeds";
  const auto bench = [&](const std::string &name, const std::string &seed_args, std::string &out) {
    const std::filesystem::path dir = base / name;
    std::filesystem::create_directories(dir);
    const int code = run(std::string("bench error-vs-time ") + GLIMMER_TEST_SOURCE_DIR +
                             "/examples/frosted_closeup.xml --methods sg --samples 2 --reference-samples 4 "
                             "--regions auto --width 12 --height 8 --threads 1 --clock cpu --out-dir " +
                             dir.string() + " " + seed_args,
                         out);
    EXPECT_EQ(code, 0) << out;
    return csv_rmse(dir, "sg", 2);
  };
  std::string out;
  const double a = bench("a", "--seed 5", out), again = bench("b", "--seed 5", out), c = bench("c", "--seed 6", out);
  const double both = bench("d", "--seed 5 --seeds 2", out);
  ASSERT_GT(a, 0.0);
  ASSERT_GT(c, 0.0);
  EXPECT_EQ(a, again) << "the same seed must give the same image";
  EXPECT_GT(std::fabs(a - c), 1e-3 * a) << "two seeds must give different images";
  EXPECT_NEAR(both * both, 0.5 * (a * a + c * c), 5e-5 * both * both) << a << " " << c << " " << both;
  EXPECT_NE(out.find("over 2 seeds noise "), std::string::npos) << out;
  std::ifstream regions(base / "d" / "frosted_error_vs_time_regions.csv");
  std::string header;
  std::getline(regions, header);
  EXPECT_EQ(header, "method,samples,seconds,region,pixels,rmse,rmse_raw,seeds,variance,bias2");
  std::printf("seed 5 RMSE %.6g (again %.6g), seed 6 %.6g, seeds 5+6 %.6g (sqrt of the mean MSE %.6g)\n", a, again,
              c, both, std::sqrt(0.5 * (a * a + c * c)));
  std::filesystem::remove_all(base);
}

TEST(BenchErrorVsTime, FrostedSeedsNeedASeedAndAvoidTheReferencesSeeds) {
  const std::string scene = std::string(GLIMMER_TEST_SOURCE_DIR) + "/examples/frosted_closeup.xml";
  expect_bad_input(scene + " --seeds 2 --samples 1 --reference-samples 1", "--seeds 2 needs --seed");
  expect_bad_input(scene + " --seed 7918 --seeds 2 --samples 1 --reference-samples 1",
                   "seed 7919 is a reference's seed");
}

TEST(BenchErrorVsTime, FrostedPathStrategyAndRegionImageAreChecked) {
  const std::string scene = std::string(GLIMMER_TEST_SOURCE_DIR) + "/examples/frosted_closeup.xml";
  expect_bad_input(scene + " --path-strategy light --samples 1 --reference-samples 1", "--path-strategy");
  expect_bad_input(scene + " --methods path,path-light --samples 1 --reference-samples 1",
                   "unknown method 'path-light' for frosted");
  expect_bad_input(scene + " --regions /nonexistent/ids.exr --samples 1 --reference-samples 1 --width 4 --height 4",
                   "/nonexistent/ids.exr");
}

}  // namespace
