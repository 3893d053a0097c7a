// Image lookups through OpenImageIO's TextureSystem (render/textures.h): test
// images written here with OIIO, looked up and compared with the texels they
// hold (closest, bilinear, extensions, box projection, MIP average of a large
// footprint); a swapped-(u, v) lookup as the negative control; renders:
// missing image magenta with one warning, the same image for any thread count.
#include <OpenImageIO/imageio.h>
#include <tbb/global_control.h>

#include <random>

#include "render/textures.h"
#include "render_test_util.h"

namespace glimmer::test {
namespace {

using render::Extension;
using render::ImageSampling;
using render::Interpolation;
using render::UvFootprint;

// A float RGBA image, row 0 = top, with distinct values per texel.
struct TestImage {
  int w = 0, h = 0;
  std::vector<float> rgba;
  std::string path;
  float at(int x, int y, int c) const { return rgba[(static_cast<size_t>(y) * w + x) * 4 + c]; }
};

TestImage write_test_image(const std::string &name, int w, int h, uint32_t seed) {
  TestImage img;
  img.w = w;
  img.h = h;
  img.path = (temp_dir() / name).string();
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> uniform(0.0f, 1.0f);
  for (int i = 0; i < w * h * 4; ++i) img.rgba.push_back(uniform(rng));
  auto out = OIIO::ImageOutput::create(img.path);
  OIIO::ImageSpec spec(w, h, 4, OIIO::TypeDesc::FLOAT);
  EXPECT_TRUE(out && out->open(img.path, spec) && out->write_image(OIIO::TypeDesc::FLOAT, img.rgba.data()) &&
              out->close());
  return img;
}

// The texel centre (x, y) (row y from the top) in Cycles' (u, v), v = 0 at the bottom.
UvFootprint texel_centre(const TestImage &img, float x, float y) {
  UvFootprint at;
  at.u = (x + 0.5f) / img.w;
  at.v = 1.0f - (y + 0.5f) / img.h;
  return at;
}

float max_abs_error(const float a[4], const float b[4]) {
  float e = 0.0f;
  for (int c = 0; c < 4; ++c) e = std::max(e, std::fabs(a[c] - b[c]));
  return e;
}

// Largest error over all texel centres of a closest lookup against the stored texel;
// `swap` looks up (v, u) instead, the negative control.
float closest_texel_error(const render::ImageTexture &tex, const TestImage &img, bool swap) {
  ImageSampling s;
  s.interpolation = Interpolation::Closest;
  float worst = 0.0f;
  for (int y = 0; y < img.h; ++y)
    for (int x = 0; x < img.w; ++x) {
      UvFootprint at = texel_centre(img, static_cast<float>(x), static_cast<float>(y));
      if (swap) std::swap(at.u, at.v);
      float got[4], want[4];
      tex.lookup(at, s, got);
      for (int c = 0; c < 4; ++c) want[c] = img.at(x, y, c);
      worst = std::max(worst, max_abs_error(got, want));
    }
  return worst;
}

TEST(ImageLookup, ClosestAtTexelCentresIsTheTexelAndSwappedUvIsNot) {
  const TestImage img = write_test_image("texels.exr", 8, 6, 1);
  render::TextureCache cache;
  const render::ImageTexture &tex = *cache.load(img.path, false);
  EXPECT_EQ(tex.width(), 8);
  EXPECT_EQ(tex.height(), 6);
  EXPECT_LE(closest_texel_error(tex, img, false), 1e-6f);
  EXPECT_GT(closest_texel_error(tex, img, true), 0.1f);  // negative control: (v, u) reads other texels
}

TEST(ImageLookup, BilinearAtTexelCornersIsTheAverageOfFour) {
  const TestImage img = write_test_image("corners.exr", 8, 6, 2);
  render::TextureCache cache;
  const render::ImageTexture &tex = *cache.load(img.path, false);
  ImageSampling s;  // linear, repeat
  float worst = 0.0f;
  for (int y = 0; y + 1 < img.h; ++y)
    for (int x = 0; x + 1 < img.w; ++x) {
      float got[4], want[4];
      tex.lookup(texel_centre(img, x + 0.5f, y + 0.5f), s, got);
      for (int c = 0; c < 4; ++c)
        want[c] = 0.25f * (img.at(x, y, c) + img.at(x + 1, y, c) + img.at(x, y + 1, c) + img.at(x + 1, y + 1, c));
      worst = std::max(worst, max_abs_error(got, want));
    }
  EXPECT_LE(worst, 1e-5f);
  // Negative control: a quarter-texel shift is no longer the average.
  float shifted[4], want[4];
  tex.lookup(texel_centre(img, 3.75f, 2.5f), s, shifted);
  for (int c = 0; c < 4; ++c)
    want[c] = 0.25f * (img.at(3, 2, c) + img.at(4, 2, c) + img.at(3, 3, c) + img.at(4, 3, c));
  EXPECT_GT(max_abs_error(shifted, want), 1e-3f);
}

TEST(ImageLookup, ExtensionModesOutsideTheImage) {
  // 6 texels across: u = 0.25 and 0.75 are the centres of texels 1 and 4.
  const TestImage img = write_test_image("extension.exr", 6, 4, 3);
  render::TextureCache cache;
  const render::ImageTexture &tex = *cache.load(img.path, false);
  struct Case {
    Extension extension;
    int texel_at_minus_quarter, texel_at_five_quarters;  // -1: (0, 0, 0, 0)
  };
  const Case cases[] = {{Extension::Repeat, 4, 1}, {Extension::Extend, 0, 5}, {Extension::Clip, -1, -1},
                        {Extension::Mirror, 1, 4}};
  const int row = 2;
  for (const Case &c : cases) {
    SCOPED_TRACE(static_cast<int>(c.extension));
    ImageSampling s;
    s.extension = s.vertical = c.extension;
    const float us[2] = {-0.25f, 1.25f};
    const int texels[2] = {c.texel_at_minus_quarter, c.texel_at_five_quarters};
    for (int i = 0; i < 2; ++i) {
      UvFootprint at = texel_centre(img, 0, row);
      at.u = us[i];
      float got[4], want[4] = {0, 0, 0, 0};
      tex.lookup(at, s, got);
      if (texels[i] >= 0)
        for (int k = 0; k < 4; ++k) want[k] = img.at(texels[i], row, k);
      EXPECT_LE(max_abs_error(got, want), 1e-5f) << "u = " << us[i];
    }
  }
}

// Cycles 3.4's CPU clip lookup (kernel/device/cpu/image.h), brute force from its definition: the texels the
// interpolation reads around x = u w - 0.5 (closest: floor(u w)), those outside the image read as zero (read_clip);
// cubic (and Smart, which Cycles' CPU kernel reads as cubic) weighs 4 x 4 texels with the uniform cubic B-spline.
float cycles_clip_lookup(const TestImage &img, Interpolation interpolation, float u, float v, int c) {
  auto texel = [&](int x, int y_from_bottom) {
    const int y = img.h - 1 - y_from_bottom;
    return x < 0 || x >= img.w || y < 0 || y >= img.h ? 0.0f : img.at(x, y, c);
  };
  if (interpolation == Interpolation::Closest)
    return texel(static_cast<int>(std::floor(u * img.w)), static_cast<int>(std::floor(v * img.h)));
  const float x = u * img.w - 0.5f, y = v * img.h - 0.5f;
  const int ix = static_cast<int>(std::floor(x)), iy = static_cast<int>(std::floor(y));
  const float tx = x - ix, ty = y - iy;
  auto weights = [interpolation](float t, float w[4]) {
    if (interpolation == Interpolation::Linear) {
      w[0] = 0.0f, w[1] = 1.0f - t, w[2] = t, w[3] = 0.0f;
      return;
    }
    w[0] = (1 - t) * (1 - t) * (1 - t) / 6.0f;
    w[1] = (3 * t * t * t - 6 * t * t + 4) / 6.0f;
    w[2] = (-3 * t * t * t + 3 * t * t + 3 * t + 1) / 6.0f;
    w[3] = t * t * t / 6.0f;
  };
  float wx[4], wy[4];
  weights(tx, wx);
  weights(ty, wy);
  float sum = 0.0f;
  for (int j = 0; j < 4; ++j)
    for (int i = 0; i < 4; ++i) sum += wx[i] * wy[j] * texel(ix - 1 + i, iy - 1 + j);
  return sum;
}

// Largest |lookup - Cycles' clip lookup| over points within 2.5 texels of the left and top edges (in and out),
// off the texel boundaries (where the closest texel depends on the rounding of the flipped v).
float clip_border_error(const render::ImageTexture &tex, const TestImage &img, Interpolation interpolation) {
  ImageSampling s;
  s.interpolation = interpolation;
  s.extension = s.vertical = Extension::Clip;
  float worst = 0.0f;
  for (float d = -2.4375f; d <= 2.5f; d += 0.125f)
    for (int k = 0; k < 2; ++k) {
      UvFootprint at;
      at.u = k == 0 ? d / img.w : 0.43f;       // across the left edge
      at.v = k == 0 ? 0.57f : 1.0f + d / img.h;  // across the top edge
      float got[4];
      tex.lookup(at, s, got);
      for (int c = 0; c < 4; ++c)
        worst = std::max(worst, std::fabs(got[c] - cycles_clip_lookup(img, interpolation, at.u, at.v, c)));
    }
  return worst;
}

TEST(ImageLookup, ClipBorderInterpolatesAcrossTheEdgeAsCycles) {
  const TestImage img = write_test_image("clip_border.exr", 8, 6, 5);
  render::TextureCache cache;
  const render::ImageTexture &tex = *cache.load(img.path, false);
  for (Interpolation i : {Interpolation::Closest, Interpolation::Linear, Interpolation::Cubic, Interpolation::Smart})
    EXPECT_LE(clip_border_error(tex, img, i), 2e-5f) << "interpolation " << static_cast<int>(i);
  // Negative control: zero wherever (u, v) is outside [0, 1]^2 (the previous rule) misses Cycles' cubic border:
  // half a texel outside the left edge Cycles still reads the first texels.
  EXPECT_GT(cycles_clip_lookup(img, Interpolation::Cubic, -0.5f / img.w, 0.57f, 0), 0.02f);
  EXPECT_GT(cycles_clip_lookup(img, Interpolation::Linear, -0.25f / img.w, 0.57f, 0), 0.02f);
}

TEST(ImageLookup, LargeFootprintReadsTheImageAverage) {
  const TestImage img = write_test_image("mip.exr", 16, 16, 4);
  render::TextureCache cache;
  const render::ImageTexture &tex = *cache.load(img.path, false);
  double mean[4] = {0, 0, 0, 0};
  for (int y = 0; y < img.h; ++y)
    for (int x = 0; x < img.w; ++x)
      for (int c = 0; c < 4; ++c) mean[c] += img.at(x, y, c) / (img.w * img.h);
  ImageSampling s;
  UvFootprint at = texel_centre(img, 7, 9);
  at.dudx = at.dvdy = 4.0f;  // one pixel covers the image four times over
  float got[4];
  tex.lookup(at, s, got);
  for (int c = 0; c < 4; ++c) EXPECT_NEAR(got[c], mean[c], 2e-3) << c;
  // Negative control: without a footprint the same point reads its texel neighbourhood, not the mean.
  at.dudx = at.dvdy = 0.0f;
  tex.lookup(at, s, got);
  float mean_f[4] = {float(mean[0]), float(mean[1]), float(mean[2]), float(mean[3])};
  EXPECT_GT(max_abs_error(got, mean_f), 0.05f);
}

// 8-bit sRGB: the MIP levels average linear values (the film averages linear radiance), not sRGB codes.
TEST(ImageLookup, SrgbImageLargeFootprintIsTheLinearAverage) {
  const int w = 8, h = 8;
  std::vector<float> codes;  // a checker of sRGB 0.1 and 0.9 (8-bit)
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) codes.push_back((x + y) % 2 ? 0.9f : 0.1f);
  const std::string path = (temp_dir() / "srgb_checker.png").string();
  auto out = OIIO::ImageOutput::create(path);
  OIIO::ImageSpec spec(w, h, 3, OIIO::TypeDesc::UINT8);
  ASSERT_TRUE(out && out->open(path, spec) && out->write_image(OIIO::TypeDesc::FLOAT, codes.data()) && out->close());
  auto linear = [](float c) { return c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f); };
  const float q1 = std::round(0.1f * 255) / 255, q9 = std::round(0.9f * 255) / 255;  // the stored codes
  const float mean_linear = 0.5f * (linear(q1) + linear(q9));
  const float linear_of_mean = linear(0.5f * (q1 + q9));  // negative control: filtering the codes
  render::TextureCache cache;
  const render::ImageTexture &tex = *cache.load(path, false);
  UvFootprint at;
  at.u = at.v = 0.5f;
  at.dudx = at.dvdy = 4.0f;
  float got[4];
  tex.lookup(at, ImageSampling{}, got);
  EXPECT_NEAR(got[0], mean_linear, 2e-3f);
  EXPECT_GT(std::fabs(got[0] - linear_of_mean), 0.1f);
  // A texel centre with no footprint is that texel, decoded.
  at = UvFootprint{};
  at.u = 0.5f / w;
  at.v = 1.0f - 0.5f / h;  // texel (0, 0): code 0.1
  tex.lookup(at, ImageSampling{}, got);
  EXPECT_NEAR(got[0], linear(q1), 1e-3f);
}

