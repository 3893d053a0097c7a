// Image textures read with OpenImageIO (loaded only when a used shader needs
// them) and Cycles' procedural checker.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "glimmer/math.h"

namespace glimmer::render {

// Largest image (width x height) a texture may claim before any pixel is
// allocated; $GLIMMER_MAX_IMAGE_PIXELS overrides it (docs/scene-format.md).
constexpr uint64_t kDefaultMaxImagePixels = uint64_t{1} << 27;  // 134 M pixels, e.g. 16384 x 8192
uint64_t max_image_pixels();

class ImageTexture {
 public:
  // Reads `path` as RGBA floats. 8/16-bit images are treated as sRGB (Cycles'
  // default "sRGB" colour space) unless `linear` is set; like Cycles'
  // "compress as sRGB" byte textures they keep their sRGB values and lookup()
  // converts to linear after interpolating. Throws std::runtime_error naming
  // the file on failure: not a regular file, a header over the pixel budget
  // (max_image_pixels()), out of memory, a decoding error.
  static std::unique_ptr<ImageTexture> load(const std::string &path, bool linear);
  // Texture with given linear RGBA pixels (row 0 = top), for tests.
  ImageTexture(int width, int height, std::vector<float> rgba) : width_(width), height_(height), rgba_(std::move(rgba)) {}

  // Bilinear (or, with `closest`, nearest-texel) lookup with repeat wrapping,
  // Cycles' convention: v = 0 is the bottom row of the image, v = 1 the top.
  // Returns linear RGB (+ alpha).
  void lookup(float u, float v, float out_rgba[4], bool closest = false) const;
  int width() const { return width_; }
  int height() const { return height_; }
  const std::string &path() const { return path_; }

 private:
  int width_ = 0, height_ = 0;
  std::vector<float> rgba_;
  std::string path_;
  bool srgb_ = false;  // rgba_ holds sRGB-encoded colour: converted after interpolation
};

// Cycles' svm_checker: 1 for color1, 0 for color2.
inline float checker(Vec3 p) {
  p.x = (p.x + 0.000001f) * 0.999999f;
  p.y = (p.y + 0.000001f) * 0.999999f;
  p.z = (p.z + 0.000001f) * 0.999999f;
  const int xi = std::abs(static_cast<int>(std::floor(p.x)));
  const int yi = std::abs(static_cast<int>(std::floor(p.y)));
  const int zi = std::abs(static_cast<int>(std::floor(p.z)));
  return ((xi % 2 == yi % 2) == (zi % 2 != 0)) ? 1.0f : 0.0f;
}

// Equirectangular mapping as Cycles' direction_to_equirectangular (z up):
// u = 0.5 - atan2(y, x) / (2 pi), v = 1 - acos(z) / pi.
inline void direction_to_equirectangular(const Vec3 &d, float &u, float &v) {
  u = 0.5f - std::atan2(d.y, d.x) * kInv2Pi;
  v = 1.0f - safe_acos(d.z) * kInvPi;
}
inline Vec3 equirectangular_to_direction(float u, float v) {
  const float phi = kPi - kTwoPi * u, theta = kPi * (1.0f - v);
  const float s = std::sin(theta);
  return {s * std::cos(phi), s * std::sin(phi), std::cos(theta)};
}

}  // namespace glimmer::render
