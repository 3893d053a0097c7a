// MicrofacetDielectricClosure (declared in microfacet_dielectric.h, where the model is described) registered
// with the plugin; the header lets the tests use the class directly (raw outputs).
#include "closures/microfacet_dielectric.h"

namespace glimmer::plugin {

GLIMMER_REGISTER_CLOSURE(MicrofacetDielectricClosure)

}  // namespace glimmer::plugin
