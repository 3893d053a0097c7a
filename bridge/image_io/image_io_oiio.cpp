// libglimmer_image_io.so: every use of OpenImageIO in Glimmer (render/image_io.h says why it is a module
// loaded on first use): writing and reading renders (render/image_output.h), the render's texture system
// (render/textures.h), reading a beauty pass and drawing text for `glimmer bench`.
#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imageio.h>
#include <OpenImageIO/texture.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <filesystem>
#include <stdexcept>
#include <vector>

#include "glimmer/atomic_file.h"
#include "image_io/render_layout.h"
#include "render/clamped_parameters.h"
#include "render/image_io.h"
#include "render/textures.h"

namespace glimmer::render::oiio_module {

namespace fs = std::filesystem;
using namespace image_layout;

// ---- Renders (render/image_output.h) ----

namespace {

float srgb_encode(float v) {
  if (!(v > 0.0f)) return 0.0f;
  if (v >= 1.0f) return 1.0f;
  return linear_to_srgb(v);
}

std::string lower_extension(const std::string &path) {
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

}  // namespace

void check_output_format(const std::string &path) {
  auto out = OIIO::ImageOutput::create(path);
  if (!out)
    throw std::runtime_error("output '" + path + "': no image format for extension '" +
                             fs::path(path).extension().string() + "' (use .exr or .png)");
  if (!out->supports("ioproxy"))
    throw std::runtime_error("output '" + path + "': format '" + std::string(out->format_name()) +
                             "' cannot be written atomically (use .exr or .png)");
}

void write_image_file(const std::string &path, const OIIO::ImageSpec &spec, const void *pixels) {
  check_output_format(path);
  auto out = OIIO::ImageOutput::create(path);
  std::vector<unsigned char> encoded;
  OIIO::Filesystem::IOVecOutput memory(encoded);
  const bool ok = out && out->set_ioproxy(&memory) && out->open(path, spec) &&
                  out->write_image(spec.format, pixels) && out->close();
  if (!ok) throw std::runtime_error("cannot encode '" + path + "': " + (out ? out->geterror() : OIIO::geterror()));
  const std::string problem = write_file_atomically(path, encoded.data(), encoded.size());
  if (!problem.empty()) throw std::runtime_error(problem);
}

namespace {

// A float spec for `names` over the render's data window (image_layout::data_window), Combined RGBA first.
OIIO::ImageSpec float_spec(const RenderResult &r, const std::vector<std::string> &names) {
  const DataWindow w = data_window(r);
  OIIO::ImageSpec spec(w.width, w.height, static_cast<int>(names.size()), OIIO::TypeDesc::FLOAT);
  spec.x = w.x;
  spec.y = w.y;
  spec.full_x = spec.full_y = 0;
  spec.full_width = r.width;
  spec.full_height = r.height;
  spec.channelnames = names;
  spec.alpha_channel = 3;
  return spec;
}

}  // namespace

// A display image in a format other than EXR (EXR: the EXR module, render/image_io.h ExrWriter).
void write_display_image(const std::string &path, const RenderResult &r) {
  OIIO::ImageSpec spec = float_spec(r, {"R", "G", "B", "A"});
  spec.attribute("glimmer:samples", r.samples_done);
  const auto pixels = window_pixels(data_window(r), r.width, 4, [&r](size_t i, int k) { return r.combined[4 * i + k]; });
  write_image_file(path, spec, pixels.data());
}

// 8-bit formats; renders and checkpoints as EXR are the EXR module's (render/image_output.cpp routes them there).
void write_image(const std::string &path, const RenderResult &r) {
  if (lower_extension(path) == ".exr")
    throw std::logic_error("'" + path + "': EXR renders are written by " + std::string(kExrWriterFileName));
  const size_t npix = static_cast<size_t>(r.width) * r.height;
  // 8-bit sRGB; RGBA with straight (unassociated) alpha, as Blender writes PNGs, where the format has alpha.
  auto out = OIIO::ImageOutput::create(path);
  const int nc = out && out->supports("alpha") ? 4 : 3;
  OIIO::ImageSpec spec(r.width, r.height, nc, OIIO::TypeDesc::UINT8);
  spec.attribute("oiio:ColorSpace", "sRGB");
  if (nc == 4) spec.attribute("oiio:UnassociatedAlpha", 1);  // already straight: OIIO must not divide again
  std::vector<unsigned char> pixels(npix * nc);
  for (size_t i = 0; i < npix; ++i) {
    const float alpha = std::clamp(r.combined[4 * i + 3], 0.0f, 1.0f);
    // Premultiplied RGB over alpha 1 (or without an alpha channel) is written as it is.
    const float straight = nc == 4 && alpha > 0.0f ? 1.0f / alpha : 1.0f;
    for (int k = 0; k < 3; ++k)
      pixels[nc * i + k] =
          static_cast<unsigned char>(std::lround(srgb_encode(r.combined[4 * i + k] * straight) * 255.0f));
    if (nc == 4) pixels[nc * i + 3] = static_cast<unsigned char>(std::lround(alpha * 255.0f));
  }
  write_image_file(path, spec, pixels.data());
}

RenderResult read_image(const std::string &path) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) throw std::runtime_error("cannot read '" + path + "': " + OIIO::geterror());
  const OIIO::ImageSpec &spec = in->spec();
  RenderResult r;
  r.width = spec.full_width;
  r.height = spec.full_height;
  const size_t npix = static_cast<size_t>(r.width) * r.height;
  if (spec.x < 0 || spec.y < 0 || spec.x + spec.width > r.width || spec.y + spec.height > r.height ||
      spec.full_x != 0 || spec.full_y != 0)
    throw std::runtime_error("'" + path + "': data window is not inside the display window");
  // OpenEXR stores channels sorted by name: find each of ours by name.
  const auto &have = spec.channelnames;
  auto find_all = [&have](const std::vector<std::string> &names, std::vector<int> &index) {
    index.clear();
    for (const auto &n : names) {
      const auto it = std::find(have.begin(), have.end(), n);
      if (it == have.end()) return false;
      index.push_back(static_cast<int>(it - have.begin()));
    }
    return true;
  };
  std::vector<int> index;
  const bool aovs = find_all(exr_channel_names(true), index);
  if (!aovs && !find_all(exr_channel_names(false), index))
    throw std::runtime_error("'" + path + "' is not a Glimmer EXR (no ViewLayer.Combined.R/G/B/A channels)");
  const auto alpha_sum_channel = std::find(have.begin(), have.end(), kAlphaSumChannel);
  const bool alpha_sums = alpha_sum_channel != have.end();
  const int nc = spec.nchannels;
  std::vector<float> pixels(static_cast<size_t>(spec.width) * spec.height * nc);
  if (!in->read_image(0, 0, 0, nc, OIIO::TypeDesc::FLOAT, pixels.data()))
    throw std::runtime_error("cannot read '" + path + "': " + in->geterror());
  r.combined.assign(4 * npix, 0.0f);
  if (aovs) {
    r.albedo.assign(3 * npix, 0.0f);
    r.normal.assign(3 * npix, 0.0f);
    r.depth.assign(npix, 0.0f);
  }
  if (alpha_sums) r.alpha_sum.assign(npix, 0.0f);
  for (int y = 0; y < spec.height; ++y)
    for (int x = 0; x < spec.width; ++x) {
      const size_t i = static_cast<size_t>(y + spec.y) * r.width + (x + spec.x);
      const float *p = &pixels[(static_cast<size_t>(y) * spec.width + x) * nc];
      for (int k = 0; k < 4; ++k) r.combined[4 * i + k] = p[index[k]];
      if (aovs) {
        for (int k = 0; k < 3; ++k) r.albedo[3 * i + k] = p[index[4 + k]];
        for (int k = 0; k < 3; ++k) r.normal[3 * i + k] = p[index[7 + k]];
        r.depth[i] = p[index[10]];
      }
      if (alpha_sums) r.alpha_sum[i] = p[alpha_sum_channel - have.begin()];
    }
  PartInfo &part = r.part;
  part.scene_hash = spec.get_string_attribute("glimmer:scene_hash");
  part.strategy = spec.get_string_attribute("glimmer:strategy", "mis");
  part.seed = spec.get_int_attribute("glimmer:seed", 0);
  part.samples_total = spec.get_int_attribute("glimmer:samples_total", 0);
  part.sample_begin = spec.get_int_attribute("glimmer:sample_begin", 0);
  part.sample_end = spec.get_int_attribute("glimmer:sample_end", 0);
  part.full_width = r.width;
  part.full_height = r.height;
  part.window[0] = spec.x;
  part.window[1] = spec.y;
  part.window[2] = spec.x + spec.width;
  part.window[3] = spec.y + spec.height;
  r.samples_done = spec.get_int_attribute("glimmer:samples", 0);
  r.samples_requested = part.sample_end - part.sample_begin;
  r.interrupted = spec.get_int_attribute("glimmer:incomplete", 0) != 0;
  r.film_sums = spec.get_int_attribute("glimmer:checkpoint", 0) != 0;
  r.nan_samples = std::stoull(spec.get_string_attribute("glimmer:nan_samples", "0"));
  r.paths = std::stoull(spec.get_string_attribute("glimmer:paths", "0"));
  try {  // absent in images of builds before it: no records
    r.clamped_parameters = decode_clamped_records(spec.get_string_attribute(kClampedParametersAttribute));
  } catch (const std::exception &e) {
    throw std::runtime_error("'" + path + "': " + e.what());
  }
  r.warnings = clamped_parameter_warnings(r.clamped_parameters);
  if (part.samples_total <= 0)
    throw std::runtime_error("'" + path + "' has no glimmer:samples_total metadata (not written by glimmer render)");
  return r;
}


