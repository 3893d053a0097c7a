// libFuzzer target: the Cycles XML loader on arbitrary text. Bad input must
// end in SceneError (file:line message); anything else (crash, sanitizer
// report, other exception, hang) is a finding.
#include <cstddef>
#include <cstdint>
#include <string>

#include "scene/xml_loader.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  const std::string text(reinterpret_cast<const char *>(data), size);
  try {
    // A folder without files: relative <include>/<mesh src> find nothing.
    glimmer::scene::load_scene_text(text, "/nonexistent-fuzz-dir/scene.xml");
  } catch (const glimmer::scene::SceneError &) {
  }
  return 0;
}
