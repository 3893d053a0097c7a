// Pieces shared by the two glint closures (glint.cpp and glint_jakob14.cpp):
// the per-glint weight W of the BRDF and the smooth-lobe sampler whose
// density pdf() returns exactly.
#pragma once

#include <cmath>

#include "glimmer/math.h"
#include "glimmer/microfacet.h"
#include "glimmer/sampling.h"

namespace glimmer::plugin::glint {

namespace mf = glimmer::microfacet;

// W(wi, wo) = F(wi.h) G2(wi, wo) (wi.h) / (cos_i cos_h): the glint BRDF times
// cos(wo) is W times the reflected-direction density (P / sigma for the
// mean, K / (N a sigma) for a count K of reflecting particles). Zero when
// either direction is below the surface.
inline bool glint_weight(mf::Distribution dist, float alpha, const Spectrum &f0, const Vec3 &wi, const Vec3 &wo,
                         Spectrum &weight) {
  if (!(wi.z > 0.0f) || !(wo.z > 0.0f)) return false;
  Vec3 h;
  if (!mf::half_vector_reflect(wi, wo, h)) return false;
  const float wi_h = dot(wi, h);
  if (!(wi_h > 0.0f) || !(h.z > 0.0f)) return false;
  const float g2 = mf::G2(dist, wi, wo, alpha, alpha);
  weight = mf::fresnel_schlick(wi_h, f0) * (g2 * wi_h / (wi.z * h.z));
  return true;
}

// Sampler: visible normals of the smooth lobe at alpha_w (weight 1 - c) mixed
// with cosine sampling (weight c), reflection only.
inline constexpr float kCosineMixture = 0.1f;

inline float smooth_lobe_pdf(mf::Distribution dist, float alpha_w, const Vec3 &wi, const Vec3 &wo) {
  if (!(wi.z > 0.0f) || !(wo.z > 0.0f)) return 0.0f;
  float pdf = kCosineMixture * wo.z * kInvPi;
  Vec3 h;
  if (mf::half_vector_reflect(wi, wo, h) && dot(wi, h) > 0.0f) {
    const float vndf = mf::visible_D(dist, wi, h, alpha_w, alpha_w);
    pdf += (1.0f - kCosineMixture) * vndf / (4.0f * dot(wo, h));
  }
  return pdf;
}

inline bool sample_smooth_lobe(mf::Distribution dist, float alpha_w, const Vec3 &wi, const Vec3 &rand, Vec3 &wo) {
  if (!(wi.z > 0.0f)) return false;
  if (rand.z < kCosineMixture) {
    wo = sample_cosine_hemisphere(rand.x, rand.y);
  } else {
    const Vec3 h = mf::sample_visible_normal(dist, wi, alpha_w, alpha_w, rand.x, rand.y);
    wo = mf::reflect_about(wi, h);
  }
  return wo.z > 0.0f;
}

}  // namespace glimmer::plugin::glint
