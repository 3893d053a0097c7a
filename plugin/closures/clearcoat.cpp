// ClearcoatClosure (declared in clearcoat.h, where the model is described) registered with the plugin; the header
// lets the tests use the lobe's D and sampling directly.
#include "closures/clearcoat.h"

namespace glimmer::plugin {

GLIMMER_REGISTER_CLOSURE(ClearcoatClosure)

}  // namespace glimmer::plugin
