// PrincipledSpecularClosure (declared in principled_specular.h, where the model is described) registered with the
// plugin; the header lets the tests use the Fresnel blend directly.
#include "closures/principled_specular.h"

namespace glimmer::plugin {

GLIMMER_REGISTER_CLOSURE(PrincipledSpecularClosure)

}  // namespace glimmer::plugin