TEST(ImageLookup, BoxProjectionWeights) {
  using render::box_projection_weights;
  auto expect_weights = [](const Vec3 &w, const Vec3 &want) {
    EXPECT_NEAR(w.x, want.x, 1e-6f);
    EXPECT_NEAR(w.y, want.y, 1e-6f);
    EXPECT_NEAR(w.z, want.z, 1e-6f);
  };
  expect_weights(box_projection_weights(Vec3(-1, 0, 0), 0.3f), Vec3(1, 0, 0));
  expect_weights(box_projection_weights(Vec3(0.1f, 0.2f, -0.9f), 0.3f), Vec3(0, 0, 1));
  // A 45-degree edge between x and y: half and half with any blend > 0.
  expect_weights(box_projection_weights(normalize(Vec3(1, 1, 0)), 0.5f), Vec3(0.5f, 0.5f, 0));
  // The cube's corner with full blend: a third each.
  expect_weights(box_projection_weights(normalize(Vec3(1, -1, 1)), 1.0f), Vec3(1, 1, 1) / 3.0f);
  // Edge ramp, closed form: share s = nx / (nx + ny), w = (s - (1 - b) / 2) / b.
  const float b = 0.5f, s = 0.6f;
  expect_weights(box_projection_weights(Vec3(s, 1 - s, 0), b), Vec3((s - 0.25f) / 0.5f, 1 - (s - 0.25f) / 0.5f, 0));
  // Everywhere: weights in [0, 1] summing to 1; blend 0 picks one plane.
  std::mt19937 rng(5);
  std::normal_distribution<float> g;
  for (int i = 0; i < 2000; ++i) {
    const Vec3 n = normalize(Vec3(g(rng), g(rng), g(rng)));
    for (float blend : {0.0f, 0.2f, 1.0f}) {
      const Vec3 w = box_projection_weights(n, blend);
      EXPECT_NEAR(w.x + w.y + w.z, 1.0f, 1e-5f);
      EXPECT_TRUE(w.x >= 0 && w.y >= 0 && w.z >= 0);
      if (blend == 0.0f) {
        EXPECT_EQ(std::max({w.x, w.y, w.z}), 1.0f);
      }
    }
  }
}

