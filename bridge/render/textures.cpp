#include "render/textures.h"

#include <unistd.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <vector>

#include "render/image_io.h"
#include "scene/input_file.h"
#include "scene/parse_number.h"

namespace glimmer::render {

namespace {

float finite_or_zero(float x) { return std::isfinite(x) ? x : 0.0f; }

std::atomic<uint64_t> next_cache_id{1};

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

TextureCache::TextureCache() : files_(image_io().create_texture_files()), id_(next_cache_id++) {}

TextureCache::~TextureCache() {
  files_.reset();  // the texture system first: it may hold the scratch files open
  if (!scratch_dir_.empty()) {
    std::error_code ec;
    std::filesystem::remove_all(scratch_dir_, ec);
  }
}

std::string TextureCache::scratch_file(size_t index) {
  if (scratch_dir_.empty()) {
    scratch_dir_ = (std::filesystem::temp_directory_path() /
                    ("glimmer-textures-" + std::to_string(::getpid()) + "-" + std::to_string(id_)))
                       .string();
    std::filesystem::create_directories(scratch_dir_);
  }
  return (std::filesystem::path(scratch_dir_) / (std::to_string(index) + ".exr")).string();
}

const ImageTexture *TextureCache::load(const std::string &path, bool linear) {
  const std::string key = (linear ? "linear:" : "default:") + path;
  if (auto it = images_.find(key); it != images_.end()) return it->second.get();
  scene::require_regular_file(path, "image");  // a FIFO or device would block the texture system
  const TextureFiles::Opened opened =
      files_->open(path, linear, max_image_pixels(), [this] { return scratch_file(images_.size()); });
  auto tex = std::unique_ptr<ImageTexture>(new ImageTexture());
  tex->cache_ = this;
  tex->path_ = path;
  tex->handle_ = opened.handle;
  tex->width_ = opened.width;
  tex->height_ = opened.height;
  tex->channels_ = opened.channels;
  tex->srgb_ = opened.srgb;
  return (images_[key] = std::move(tex)).get();
}

// Cycles 3.4's clip test (kernel/device/cpu/image.h): closest reads texel floor(u w), zero outside [0, w);
// linear and cubic centre their 2 / 4 texels at u w - 0.5 and return zero only when none of them is in the
// image: ix = floor(u w - 0.5) < -1 or >= w (linear), < -2 or > w (cubic). Per axis, the same for v.
static bool outside_clip_support(float u, float v, int width, int height, Interpolation interpolation) {
  auto outside = [interpolation](float x, int n) {
    if (interpolation == Interpolation::Closest) return !(x >= 0.0f && x * n < n);
    const float i = std::floor(x * n - 0.5f);
    return interpolation == Interpolation::Linear ? (i < -1.0f || i >= n) : (i < -2.0f || i > n);
  };
  return outside(u, width) || outside(v, height);
}

void ImageTexture::lookup(const UvFootprint &at, const ImageSampling &sampling, float out[4]) const {
  UvFootprint where = at;
  if (!std::isfinite(where.u) || !std::isfinite(where.v)) where.u = where.v = 0.0f;
  // Cycles' clip: (0, 0, 0, 0) where the filter reads no texel of the image, also for files without alpha;
  // nearer, the texture system's black border interpolates across the edge as Cycles' read_clip.
  if (sampling.extension == Extension::Clip &&
      outside_clip_support(where.u, where.v, width_, height_, sampling.interpolation)) {
    for (int k = 0; k < 4; ++k) out[k] = 0.0f;
    return;
  }
  const int nc = std::min(channels_, 4);
  float texel[4] = {0, 0, 0, 1};
  if (!cache_->files_->texture(handle_, where, sampling, nc, texel)) {
    for (int k = 0; k < 4; ++k) out[k] = 0.0f;
    return;
  }
  // Grey (+ alpha) files fill the three colour channels.
  if (nc <= 2) {
    out[3] = nc == 2 ? texel[1] : 1.0f;
    out[0] = out[1] = out[2] = texel[0];
  } else {
    for (int k = 0; k < 4; ++k) out[k] = texel[k];
    if (nc == 3) out[3] = 1.0f;
  }
  for (int k = 0; k < 3; ++k) {
    out[k] = std::max(finite_or_zero(out[k]), 0.0f);
    if (srgb_) out[k] = srgb_to_linear(out[k]);  // after filtering, as Cycles' byte textures
  }
  out[3] = std::isfinite(out[3]) ? out[3] : 1.0f;
}

// ---- Projections ----

Vec3 box_projection_weights(const Vec3 &normal, float blend) {
  Vec3 n(std::fabs(normal.x), std::fabs(normal.y), std::fabs(normal.z));
  const float sum = n.x + n.y + n.z;
  if (!(sum > 0.0f)) return {1.0f, 0.0f, 0.0f};
  n = n / sum;
  blend = saturate(blend);
  // Within `limit` of an axis one plane alone; past it the two (edge) or three (corner) nearest planes blend.
  const float limit = 0.5f * (1.0f + blend);
  if (n.x > limit * (n.x + n.y) && n.x > limit * (n.x + n.z)) return {1.0f, 0.0f, 0.0f};
  if (n.y > limit * (n.x + n.y) && n.y > limit * (n.y + n.z)) return {0.0f, 1.0f, 0.0f};
  if (n.z > limit * (n.x + n.z) && n.z > limit * (n.y + n.z)) return {0.0f, 0.0f, 1.0f};
  if (!(blend > 0.0f)) return {1.0f, 0.0f, 0.0f};  // no blend and no dominant axis (a tie): one plane
  auto ramp = [blend](float share) { return saturate((share - 0.5f * (1.0f - blend)) / blend); };
  if (n.z < (1.0f - limit) * (n.x + n.y)) {
    const float wx = ramp(n.x / (n.x + n.y));
    return {wx, 1.0f - wx, 0.0f};
  }
  if (n.x < (1.0f - limit) * (n.y + n.z)) {
    const float wy = ramp(n.y / (n.y + n.z));
    return {0.0f, wy, 1.0f - wy};
  }
  if (n.y < (1.0f - limit) * (n.x + n.z)) {
    const float wx = ramp(n.x / (n.x + n.z));
    return {wx, 0.0f, 1.0f - wx};
  }
  auto corner = [limit](float c) { return ((2.0f - limit) * c + (limit - 1.0f)) / (2.0f * limit - 1.0f); };
  return {corner(n.x), corner(n.y), corner(n.z)};
}

void box_plane_uv(int axis, const Vec3 &co, const Vec3 &N, float &u, float &v) {
  switch (axis) {
    case 0: u = N.x < 0.0f ? 1.0f - co.y : co.y; v = co.z; break;
    case 1: u = N.y > 0.0f ? 1.0f - co.x : co.x; v = co.z; break;
    default: u = N.z > 0.0f ? 1.0f - co.y : co.y; v = co.x; break;
  }
}

void box_lookup(const ImageTexture &image, const ImageSampling &sampling, const Vec3 &weights, const Vec3 &N,
                const Vec3 &co, const Vec3 &dco_dx, const Vec3 &dco_dy, float out[4]) {
  for (int k = 0; k < 4; ++k) out[k] = 0.0f;
  const float w[3] = {weights.x, weights.y, weights.z};
  for (int axis = 0; axis < 3; ++axis) {
    if (!(w[axis] > 0.0f)) continue;
    UvFootprint at;
    box_plane_uv(axis, co, N, at.u, at.v);
    float u, v;  // the plane's (u, v) is affine in co: its derivative is the difference over one step
    box_plane_uv(axis, co + dco_dx, N, u, v);
    at.dudx = u - at.u;
    at.dvdx = v - at.v;
    box_plane_uv(axis, co + dco_dy, N, u, v);
    at.dudy = u - at.u;
    at.dvdy = v - at.v;
    float rgba[4];
    image.lookup(at, sampling, rgba);
    for (int k = 0; k < 4; ++k) out[k] += w[axis] * rgba[k];
  }
}

void map_to_sphere(const Vec3 &co, float &u, float &v) {
  const Vec3 d = (co - Vec3(0.5f)) * 2.0f;
  const float len = length(d);
  u = v = 0.0f;
  if (!(len > 0.0f)) return;
  u = (d.x == 0.0f && d.y == 0.0f) ? 0.0f : (1.0f - std::atan2(d.x, d.y) * kInvPi) * 0.5f;
  v = 1.0f - safe_acos(d.z / len) * kInvPi;
}

void map_to_tube(const Vec3 &co, float &u, float &v) {
  const Vec3 d = (co - Vec3(0.5f)) * 2.0f;
  u = v = 0.0f;
  if (d.x == 0.0f && d.y == 0.0f) return;
  const float len = std::sqrt(d.x * d.x + d.y * d.y);
  u = (1.0f - std::atan2(d.x / len, d.y / len) * kInvPi) * 0.5f;
  v = (d.z + 1.0f) * 0.5f;
}

void direction_to_mirrorball(const Vec3 &d, float &u, float &v) {
  Vec3 n = d;
  n.y -= 1.0f;
  const float div = 2.0f * std::sqrt(std::max(-0.5f * n.y, 0.0f));
  if (div > 0.0f) n = n / div;
  u = 0.5f * (n.x + 1.0f);
  v = 0.5f * (n.z + 1.0f);
}

}  // namespace glimmer::render
