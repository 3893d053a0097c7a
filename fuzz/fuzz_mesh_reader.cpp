// libFuzzer target: a mesh reader on arbitrary bytes, built twice
// (fuzz_obj_reader, fuzz_ply_reader) with GLIMMER_FUZZ_MESH_EXTENSION "obj"
// or "ply". Bad input must end in SceneError naming the file and line;
// anything else (crash, sanitizer report, other exception, hang) is a finding.
#include <cstddef>
#include <cstdint>
#include <string>

#include "scene/mesh_files.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  const std::string text(reinterpret_cast<const char *>(data), size);
  try {
    glimmer::scene::parse_mesh_text(text, "fuzz." GLIMMER_FUZZ_MESH_EXTENSION,
                                    glimmer::scene::SourceLocation{"fuzz.xml", 1});
  } catch (const glimmer::scene::SceneError &) {
  }
  return 0;
}
