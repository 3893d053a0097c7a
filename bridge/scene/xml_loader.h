// Cycles standalone XML reader (Cycles' src/app/cycles_xml.cpp conventions).
// Errors (malformed XML, missing files, bad numbers) throw SceneError whose
// message starts with file:line; unknown nodes and attributes become warnings
// in Scene::warnings with a documented fallback (docs/scene-format.md).
#pragma once

#include <string>

#include "scene/scene.h"

namespace glimmer::scene {

Scene load_scene(const std::string &path);

// Parses whitespace/comma separated floats; throws SceneError at `where`
// naming the attribute when a token is not a number.
std::vector<float> parse_floats(const std::string &text, const SourceLocation &where, const std::string &what);

}  // namespace glimmer::scene
