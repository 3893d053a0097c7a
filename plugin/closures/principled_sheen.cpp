// PrincipledSheenClosure (declared in principled_sheen.h, where the model is described) registered with the
// plugin; the header lets the tests use the formula directly.
#include "closures/principled_sheen.h"

namespace glimmer::plugin {

GLIMMER_REGISTER_CLOSURE(PrincipledSheenClosure)

}  // namespace glimmer::plugin
