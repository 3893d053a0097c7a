// Writes a render with OpenImageIO, atomically (temporary file + rename).
//  - .exr: float multilayer channels with Blender's names (view layer "ViewLayer"):
//    ViewLayer.Combined.R/G/B/A, ViewLayer.Albedo.R/G/B, ViewLayer.Normal.X/Y/Z, ViewLayer.Depth.Z.
//  - other formats (.png, .jpg, .tif): the Combined pass, sRGB-encoded 8-bit.
#pragma once

#include <string>

#include "render/renderer.h"

namespace glimmer::render {

// Throws std::runtime_error naming the file on failure.
void write_image(const std::string &path, const RenderResult &result);

// "out_####.png" with frame 7 -> "out_0007.png" (the run of '#' sets the padding).
std::string frame_path(const std::string &pattern, int frame);

}  // namespace glimmer::render
