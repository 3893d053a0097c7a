// Writes a render with OpenImageIO, atomically (temporary file + rename).
//  - .exr: float multilayer channels with Blender's names (view layer "ViewLayer"):
//    ViewLayer.Combined.R/G/B/A, ViewLayer.Albedo.R/G/B, ViewLayer.Normal.X/Y/Z, ViewLayer.Depth.Z.
//    The EXR data window is the rendered window (a --region part holds just its crop) and
//    glimmer:* attributes record the part (scene hash, seed, sample range; render/film.h).
//  - other formats (.png, .jpg, .tif): the Combined pass, sRGB-encoded 8-bit.
#pragma once

#include <string>

#include "render/renderer.h"

namespace glimmer::render {

// Throws std::runtime_error naming the file on failure.
void write_image(const std::string &path, const RenderResult &result);

// Reads an EXR written by write_image (a part, a checkpoint or a whole render) back
// into a full-resolution result (zeros outside the data window) with its PartInfo.
// Throws std::runtime_error naming the file when it is not such an image.
RenderResult read_image(const std::string &path);

// "out_####.png" with frame 7 -> "out_0007.png" (the run of '#' sets the padding).
std::string frame_path(const std::string &pattern, int frame);

}  // namespace glimmer::render
