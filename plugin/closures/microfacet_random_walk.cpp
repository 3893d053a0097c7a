// MicrofacetRandomWalkClosure (declared in microfacet_random_walk.h, where the model is described) registered
// with the plugin; the header lets the tests use the class directly (raw outputs).
#include "closures/microfacet_random_walk.h"

namespace glimmer::plugin {

GLIMMER_REGISTER_CLOSURE(MicrofacetRandomWalkClosure)

}  // namespace glimmer::plugin
