#include "render/image_output.h"

#include <OpenImageIO/imageio.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <stdexcept>

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

}  // namespace

void write_image(const std::string &path, const RenderResult &r) {
  const fs::path target(path);
  std::string ext = target.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (ext.empty()) throw std::runtime_error("output '" + path + "' has no file extension (.exr or .png)");
  const fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
  if (!fs::is_directory(dir)) throw std::runtime_error("output folder '" + dir.string() + "' does not exist");
  std::string temp_name(1, '.');
  temp_name += target.stem().string();
  temp_name += ".tmp";
  temp_name += std::to_string(::getpid());
  temp_name += ext;
  const fs::path temp = dir / temp_name;
  auto out = OIIO::ImageOutput::create(temp.string());
  if (!out) throw std::runtime_error("cannot write '" + path + "': " + OIIO::geterror());
  const size_t npix = static_cast<size_t>(r.width) * r.height;
  bool ok = false;
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
    ok = out->open(temp.string(), spec) && out->write_image(OIIO::TypeDesc::FLOAT, pixels.data()) && out->close();
  } else {
    OIIO::ImageSpec spec(r.width, r.height, 4, OIIO::TypeDesc::UINT8);
    spec.attribute("oiio:ColorSpace", "sRGB");
    std::vector<unsigned char> pixels(npix * 4);
    for (size_t i = 0; i < npix; ++i) {
      for (int k = 0; k < 3; ++k)
        pixels[4 * i + k] = static_cast<unsigned char>(std::lround(srgb_encode(r.combined[4 * i + k]) * 255.0f));
      pixels[4 * i + 3] = static_cast<unsigned char>(std::lround(std::clamp(r.combined[4 * i + 3], 0.0f, 1.0f) * 255.0f));
    }
    ok = out->open(temp.string(), spec) && out->write_image(OIIO::TypeDesc::UINT8, pixels.data()) && out->close();
  }
  if (!ok) {
    const std::string err = out->geterror();
    std::error_code ec;
    fs::remove(temp, ec);
    throw std::runtime_error("cannot write '" + path + "': " + err);
  }
  std::error_code ec;
  fs::rename(temp, target, ec);
  if (ec) {
    fs::remove(temp, ec);
    throw std::runtime_error("cannot move the image into place at '" + path + "'");
  }
}

}  // namespace glimmer::render
