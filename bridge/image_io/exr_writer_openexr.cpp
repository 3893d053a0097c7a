// libglimmer_exr_io.so: writes renders, checkpoints and display images as float EXR with OpenEXR alone
// (OpenEXR, Iex, IlmThread, Imath, zlib), so that `glimmer render -o image.exr` does not load the OIIO module
// and its 260 libraries (render/image_io.h, docs/architecture.md "Start-up"). Encoded in memory, then written
// with glimmer/atomic_file.h as every image output. The OIIO module reads these files back (read_image).
#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfIO.h>
#include <ImfIntAttribute.h>
#include <ImfOutputFile.h>
#include <ImfStringAttribute.h>

#include <cstring>
#include <exception>
#include <stdexcept>
#include <string>
#include <vector>

#include "glimmer/atomic_file.h"
#include "image_io/render_layout.h"
#include "render/clamped_parameters.h"
#include "render/image_io.h"

namespace glimmer::render::exr_module {

namespace {

using namespace image_layout;

// An OpenEXR output stream into memory (OutputFile seeks back to fill in the line offset table).
class MemoryStream final : public Imf::OStream {
 public:
  MemoryStream() : Imf::OStream("memory") {}
  void write(const char c[], int n) override {
    if (position_ + n > bytes_.size()) bytes_.resize(position_ + n);
    std::memcpy(bytes_.data() + position_, c, static_cast<size_t>(n));
    position_ += static_cast<uint64_t>(n);
  }
  uint64_t tellp() override { return position_; }
  void seekp(uint64_t position) override { position_ = position; }
  const std::vector<char> &bytes() const { return bytes_; }

 private:
  std::vector<char> bytes_;
  uint64_t position_ = 0;
};

// glimmer:* attributes: what part of which render the image holds (render/film.h PartInfo).
void write_part_metadata(const RenderResult &r, Imf::Header &header) {
  const PartInfo &p = r.part;
  auto set_int = [&header](const char *name, int v) { header.insert(name, Imf::IntAttribute(v)); };
  auto set_string = [&header](const char *name, const std::string &v) { header.insert(name, Imf::StringAttribute(v)); };
  if (!p.scene_hash.empty()) set_string("glimmer:scene_hash", p.scene_hash);
  set_string("glimmer:strategy", p.strategy);
  set_int("glimmer:seed", p.seed);
  set_int("glimmer:samples_total", p.samples_total);
  set_int("glimmer:sample_begin", p.sample_begin);
  set_int("glimmer:sample_end", p.sample_end);
  set_int("glimmer:incomplete", r.samples_done != p.sample_end - p.sample_begin || r.interrupted ? 1 : 0);
  set_string("glimmer:nan_samples", std::to_string(r.nan_samples));
  set_string("glimmer:paths", std::to_string(r.paths));
  if (r.film_sums) set_int("glimmer:checkpoint", 1);
  // The out-of-range textured values counted over the image's samples (merge and --resume add them up).
  if (!r.clamped_parameters.empty())
    set_string(kClampedParametersAttribute, encode_clamped_records(r.clamped_parameters));
}

// A float EXR header for `names` over the render's data window (the display window is the whole image).
Imf::Header float_header(const RenderResult &r, const DataWindow &w, const std::vector<std::string> &names,
                         Imf::Compression compression) {
  const Imath::Box2i display(Imath::V2i(0, 0), Imath::V2i(r.width - 1, r.height - 1));
  const Imath::Box2i data(Imath::V2i(w.x, w.y), Imath::V2i(w.x + w.width - 1, w.y + w.height - 1));
  Imf::Header header(display, data);
  header.compression() = compression;
  for (const auto &n : names) header.channels().insert(n, Imf::Channel(Imf::FLOAT));
  return header;
}

// Encodes `pixels` (the data window, names.size() interleaved floats per pixel) and writes the file atomically.
void write_exr(const std::string &path, const Imf::Header &header, const std::vector<std::string> &names,
               const std::vector<float> &pixels) {
  MemoryStream memory;
  try {
    const size_t nc = names.size(), x_stride = nc * sizeof(float);
    const Imath::Box2i &data = header.dataWindow();
    const size_t y_stride = x_stride * static_cast<size_t>(data.max.x - data.min.x + 1);
    Imf::FrameBuffer frame;
    for (size_t k = 0; k < nc; ++k)
      frame.insert(names[k], Imf::Slice::Make(Imf::FLOAT, pixels.data() + k, data, x_stride, y_stride));
    Imf::OutputFile file(memory, header, 0);  // no OpenEXR thread pool: 96x96 to 4K lines encode in ms
    file.setFrameBuffer(frame);
    file.writePixels(data.max.y - data.min.y + 1);
  } catch (const std::exception &e) {
    throw std::runtime_error("cannot encode '" + path + "': " + e.what());
  }
  const std::string problem = write_file_atomically(path, memory.bytes().data(), memory.bytes().size());
  if (!problem.empty()) throw std::runtime_error(problem);
}

}  // namespace

class OpenExrWriter final : public ExrWriter {
 public:
  // Combined RGBA, the AOVs when the render has them, a checkpoint's alpha sums; ZIP, glimmer:* metadata.
  void write_image(const std::string &path, const RenderResult &r) const override {
    const size_t npix = static_cast<size_t>(r.width) * r.height;
    std::vector<std::string> names = exr_channel_names(r.albedo.size() == 3 * npix);
    const bool aovs = names.size() > 4;
    if (r.alpha_sum.size() == npix) names.push_back(kAlphaSumChannel);
    const DataWindow w = data_window(r);
    Imf::Header header = float_header(r, w, names, Imf::ZIP_COMPRESSION);
    header.insert("glimmer:samples", Imf::IntAttribute(r.samples_done));
    write_part_metadata(r, header);
    const auto pixels = window_pixels(w, r.width, static_cast<int>(names.size()), [&r, aovs](size_t i, int k) {
      if (k < 4) return r.combined[4 * i + k];
      if (aovs && k < 7) return r.albedo[3 * i + k - 4];
      if (aovs && k < 10) return r.normal[3 * i + k - 7];
      if (aovs && k == 10) return r.depth[i];
      return r.alpha_sum[i];
    });
    write_exr(path, header, names, pixels);
  }
  // Plain R, G, B, A, uncompressed (a viewer reloads it while the render runs).
  void write_display_image(const std::string &path, const RenderResult &r) const override {
    const std::vector<std::string> names = {"R", "G", "B", "A"};
    const DataWindow w = data_window(r);
    Imf::Header header = float_header(r, w, names, Imf::NO_COMPRESSION);
    header.insert("glimmer:samples", Imf::IntAttribute(r.samples_done));
    const auto pixels = window_pixels(w, r.width, 4, [&r](size_t i, int k) { return r.combined[4 * i + k]; });
    write_exr(path, header, names, pixels);
  }
};

}  // namespace glimmer::render::exr_module

extern "C" __attribute__((visibility("default"))) const glimmer::render::ExrWriter *glimmer_exr_writer() {
  static const glimmer::render::exr_module::OpenExrWriter writer;
  return &writer;
}