TEST(ImageLookup, BoxProjectionSumsThePlanarLookups) {
  const TestImage img = write_test_image("box.exr", 8, 8, 6);
  render::TextureCache cache;
  const render::ImageTexture &tex = *cache.load(img.path, false);
  ImageSampling s;
  const Vec3 N = normalize(Vec3(0.7f, -0.5f, 0.5f)), co(0.3f, 0.6f, 0.8f);
  const Vec3 w = render::box_projection_weights(N, 0.8f);
  ASSERT_GT(std::min({w.x, w.y, w.z}), 0.0f);  // a corner: all three planes
  float got[4];
  render::box_lookup(tex, s, w, N, co, Vec3(0.0f), Vec3(0.0f), got);
  // Independently: plane x reads (y, z), plane y (x, z), plane z (1 - y, x): Cycles mirrors u on the
  // negative x side and the positive y and z sides (N.x > 0, N.y < 0, N.z > 0 here).
  const float plane_uv[3][2] = {{co.y, co.z}, {co.x, co.z}, {1.0f - co.y, co.x}};
  const float weights[3] = {w.x, w.y, w.z};
  float want[4] = {0, 0, 0, 0};
  for (int p = 0; p < 3; ++p) {
    UvFootprint at;
    at.u = plane_uv[p][0];
    at.v = plane_uv[p][1];
    float one[4];
    tex.lookup(at, s, one);
    for (int c = 0; c < 4; ++c) want[c] += weights[p] * one[c];
  }
  EXPECT_LE(max_abs_error(got, want), 1e-5f);
}

