#include "render/textures.h"

#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imageio.h>
#include <OpenImageIO/texture.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <vector>

#include "scene/input_file.h"
#include "scene/parse_number.h"

namespace glimmer::render {

namespace {

float srgb_to_linear(float c) {
  return c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f);
}

OIIO::TextureOpt::Wrap wrap_mode(Extension e) {
  switch (e) {
    case Extension::Repeat: return OIIO::TextureOpt::WrapPeriodic;
    case Extension::Extend: return OIIO::TextureOpt::WrapClamp;
    case Extension::Clip: return OIIO::TextureOpt::WrapBlack;  // Cycles' clip: (0, 0, 0, 0) outside
    case Extension::Mirror: return OIIO::TextureOpt::WrapMirror;
  }
  return OIIO::TextureOpt::WrapPeriodic;
}

OIIO::TextureOpt::InterpMode interp_mode(Interpolation i) {
  switch (i) {
    case Interpolation::Closest: return OIIO::TextureOpt::InterpClosest;
    case Interpolation::Linear: return OIIO::TextureOpt::InterpBilinear;
    case Interpolation::Cubic: return OIIO::TextureOpt::InterpBicubic;
    // Cycles 3.4's CPU kernel reads Smart as Cubic at any scale (kernel/device/cpu/image.h interp: closest,
    // linear, else cubic); OIIO's InterpSmartBicubic would be bilinear when minified.
    case Interpolation::Smart: return OIIO::TextureOpt::InterpBicubic;
  }
  return OIIO::TextureOpt::InterpBilinear;
}

float finite_or_zero(float x) { return std::isfinite(x) ? x : 0.0f; }

// Cycles 3.4's clip test (kernel/device/cpu/image.h): closest reads texel floor(u w), zero outside [0, w);
// linear and cubic centre their 2 / 4 texels at u w - 0.5 and return zero only when none of them is in the
// image: ix = floor(u w - 0.5) < -1 or >= w (linear), < -2 or > w (cubic). Per axis, the same for v.
bool outside_clip_support(float u, float v, int width, int height, Interpolation interpolation) {
  auto outside = [interpolation](float x, int n) {
    if (interpolation == Interpolation::Closest) return !(x >= 0.0f && x * n < n);
    const float i = std::floor(x * n - 0.5f);
    return interpolation == Interpolation::Linear ? (i < -1.0f || i >= n) : (i < -2.0f || i > n);
  };
  return outside(u, width) || outside(v, height);
}

// Header checks before the texture system may read the file: a FIFO or device would
// block, a tiny file can claim 30000 x 30000. Returns the header.
OIIO::ImageSpec checked_header(const std::string &path) {
  scene::require_regular_file(path, "image");
  auto in = OIIO::ImageInput::open(path);
  if (!in) throw std::runtime_error("cannot read image '" + path + "': " + OIIO::geterror());
  const OIIO::ImageSpec spec = in->spec();
  const int w = spec.width, h = spec.height, nc = spec.nchannels;
  if (w <= 0 || h <= 0 || nc <= 0) throw std::runtime_error("image '" + path + "' is empty");
  const uint64_t pixels_claimed = static_cast<uint64_t>(w) * static_cast<uint64_t>(h);
  const uint64_t budget = max_image_pixels();
  if (pixels_claimed > budget || nc > 64)
    throw std::runtime_error("image '" + path + "' claims " + std::to_string(w) + "x" + std::to_string(h) + "x" +
                             std::to_string(nc) + " values, more than the budget of " + std::to_string(budget) +
                             " pixels (set GLIMMER_MAX_IMAGE_PIXELS to raise it)");
  return spec;
}

std::atomic<uint64_t> next_cache_id{1};

float linear_to_srgb(float c) {
  return c <= 0.0031308f ? c * 12.92f : 1.055f * std::pow(c, 1.0f / 2.4f) - 0.055f;
}

// The next MIP level of a w x h x nc image of sRGB codes: box averages of the linear values,
// encoded back to sRGB (the first `colour` channels; alpha is averaged as is).
std::vector<float> srgb_half_level(const std::vector<float> &codes, int w, int h, int nc, int colour, int nw, int nh) {
  std::vector<float> next(static_cast<size_t>(nw) * nh * nc, 0.0f);
  for (int y = 0; y < nh; ++y)
    for (int x = 0; x < nw; ++x) {
      const int x0 = x * w / nw, x1 = std::max(x0 + 1, (x + 1) * w / nw);
      const int y0 = y * h / nh, y1 = std::max(y0 + 1, (y + 1) * h / nh);
      const float inv = 1.0f / static_cast<float>((x1 - x0) * (y1 - y0));
      float *dst = &next[(static_cast<size_t>(y) * nw + x) * nc];
      for (int sy = y0; sy < y1; ++sy)
        for (int sx = x0; sx < x1; ++sx)
          for (int c = 0; c < nc; ++c) {
            const float v = codes[(static_cast<size_t>(sy) * w + sx) * nc + c];
            dst[c] += (c < colour ? srgb_to_linear(v) : v) * inv;
          }
      for (int c = 0; c < colour; ++c) dst[c] = linear_to_srgb(dst[c]);
    }
  return next;
}

// An sRGB-encoded (8/16-bit) file as a tiled, MIP-mapped half-float texture at `tx` holding sRGB
// codes: level 0 is the file (so a magnified lookup interpolates the codes and converts afterwards,
// as Cycles' byte textures), each coarser level the sRGB encoding of the linear box average (so a
// minified lookup keeps the mean radiance; averaging the codes darkens contrast: 5 % on the box
// parity scene's checker).
void write_srgb_mipmap(const std::string &path, const OIIO::ImageSpec &file, const std::string &tx) {
  OIIO::ImageBuf image(path);
  if (!image.read(0, 0, true, OIIO::TypeDesc::FLOAT))
    throw std::runtime_error("cannot read image '" + path + "': " + image.geterror());
  int w = file.width, h = file.height;
  const int nc = file.nchannels, colour = nc >= 3 ? 3 : 1;
  std::vector<float> level(static_cast<size_t>(w) * h * nc);
  image.get_pixels(OIIO::ROI::All(), OIIO::TypeDesc::FLOAT, level.data());
  auto out = OIIO::ImageOutput::create(tx);
  OIIO::ImageSpec spec(w, h, nc, OIIO::TypeDesc::HALF);
  spec.tile_width = spec.tile_height = 64;
  spec.attribute("textureformat", "Plain Texture");
  bool ok = out && out->open(tx, spec) && out->write_image(OIIO::TypeDesc::FLOAT, level.data());
  while (ok && (w > 1 || h > 1)) {
    const int nw = std::max(1, w / 2), nh = std::max(1, h / 2);
    level = srgb_half_level(level, w, h, nc, colour, nw, nh);
    w = nw;
    h = nh;
    spec.width = spec.full_width = w;
    spec.height = spec.full_height = h;
    ok = out->open(tx, spec, OIIO::ImageOutput::AppendMIPLevel) && out->write_image(OIIO::TypeDesc::FLOAT, level.data());
  }
  if (!ok || !out->close())
    throw std::runtime_error("cannot prepare image '" + path + "' as a texture: " +
                             (out ? out->geterror() : OIIO::geterror()));
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

TextureCache::TextureCache() : system_(OIIO::TextureSystem::create(/*shared=*/false)), id_(next_cache_id++) {
  // Scanline files (PNG, JPEG, flat EXR) are tiled and MIP-mapped in memory as read.
  system_->attribute("automip", 1);
  system_->attribute("autotile", 64);
  system_->attribute("unassociatedalpha", 1);  // keep the file's colour (Cycles' colour output is unassociated)
  system_->attribute("max_memory_MB", 2048.0f);
}

TextureCache::~TextureCache() {
  OIIO::TextureSystem::destroy(system_);
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

void *TextureCache::perthread() const {
  // The record belongs to this cache's texture system; a thread that meets another cache fetches that one's.
  thread_local uint64_t owner = 0;
  thread_local OIIO::TextureSystem::Perthread *record = nullptr;
  if (owner != id_) {
    record = system_->get_perthread_info();
    owner = id_;
  }
  return record;
}

const ImageTexture *TextureCache::load(const std::string &path, bool linear) {
  const std::string key = (linear ? "linear:" : "default:") + path;
  if (auto it = images_.find(key); it != images_.end()) return it->second.get();
  const OIIO::ImageSpec spec = checked_header(path);
  auto tex = std::unique_ptr<ImageTexture>(new ImageTexture());
  tex->cache_ = this;
  tex->path_ = path;
  tex->width_ = spec.width;
  tex->height_ = spec.height;
  tex->channels_ = spec.nchannels;
  const bool is_byte = spec.format == OIIO::TypeDesc::UINT8 || spec.format == OIIO::TypeDesc::UINT16;
  std::string source = path;
  tex->srgb_ = is_byte && !linear;
  if (tex->srgb_) {
    source = scratch_file(images_.size());
    write_srgb_mipmap(path, spec, source);
  }
  tex->handle_ = system_->get_texture_handle(OIIO::ustring(source));
  if (tex->handle_ == nullptr) throw std::runtime_error("cannot read image '" + path + "': " + system_->geterror());
  return (images_[key] = std::move(tex)).get();
}

void ImageTexture::lookup(const UvFootprint &at, const ImageSampling &sampling, float out[4]) const {
  OIIO::TextureOpt opt;
  opt.swrap = wrap_mode(sampling.extension);
  opt.twrap = wrap_mode(sampling.vertical);
  opt.interpmode = interp_mode(sampling.interpolation);
  // Anisotropic over the footprint's ellipse; closest is Cycles' point sample of the full image.
  const bool point = sampling.interpolation == Interpolation::Closest;
  opt.mipmode = point ? OIIO::TextureOpt::MipModeNoMIP : OIIO::TextureOpt::MipModeDefault;
  opt.fill = 0.0f;
  float u = at.u, v = at.v;
  if (!std::isfinite(u) || !std::isfinite(v)) u = v = 0.0f;
  // Cycles' clip: (0, 0, 0, 0) where the filter reads no texel of the image, also for files without alpha;
  // nearer, the texture system's black border interpolates across the edge as Cycles' read_clip.
  if (sampling.extension == Extension::Clip && outside_clip_support(u, v, width_, height_, sampling.interpolation)) {
    for (int k = 0; k < 4; ++k) out[k] = 0.0f;
    return;
  }
  const float scale = point ? 0.0f : 1.0f;
  // OIIO's t runs down from the top row; Cycles' v up from the bottom.
  const int nc = std::min(channels_, 4);
  float texel[4] = {0, 0, 0, 1};
  OIIO::TextureSystem *ts = cache_->system_;
  const bool ok = ts->texture(static_cast<OIIO::TextureSystem::TextureHandle *>(handle_),
                              static_cast<OIIO::TextureSystem::Perthread *>(cache_->perthread()), opt, u, 1.0f - v,
                              scale * finite_or_zero(at.dudx), -scale * finite_or_zero(at.dvdx),
                              scale * finite_or_zero(at.dudy), -scale * finite_or_zero(at.dvdy), nc, texel);
  if (!ok) {
    (void)ts->geterror();  // checked at load; a later read error (file changed on disk) reads black
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
