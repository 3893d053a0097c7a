// MicrofacetConductorClosure (declared in microfacet_conductor.h, where the model is described) registered
// with the plugin; the header lets the tests use the class directly (raw outputs).
#include "closures/microfacet_conductor.h"

namespace glimmer::plugin {

GLIMMER_REGISTER_CLOSURE(MicrofacetConductorClosure)

}  // namespace glimmer::plugin