// A textured quad filling the view; `image` and `extra` (node attributes) decide the texture.
std::string textured_quad_scene(const std::string &name, const std::string &image, const std::string &extra) {
  return write_file(name,
                    "<cycles>\n<camera width=\"24\" height=\"24\" fov=\"0.8\" />\n<camera />\n"
                    "<shader name=\"s\"><image_texture name=\"t\" filename=\"" + image + "\" " + extra +
                        " /><emission name=\"e\" strength=\"1\" /><connect from=\"t color\" to=\"e color\" />"
                        "<connect from=\"e emission\" to=\"output surface\" /></shader>\n"
                        "<state shader=\"s\"><mesh P=\"-1.2 -1.2 3  1.2 -1.2 3  1.2 1.2 3  -1.2 1.2 3\" nverts=\"4\" "
                        "verts=\"0 1 2 3\" UV=\"0 0 3 0 3 3 0 3\" /></state>\n</cycles>\n");
}

TEST(ImageLookup, MissingImageRendersMagentaWithOneWarning) {
  const std::string path = textured_quad_scene("missing_image.xml", "no_such_image.png", "");
  const scene::Scene scene = scene::load_scene(path);
  render::RenderOptions opt;
  opt.samples = 1;
  render::Renderer renderer(scene, plugin(), opt);
  const auto r = renderer.render();
  int warnings = 0;
  for (const auto &w : renderer.warnings()) warnings += w.find("no_such_image.png") != std::string::npos;
  EXPECT_EQ(warnings, 1);
  // The quad's inner part (its border meets the background within the pixel filter).
  EXPECT_NEAR(mean_channel(r, 0, 6, 6, 18, 18), 1.0, 1e-4);
  EXPECT_NEAR(mean_channel(r, 1, 6, 6, 18, 18), 0.0, 1e-4);
  EXPECT_NEAR(mean_channel(r, 2, 6, 6, 18, 18), 1.0, 1e-4);
}

TEST(ImageLookup, SameImageForAnyThreadCountAndTileSize) {
  const TestImage img = write_test_image("threads.exr", 32, 32, 7);
  const std::string path = textured_quad_scene("threads.xml", img.path, "interpolation=\"smart\" extension=\"mirror\"");
  render::RenderOptions opt;
  opt.samples = 2;
  render::RenderResult one;
  {
    tbb::global_control single(tbb::global_control::max_allowed_parallelism, 1);
    opt.tile_size = 32;
    one = render_scene(path, opt);
  }
  opt.tile_size = 5;
  const render::RenderResult many = render_scene(path, opt);
  ASSERT_EQ(one.combined.size(), many.combined.size());
  EXPECT_TRUE(one.combined == many.combined);
  EXPECT_GT(mean_channel(one, 0), 0.1);  // the texture was read (not black)
}

}  // namespace
}  // namespace glimmer::test
