// FrostedGlassClosure (declared in frosted_glass.h, where the model is described) registered with the
// plugin; the header lets the tests use the class directly (raw outputs).
#include "closures/frosted_glass.h"

#include <cstdlib>
#include <cstring>

namespace glimmer::plugin {

GLIMMER_REGISTER_CLOSURE(FrostedGlassClosure)

int FrostedGlassClosure::pane_walk_level() {
  static const int level = [] {
    const char *e = std::getenv("GLIMMER_FROSTED_PANE_WALK");
    if (e != nullptr && std::strcmp(e, "1") == 0) return kPaneWalkResampled;
    return kPaneWalkLobe;  // unset, "0" or anything else: main's walk
  }();
  return level;
}

}  // namespace glimmer::plugin
