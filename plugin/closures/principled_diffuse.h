// The Principled BSDF's diffuse lobe as Blender 3.4 Cycles evaluates it (CLOSURE_BSDF_PRINCIPLED_DIFFUSE_ID,
// kernel/closure/bsdf_principled_diffuse.h, components PRINCIPLED_DIFFUSE_FULL, set up by svm_closure.h with the
// Principled node's roughness): Burley's diffuse with retro-reflection,
//
//   f(wi, wo) = color / pi * [ (1 - F_L / 2)(1 - F_V / 2) + R_R (F_L + F_V + F_L F_V (R_R - 1)) ]
//
// (Burley 2015, "Extending the Disney BRDF to a BSDF with Integrated Subsurface Scattering", sec. 2.3, eqs. 4-5;
// the 2012 course notes' eq. 3 without the separated sheen), with the Schlick weights F_L = (1 - cos theta_L)^5,
// F_V = (1 - cos theta_V)^5 and R_R = 2 roughness cos^2 theta_d, cos theta_d = wi.h; Cycles writes
// 2 cos^2 theta_d = 1 + wi.wo, which needs no half vector. The roughness is the Principled roughness itself (not
// squared). Sampling is the cosine hemisphere (as Cycles), pdf = cos theta_o / pi. Only wo.z > 0 scatters (the
// host orients N toward wi, as for the Lambert closure).
#pragma once

#include <algorithm>
#include <array>

#include "core/closure.h"
#include "core/cosine_lobe.h"
#include "glimmer/microfacet.h"
#include "glimmer/sampling.h"

namespace glimmer::plugin {

namespace principled_diffuse {

// The bracket of the formula above (f = color / pi * shape): cos_i = wi.z, cos_o = wo.z, cos_io = wi.wo.
inline float shape(float cos_i, float cos_o, float cos_io, float roughness) {
  const float f_v = microfacet::schlick_weight(cos_i);
  const float f_l = microfacet::schlick_weight(cos_o);
  const float lambert = (1.0f - 0.5f * f_l) * (1.0f - 0.5f * f_v);
  const float rr = roughness * (1.0f + cos_io);  // 2 roughness cos^2 theta_d
  const float retro = rr * (f_l + f_v + f_l * f_v * (rr - 1.0f));
  return std::max(0.0f, lambert + retro);
}

}  // namespace principled_diffuse

class PrincipledDiffuseClosure {
 public:
  static constexpr const char *kName = "principled_diffuse";
  static constexpr const char *kDoc =
      "Cycles 3.4 Principled diffuse (Burley 2015 diffuse with retro-reflection, R_R = 2 roughness cos^2 theta_d), "
      "cosine-sampled.";
  static constexpr uint32_t kFlags = 0;

  static std::span<const GlimmerParamSpec> params() {
    static const std::array<GlimmerParamSpec, 2> schema{{
        {"color", GLIMMER_PARAM_COLOR, {0.8f, 0.8f, 0.8f}, 0.0f, 1.0f, nullptr, nullptr,
         "base colour per RGB channel, 0..1", GLIMMER_PARAM_VARYING},
        {"roughness", GLIMMER_PARAM_FLOAT, {0.5f, 0, 0}, 0.0f, 1.0f, nullptr, nullptr,
         "Principled roughness in [0, 1]: the retro-reflection R_R = 2 roughness cos^2 theta_d",
         GLIMMER_PARAM_VARYING},
    }};
    return schema;
  }

  static std::unique_ptr<PrincipledDiffuseClosure> create(const ParamReader &p) {
    auto c = std::make_unique<PrincipledDiffuseClosure>();
    c->color_ = p.get_color("color");
    c->color_param_ = p.index("color");
    c->roughness_ = p.get_float("roughness");
    c->roughness_param_ = p.index("roughness");
    return c;
  }

  LocalEval eval(const ShadingPoint &sp, const Vec3 &wo) const {
    return cosine_lobe::eval(wo, [&](const Vec3 &w) { return f_cos(sp, w); });
  }

  bool sample(const ShadingPoint &sp, const Vec3 &rand, LocalSample &out) const {
    return cosine_lobe::sample(rand, [&](const Vec3 &w) { return f_cos(sp, w); }, out);
  }

  // The closure-picking / Albedo estimate: the colour (as Cycles' sample weight).
  Spectrum albedo(const ShadingPoint &sp) const { return color(sp); }

 private:
  Spectrum color(const ShadingPoint &sp) const { return sp.param_color(color_param_, color_); }
  float roughness(const ShadingPoint &sp) const {
    return std::clamp(sp.param_float(roughness_param_, roughness_), 0.0f, 1.0f);
  }
  Spectrum f_cos(const ShadingPoint &sp, const Vec3 &wo) const {
    const float cos_i = clamp(sp.wi.z, 0.0f, 1.0f);
    const float s = principled_diffuse::shape(cos_i, wo.z, dot(sp.wi, wo), roughness(sp));
    return color(sp) * (s * wo.z * kInvPi);
  }

  Spectrum color_{0.8f};
  float roughness_ = 0.5f;
  uint32_t color_param_ = 0, roughness_param_ = 0;
};

}  // namespace glimmer::plugin
