// Image textures looked up through OpenImageIO's TextureSystem (one per render,
// created only when a used shader reads an image, in the image module: render/image_io.h): MIP-mapped, filtered with the
// ray footprint, Cycles' projections, extensions and interpolations; and Cycles'
// procedural checker.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <string>

#include "glimmer/math.h"

namespace glimmer::render {

class TextureFiles;  // render/image_io.h

// sRGB transfer functions (IEC 61966-2-1) of one channel.
inline float srgb_to_linear(float c) { return c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f); }
inline float linear_to_srgb(float c) {
  return c <= 0.0031308f ? c * 12.92f : 1.055f * std::pow(c, 1.0f / 2.4f) - 0.055f;
}

// Largest image (width x height) a texture may claim before any pixel is
// allocated; $GLIMMER_MAX_IMAGE_PIXELS overrides it (docs/scene-format.md).
constexpr uint64_t kDefaultMaxImagePixels = uint64_t{1} << 27;  // 134 M pixels, e.g. 16384 x 8192
uint64_t max_image_pixels();

// Cycles' image node settings (ImageTextureNode / EnvironmentTextureNode).
enum class Interpolation { Closest, Linear, Cubic, Smart };
enum class Extension { Repeat, Extend, Clip, Mirror };
enum class Projection { Flat, Box, Sphere, Tube, Equirectangular, MirrorBall };

struct ImageSampling {
  Interpolation interpolation = Interpolation::Linear;
  Extension extension = Extension::Repeat;
  Extension vertical = Extension::Repeat;  // the environment clamps v (the poles), repeats u
};

// A lookup in Cycles' convention (v = 0 is the bottom row, v = 1 the top) with the
// derivatives of (u, v) per pixel step in x and y (zero: the finest level).
struct UvFootprint {
  float u = 0.0f, v = 0.0f;
  float dudx = 0.0f, dvdx = 0.0f, dudy = 0.0f, dvdy = 0.0f;
};

class TextureCache;

// One image file of a TextureCache. The lookup returns linear RGB + alpha:
// 8/16-bit images are sRGB (Cycles' default colour space) unless read as linear
// ("Non-Color"); like Cycles' byte textures they are interpolated as sRGB codes
// and converted afterwards, from a MIP map whose coarser levels encode linear
// averages (written to the cache's scratch folder). Alpha is unassociated.
class ImageTexture {
 public:
  void lookup(const UvFootprint &at, const ImageSampling &sampling, float out_rgba[4]) const;
  int width() const { return width_; }
  int height() const { return height_; }
  const std::string &path() const { return path_; }

 private:
  friend class TextureCache;
  const TextureCache *cache_ = nullptr;
  void *handle_ = nullptr;  // the texture system's handle (TextureFiles::Opened)
  int width_ = 0, height_ = 0, channels_ = 0;
  std::string path_;
  bool srgb_ = false;  // the texture holds sRGB codes: converted after filtering
};

// The render's OIIO TextureSystem (not the process-wide shared one, a TextureFiles of the
// image module): created with the cache, each image validated (regular file, header within the pixel budget)
// before the texture system may read it. Lookups are thread safe; each thread uses
// its own per-thread record of this cache.
class TextureCache {
 public:
  TextureCache();
  ~TextureCache();
  TextureCache(const TextureCache &) = delete;
  TextureCache &operator=(const TextureCache &) = delete;

  // The image at `path` (once per path and colour space). Throws std::runtime_error
  // naming the file: not a regular file, unreadable, a header over the pixel budget
  // (max_image_pixels()).
  const ImageTexture *load(const std::string &path, bool linear);

 private:
  friend class ImageTexture;
  std::unique_ptr<TextureFiles> files_;
  uint64_t id_ = 0;  // unique per cache: names its scratch folder
  std::map<std::string, std::unique_ptr<ImageTexture>> images_;
  std::string scratch_dir_;  // MIP maps of sRGB files; removed with the cache
  std::string scratch_file(size_t index);
};

// ---- Projections (Cycles' svm_node_tex_image / svm_node_tex_environment) ----

// Box projection weights of the three axis-aligned planes (x, y, z) for normal `N`
// with blend in [0, 1] (Cycles' svm_node_tex_image_box): one plane near an axis,
// two or three blended across the edges and corners; the weights sum to 1.
Vec3 box_projection_weights(const Vec3 &N, float blend);
// The (u, v) one box plane (axis 0/1/2) reads from coordinate `co`, mirrored on the
// negative side as Cycles does so that the texture is not flipped across a face.
void box_plane_uv(int axis, const Vec3 &co, const Vec3 &N, float &u, float &v);
// Box projection (Cycles' svm_node_tex_image_box): the planes' lookups at `co` (with its
// derivatives per pixel step) summed with `weights` (box_projection_weights).
void box_lookup(const ImageTexture &image, const ImageSampling &sampling, const Vec3 &weights, const Vec3 &N,
                const Vec3 &co, const Vec3 &dco_dx, const Vec3 &dco_dy, float out_rgba[4]);
// Sphere and tube projections of a coordinate in [0, 1]^3 (centred at 0.5).
void map_to_sphere(const Vec3 &co, float &u, float &v);
void map_to_tube(const Vec3 &co, float &u, float &v);

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
// Mirror ball as Cycles' direction_to_mirrorball: the ball seen from -y.
void direction_to_mirrorball(const Vec3 &d, float &u, float &v);

}  // namespace glimmer::render
