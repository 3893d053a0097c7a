// FrostedGlassClosure (declared in frosted_glass.h, where the model is described) registered with the
// plugin; the header lets the tests use the class directly (raw outputs).
#include "closures/frosted_glass.h"

namespace glimmer::plugin {

GLIMMER_REGISTER_CLOSURE(FrostedGlassClosure)

}  // namespace glimmer::plugin
