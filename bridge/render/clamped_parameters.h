// The shading points where a textured (varying) closure parameter fell outside the parameter's range, as data that
// travels with the image: a render counts them (ShaderSystem, ClampedParameterCount), keeps them in its result, its
// EXR and its checkpoints (the glimmer:clamped_parameters attribute), a resumed render adds the checkpoint's to its
// own, and `glimmer merge` adds the parts' (docs/farm.md). The warning lines are formatted here, for all of them.
// Compiled into the host and into both image modules (bridge/CMakeLists.txt), which encode and decode the attribute.
#pragma once

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace glimmer::render {

// One textured parameter's out-of-range shading points (only parameters with some are recorded).
struct ClampedParameterRecord {
  std::string where;                                        // "scene.xml:20": the <connect> into the parameter
  std::string what;                                         // "<glint_bsdf> 'g' parameter 'density'"
  float min_value = 0.0f, max_value = 0.0f;                 // the parameter's range
  uint64_t below = 0, above = 0;                            // shading points below the minimum, above the maximum
  float lowest = std::numeric_limits<float>::infinity();    // the lowest value below the minimum (+inf: none)
  float highest = -std::numeric_limits<float>::infinity();  // the highest value above the maximum (-inf: none)
};
using ClampedParameterRecords = std::vector<ClampedParameterRecord>;

// Adds `from` into `into`: a record of the same parameter (where, what and range) adds its counts and extends the
// extremes (lowest = min, highest = max); any other is appended, in order.
void add_clamped_records(ClampedParameterRecords &into, const ClampedParameterRecords &from);

// "file:line: warning: ..." per record and direction, with the count, the extreme value and the range.
std::vector<std::string> clamped_parameter_warnings(const ClampedParameterRecords &records);

// The EXR string attribute that holds the records (absent: none, or an image of a build before it existed).
inline constexpr const char *kClampedParametersAttribute = "glimmer:clamped_parameters";
// Version 1: a first line "glimmer-clamped-parameters 1", then one line per record of eight tab-separated fields:
// where, what, min, max, below, above, lowest, highest. Floats in the shortest text that reads back to the same
// float (std::to_chars; "inf" / "-inf" for no extreme); '\\', tab, newline and carriage return in the texts escaped
// as \\ \t \n \r. No records: the empty string.
std::string encode_clamped_records(const ClampedParameterRecords &records);
// The inverse (the empty string: no records). Throws std::runtime_error saying what is wrong with a malformed text
// or another version.
ClampedParameterRecords decode_clamped_records(const std::string &text);

}  // namespace glimmer::render
