// The image modules (render/image_io.h): OpenImageIO is loaded with libglimmer_image_io.so on first use,
// not linked into the glimmer executable; EXR renders are written by libglimmer_exr_io.so (OpenEXR alone), so a
// render to .exr loads no OIIO; the output extensions checked without the module are ones the module can
// write; a missing module is a clear error before any render work.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <string>

#include "render/image_io.h"
#include "render/image_output.h"
#include "render_test_util.h"

namespace glimmer::test {
namespace {

std::string ldd(const std::string &binary) {
  std::string text;
  FILE *p = popen(("ldd '" + binary + "' 2>&1").c_str(), "r");
  if (p == nullptr) return text;
  char buf[512];
  while (fgets(buf, sizeof(buf), p) != nullptr) text += buf;
  pclose(p);
  return text;
}

TEST(ImageModule, CliDoesNotLinkOpenImageIO) {
  EXPECT_EQ(ldd(GLIMMER_TEST_CLI_PATH).find("libOpenImageIO"), std::string::npos);
  const std::string exr_module = ldd(std::string(GLIMMER_TEST_BINARY_DIR) + "/" + render::kExrWriterFileName);
  EXPECT_EQ(exr_module.find("libOpenImageIO"), std::string::npos) << exr_module;
  EXPECT_NE(exr_module.find("libOpenEXR"), std::string::npos) << exr_module;
  // Control: the module links it (and this test binary, which reads images itself), so ldd shows it there.
  EXPECT_NE(ldd(std::string(GLIMMER_TEST_BINARY_DIR) + "/" + render::kImageIoFileName).find("libOpenImageIO"),
            std::string::npos);
}

// check_output_path accepts these without asking the module; the module must agree.
TEST(ImageModule, KnownWritableExtensionsAreWritable) {
  const render::ImageIo &io = render::image_io();
  for (const auto ext : render::kKnownWritableExtensions) {
    const std::string path = (temp_dir() / ("known" + std::string(ext))).string();
    EXPECT_NO_THROW(io.check_output_format(path)) << ext;
    EXPECT_TRUE(render::known_writable_extension(path)) << ext;
  }
  EXPECT_TRUE(render::known_writable_extension("a/B.EXR"));
  // Control: an unknown extension is not on the list and the module refuses it.
  EXPECT_FALSE(render::known_writable_extension("a/b.xyz"));
  EXPECT_THROW(io.check_output_format((temp_dir() / "unknown.xyz").string()), std::runtime_error);
  EXPECT_THROW(render::check_output_path((temp_dir() / "unknown.xyz").string()), std::runtime_error);
}

std::string tiny_scene() {
  return write_file("module_scene.xml",
                    "<cycles>\n<camera width=\"8\" height=\"8\" />\n"
                    "<transform translate=\"0 0 -3\"><camera /></transform>\n"
                    "<mesh P=\"-1 -1 0  1 -1 0  1 1 0  -1 1 0\" nverts=\"4\" verts=\"0 1 2 3\" />\n"
                    "</cycles>\n");
}

// Renders the tiny scene to `file` with the module variable `env` pointing at a missing file: the exit code
// (and the output in `out`); the image must not exist when the render fails.
int render_with_missing_module(const char *env, const std::string &file, std::string &out) {
  const auto out_path = temp_dir() / file;
  std::filesystem::remove(out_path);
  ::setenv(env, "/no/such/module.so", 1);
  const int code = run_cli("render '" + tiny_scene() + "' -o '" + out_path.string() + "' --samples 1 --quiet", out);
  ::unsetenv(env);
  if (code != 0) {
    EXPECT_FALSE(std::filesystem::exists(out_path)) << file;
  }
  return code;
}

TEST(ImageModule, MissingModuleIsAClearErrorBeforeTheRender) {
  std::string out;
  // .exr: the EXR module writes it.
  EXPECT_EQ(render_with_missing_module("GLIMMER_EXR_IO_PATH", "module_missing.exr", out), 2) << out;
  EXPECT_NE(out.find("cannot load the image module '/no/such/module.so'"), std::string::npos) << out;
  // .png: the OIIO module writes it.
  EXPECT_EQ(render_with_missing_module("GLIMMER_IMAGE_IO_PATH", "module_missing.png", out), 2) << out;
  EXPECT_NE(out.find("cannot load the image module '/no/such/module.so'"), std::string::npos) << out;
  // Control: with the modules found next to the executable the same commands render.
  for (const char *file : {"module_found.exr", "module_found.png"}) {
    const auto out_path = temp_dir() / file;
    EXPECT_EQ(run_cli("render '" + tiny_scene() + "' -o '" + out_path.string() + "' --samples 1 --quiet", out), 0) << out;
    EXPECT_TRUE(std::filesystem::exists(out_path)) << file;
  }
}

// A render to .exr never loads OIIO (its 260 libraries were most of a small render's wall time): it
// succeeds with the OIIO module missing. Control: the same render to .png fails then (previous test).
TEST(ImageModule, ExrRenderLoadsNoOpenImageIO) {
  std::string out;
  EXPECT_EQ(render_with_missing_module("GLIMMER_IMAGE_IO_PATH", "no_oiio.exr", out), 0) << out;
  EXPECT_TRUE(std::filesystem::exists(temp_dir() / "no_oiio.exr"));
}

// What the EXR module writes, the OIIO module reads back bit for bit: every channel (AOVs, a checkpoint's
// alpha sums), the crop of a region part and the glimmer:* metadata.
TEST(ImageModule, ExrModuleRoundTripsThroughTheReader) {
  render::RenderResult r;
  r.width = 7;
  r.height = 5;
  const size_t npix = 35;
  r.part.scene_hash = "0123456789abcdef";
  r.part.strategy = "bsdf";
  r.part.seed = 11;
  r.part.samples_total = 64;
  r.part.sample_begin = 16;
  r.part.sample_end = 48;
  r.part.full_width = 7;
  r.part.full_height = 5;
  const int window[4] = {2, 1, 6, 4};
  std::memcpy(r.part.window, window, sizeof(window));
  r.samples_requested = 32;
  r.samples_done = 20;
  r.film_sums = true;
  r.nan_samples = 3;
  r.paths = 123456789012ull;
  uint32_t bits = 0x3f8ccccdu;
  auto next = [&bits]() {  // distinct floats, including a subnormal and a negative zero
    bits = bits * 1664525u + 1013904223u;
    float f;
    std::memcpy(&f, &bits, sizeof(f));
    return std::isfinite(f) ? f : -0.0f;
  };
  for (auto *v : {&r.combined, &r.albedo, &r.normal, &r.depth, &r.alpha_sum}) {
    const size_t n = v == &r.combined ? 4 : (v == &r.depth || v == &r.alpha_sum) ? 1 : 3;
    v->resize(n * npix);
    for (auto &x : *v) x = next();
  }
  r.combined[0] = 1.0e-40f;
  const std::string path = (temp_dir() / "roundtrip.exr").string();
  render::write_image(path, r);
  const render::RenderResult back = render::read_image(path);
  ASSERT_EQ(back.width, 7);
  ASSERT_EQ(back.height, 5);
  EXPECT_EQ(back.part.scene_hash, r.part.scene_hash);
  EXPECT_EQ(back.part.strategy, "bsdf");
  EXPECT_EQ(back.part.seed, 11);
  EXPECT_EQ(back.part.samples_total, 64);
  EXPECT_EQ(back.part.sample_begin, 16);
  EXPECT_EQ(back.part.sample_end, 48);
  for (int k = 0; k < 4; ++k) EXPECT_EQ(back.part.window[k], window[k]) << k;
  EXPECT_EQ(back.samples_done, 20);
  EXPECT_TRUE(back.interrupted);  // 20 of 32 samples: incomplete
  EXPECT_TRUE(back.film_sums);
  EXPECT_EQ(back.nan_samples, 3u);
  EXPECT_EQ(back.paths, 123456789012ull);
  // Inside the window every value's bits come back; outside it the reader fills zeros.
  int compared = 0;
  for (int y = 0; y < 5; ++y)
    for (int x = 0; x < 7; ++x) {
      const size_t i = static_cast<size_t>(y) * 7 + x;
      const bool inside = x >= window[0] && x < window[2] && y >= window[1] && y < window[3];
      auto same = [&](const std::vector<float> &a, const std::vector<float> &b, size_t n) {
        for (size_t k = 0; k < n; ++k) {
          const float want = inside ? a[n * i + k] : 0.0f;
          EXPECT_EQ(std::memcmp(&want, &b[n * i + k], sizeof(float)), 0) << x << "," << y << " " << k;
          ++compared;
        }
      };
      same(r.combined, back.combined, 4);
      same(r.albedo, back.albedo, 3);
      same(r.normal, back.normal, 3);
      same(r.depth, back.depth, 1);
      same(r.alpha_sum, back.alpha_sum, 1);
    }
  EXPECT_EQ(compared, 35 * 12);
  // The display image: plain R, G, B (of the whole image here: read_rgb reads from the origin), read by the
  // OIIO module.
  render::RenderResult whole = r;
  std::memset(whole.part.window, 0, sizeof(whole.part.window));
  const std::string display = (temp_dir() / "display.exr").string();
  render::write_display_image(display, whole);
  int w = 0, h = 0;
  const std::vector<float> rgb = render::image_io().read_rgb(display, w, h);
  ASSERT_EQ(w, 7);
  ASSERT_EQ(h, 5);
  for (size_t i = 0; i < npix; ++i)
    for (int k = 0; k < 3; ++k)
      EXPECT_EQ(std::memcmp(&r.combined[4 * i + k], &rgb[3 * i + k], sizeof(float)), 0) << i << " " << k;
}

}  // namespace
}  // namespace glimmer::test
