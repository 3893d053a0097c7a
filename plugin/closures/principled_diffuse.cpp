// PrincipledDiffuseClosure (declared in principled_diffuse.h, where the model is described) registered with the
// plugin; the header lets the tests use the formula directly.
#include "closures/principled_diffuse.h"

namespace glimmer::plugin {

GLIMMER_REGISTER_CLOSURE(PrincipledDiffuseClosure)

}  // namespace glimmer::plugin
