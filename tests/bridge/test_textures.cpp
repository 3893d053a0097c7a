// Texture conventions: image_texture UV orientation (v = 0 is the bottom row),
// environment_texture equirectangular mapping (Cycles: u = 0.5 - atan2(y,x)/2pi,
// v = 1 - acos(z)/pi), sRGB decoding of 8-bit images.
#include <OpenImageIO/imageio.h>

#include "render_test_util.h"

namespace glimmer::test {
namespace {

std::string write_image(const std::string &name, int w, int h, const std::vector<float> &rgb, bool eight_bit) {
  const std::string path = (temp_dir() / name).string();
  auto out = OIIO::ImageOutput::create(path);
  OIIO::ImageSpec spec(w, h, 3, eight_bit ? OIIO::TypeDesc::UINT8 : OIIO::TypeDesc::FLOAT);
  EXPECT_TRUE(out->open(path, spec) && out->write_image(OIIO::TypeDesc::FLOAT, rgb.data()) && out->close());
  return path;
}

Spectrum pixel(const render::RenderResult &r, int x, int y) {
  const float *p = &r.combined[4 * (static_cast<size_t>(y) * r.width + x)];
  return {p[0], p[1], p[2]};
}

TEST(Textures, ImageTextureUvOrientationAndSrgb) {
  // 2x2 image, row 0 = top: red, green / blue, grey 0.5 (8-bit sRGB -> linear 0.214).
  const std::string img = write_image("quad.png", 2, 2, {1, 0, 0, 0, 1, 0, 0, 0, 1, 0.5f, 0.5f, 0.5f}, true);
  const std::string path = write_file(
      "uv.xml",
      "<cycles>\n<camera width=\"40\" height=\"40\" fov=\"0.8\" />\n<camera />\n"
      // A pixel-sized point filter: the one sample looks through the pixel centre, wherever the sampler's first
      // point falls (with the default 1.5 px Gaussian it could land 0.75 px off, in the bilinear blend).
      "<film filter_type=\"box\" filter_width=\"0.01\" />\n"
      "<shader name=\"s\"><image_texture name=\"t\" filename=\"" + img +
          "\" /><emission name=\"e\" strength=\"1\" /><connect from=\"t color\" to=\"e color\" />"
          "<connect from=\"e emission\" to=\"output surface\" /></shader>\n"
          "<state shader=\"s\"><mesh P=\"-1.2 -1.2 3  1.2 -1.2 3  1.2 1.2 3  -1.2 1.2 3\" nverts=\"4\" verts=\"0 1 2 3\" UV=\"0 0 1 0 1 1 0 1\" /></state>\n"
          "</cycles>\n");
  render::RenderOptions opt;
  opt.samples = 1;
  const auto r = render_scene(path, opt);
  // Image quadrants (row 0 = top) sample texel centres away from the bilinear blend.
  const Spectrum tl = pixel(r, 10, 10), tr = pixel(r, 29, 10), bl = pixel(r, 10, 29), br = pixel(r, 29, 29);
  EXPECT_GT(tl.x, 0.95f);
  EXPECT_LT(tl.y + tl.z, 0.05f);
  EXPECT_GT(tr.y, 0.95f);
  EXPECT_GT(bl.z, 0.95f);
  EXPECT_NEAR(br.x, 0.2140f, 0.01f);  // sRGB 0.5 (128/255) decoded to linear
}

TEST(Textures, EnvironmentEquirectangularLikeCycles) {
  // 8 columns: column i has red = i / 8; top half green = 1, bottom half green = 0.5.
  const int w = 8, h = 16;
  std::vector<float> px;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) px.insert(px.end(), {x / 8.0f, y < h / 2 ? 1.0f : 0.5f, 0.0f});
  const std::string env = write_image("columns.exr", w, h, px, false);
  // Camera looking along (1, -1, 0)/sqrt2 with +Z up: u = 0.5 - atan2(-1, 1) / 2pi = 0.625 -> column 5.
  // Cycles' camera space is x right, y up, z forward; the matrix columns are camera x = (1, 1, 0)/sqrt2,
  // y = +Z, z = the view direction.
  const float s = 0.70710678f;
  char matrix[256];
  std::snprintf(matrix, sizeof(matrix), "%f %f 0 0  0 0 1 0  %f %f 0 0  0 0 0 1", s, s, s, -s);
  const std::string path = write_file(
      "env_orientation.xml",
      "<cycles>\n<camera width=\"40\" height=\"40\" fov=\"1.0\" />\n<transform matrix=\"" + std::string(matrix) +
          "\"><camera /></transform>\n<background><environment_texture name=\"env\" filename=\"" + env +
          "\" /><background name=\"bg\" strength=\"1\" /><connect from=\"env color\" to=\"bg color\" />"
          "<connect from=\"bg background\" to=\"output surface\" /></background>\n</cycles>\n");
  render::RenderOptions opt;
  opt.samples = 1;
  const auto r = render_scene(path, opt);
  const Spectrum above = pixel(r, 20, 10), below = pixel(r, 20, 30);
  EXPECT_NEAR(above.x, 5.0f / 8.0f, 0.07f);  // bilinear between columns 4.5..5.5 stays within 1/16
  EXPECT_NEAR(above.y, 1.0f, 0.01f);          // looking up: the image's top row
  EXPECT_NEAR(below.y, 0.5f, 0.01f);
  // Toward the image's right the view turns toward camera +x = (1, 1, 0)/sqrt2: atan2 grows, u shrinks.
  EXPECT_LT(pixel(r, 35, 10).x, above.x - 0.05f);
}

}  // namespace
}  // namespace glimmer::test
