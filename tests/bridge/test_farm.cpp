// Farm pieces (docs/farm.md): --tile/--region crops and --sample-range parts merged
// by `glimmer merge` equal the one-machine render (tiles bit for bit, sample ranges
// within float rounding), merge refuses parts of different renders, and a render
// killed with SIGKILL after a checkpoint resumes to the uninterrupted image.
#include <OpenImageIO/imageio.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <fstream>
#include <regex>
#include <thread>

#include "render_test_util.h"

namespace glimmer::test {
namespace {

namespace fs = std::filesystem;

// The demo scene, small: 48x32 pixels.
std::string demo_scene() { return std::string(GLIMMER_TEST_SOURCE_DIR) + "/examples/demo.xml"; }
const std::string kSmall = " --width 48 --height 32 --threads 2 --quiet";

struct Exr {
  OIIO::ImageSpec spec;
  std::vector<float> pixels;  // data window, all channels
};

Exr read_exr(const fs::path &path) {
  auto in = OIIO::ImageInput::open(path.string());
  EXPECT_TRUE(in) << path << ": " << OIIO::geterror();
  Exr e;
  if (!in) return e;
  e.spec = in->spec();
  e.pixels.resize(static_cast<size_t>(e.spec.width) * e.spec.height * e.spec.nchannels);
  EXPECT_TRUE(in->read_image(0, 0, 0, -1, OIIO::TypeDesc::FLOAT, e.pixels.data()));
  return e;
}

// Per channel: max over pixels of |a - b| / max over pixels of |b|; the largest over channels
// (the "relative" difference of the acceptance; per channel so that the 1e10 background
// depth does not hide a difference in the Combined pass).
double max_relative_difference(const Exr &a, const Exr &b) {
  const int nc = b.spec.nchannels;
  double worst = 0.0;
  for (int c = 0; c < nc; ++c) {
    double diff = 0.0, scale = 0.0;
    for (size_t i = c; i < b.pixels.size(); i += nc) {
      diff = std::max(diff, static_cast<double>(std::fabs(a.pixels[i] - b.pixels[i])));
      scale = std::max(scale, static_cast<double>(std::fabs(b.pixels[i])));
    }
    if (scale > 0.0) worst = std::max(worst, diff / scale);
    else if (diff > 0.0) return INFINITY;
  }
  return worst;
}

std::string render_to(const std::string &name, const std::string &extra) {
  const std::string path = (temp_dir() / name).string();
  fs::remove(path);
  std::string out;
  EXPECT_EQ(0, run_cli("render '" + demo_scene() + "' -o '" + path + "'" + kSmall + " " + extra, out)) << out;
  return path;
}

std::string merge(const std::vector<std::string> &parts, const std::string &name, int &code) {
  std::string args = "merge";
  for (const auto &p : parts) args += " '" + p + "'";
  const std::string path = (temp_dir() / name).string();
  fs::remove(path);
  std::string out;
  code = run_cli(args + " -o '" + path + "'", out);
  return out;
}

TEST(Farm, TilesWriteCropsAndMergeBitIdentical) {
  const std::string full = render_to("full.exr", "--samples 4");
  std::vector<std::string> tiles;
  for (int k = 0; k < 4; ++k) tiles.push_back(render_to("tile" + std::to_string(k) + ".exr", "--samples 4 --tile " + std::to_string(k) + "/4"));
  // Each part holds just its band: data window 48x8 at y = 8k, display window 48x32.
  for (int k = 0; k < 4; ++k) {
    const Exr t = read_exr(tiles[k]);
    EXPECT_EQ(t.spec.width, 48);
    EXPECT_EQ(t.spec.height, 8);
    EXPECT_EQ(t.spec.y, 8 * k);
    EXPECT_EQ(t.spec.full_width, 48);
    EXPECT_EQ(t.spec.full_height, 32);
  }
  int code = -1;
  const std::string out = merge(tiles, "merged_tiles.exr", code);
  ASSERT_EQ(code, 0) << out;
  const Exr a = read_exr(temp_dir() / "merged_tiles.exr"), b = read_exr(full);
  ASSERT_EQ(a.spec.channelnames, b.spec.channelnames);
  ASSERT_EQ(a.pixels.size(), b.pixels.size());
  EXPECT_EQ(0, std::memcmp(a.pixels.data(), b.pixels.data(), a.pixels.size() * sizeof(float))) << "not bit-identical";
  // --region parts too (uneven rectangles), and a missing tile is refused.
  const std::vector<std::string> regions = {render_to("rA.exr", "--samples 4 --region 0,0,30,32"),
                                            render_to("rB.exr", "--samples 4 --region 30,0,48,20"),
                                            render_to("rC.exr", "--samples 4 --region 30,20,48,32")};
  ASSERT_EQ(0, (merge(regions, "merged_regions.exr", code), code));
  const Exr c = read_exr(temp_dir() / "merged_regions.exr");
  EXPECT_EQ(0, std::memcmp(c.pixels.data(), b.pixels.data(), b.pixels.size() * sizeof(float)));
  const std::string missing = merge({tiles[0], tiles[1], tiles[3]}, "missing.exr", code);
  EXPECT_EQ(code, 1);
  EXPECT_NE(missing.find("cover 1152 of the 1536 pixels"), std::string::npos) << missing;
  EXPECT_FALSE(fs::exists(temp_dir() / "missing.exr"));
}

TEST(Farm, SampleRangesMergeWithinFloatRounding) {
  const std::string full = render_to("full16.exr", "--samples 16");
  // Uneven ranges: an unweighted mean of the parts would be wrong (negative control below).
  const std::vector<std::string> parts = {render_to("s0.exr", "--samples 16 --sample-range 0,3"),
                                          render_to("s1.exr", "--samples 16 --sample-range 3,10"),
                                          render_to("s2.exr", "--samples 16 --sample-range 10,16")};
  int code = -1;
  const std::string out = merge(parts, "merged_samples.exr", code);
  ASSERT_EQ(code, 0) << out;
  const Exr merged = read_exr(temp_dir() / "merged_samples.exr"), ref = read_exr(full);
  ASSERT_EQ(merged.pixels.size(), ref.pixels.size());
  const double rel = max_relative_difference(merged, ref);
  EXPECT_LE(rel, 1e-6);
  std::printf("sample-range merge: max |merged - full| / max |full| = %.3g\n", rel);
  // Negative control: the unweighted mean of the three parts is far off.
  Exr unweighted = ref;
  const Exr p0 = read_exr(parts[0]), p1 = read_exr(parts[1]), p2 = read_exr(parts[2]);
  for (size_t i = 0; i < unweighted.pixels.size(); ++i)
    unweighted.pixels[i] = (p0.pixels[i] + p1.pixels[i] + p2.pixels[i]) / 3.0f;
  EXPECT_GT(max_relative_difference(unweighted, ref), 1e-3);
  // --sample-split k/N cuts [0, N) the same way (16/4 -> 4 samples each).
  std::vector<std::string> splits;
  for (int k = 0; k < 4; ++k) splits.push_back(render_to("split" + std::to_string(k) + ".exr", "--samples 16 --sample-split " + std::to_string(k) + "/4"));
  ASSERT_EQ(0, (merge(splits, "merged_splits.exr", code), code));
  EXPECT_LE(max_relative_difference(read_exr(temp_dir() / "merged_splits.exr"), ref), 1e-6);
  EXPECT_EQ(read_exr(splits[2]).spec.get_int_attribute("glimmer:sample_begin"), 8);
  EXPECT_EQ(read_exr(splits[2]).spec.get_int_attribute("glimmer:sample_end"), 12);
}

TEST(Farm, MergeRefusesPartsOfDifferentRenders) {
  const std::string a = render_to("a.exr", "--samples 4 --sample-range 0,2");
  const std::string b = render_to("b.exr", "--samples 4 --sample-range 2,4");
  int code = -1;
  auto refused = [&](const std::vector<std::string> &parts, const std::string &want) {
    const std::string out = merge(parts, "refused.exr", code);
    EXPECT_EQ(code, 1) << out;
    EXPECT_NE(out.find(want), std::string::npos) << out;
    EXPECT_FALSE(fs::exists(temp_dir() / "refused.exr"));
  };
  ASSERT_EQ(0, (merge({a, b}, "ok.exr", code), code));  // the positive control
  refused({a, render_to("seed.exr", "--samples 4 --sample-range 2,4 --seed 7")}, "seed 0 vs 7");
  const std::string res = (temp_dir() / "res.exr").string();
  std::string out;
  ASSERT_EQ(0, run_cli("render '" + demo_scene() + "' -o '" + res + "' --width 40 --height 32 --samples 4 --sample-range 2,4 --quiet", out)) << out;
  refused({a, res}, "resolution 48x32 vs 40x32");
  refused({a, render_to("n.exr", "--samples 5 --sample-range 2,5")}, "samples per pixel 4 vs 5");
  refused({a, render_to("strategy.exr", "--samples 4 --sample-range 2,4 --strategy light")}, "strategy mis vs light");
  // The same scene with its mesh named by absolute path: the same picture, another scene hash.
  std::ifstream in(demo_scene());
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string mesh = "\"sphere.obj\"";
  ASSERT_NE(text.find(mesh), std::string::npos);
  for (auto at = text.find(mesh); at != std::string::npos; at = text.find(mesh))
    text.replace(at, mesh.size(), "\"" + std::string(GLIMMER_TEST_SOURCE_DIR) + "/examples/sphere.obj\"");
  const std::string other_scene = write_file("demo_moved.xml", text);
  const std::string other = (temp_dir() / "other.exr").string();
  ASSERT_EQ(0, run_cli("render '" + other_scene + "' -o '" + other + "'" + kSmall + " --samples 4 --sample-range 2,4", out));
  refused({a, other}, "scene hash");
  refused({a, render_to("overlap.exr", "--samples 4 --sample-range 1,4")}, "sample ranges overlap");
  refused({a, a, b}, "duplicate parts");
  refused({a}, "samples [2, 4) of pixels [0,0 - 48,32) are missing");
  refused({render_to("t0.exr", "--samples 4 --region 0,0,48,20"), render_to("t1.exr", "--samples 4 --region 0,16,48,32")},
          "overlap");
  refused({a, b, (temp_dir() / "missing_part.exr").string()}, "missing_part.exr");
}

// Runs the CLI in the background; returns its pid.
pid_t spawn_cli(const std::string &args) {
  const std::string cmd = std::string("exec '") + GLIMMER_TEST_CLI_PATH + "' " + args + " > /dev/null 2>&1";
  const pid_t pid = fork();
  if (pid == 0) {
    execl("/bin/sh", "sh", "-c", cmd.c_str(), static_cast<char *>(nullptr));
    _exit(127);
  }
  return pid;
}

TEST(Farm, KilledRenderResumesToTheUninterruptedImage) {
  const std::string samples = " --samples 300";
  const std::string reference = render_to("uninterrupted.exr", samples);
  const std::string output = (temp_dir() / "killed.exr").string(), checkpoint = (temp_dir() / "killed.checkpoint.exr").string();
  fs::remove(output);
  fs::remove(checkpoint);
  const pid_t pid = spawn_cli("render '" + demo_scene() + "' -o '" + output + "'" + kSmall + samples + " --checkpoint-every 0");
  ASSERT_GT(pid, 0);
  // The checkpoint is renamed into place complete, so once it exists it can be read.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::minutes(2);
  while (!fs::exists(checkpoint) && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  ASSERT_EQ(0, ::kill(pid, SIGKILL));
  int status = 0;
  ::waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFSIGNALED(status)) << "the render finished before it could be killed";
  ASSERT_TRUE(fs::exists(checkpoint));
  EXPECT_FALSE(fs::exists(output));
  const Exr saved = read_exr(checkpoint);
  const int done = saved.spec.get_int_attribute("glimmer:samples");
  EXPECT_GE(done, 1);
  EXPECT_LT(done, 300);
  std::string out;
  ASSERT_EQ(0, run_cli("render '" + demo_scene() + "' -o '" + output + "' --width 48 --height 32 --threads 2" + samples +
                           " --checkpoint-every 1000 --resume", out)) << out;
  EXPECT_NE(out.find("Resuming " + checkpoint + " from sample "), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(checkpoint)) << "a finished render removes its checkpoint";
  const Exr a = read_exr(output), b = read_exr(reference);
  ASSERT_EQ(a.pixels.size(), b.pixels.size());
  EXPECT_EQ(0, std::memcmp(a.pixels.data(), b.pixels.data(), a.pixels.size() * sizeof(float))) << "not bit-identical";
  // Negative control: the checkpoint alone (fewer samples) is not the final image.
  EXPECT_NE(0, std::memcmp(saved.pixels.data(), b.pixels.data(), std::min(saved.pixels.size(), b.pixels.size()) * sizeof(float)));
}

TEST(Farm, ResumeRefusesACheckpointOfAnotherRender) {
  const std::string output = (temp_dir() / "ck.exr").string();
  const std::string checkpoint = (temp_dir() / "ck.checkpoint.exr").string();
  fs::remove(checkpoint);
  std::string out;
  // --time-limit 0 is "none"; interrupt after one pass via a tiny time limit instead, keeping the checkpoint.
  ASSERT_EQ(0, run_cli("render '" + demo_scene() + "' -o '" + output + "'" + kSmall +
                           " --samples 50 --checkpoint-every 0 --time-limit 0.000001", out)) << out;
  ASSERT_TRUE(fs::exists(checkpoint)) << "a time-limited render keeps its checkpoint";
  EXPECT_EQ(1, run_cli("render '" + demo_scene() + "' -o '" + output + "'" + kSmall + " --samples 50 --seed 3 --resume", out));
  EXPECT_NE(out.find("belongs to another render (seed 0, this render 3)"), std::string::npos) << out;
}

TEST(Farm, BlenderStyleProgressLines) {
  std::string out;
  ASSERT_EQ(0, run_cli("render '" + demo_scene() + "' -o '" + (temp_dir() / "p.exr").string() +
                           "' --width 8 --height 8 --samples 2 --frames 5 --progress-format blender", out)) << out;
  const std::regex line(R"(Fra:5 Time:\d\d:\d\d\.\d\d \| Remaining:\d\d:\d\d\.\d\d \| Sample 2/2)");
  EXPECT_TRUE(std::regex_search(out, line)) << out;
}

}  // namespace
}  // namespace glimmer::test
