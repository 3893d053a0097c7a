// Issue 11: no function in bridge/render longer than ~80 lines. tools/check_function_length.py (a brace
// counter) lists the longer ones; this runs it over bridge/render, and its self-test shows it catches an
// 81-line function (negative control).
#include "render_test_util.h"

namespace glimmer::test {
namespace {

int run_checker(const std::string &args, std::string &output) {
  const auto log = temp_dir() / "function_length.txt";
  const std::string cmd = std::string("python3 '") + GLIMMER_TEST_SOURCE_DIR + "/tools/check_function_length.py' " +
                          args + " > '" + log.string() + "' 2>&1";
  const int status = std::system(cmd.c_str());
  std::ifstream in(log);
  output.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(RenderCode, CheckerCatchesAFunctionOver80Lines) {
  std::string out;
  EXPECT_EQ(run_checker("--self-test", out), 0) << out;
}

TEST(RenderCode, NoFunctionInBridgeRenderLongerThan80Lines) {
  // One exception: node_table is data (one row per shader node, render/nodes/node_table.cpp), not logic.
  std::string out;
  EXPECT_EQ(run_checker("--max 80 --allow render/nodes/node_table.cpp:node_table '" +
                        std::string(GLIMMER_TEST_SOURCE_DIR) + "/bridge/render'", out), 0)
      << out;
}

}  // namespace
}  // namespace glimmer::test
