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

void write_image(const std::string &path, const RenderResult &r) {
  const std::string ext = lower_extension(path);
  const size_t npix = static_cast<size_t>(r.width) * r.height;
  if (ext == ".exr") {
    std::vector<std::string> names = {"ViewLayer.Combined.R", "ViewLayer.Combined.G", "ViewLayer.Combined.B",
                                      "ViewLayer.Combined.A"};
    const bool aovs = r.albedo.size() == 3 * npix;
    if (aovs) {
      for (const char *c : {"R", "G", "B"}) names.push_back(std::string("ViewLayer.Albedo.") + c);
      for (const char *c : {"X", "Y", "Z"}) names.push_back(std::string("ViewLayer.Normal.") + c);
      names.push_back("ViewLayer.Depth.Z");
    }
    const int nc = static_cast<int>(names.size());
    OIIO::ImageSpec spec(r.width, r.height, nc, OIIO::TypeDesc::FLOAT);
    spec.channelnames = names;
    spec.alpha_channel = 3;
    spec.z_channel = aovs ? nc - 1 : -1;
    spec.attribute("compression", "zip");
    spec.attribute("glimmer:samples", r.samples_done);
    std::vector<float> pixels(npix * nc);
    for (size_t i = 0; i < npix; ++i) {
      float *p = &pixels[i * nc];
      for (int k = 0; k < 4; ++k) p[k] = r.combined[4 * i + k];
      if (aovs) {
        for (int k = 0; k < 3; ++k) p[4 + k] = r.albedo[3 * i + k];
        for (int k = 0; k < 3; ++k) p[7 + k] = r.normal[3 * i + k];
        p[10] = r.depth[i];
      }
    }
    write_image_file(path, spec, pixels.data());
  } else {
    OIIO::ImageSpec spec(r.width, r.height, 4, OIIO::TypeDesc::UINT8);
    spec.attribute("oiio:ColorSpace", "sRGB");
    std::vector<unsigned char> pixels(npix * 4);
    for (size_t i = 0; i < npix; ++i) {
      for (int k = 0; k < 3; ++k)
        pixels[4 * i + k] = static_cast<unsigned char>(std::lround(srgb_encode(r.combined[4 * i + k]) * 255.0f));
      pixels[4 * i + 3] = static_cast<unsigned char>(std::lround(std::clamp(r.combined[4 * i + 3], 0.0f, 1.0f) * 255.0f));
    }
    write_image_file(path, spec, pixels.data());
  }
}

}  // namespace glimmer::render
