#include "render/textures.h"

#include <OpenImageIO/imageio.h>

#include <cmath>
#include <cstdlib>
#include <new>
#include <stdexcept>

#include "scene/input_file.h"
#include "scene/parse_number.h"

namespace glimmer::render {

namespace {
float srgb_to_linear(float c) {
  return c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f);
}
}  // namespace

uint64_t max_image_pixels() {
  const char *env = std::getenv("GLIMMER_MAX_IMAGE_PIXELS");
  if (env == nullptr || *env == '\0') return kDefaultMaxImagePixels;
  try {
    return static_cast<uint64_t>(scene::parse_integer(env, 1, int64_t{1} << 40));
  } catch (const scene::NumberError &e) {
    throw std::runtime_error(std::string("GLIMMER_MAX_IMAGE_PIXELS: ") + e.what());
  }
}

std::unique_ptr<ImageTexture> ImageTexture::load(const std::string &path, bool linear) {
  scene::require_regular_file(path, "image");  // a FIFO or device would block or never end
  auto in = OIIO::ImageInput::open(path);
  if (!in) throw std::runtime_error("cannot read image '" + path + "': " + OIIO::geterror());
  const OIIO::ImageSpec &spec = in->spec();
  const int w = spec.width, h = spec.height, nc = spec.nchannels;
  if (w <= 0 || h <= 0 || nc <= 0) throw std::runtime_error("image '" + path + "' is empty");
  // The header alone decides: refuse before allocating anything (a tiny file can claim 30000x30000).
  const uint64_t pixels_claimed = static_cast<uint64_t>(w) * static_cast<uint64_t>(h);
  const uint64_t budget = max_image_pixels();
  if (pixels_claimed > budget || nc > 64)
    throw std::runtime_error("image '" + path + "' claims " + std::to_string(w) + "x" + std::to_string(h) + "x" +
                             std::to_string(nc) + " values, more than the budget of " + std::to_string(budget) +
                             " pixels (set GLIMMER_MAX_IMAGE_PIXELS to raise it)");
  std::vector<float> pixels, rgba;
  try {
    pixels.resize(static_cast<size_t>(pixels_claimed) * nc);
    rgba.resize(static_cast<size_t>(pixels_claimed) * 4);
  } catch (const std::bad_alloc &) {
    throw std::runtime_error("out of memory for image '" + path + "' (" + std::to_string(w) + "x" +
                             std::to_string(h) + ")");
  }
  if (!in->read_image(0, 0, 0, nc, OIIO::TypeDesc::FLOAT, pixels.data()))
    throw std::runtime_error("cannot read image '" + path + "': " + in->geterror());
  const bool is_byte = spec.format == OIIO::TypeDesc::UINT8 || spec.format == OIIO::TypeDesc::UINT16;
  const bool to_linear = is_byte && !linear;
  for (size_t i = 0; i < static_cast<size_t>(w) * h; ++i) {
    float c[4] = {0, 0, 0, 1};
    if (nc == 1 || nc == 2) {
      c[0] = c[1] = c[2] = pixels[i * nc];
      if (nc == 2) c[3] = pixels[i * nc + 1];
    } else {
      for (int k = 0; k < std::min(nc, 4); ++k) c[k] = pixels[i * nc + k];
    }
    for (int k = 0; k < 3; ++k) rgba[i * 4 + k] = std::isfinite(c[k]) ? std::max(c[k], 0.0f) : 0.0f;
    rgba[i * 4 + 3] = std::isfinite(c[3]) ? c[3] : 1.0f;
  }
  auto tex = std::make_unique<ImageTexture>(w, h, std::move(rgba));
  tex->path_ = path;
  tex->srgb_ = to_linear;
  return tex;
}

void ImageTexture::lookup(float u, float v, float out[4], bool closest) const {
  if (!std::isfinite(u) || !std::isfinite(v)) u = v = 0.0f;
  auto wrap = [](int i, int n) { i %= n; return i < 0 ? i + n : i; };
  // Cycles (kernel/svm/image.h): 8-bit sRGB images are interpolated in sRGB and converted afterwards.
  auto finish = [&]() {
    if (srgb_)
      for (int k = 0; k < 3; ++k) out[k] = srgb_to_linear(out[k]);
  };
  if (closest) {
    const int xi = wrap(static_cast<int>(std::floor((u - std::floor(u)) * width_)), width_);
    const int yi = wrap(static_cast<int>(std::floor((1.0f - (v - std::floor(v))) * height_)), height_);
    for (int k = 0; k < 4; ++k) out[k] = rgba_[(static_cast<size_t>(yi) * width_ + xi) * 4 + k];
    finish();
    return;
  }
  const float x = (u - std::floor(u)) * width_ - 0.5f;
  const float y = (1.0f - (v - std::floor(v))) * height_ - 0.5f;  // v = 1 is the top row (row 0)
  const float fx = std::floor(x), fy = std::floor(y);
  const float tx = x - fx, ty = y - fy;
  const int x0 = wrap(static_cast<int>(fx), width_), x1 = wrap(static_cast<int>(fx) + 1, width_);
  const int y0 = wrap(static_cast<int>(fy), height_), y1 = wrap(static_cast<int>(fy) + 1, height_);
  for (int k = 0; k < 4; ++k) {
    auto at = [&](int xx, int yy) { return rgba_[(static_cast<size_t>(yy) * width_ + xx) * 4 + k]; };
    out[k] = (1 - ty) * ((1 - tx) * at(x0, y0) + tx * at(x1, y0)) + ty * ((1 - tx) * at(x0, y1) + tx * at(x1, y1));
  }
  finish();
}

}  // namespace glimmer::render
