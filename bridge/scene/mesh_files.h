// Mesh data as read from XML attributes or an external file (<mesh src="x.obj|x.ply">),
// before fan triangulation and transformation (xml_loader.cpp).
#pragma once

#include <string>
#include <vector>

#include "scene/scene.h"

namespace glimmer::scene {

struct RawMesh {
  std::vector<float> P;       // 3 per vertex
  std::vector<int> verts;     // polygon corners
  std::vector<int> nverts;    // corners per polygon
  std::vector<float> uv;      // 2 per corner (uv_per_corner) or per vertex
  std::vector<float> N;       // 3 per vertex (may be empty)
  bool uv_per_corner = true;
};

// Wavefront OBJ (v, vt, vn, f with v/vt/vn indices, negative indices allowed)
// or PLY (ascii / binary_little_endian; vertex x y z [nx ny nz] [u v|s t], face
// vertex_indices). Throws SceneError at `where` for missing or malformed files.
RawMesh read_mesh_file(const std::string &path, const SourceLocation &where);

}  // namespace glimmer::scene
