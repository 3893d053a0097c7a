// Sampling steps shared by the Principled BSDF's microfacet reflection lobes (clearcoat.h, principled_specular.h):
// the perfect mirror Cycles uses below alpha^2 1e-7, and the reflection about a sampled microfacet normal.
#pragma once

#include "core/closure.h"
#include "glimmer/microfacet.h"

namespace glimmer::plugin::principled_reflection {

// Cycles treats alpha_x * alpha_y <= 1e-7 as a perfect mirror (roughness below about 0.0178 for alpha = r^2).
inline constexpr float kSingularAlpha2 = 1e-7f;

// The mirror direction of wi (wi.z > 0) with the delta weight `weight` (Cycles: the Fresnel at wi.n).
inline bool sample_mirror(const Vec3 &wi, const Spectrum &weight, LocalSample &out) {
  out.wo = Vec3(-wi.x, -wi.y, wi.z);
  out.f_cos = weight;
  out.pdf = 1.0f;
  out.roughness = 0.0f;
  out.label = GLIMMER_LABEL_REFLECT | GLIMMER_LABEL_SINGULAR;
  return true;
}

// wo = reflect(wi, m) for a sampled microfacet normal m, its value and pdf from lobe.eval(wi, wo) (Walter 2007
// eq. 14: the lobe's eval carries the half-vector Jacobian). False when m faces away from wi or wo is below.
template <class Lobe>
bool sample_reflection_about(const Lobe &lobe, const Vec3 &wi, const Vec3 &m, float roughness, LocalSample &out) {
  if (!(dot(wi, m) > 0.0f)) return false;
  out.wo = normalize(microfacet::reflect_about(wi, m));
  if (!(out.wo.z > 0.0f)) return false;
  const LocalEval e = lobe.eval(wi, out.wo);
  out.f_cos = e.f_cos;
  out.pdf = e.pdf;
  out.roughness = roughness;
  out.label = GLIMMER_LABEL_REFLECT | GLIMMER_LABEL_GLOSSY;
  return out.pdf > 0.0f;
}

}  // namespace glimmer::plugin::principled_reflection
