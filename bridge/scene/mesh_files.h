// Mesh data as read from XML attributes or an external file (<mesh src="x.obj|x.ply">),
// before fan triangulation and transformation (xml_loader.cpp).
#pragma once

#include <atomic>
#include <string>
#include <vector>

#include "scene/scene.h"
#include "scene/xml_loader.h"

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
// The file must be a regular file (no FIFO/device/directory) of at most
// kMaxMeshFileBytes; numbers are parsed strictly (parse_number.h); `cancel`
// (may be null) is polled every few thousand lines (throws LoadCancelled).
RawMesh read_mesh_file(const std::string &path, const SourceLocation &where,
                       const std::atomic<bool> *cancel = nullptr);

// The same readers on `text` as the content of `path` (.obj or .ply by its
// extension); for the fuzz targets.
RawMesh parse_mesh_text(const std::string &text, const std::string &path, const SourceLocation &where,
                        const std::atomic<bool> *cancel = nullptr);

}  // namespace glimmer::scene