// ---- Textures (render/textures.h) ----

namespace {

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

// Header checks before the texture system may read the file (the host has checked that it is a regular
// file: a FIFO or device would block): a tiny file can claim 30000 x 30000. Returns the header.
OIIO::ImageSpec checked_header(const std::string &path, uint64_t budget) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) throw std::runtime_error("cannot read image '" + path + "': " + OIIO::geterror());
  const OIIO::ImageSpec spec = in->spec();
  const int w = spec.width, h = spec.height, nc = spec.nchannels;
  if (w <= 0 || h <= 0 || nc <= 0) throw std::runtime_error("image '" + path + "' is empty");
  const uint64_t pixels_claimed = static_cast<uint64_t>(w) * static_cast<uint64_t>(h);
  if (pixels_claimed > budget || nc > 64)
    throw std::runtime_error("image '" + path + "' claims " + std::to_string(w) + "x" + std::to_string(h) + "x" +
                             std::to_string(nc) + " values, more than the budget of " + std::to_string(budget) +
                             " pixels (set GLIMMER_MAX_IMAGE_PIXELS to raise it)");
  return spec;
}

std::atomic<uint64_t> next_texture_system_id{1};

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

class OiioTextureFiles final : public TextureFiles {
 public:
  OiioTextureFiles() : system_(OIIO::TextureSystem::create(/*shared=*/false)), id_(next_texture_system_id++) {
    // Scanline files (PNG, JPEG, flat EXR) are tiled and MIP-mapped in memory as read.
    system_->attribute("automip", 1);
    system_->attribute("autotile", 64);
    system_->attribute("unassociatedalpha", 1);  // keep the file's colour (Cycles' colour output is unassociated)
    system_->attribute("max_memory_MB", 2048.0f);
  }
  ~OiioTextureFiles() override { OIIO::TextureSystem::destroy(system_); }

