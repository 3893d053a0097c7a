// What the Blender viewport and render window read (issue 16): `glimmer render --display` writes the image so far
// (plain R, G, B, A float, uncompressed) after sample passes, and its last one is the final image's Combined pass;
// `glimmer serve` renders one command line per stdin line in one process, the newest line interrupting the render
// in progress, a bad command reported without ending the server.
#include <sys/wait.h>

#include <chrono>
#include <thread>

#include "exr_compare.h"
#include "render_test_util.h"

namespace glimmer::test {
namespace {

namespace fs = std::filesystem;

std::string demo_scene() { return std::string(GLIMMER_TEST_SOURCE_DIR) + "/examples/demo.xml"; }

std::vector<float> channel(const Exr &e, const std::string &name) {
  std::vector<float> v;
  const auto &names = e.spec.channelnames;
  const auto it = std::find(names.begin(), names.end(), name);
  if (it == names.end()) return v;
  for (size_t i = it - names.begin(); i < e.pixels.size(); i += e.spec.nchannels) v.push_back(e.pixels[i]);
  return v;
}

TEST(Display, ImagesAfterPassesTheLastEqualsTheFinalImage) {
  const std::string out = (temp_dir() / "display_final.exr").string(),
                    display = (temp_dir() / "display.exr").string();
  fs::remove(display);
  std::string log;
  ASSERT_EQ(0, run_cli("render '" + demo_scene() + "' -o '" + out + "' --width 40 --height 30 --samples 5 --threads 2 "
                       "--display '" + display + "'",
                       log))
      << log;
  for (int n = 1; n <= 5; ++n)
    EXPECT_NE(log.find("Display " + std::to_string(n) + "/5 " + display + "\n"), std::string::npos) << log;
  const Exr shown = read_exr(display), final_image = read_exr(out);
  EXPECT_EQ(shown.spec.nchannels, 4);
  EXPECT_EQ(shown.spec.get_string_attribute("compression"), "none");
  EXPECT_EQ(shown.spec.get_int_attribute("glimmer:samples"), 5);
  for (const char *c : {"R", "G", "B", "A"}) {
    const std::vector<float> a = channel(shown, c), b = channel(final_image, std::string("ViewLayer.Combined.") + c);
    ASSERT_EQ(a.size(), 40u * 30u) << c;
    EXPECT_TRUE(a == b) << c;
  }
  // --display-every: only the first pass within the interval.
  ASSERT_EQ(0, run_cli("render '" + demo_scene() + "' -o '" + out + "' --width 40 --height 30 --samples 5 --threads 2 "
                       "--display '" + display + "' --display-every 1000",
                       log))
      << log;
  EXPECT_NE(log.find("Display 1/5 "), std::string::npos) << log;
  EXPECT_EQ(log.find("Display 2/5 "), std::string::npos) << log;
}

// `glimmer serve` with our pipe on its stdin; its output goes to a file the test reads.
class Server {
 public:
  explicit Server(const fs::path &log) : log_(log) {
    fs::remove(log);
    pipe_ = ::popen(("'" + std::string(GLIMMER_TEST_CLI_PATH) + "' serve > '" + log.string() + "' 2>&1").c_str(), "w");
  }
  ~Server() {
    if (pipe_) ::pclose(pipe_);
  }
  void send(const std::string &line) {
    std::fputs((line + "\n").c_str(), pipe_);
    std::fflush(pipe_);
  }
  // Waits (at most 2 minutes: a loaded machine) until the output holds `text`.
  bool wait_for(const std::string &text) const {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::minutes(2);
    while (std::chrono::steady_clock::now() < deadline) {
      if (output().find(text) != std::string::npos) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return false;
  }
  std::string output() const {
    std::ifstream in(log_);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  // Closes stdin: the newest command finishes, then the server exits; returns its exit status.
  int close() {
    const int status = ::pclose(pipe_);
    pipe_ = nullptr;
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }

 private:
  fs::path log_;
  FILE *pipe_ = nullptr;
};

TEST(Serve, RendersEachLineInOneProcessTheNewestInterruptingTheOlder) {
  const std::string args = " --width 40 --height 30 --threads 2 --quiet";
  auto output = [](const std::string &name) { return (temp_dir() / name).string(); };
  // The straight render to compare with.
  std::string log;
  ASSERT_EQ(0, run_cli("render '" + demo_scene() + "' -o '" + output("serve_ref.exr") + "' --samples 6" + args, log))
      << log;

  Server server(temp_dir() / "serve_log.txt");
  // A bad command is reported and the server goes on.
  server.send("'" + output("missing.xml") + "' -o '" + output("bad.exr") + "'" + args);
  ASSERT_TRUE(server.wait_for("Finished 1 " + output("bad.exr") + "\n")) << server.output();
  EXPECT_NE(server.output().find("missing.xml"), std::string::npos) << server.output();
  server.send("'" + demo_scene() + "' -o '" + output("serve_a.exr") + "' --samples 6" + args);
  ASSERT_TRUE(server.wait_for("Finished 0 " + output("serve_a.exr") + "\n")) << server.output();
  EXPECT_TRUE(bit_identical(read_exr(output("serve_a.exr")), read_exr(output("serve_ref.exr"))));
  // Two long renders, then a new line at once: each long one is interrupted or replaced before it starts, and either
  // way answered 'Finished 3' (session 40: a replaced line had no answer, and a driver waiting for one hung); the
  // newest runs.
  server.send("'" + demo_scene() + "' -o '" + output("serve_long.exr") + "' --samples 100000" + args);
  server.send("'" + demo_scene() + "' -o '" + output("serve_long2.exr") + "' --samples 100000" + args);
  server.send("'" + demo_scene() + "' -o '" + output("serve_b.exr") + "' --samples 6" + args);
  EXPECT_EQ(0, server.close()) << server.output();
  const std::string text = server.output();
  EXPECT_NE(text.find("Finished 0 " + output("serve_b.exr") + "\n"), std::string::npos) << text;
  EXPECT_NE(text.find("Finished 3 " + output("serve_long.exr") + "\n"), std::string::npos) << text;
  EXPECT_NE(text.find("Finished 3 " + output("serve_long2.exr") + "\n"), std::string::npos) << text;
  EXPECT_TRUE(bit_identical(read_exr(output("serve_b.exr")), read_exr(output("serve_ref.exr"))));
}

// The previous render is kept until the next one's closures are prepared: the glint table (built here, the disk
// cache being off) is built for the first command only, not again for the second.
TEST(Serve, ConsecutiveRendersShareTheGlintTable) {
  const std::string not_a_folder = write_file("cache_is_a_file", "x");
  const std::string scene = write_file(
      "one_glint.xml",
      "<cycles>\n<camera width=\"16\" height=\"10\" />\n"
      "<shader name=\"g\"><glint_bsdf name=\"glint\" roughness=\"0.35\" gamma=\"2\" density=\"1000\" />"
      "<connect from=\"glint bsdf\" to=\"output surface\" /></shader>\n"
      "<state shader=\"g\"><mesh P=\"-1 -1 3  1 -1 3  0 1 3\" nverts=\"3\" verts=\"0 1 2\" /></state>\n</cycles>\n");
  const std::string args = " --width 16 --height 10 --samples 1 --threads 2 --quiet";
  const fs::path log = temp_dir() / "serve_glint_log.txt";
  fs::remove(log);
  FILE *pipe = ::popen(("GLIMMER_CACHE_DIR='" + not_a_folder + "' '" + GLIMMER_TEST_CLI_PATH + "' serve > '" +
                        log.string() + "' 2>&1")
                           .c_str(),
                       "w");
  ASSERT_TRUE(pipe);
  const std::string first = (temp_dir() / "glint_1.exr").string(), second = (temp_dir() / "glint_2.exr").string();
  std::fputs(("'" + scene + "' -o '" + first + "'" + args + "\n").c_str(), pipe);
  std::fflush(pipe);
  auto text = [&log] {
    std::ifstream in(log);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  };
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::minutes(3);
  while (text().find("Finished 0 " + first) == std::string::npos && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  std::fputs(("'" + scene + "' -o '" + second + "'" + args + "\n").c_str(), pipe);
  EXPECT_EQ(0, WEXITSTATUS(::pclose(pipe)));
  const std::string out = text();
  const size_t first_done = out.find("Finished 0 " + first);
  ASSERT_NE(first_done, std::string::npos) << out;
  EXPECT_NE(out.find("precomputed directional table"), std::string::npos) << "built for the first command: " << out;
  EXPECT_EQ(out.find("precomputed directional table", first_done), std::string::npos) << out;
  EXPECT_NE(out.find("Finished 0 " + second), std::string::npos) << out;
}

}  // namespace
}  // namespace glimmer::test
