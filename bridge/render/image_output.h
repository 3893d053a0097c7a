// Writes a render, atomically: .exr with OpenEXR (the EXR module), other formats with OpenImageIO (the image
// module; render/image_io.h says why both are modules loaded on first use); encoded in memory, then
// written with glimmer/atomic_file.h (random O_EXCL|O_NOFOLLOW temporary
// file in the target folder, fsync, rename).
//  - .exr: float multilayer channels with Blender's names (view layer "ViewLayer"):
//    ViewLayer.Combined.R/G/B/A (premultiplied alpha), ViewLayer.Albedo.R/G/B, ViewLayer.Normal.X/Y/Z,
//    ViewLayer.Depth.Z; a checkpoint adds glimmer.alpha_sum (Combined.A holds the sample counts there).
//    The EXR data window is the rendered window (a --region part holds just its crop) and
//    glimmer:* attributes record the part (scene hash, seed, sample range; render/film.h).
//  - other formats (.png, .jpg, .tif): the Combined pass, sRGB-encoded 8-bit; RGBA with straight
//    alpha where the format has alpha (PNG, TIFF), RGB otherwise (JPEG).
#pragma once

#include <array>
#include <string>
#include <string_view>

#include "render/renderer.h"

namespace glimmer::render {

// Throws std::runtime_error naming the file on failure.
void write_image(const std::string &path, const RenderResult &result);

// The image so far for a viewer (Blender's viewport and render window): the Combined pass only, as plain R, G,
// B, A float channels (premultiplied alpha) in an uncompressed EXR (read with numpy without a decoder), data
// window = the rendered window, glimmer:samples = the samples in it. Written atomically like write_image.
void write_display_image(const std::string &path, const RenderResult &result);

// Reads an EXR written by write_image (a part, a checkpoint or a whole render) back
// into a full-resolution result (zeros outside the data window) with its PartInfo.
// Throws std::runtime_error naming the file when it is not such an image.
RenderResult read_image(const std::string &path);

// Checks before any work that `path` can be written: a known image extension
// whose writer can encode to memory, an existing writable folder, not a
// folder itself. Throws std::runtime_error saying what is wrong. The extensions of
// kKnownWritableExtensions are checked without the image module (so that a render
// need not wait for it to load); any other asks the module.
void check_output_path(const std::string &path);
// The format part of check_output_path alone (an extension the writer can encode), for an output written
// later or elsewhere (`glimmer farm slurm`'s merge job): throws std::runtime_error saying what is wrong.
void check_output_format(const std::string &path);
// Before a render: creates and removes a file in `path`'s folder, since access(W_OK) can pass where no file can be
// created (/proc for root, some FUSE and network mounts) and the render would be lost at the write. Throws
// std::runtime_error naming the folder and the reason.
void check_output_folder_takes_files(const std::string &path);
// Lower case; the test ImageModule.KnownWritableExtensionsAreWritable checks each against the module.
inline constexpr std::array<std::string_view, 2> kKnownWritableExtensions = {".exr", ".png"};
bool known_writable_extension(const std::string &path);
// True when path's extension is .exr (any case): write_image and write_display_image use the EXR module.
bool is_exr_path(const std::string &path);
// Loads the module write_image needs for `path` (a missing or broken one throws std::runtime_error).
void load_output_module(const std::string &path);

// Encodes 8-bit `pixels` (width x height x channels, interleaved, row 0 = top) to the format of `path`'s
// extension and writes the file atomically. Throws std::runtime_error naming the file.
void write_8bit_image(const std::string &path, int width, int height, int channels, const unsigned char *pixels);

// "out_####.png" with frame 7 -> "out_0007.png" (the run of '#' sets the padding).
std::string frame_path(const std::string &pattern, int frame);

}  // namespace glimmer::render
