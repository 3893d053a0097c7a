#include "render/image_output.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <stdexcept>

#include "glimmer/atomic_file.h"

namespace glimmer::render {

namespace fs = std::filesystem;

std::string frame_path(const std::string &pattern, int frame) {
  const auto start = pattern.find('#');
  if (start == std::string::npos) return pattern;
  auto end = start;
  while (end < pattern.size() && pattern[end] == '#') ++end;
  std::string number = std::to_string(std::abs(frame));
  const size_t pad = end - start;
  if (number.size() < pad) number = std::string(pad - number.size(), '0') + number;
  if (frame < 0) number = "-" + number;
  return pattern.substr(0, start) + number + pattern.substr(end);
}

namespace {

float srgb_encode(float v) {
  if (!(v > 0.0f)) return 0.0f;
  if (v >= 1.0f) return 1.0f;
  return v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
}

// A checkpoint's per-pixel alpha sums (RenderResult::alpha_sum): not a Blender pass.
constexpr const char *kAlphaSumChannel = "glimmer.alpha_sum";

std::vector<std::string> exr_channel_names(bool aovs) {
  std::vector<std::string> names = {"ViewLayer.Combined.R", "ViewLayer.Combined.G", "ViewLayer.Combined.B",
                                    "ViewLayer.Combined.A"};
  if (aovs) {
    for (const char *c : {"R", "G", "B"}) names.push_back(std::string("ViewLayer.Albedo.") + c);
    for (const char *c : {"X", "Y", "Z"}) names.push_back(std::string("ViewLayer.Normal.") + c);
    names.push_back("ViewLayer.Depth.Z");
  }
  return names;
}

// glimmer:* attributes: what part of which render the image holds (render/film.h PartInfo).
void write_part_metadata(const RenderResult &r, OIIO::ImageSpec &spec) {
  const PartInfo &p = r.part;
  if (!p.scene_hash.empty()) spec.attribute("glimmer:scene_hash", p.scene_hash);
  spec.attribute("glimmer:strategy", p.strategy);
  spec.attribute("glimmer:seed", p.seed);
  spec.attribute("glimmer:samples_total", p.samples_total);
  spec.attribute("glimmer:sample_begin", p.sample_begin);
  spec.attribute("glimmer:sample_end", p.sample_end);
  spec.attribute("glimmer:incomplete", r.samples_done != p.sample_end - p.sample_begin || r.interrupted ? 1 : 0);
  spec.attribute("glimmer:nan_samples", std::to_string(r.nan_samples));
  spec.attribute("glimmer:paths", std::to_string(r.paths));
  if (r.film_sums) spec.attribute("glimmer:checkpoint", 1);
}

std::string lower_extension(const std::string &path) {
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

}  // namespace

void check_output_path(const std::string &path) {
  const fs::path target(path);
  if (lower_extension(path).empty())
    throw std::runtime_error("output '" + path + "' has no file extension (.exr or .png)");
  auto out = OIIO::ImageOutput::create(path);
  if (!out)
    throw std::runtime_error("output '" + path + "': no image format for extension '" + target.extension().string() +
                             "' (use .exr or .png)");
  if (!out->supports("ioproxy"))
    throw std::runtime_error("output '" + path + "': format '" + std::string(out->format_name()) +
                             "' cannot be written atomically (use .exr or .png)");
  const fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw std::runtime_error("output folder '" + dir.string() + "' does not exist");
  if (fs::is_directory(target, ec)) throw std::runtime_error("output '" + path + "' is a folder");
  if (::access(dir.c_str(), W_OK | X_OK) != 0)
    throw std::runtime_error("output folder '" + dir.string() + "' is not writable");
}

void write_image_file(const std::string &path, const OIIO::ImageSpec &spec, const void *pixels) {
  check_output_path(path);
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

// A float EXR spec for `names`: the data window is the rendered window (a region writes just its crop), the display
// window the whole image; Combined RGBA first.
OIIO::ImageSpec exr_spec(const RenderResult &r, const std::vector<std::string> &names) {
  const PartInfo &part = r.part;
  const bool windowed = part.window[2] > part.window[0] && part.window[3] > part.window[1] &&
                        part.full_width == r.width && part.full_height == r.height;
  const int wx0 = windowed ? part.window[0] : 0, wy0 = windowed ? part.window[1] : 0;
  OIIO::ImageSpec spec(windowed ? part.window[2] - wx0 : r.width, windowed ? part.window[3] - wy0 : r.height,
                       static_cast<int>(names.size()), OIIO::TypeDesc::FLOAT);
  spec.x = wx0;
  spec.y = wy0;
  spec.full_x = spec.full_y = 0;
  spec.full_width = r.width;
  spec.full_height = r.height;
  spec.channelnames = names;
  spec.alpha_channel = 3;
  return spec;
}

// The pixels of spec's data window, channel k of a pixel from channel(i, k) (i: the pixel's index in the full image).
template <class Channel>
std::vector<float> window_pixels(const OIIO::ImageSpec &spec, int full_width, Channel channel) {
  const int nc = spec.nchannels;
  std::vector<float> pixels(static_cast<size_t>(spec.width) * spec.height * nc);
  for (int y = 0; y < spec.height; ++y)
    for (int x = 0; x < spec.width; ++x) {
      const size_t i = static_cast<size_t>(y + spec.y) * full_width + (x + spec.x);
      float *p = &pixels[(static_cast<size_t>(y) * spec.width + x) * nc];
      for (int k = 0; k < nc; ++k) p[k] = channel(i, k);
    }
  return pixels;
}

}  // namespace

void write_display_image(const std::string &path, const RenderResult &r) {
  OIIO::ImageSpec spec = exr_spec(r, {"R", "G", "B", "A"});
  spec.attribute("compression", "none");
  spec.attribute("glimmer:samples", r.samples_done);
  const auto pixels = window_pixels(spec, r.width, [&r](size_t i, int k) { return r.combined[4 * i + k]; });
  write_image_file(path, spec, pixels.data());
}

void write_image(const std::string &path, const RenderResult &r) {
  const std::string ext = lower_extension(path);
  const size_t npix = static_cast<size_t>(r.width) * r.height;
  if (ext == ".exr") {
    std::vector<std::string> names = exr_channel_names(r.albedo.size() == 3 * npix);
    const bool aovs = names.size() > 4;
    if (r.alpha_sum.size() == npix) names.push_back(kAlphaSumChannel);
    OIIO::ImageSpec spec = exr_spec(r, names);
    spec.z_channel = aovs ? 10 : -1;
    spec.attribute("compression", "zip");
    spec.attribute("glimmer:samples", r.samples_done);
    write_part_metadata(r, spec);
    const auto pixels = window_pixels(spec, r.width, [&r, aovs](size_t i, int k) {
      if (k < 4) return r.combined[4 * i + k];
      if (aovs && k < 7) return r.albedo[3 * i + k - 4];
      if (aovs && k < 10) return r.normal[3 * i + k - 7];
      if (aovs && k == 10) return r.depth[i];
      return r.alpha_sum[i];
    });
    write_image_file(path, spec, pixels.data());
  } else {
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
  if (part.samples_total <= 0)
    throw std::runtime_error("'" + path + "' has no glimmer:samples_total metadata (not written by glimmer render)");
  return r;
}

}  // namespace glimmer::render
