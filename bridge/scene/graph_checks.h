// Structural checks of a shader graph as read from XML, before the renderer
// compiles it (docs/scene-format.md, "Limits"):
//  - node names are unique within a shader;
//  - every <connect> names existing nodes and, for the Cycles node types the
//    renderer knows, existing sockets (an input on the `to` side, an output on
//    the `from` side; names compare case-insensitively like Cycles);
//  - links form no cycle (a texture feeding itself through other nodes);
//  - no chain of links is longer than kMaxShaderGraphDepth nodes.
// Each failure throws SceneError at the offending element's file:line.
#pragma once

#include "scene/scene.h"

namespace glimmer::scene {

// Longest accepted chain of linked nodes (output <- closure <- texture <- ...).
constexpr int kMaxShaderGraphDepth = 64;

void validate_shader_graph(const ShaderGraph &graph);

}  // namespace glimmer::scene