  Opened open(const std::string &path, bool linear, uint64_t max_pixels,
              const std::function<std::string()> &scratch_file) override {
    const OIIO::ImageSpec spec = checked_header(path, max_pixels);
    Opened o;
    o.width = spec.width;
    o.height = spec.height;
    o.channels = spec.nchannels;
    const bool is_byte = spec.format == OIIO::TypeDesc::UINT8 || spec.format == OIIO::TypeDesc::UINT16;
    o.srgb = is_byte && !linear;
    std::string source = path;
    if (o.srgb) {
      source = scratch_file();
      write_srgb_mipmap(path, spec, source);
    }
    o.handle = system_->get_texture_handle(OIIO::ustring(source));
    if (o.handle == nullptr) throw std::runtime_error("cannot read image '" + path + "': " + system_->geterror());
    return o;
  }

  bool texture(void *handle, const UvFootprint &at, const ImageSampling &sampling, int channels,
               float texel[4]) const override {
    OIIO::TextureOpt opt;
    opt.swrap = wrap_mode(sampling.extension);
    opt.twrap = wrap_mode(sampling.vertical);
    opt.interpmode = interp_mode(sampling.interpolation);
    // Anisotropic over the footprint's ellipse; closest is Cycles' point sample of the full image.
    const bool point = sampling.interpolation == Interpolation::Closest;
    opt.mipmode = point ? OIIO::TextureOpt::MipModeNoMIP : OIIO::TextureOpt::MipModeDefault;
    opt.fill = 0.0f;
    const float scale = point ? 0.0f : 1.0f;
    // OIIO's t runs down from the top row; Cycles' v up from the bottom.
    const bool ok = system_->texture(static_cast<OIIO::TextureSystem::TextureHandle *>(handle), perthread(), opt,
                                     at.u, 1.0f - at.v, scale * finite_or_zero(at.dudx),
                                     -scale * finite_or_zero(at.dvdx), scale * finite_or_zero(at.dudy),
                                     -scale * finite_or_zero(at.dvdy), channels, texel);
    if (!ok) (void)system_->geterror();  // checked at open; a later read error (file changed on disk) reads black
    return ok;
  }

