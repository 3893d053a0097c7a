// Evaluation and sampling of a cosine-sampled reflection lobe (diffuse, principled_diffuse, principled_sheen):
// wo from the cosine hemisphere (pdf cos theta_o / pi), only wo.z > 0 scatters, the value is the closure's
// f * cos(wo) given as a callable. One copy of the steps the three closures share.
#pragma once

#include "core/closure.h"
#include "glimmer/sampling.h"

namespace glimmer::plugin::cosine_lobe {

template <class FCos>
LocalEval eval(const Vec3 &wo, const FCos &f_cos) {
  if (!(wo.z > 0.0f)) return {};
  return {f_cos(wo), cosine_hemisphere_pdf(wo.z)};
}

template <class FCos>
bool sample(const Vec3 &rand, const FCos &f_cos, LocalSample &out) {
  out.wo = sample_cosine_hemisphere(rand.x, rand.y);
  if (!(out.wo.z > 0.0f)) return false;
  out.pdf = cosine_hemisphere_pdf(out.wo.z);
  out.f_cos = f_cos(out.wo);
  out.roughness = 1.0f;
  out.label = GLIMMER_LABEL_REFLECT | GLIMMER_LABEL_DIFFUSE;
  return true;
}

}  // namespace glimmer::plugin::cosine_lobe
