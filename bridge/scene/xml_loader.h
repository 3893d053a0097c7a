// Cycles standalone XML reader (Cycles' src/app/cycles_xml.cpp conventions).
// Errors (malformed XML, missing files, bad numbers) throw SceneError whose
// message starts with file:line; unknown nodes and attributes become warnings
// in Scene::warnings with a documented fallback (docs/scene-format.md).
#pragma once

#include <atomic>
#include <string>

#include "scene/scene.h"

namespace glimmer::scene {

// Depth limits on what the input nests (each violation is a file:line error).
constexpr int kMaxIncludeDepth = 32;       // <include> inside included files
constexpr size_t kMaxIncludedFiles = 4096;  // files read for one scene
constexpr int kMaxTransformDepth = 256;     // nested <transform>
constexpr int kMaxStateDepth = 256;         // nested <state>

// Thrown when `cancel` became true while loading (SIGINT/SIGTERM).
class LoadCancelled : public SceneError {
 public:
  using SceneError::SceneError;
};

// `cancel` (may be null) is polled per element and per mesh line.
Scene load_scene(const std::string &path, const std::atomic<bool> *cancel = nullptr);

// `text` loaded as if it were the content of the file at `path` (includes and
// meshes resolve relative to its folder); for the fuzz targets and tests.
Scene load_scene_text(const std::string &text, const std::string &path);

// Parses whitespace/comma separated floats; throws SceneError at `where`
// naming the attribute when a token is not a number.
std::vector<float> parse_floats(const std::string &text, const SourceLocation &where, const std::string &what);

}  // namespace glimmer::scene
