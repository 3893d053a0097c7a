// glint's Beckmann visible-normal sampler in its own unit (see the header).
#include "tables/glint_beckmann_vndf.h"

namespace glimmer::plugin::glint::beckmann_vndf {

Vec3 draw_visible_normal(const Vec3 &wi, float ax, float ay, float u1, float u2) {
  return sample_visible_normal(wi, ax, ay, u1, u2);
}

}  // namespace glimmer::plugin::glint::beckmann_vndf
