// Every use of OpenImageIO sits in one shared module, libglimmer_image_io.so (bridge/image_io/), which the
// host loads with dlopen on first use instead of linking it: Debian's libOpenImageIO pulls in 260 shared
// libraries whose loading dominated the start-up of every command (docs/architecture.md "Start-up"), so
// commands that read or write no image (describe, lab, ...) no longer pay for it. `glimmer render` loads it
// after preparing the scene and before the render when its output is not an EXR. EXR renders, checkpoints and
// display images are written by a second, light module, libglimmer_exr_io.so (OpenEXR alone, 5 libraries:
// bridge/image_io/exr_writer_openexr.cpp), so a render to .exr loads no OIIO at all. Both modules sit next to
// the glimmer executable (or the test/benchmark binary); $GLIMMER_IMAGE_IO_PATH / $GLIMMER_EXR_IO_PATH
// override the files.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "render/renderer.h"

namespace glimmer::render {

struct UvFootprint;
struct ImageSampling;

// One OIIO TextureSystem (the render's own, not the process-wide shared one).
class TextureFiles {
 public:
  struct Opened {
    void *handle = nullptr;  // the texture system's handle of the file
    int width = 0, height = 0, channels = 0;
    bool srgb = false;  // the handle holds sRGB codes (8/16-bit file read as colour): convert after filtering
  };
  virtual ~TextureFiles() = default;
  // Checks the header of `path` (non-empty, width x height within `max_pixels`, at most 64 channels), then
  // opens it; an sRGB file (8/16-bit, not `linear`) is first written as a MIP map of sRGB codes to
  // scratch_file(). Throws std::runtime_error naming the file.
  virtual Opened open(const std::string &path, bool linear, uint64_t max_pixels,
                      const std::function<std::string()> &scratch_file) = 0;
  // The filtered texel (up to 4 channels, `channels` of the file) at the footprint, given in Cycles'
  // convention with finite (u, v) (v up from the bottom row; the module flips it for OIIO's t). False when
  // the read failed (the texel is then unset).
  virtual bool texture(void *handle, const UvFootprint &at, const ImageSampling &sampling, int channels,
                       float texel[4]) const = 0;
};

// The module's functions (the implementations are in bridge/image_io/image_io_oiio.cpp; the host-side
// wrappers with the documentation are in render/image_output.h, render/textures.h).
class ImageIo {
 public:
  virtual ~ImageIo() = default;
  // Throws std::runtime_error when path's extension names no format that can be encoded to memory.
  virtual void check_output_format(const std::string &path) const = 0;
  // Formats other than EXR (8-bit sRGB PNG, ...); .exr goes to the EXR module (ExrWriter) and is refused here.
  virtual void write_image(const std::string &path, const RenderResult &result) const = 0;
  virtual void write_display_image(const std::string &path, const RenderResult &result) const = 0;
  virtual RenderResult read_image(const std::string &path) const = 0;
  // An 8-bit image of `channels` interleaved channels, encoded for path's extension, written atomically.
  virtual void write_bytes(const std::string &path, int width, int height, int channels,
                           const unsigned char *pixels) const = 0;
  // The beauty pass of an image file as interleaved RGB floats ("<layer>.Combined.R/G/B" of a multilayer
  // EXR, else R, G, B). Throws std::runtime_error naming the file.
  virtual std::vector<float> read_rgb(const std::string &path, int &width, int &height) const = 0;
  // Draws `text` into an interleaved RGB float image (OIIO's render_text; `font` a file, empty: OIIO's default).
  virtual void draw_text(float *rgb, int width, int height, int x, int y, const std::string &text, int size,
                         const std::string &font, const float colour[3]) const = 0;
  virtual std::unique_ptr<TextureFiles> create_texture_files() const = 0;
};

// The module's entry point (extern "C", looked up with dlsym).
constexpr const char *kImageIoEntry = "glimmer_image_io";
constexpr const char *kImageIoFileName = "libglimmer_image_io.so";
using ImageIoEntry = const ImageIo *(*)();

// The module, loaded on first use (thread safe). Throws std::runtime_error naming the
// file and the loader's message when it cannot be loaded.
const ImageIo &image_io();

// The EXR module's functions (bridge/image_io/exr_writer_openexr.cpp; the file layout, shared with the OIIO
// module's reader, in bridge/image_io/render_layout.h).
class ExrWriter {
 public:
  virtual ~ExrWriter() = default;
  // Multilayer float EXR (ViewLayer.Combined.RGBA, AOVs, a checkpoint's alpha sums), ZIP, glimmer:* metadata.
  virtual void write_image(const std::string &path, const RenderResult &result) const = 0;
  // Plain float R, G, B, A, uncompressed.
  virtual void write_display_image(const std::string &path, const RenderResult &result) const = 0;
};

constexpr const char *kExrWriterEntry = "glimmer_exr_writer";
constexpr const char *kExrWriterFileName = "libglimmer_exr_io.so";
using ExrWriterEntry = const ExrWriter *(*)();

// The EXR module, loaded on first use (thread safe); errors as image_io().
const ExrWriter &exr_writer();

}  // namespace glimmer::render