 private:
  OIIO::TextureSystem *system_;
  uint64_t id_;  // unique per texture system: a thread's per-thread record belongs to one id

  // This thread's record of this texture system; a thread that meets another system fetches that one's.
  OIIO::TextureSystem::Perthread *perthread() const {
    thread_local uint64_t owner = 0;
    thread_local OIIO::TextureSystem::Perthread *record = nullptr;
    if (owner != id_) {
      record = system_->get_perthread_info();
      owner = id_;
    }
    return record;
  }
};

// ---- The module ----

class OiioImageIo final : public ImageIo {
 public:
  void check_output_format(const std::string &path) const override { oiio_module::check_output_format(path); }
  void write_image(const std::string &path, const RenderResult &r) const override { oiio_module::write_image(path, r); }
  void write_display_image(const std::string &path, const RenderResult &r) const override {
    oiio_module::write_display_image(path, r);
  }
  RenderResult read_image(const std::string &path) const override { return oiio_module::read_image(path); }
  void write_bytes(const std::string &path, int width, int height, int channels,
                   const unsigned char *pixels) const override {
    write_image_file(path, OIIO::ImageSpec(width, height, channels, OIIO::TypeDesc::UINT8), pixels);
  }
  std::vector<float> read_rgb(const std::string &path, int &w, int &h) const override;
  void draw_text(float *rgb, int width, int height, int x, int y, const std::string &text, int size,
                 const std::string &font, const float colour[3]) const override {
    OIIO::ImageBuf image(OIIO::ImageSpec(width, height, 3, OIIO::TypeDesc::FLOAT), rgb);  // wraps the pixels
    OIIO::ImageBufAlgo::render_text(image, x, y, text, size, font, colour);
  }
  std::unique_ptr<TextureFiles> create_texture_files() const override { return std::make_unique<OiioTextureFiles>(); }
};

std::vector<float> OiioImageIo::read_rgb(const std::string &path, int &w, int &h) const {
  OIIO::ImageBuf buf(path);
  if (!buf.read(0, 0, true, OIIO::TypeDesc::FLOAT)) throw std::runtime_error("cannot read " + path);
  const OIIO::ImageSpec &spec = buf.spec();
  w = spec.width;
  h = spec.height;
  // The beauty pass: "<layer>.Combined.{R,G,B}" in multilayer EXRs, else R, G, B.
  int channel[3] = {0, 1, 2};
  const char *suffix[3] = {"Combined.R", "Combined.G", "Combined.B"};
  const char *plain[3] = {"R", "G", "B"};
  for (int c = 0; c < 3; ++c)
    for (int i = 0; i < spec.nchannels; ++i) {
      const std::string &n = spec.channel_name(i);
      if (n == plain[c] || (n.size() >= 10 && n.compare(n.size() - 10, 10, suffix[c]) == 0)) {
        channel[c] = i;
        break;
      }
    }
  std::vector<float> all(static_cast<size_t>(w) * h * spec.nchannels);
  buf.get_pixels(OIIO::ROI(0, w, 0, h, 0, 1, 0, spec.nchannels), OIIO::TypeDesc::FLOAT, all.data());
  std::vector<float> px(static_cast<size_t>(w) * h * 3);
  for (size_t p = 0; p < static_cast<size_t>(w) * h; ++p)
    for (int c = 0; c < 3; ++c) px[3 * p + c] = all[p * spec.nchannels + channel[c]];
  return px;
}

}  // namespace glimmer::render::oiio_module

extern "C" __attribute__((visibility("default"))) const glimmer::render::ImageIo *glimmer_image_io() {
  static const glimmer::render::oiio_module::OiioImageIo io;
  return &io;
}
