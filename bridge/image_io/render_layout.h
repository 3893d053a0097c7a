// How a render (RenderResult) is laid out in an image file, shared by both image modules: the EXR writer
// (exr_writer_openexr.cpp, OpenEXR alone) writes renders, checkpoints and display images; the OIIO module
// (image_io_oiio.cpp) reads them back and writes every other format. Header-only, no image library.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "render/renderer.h"

namespace glimmer::render::image_layout {

// A checkpoint's per-pixel alpha sums (RenderResult::alpha_sum): not a Blender pass.
inline constexpr const char *kAlphaSumChannel = "glimmer.alpha_sum";

// Blender's multilayer names: Combined RGBA first, then (with AOVs) Albedo, Normal, Depth.
inline std::vector<std::string> exr_channel_names(bool aovs) {
  std::vector<std::string> names = {"ViewLayer.Combined.R", "ViewLayer.Combined.G", "ViewLayer.Combined.B",
                                    "ViewLayer.Combined.A"};
  if (aovs) {
    for (const char *c : {"R", "G", "B"}) names.push_back(std::string("ViewLayer.Albedo.") + c);
    for (const char *c : {"X", "Y", "Z"}) names.push_back(std::string("ViewLayer.Normal.") + c);
    names.push_back("ViewLayer.Depth.Z");
  }
  return names;
}

// The pixels a file holds: the rendered window (a region writes just its crop) inside the whole image
// (the display window, origin 0, 0).
struct DataWindow {
  int x = 0, y = 0, width = 0, height = 0;
};

inline DataWindow data_window(const RenderResult &r) {
  const PartInfo &part = r.part;
  const bool windowed = part.window[2] > part.window[0] && part.window[3] > part.window[1] &&
                        part.full_width == r.width && part.full_height == r.height;
  if (!windowed) return {0, 0, r.width, r.height};
  return {part.window[0], part.window[1], part.window[2] - part.window[0], part.window[3] - part.window[1]};
}

// The window's pixels, `nc` interleaved channels, channel k of a pixel from channel(i, k) (i: the pixel's
// index in the full image of width full_width).
template <class Channel>
std::vector<float> window_pixels(const DataWindow &w, int full_width, int nc, Channel channel) {
  std::vector<float> pixels(static_cast<size_t>(w.width) * w.height * nc);
  for (int y = 0; y < w.height; ++y)
    for (int x = 0; x < w.width; ++x) {
      const size_t i = static_cast<size_t>(y + w.y) * full_width + (x + w.x);
      float *p = &pixels[(static_cast<size_t>(y) * w.width + x) * nc];
      for (int k = 0; k < nc; ++k) p[k] = channel(i, k);
    }
  return pixels;
}

}  // namespace glimmer::render::image_layout
