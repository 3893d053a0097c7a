// `glimmer bench error-vs-time`: argument errors exit with code 1 and a clear
// message; --from-csv re-plots a CSV into a PNG and reports equal-RMSE speed-ups;
// --reference own measures every method against its own converged render.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
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

TEST(BenchErrorVsTime, SceneWithoutGlintsIsABadInput) {
  // A scene of its own: the examples may gain glints at any time.
  const std::filesystem::path dir = std::filesystem::path(GLIMMER_TEST_BINARY_DIR) / "bench_evt_no_glints";
  std::filesystem::create_directories(dir);
  const std::string scene = (dir / "no_glints.xml").string();
  std::ofstream(scene) << "<cycles><camera width=\"8\" height=\"8\" />\n"
                          "<shader name=\"d\"><diffuse_bsdf name=\"b\" /><connect from=\"b bsdf\" to=\"output surface\" /></shader>\n"
                          "<state shader=\"d\"><mesh P=\"-1 -1 1  1 -1 1  1 1 1\" nverts=\"3\" verts=\"0 1 2\" /></state></cycles>\n";
  std::string out;
  const int code = run("bench error-vs-time " + scene, out);
  EXPECT_EQ(code, 1) << out;
  EXPECT_NE(out.find("no <glint_bsdf>"), std::string::npos) << out;
}

TEST(BenchErrorVsTime, UnknownMethodIsABadInput) {
  std::string out;
  const int code = run(std::string("bench error-vs-time ") + GLIMMER_TEST_SOURCE_DIR +
                           "/examples/glint.xml --methods jakob14,phong --samples 1 --reference-samples 1",
                       out);
  EXPECT_EQ(code, 1) << out;
  EXPECT_NE(out.find("unknown method 'phong'"), std::string::npos) << out;
}

TEST(BenchErrorVsTime, ReplotsACsvAndReportsSpeedUps) {
  const std::filesystem::path dir = std::filesystem::path(GLIMMER_TEST_BINARY_DIR) / "bench_evt_test";
  std::filesystem::create_directories(dir);
  const std::string csv = (dir / "in.csv").string();
  std::ofstream(csv) << "method,samples,seconds,rmse\n"
                     << "jakob14,1,10,0.4\njakob14,4,40,0.2\n"
                     << "dsm-filtered,1,0.1,0.4\ndsm-filtered,4,0.4,0.2\n";
  std::string out;
  const int code = run("bench error-vs-time --from-csv " + csv + " --out-dir " + dir.string() + " --name plot", out);
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

}  // namespace
