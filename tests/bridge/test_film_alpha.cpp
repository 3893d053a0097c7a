// Film Transparent (Cycles' <background transparent="true">, issue 16): alpha is 0 where camera paths escape
// to the background (also through a transparent BSDF), 1 on opaque objects and the covered fraction of the
// pixel on their edges; RGB is premultiplied (the visible background adds nothing, its light still counts).
// The alpha survives checkpoints (--resume), `glimmer merge` and the PNG writer (straight alpha).
#include <OpenImageIO/imageio.h>

#include <cmath>

#include "exr_compare.h"
#include "render_test_util.h"

namespace glimmer::test {
namespace {

namespace fs = std::filesystem;

constexpr int kSize = 32;
// Camera at the origin looking along +Z, fov 90 degrees: the plane z = 2 maps x to pixel column 16 + 8 x
// (Cycles' fov spans the smaller side: 2 units across 16 pixels at z = 2), y to rows 16 -/+ 8 y.
// The emissive quad's vertical edges at x = -0.71875 and 0.71875 fall at columns 10.25 and 21.75: columns
// 10 and 21 are three quarters covered, 11..20 fully; its horizontal edges at y = +-1 are pixel borders
// (rows 8..23 covered).
std::string scene_text(bool transparent, const std::string &extra = "") {
  return std::string("<cycles>\n<camera width=\"32\" height=\"32\" fov=\"1.5707963267948966\" />\n") +
         "<film filter_type=\"box\" filter_width=\"1\" />\n"
         "<background" + (transparent ? " transparent=\"true\"" : "") + ">"
         "<background name=\"bg\" color=\"0.2 0.3 0.4\" strength=\"1\" />"
         "<connect from=\"bg background\" to=\"output surface\" /></background>\n"
         "<shader name=\"glow\"><emission name=\"e\" color=\"0.5 0.5 0.5\" strength=\"1\" />"
         "<connect from=\"e emission\" to=\"output surface\" /></shader>\n"
         "<state shader=\"glow\"><mesh P=\"-0.71875 -1 2  0.71875 -1 2  0.71875 1 2  -0.71875 1 2\" nverts=\"4\" "
         "verts=\"0 1 2 3\" /></state>\n" +
         extra + "</cycles>\n";
}

// Two fully transparent quads at z = 1.5, x in [-5, -0.9] and [0.9, 5] (columns 0..6.4 and 25.6..31: 16 + 16 x / z),
// with nothing behind them.
const std::string kTransparentQuads =
    "<shader name=\"clear\"><transparent_bsdf name=\"t\" color=\"1 1 1\" />"
    "<connect from=\"t bsdf\" to=\"output surface\" /></shader>\n"
    "<state shader=\"clear\"><mesh P=\"-5 -5 1.5  -0.9 -5 1.5  -0.9 5 1.5  -5 5 1.5  0.9 -5 1.5  5 -5 1.5  5 5 1.5  "
    "0.9 5 1.5\" nverts=\"4 4\" verts=\"0 1 2 3 4 5 6 7\" /></state>\n";

float alpha_at(const render::RenderResult &r, int x, int y) { return r.combined[4 * (y * r.width + x) + 3]; }

render::RenderResult render_text(const std::string &name, const std::string &text, int samples) {
  render::RenderOptions opt;
  opt.samples = samples;
  return render_scene(write_file(name, text), opt);
}

TEST(FilmAlpha, ZeroOnTheBackgroundOneOnObjectsCoverageOnEdges) {
  const render::RenderResult r = render_text("alpha.xml", scene_text(true), 64);
  ASSERT_EQ(r.width, kSize);
  // Background pixels: alpha exactly 0 and no background colour (premultiplied).
  for (int y : {0, 3, 30})
    for (int x : {0, 5, 31}) {
      EXPECT_EQ(alpha_at(r, x, y), 0.0f) << x << "," << y;
      for (int k = 0; k < 3; ++k) EXPECT_EQ(r.combined[4 * (y * kSize + x) + k], 0.0f);
    }
  // Fully covered pixels: exactly 1, the emission's 0.5.
  for (int y = 8; y < 24; ++y)
    for (int x = 11; x < 21; ++x) {
      ASSERT_EQ(alpha_at(r, x, y), 1.0f) << x << "," << y;
      EXPECT_NEAR(r.combined[4 * (y * kSize + x)], 0.5f, 1e-6f);
    }
  // Edge columns: the covered fraction of the pixel (closed form above: 0.75), within the stratified
  // estimate's error at 64 samples; the colour is premultiplied by it.
  for (int y = 8; y < 24; ++y)
    for (int x : {10, 21}) {
      EXPECT_NEAR(alpha_at(r, x, y), 0.75f, 0.03f) << x << "," << y;
      EXPECT_NEAR(r.combined[4 * (y * kSize + x)], 0.5f * alpha_at(r, x, y), 1e-6f);
    }
  // Rows just outside the quad's horizontal edges (pixel borders): not covered at all.
  for (int x = 11; x < 21; ++x) {
    EXPECT_EQ(alpha_at(r, x, 7), 0.0f);
    EXPECT_EQ(alpha_at(r, x, 24), 0.0f);
  }
  // Negative control: the same scene without Film Transparent is opaque and shows the world colour.
  const render::RenderResult opaque = render_text("opaque.xml", scene_text(false), 64);
  for (size_t i = 0; i < opaque.combined.size(); i += 4) ASSERT_EQ(opaque.combined[i + 3], 1.0f);
  EXPECT_NEAR(opaque.combined[2], 0.4f, 1e-6f);  // blue of the world at pixel (0, 0)
}

TEST(FilmAlpha, TransparentBsdfPassesTheBackgroundThrough) {
  const render::RenderResult r = render_text("alpha_clear.xml", scene_text(true, kTransparentQuads), 16);
  // Columns 0..5 and 26..31 look through the transparent quads at nothing: alpha 0, black.
  for (int y = 0; y < kSize; ++y)
    for (int x : {0, 3, 5, 26, 31}) {
      EXPECT_EQ(alpha_at(r, x, y), 0.0f) << x << "," << y;
      EXPECT_EQ(r.combined[4 * (y * kSize + x)], 0.0f);
    }
  // Control: the quads are really there (an opaque black diffuse instead gives alpha 1).
  const std::string black = "<shader name=\"clear\"><diffuse_bsdf name=\"t\" color=\"0 0 0\" />"
                            "<connect from=\"t bsdf\" to=\"output surface\" /></shader>\n" +
                            kTransparentQuads.substr(kTransparentQuads.find("<state"));
  const render::RenderResult dark = render_text("alpha_black.xml", scene_text(true, black), 16);
  for (int y = 0; y < kSize; ++y)
    for (int x : {0, 3, 5, 26, 31}) EXPECT_EQ(alpha_at(dark, x, y), 1.0f) << x << "," << y;
}

std::string cli_render(const std::string &scene, const std::string &name, const std::string &extra, int expect = 0) {
  const std::string path = (temp_dir() / name).string();
  fs::remove(path);
  std::string out;
  EXPECT_EQ(expect, run_cli("render '" + scene + "' -o '" + path + "' --threads 2 --quiet " + extra, out)) << out;
  return path;
}

std::string cli_merge(const std::vector<std::string> &parts, const std::string &name) {
  std::string args = "merge";
  for (const auto &p : parts) args += " '" + p + "'";
  const std::string path = (temp_dir() / name).string();
  std::string out;
  EXPECT_EQ(0, run_cli(args + " -o '" + path + "'", out)) << out;
  return path;
}

// Channel `name`'s values over the data window.
std::vector<float> channel(const Exr &e, const std::string &name) {
  std::vector<float> v;
  const auto &names = e.spec.channelnames;
  const int c = static_cast<int>(std::find(names.begin(), names.end(), name) - names.begin());
  if (c == static_cast<int>(names.size())) return v;
  for (size_t i = c; i < e.pixels.size(); i += e.spec.nchannels) v.push_back(e.pixels[i]);
  return v;
}

TEST(FilmAlpha, ResumedAndMergedRendersEqualTheStraightRender) {
  const std::string scene = write_file("alpha_cli.xml", scene_text(true, kTransparentQuads));
  const std::string samples = "--samples 12 ";
  const Exr straight = read_exr(cli_render(scene, "straight.exr", samples));
  const std::vector<float> alpha = channel(straight, "ViewLayer.Combined.A");
  ASSERT_EQ(alpha.size(), static_cast<size_t>(kSize * kSize));
  EXPECT_EQ(alpha[0], 0.0f);
  EXPECT_EQ(alpha[16 * kSize + 16], 1.0f);
  EXPECT_GT(alpha[16 * kSize + 10], 0.0f);
  EXPECT_LT(alpha[16 * kSize + 10], 1.0f);

  // Resume: a time limit stops after the first pass, leaving a checkpoint with alpha sums; --resume finishes.
  const std::string output = (temp_dir() / "resumed.exr").string();
  const std::string checkpoint = (temp_dir() / "resumed.checkpoint.exr").string();
  fs::remove(checkpoint);
  cli_render(scene, "resumed.exr", samples + "--checkpoint-every 0 --time-limit 1e-9");
  ASSERT_TRUE(fs::exists(checkpoint));
  const Exr saved = read_exr(checkpoint);
  ASSERT_LT(saved.spec.get_int_attribute("glimmer:samples"), 12);
  EXPECT_FALSE(channel(saved, "glimmer.alpha_sum").empty()) << "the checkpoint keeps the alpha sums";
  cli_render(scene, "resumed.exr", samples + "--resume");
  EXPECT_FALSE(fs::exists(checkpoint));
  EXPECT_TRUE(bit_identical(read_exr(output), straight));

  // Tiles merged: bit for bit. Sample ranges merged: alpha exactly 0 and 1 where it was, the rest within
  // float rounding (means of parts weighted by their sample counts).
  const std::string t0 = cli_render(scene, "alpha_t0.exr", samples + "--tile 0/2"),
                    t1 = cli_render(scene, "alpha_t1.exr", samples + "--tile 1/2");
  EXPECT_TRUE(bit_identical(read_exr(cli_merge({t0, t1}, "alpha_tiles.exr")), straight));
  const std::string s0 = cli_render(scene, "alpha_s0.exr", samples + "--sample-split 0/3"),
                    s1 = cli_render(scene, "alpha_s1.exr", samples + "--sample-split 1/3"),
                    s2 = cli_render(scene, "alpha_s2.exr", samples + "--sample-split 2/3");
  const Exr merged = read_exr(cli_merge({s0, s1, s2}, "alpha_samples.exr"));
  const std::vector<float> merged_alpha = channel(merged, "ViewLayer.Combined.A");
  ASSERT_EQ(merged_alpha.size(), alpha.size());
  for (size_t i = 0; i < alpha.size(); ++i) {
    if (alpha[i] == 0.0f || alpha[i] == 1.0f) {
      ASSERT_EQ(merged_alpha[i], alpha[i]) << i;
    }
    EXPECT_NEAR(merged_alpha[i], alpha[i], 1e-6f) << i;
  }
  EXPECT_LE(max_relative_difference(merged, straight), 1e-6);
  // Negative control: one sample part alone is not the straight render's alpha.
  EXPECT_FALSE(bit_identical(read_exr(s0), straight));
}

TEST(FilmAlpha, PngIsRgbaWithStraightAlpha) {
  const std::string scene = write_file("alpha_png.xml", scene_text(true));
  const std::string png = cli_render(scene, "alpha.png", "--samples 64");
  OIIO::ImageSpec as_stored;  // OpenImageIO premultiplies PNG pixels on reading unless asked not to
  as_stored.attribute("oiio:UnassociatedAlpha", 1);
  auto in = OIIO::ImageInput::open(png, &as_stored);
  ASSERT_TRUE(in);
  const OIIO::ImageSpec spec = in->spec();
  ASSERT_EQ(spec.nchannels, 4);
  std::vector<unsigned char> px(static_cast<size_t>(kSize) * kSize * 4);
  ASSERT_TRUE(in->read_image(0, 0, 0, 4, OIIO::TypeDesc::UINT8, px.data()));
  auto at = [&](int x, int y, int k) { return static_cast<int>(px[4 * (y * kSize + x) + k]); };
  EXPECT_EQ(at(0, 0, 3), 0);
  EXPECT_EQ(at(16, 16, 3), 255);
  // sRGB(0.5) = 188: the interior, and the edge pixel after dividing by its alpha (straight alpha), whereas
  // its premultiplied 0.375 would be sRGB 165.
  EXPECT_EQ(at(16, 16, 0), 188);
  EXPECT_NEAR(at(10, 16, 3), 191, 8);
  EXPECT_NEAR(at(10, 16, 0), 188, 1);
  // A format without alpha (JPEG) gets RGB.
  const std::string jpg = cli_render(scene, "alpha.jpg", "--samples 4");
  auto jin = OIIO::ImageInput::open(jpg);
  ASSERT_TRUE(jin);
  EXPECT_EQ(jin->spec().nchannels, 3);
}

}  // namespace
}  // namespace glimmer::test
