// The Principled BSDF's sheen lobe as Blender 3.4 Cycles evaluates it (CLOSURE_BSDF_PRINCIPLED_SHEEN_ID,
// kernel/closure/bsdf_principled_sheen.h, set up by svm_closure.h): Burley 2012's sheen ("Physically Based Shading
// at Disney", sec. 5.3 and the BRDF Explorer's disney.brdf, Fsheen = F_H sheen C_sheen, added without 1 / pi),
//
//   f(wi, wo) cos theta_o = C_sheen (1 - wo.h)^5 cos theta_o,   h = normalize(wi + wo),
//   C_sheen = sheen * mix(1, C_tint, sheen_tint),   C_tint = base_color / luminance(base_color) (1 if 0),
//
// with Rec.709 luminance (Cycles' default scene coefficients). Cycles gives the lobe the weight
// (1 - metallic)(1 - transmission); the host's principled_bsdf composite places it with the diffuse. Sampling is
// the cosine hemisphere (as Cycles), pdf = cos theta_o / pi. Only wi.z >= 0 and wo.z > 0 scatter.
#pragma once

#include <algorithm>
#include <array>

#include "core/closure.h"
#include "core/cosine_lobe.h"
#include "glimmer/microfacet.h"
#include "glimmer/sampling.h"

namespace glimmer::plugin {

namespace principled_sheen {

// C_sheen of the formula above.
inline Spectrum color(const Spectrum &base_color, float sheen, float sheen_tint) {
  const float lum = luminance(base_color);
  const Spectrum tint = lum > 0.0f ? base_color * (1.0f / lum) : Spectrum(1.0f);
  return (Spectrum(1.0f - sheen_tint) + tint * sheen_tint) * sheen;
}

// The Schlick weight at the half vector, (1 - cos theta_d)^5, cos theta_d = wo.h (wi, wo unit vectors). With theta_d
// half the angle between wi and wo, cos theta_d = |wi + wo| / 2 and sin theta_d = |wi - wo| / 2, so
// 1 - cos theta_d = sin^2 theta_d / (1 + cos theta_d): no cancellation when wo is near wi, and symmetric in wi, wo.
inline float shape(const Vec3 &wi, const Vec3 &wo) {
  const float cos_d = 0.5f * length(wi + wo);
  const float one_minus_cos_d = std::clamp(0.25f * dot(wi - wo, wi - wo) / (1.0f + cos_d), 0.0f, 1.0f);
  const float m2 = one_minus_cos_d * one_minus_cos_d;
  return m2 * m2 * one_minus_cos_d;
}

}  // namespace principled_sheen

class PrincipledSheenClosure {
 public:
  static constexpr const char *kName = "principled_sheen";
  static constexpr const char *kDoc =
      "Cycles 3.4 Principled sheen (Burley 2012: sheen * mix(1, tint, sheen_tint) (1 - wo.h)^5, no 1/pi), "
      "cosine-sampled.";
  static constexpr uint32_t kFlags = 0;

  static std::span<const GlimmerParamSpec> params() {
    static const std::array<GlimmerParamSpec, 3> schema{{
        {"base_color", GLIMMER_PARAM_COLOR, {0.8f, 0.8f, 0.8f}, 0.0f, 1.0f, nullptr, nullptr,
         "Principled base colour: the tint is base_color / its Rec.709 luminance", GLIMMER_PARAM_VARYING},
        {"sheen", GLIMMER_PARAM_FLOAT, {0.0f, 0, 0}, 0.0f, 1.0f, nullptr, nullptr,
         "Principled sheen amount (scales the lobe)", GLIMMER_PARAM_VARYING},
        {"sheen_tint", GLIMMER_PARAM_FLOAT, {0.5f, 0, 0}, 0.0f, 1.0f, nullptr, nullptr,
         "Principled sheen tint in [0, 1]: mix of white and the base colour's hue", GLIMMER_PARAM_VARYING},
    }};
    return schema;
  }

  static std::unique_ptr<PrincipledSheenClosure> create(const ParamReader &p) {
    auto c = std::make_unique<PrincipledSheenClosure>();
    c->base_color_ = p.get_color("base_color");
    c->base_color_param_ = p.index("base_color");
    c->sheen_ = p.get_float("sheen");
    c->sheen_param_ = p.index("sheen");
    c->sheen_tint_ = p.get_float("sheen_tint");
    c->sheen_tint_param_ = p.index("sheen_tint");
    return c;
  }

  LocalEval eval(const ShadingPoint &sp, const Vec3 &wo) const {
    if (sp.wi.z < 0.0f) return {};
    return cosine_lobe::eval(wo, [&](const Vec3 &w) { return f_cos(sp, w); });
  }

  bool sample(const ShadingPoint &sp, const Vec3 &rand, LocalSample &out) const {
    if (sp.wi.z < 0.0f) return false;
    return cosine_lobe::sample(rand, [&](const Vec3 &w) { return f_cos(sp, w); }, out);
  }

  // The closure-picking / Albedo estimate: C_sheen times Cycles' average (h = N: (1 - cos theta_i)^5 cos theta_i).
  Spectrum albedo(const ShadingPoint &sp) const {
    const float cos_i = clamp(sp.wi.z, 0.0f, 1.0f);
    return color(sp) * (microfacet::schlick_weight(cos_i) * cos_i);
  }

 private:
  Spectrum color(const ShadingPoint &sp) const {
    const float sheen = std::max(0.0f, sp.param_float(sheen_param_, sheen_));
    const float tint = std::clamp(sp.param_float(sheen_tint_param_, sheen_tint_), 0.0f, 1.0f);
    return principled_sheen::color(max(sp.param_color(base_color_param_, base_color_), Spectrum(0.0f)), sheen, tint);
  }
  Spectrum f_cos(const ShadingPoint &sp, const Vec3 &wo) const {
    return color(sp) * (principled_sheen::shape(sp.wi, wo) * wo.z);
  }

  Spectrum base_color_{0.8f};
  float sheen_ = 0.0f, sheen_tint_ = 0.5f;
  uint32_t base_color_param_ = 0, sheen_param_ = 0, sheen_tint_param_ = 0;
};

}  // namespace glimmer::plugin
