// The Principled BSDF's specular lobe as Blender 3.4 Cycles evaluates it (CLOSURE_BSDF_MICROFACET_GGX_FRESNEL_ID,
// kernel/closure/bsdf_microfacet.h, set up by svm_closure.h's Principled case for the GGX distribution):
//
//   f(wi, wo) = F(wo.m) D(m) G1(wi) G1(wo) / (4 |wi.n| |wo.n|),   m = normalize(wi + wo)    (Walter 2007 eq. 20)
//
//  - D: isotropic GGX, alpha = roughness^2 (Walter 2007 eq. 33); G1: separable Smith GGX masking (eq. 34).
//  - F: Cycles' "interpolate_fresnel_color": the dielectric Fresnel F_d of the IOR the Principled `specular`
//    implies, eta = 2 / (1 - sqrt(0.08 specular)) - 1 (so F_d(1) = F0 = 0.08 specular), rescaled to a blend
//    factor t = (F_d(wo.m) - F0) / (1 - F0) from the colour cspec0 at normal incidence to white at grazing:
//      F = cspec0 (1 - t) + t,
//    cspec0 = saturate(mix(0.08 specular mix(1, tint, specular_tint), base_color, metallic)),
//    tint = base_color / lum, lum = 0.3 r + 0.6 g + 0.1 b (tint = 1 when lum = 0) (Burley 2012 sec. 5.6).
//  - Like Cycles, alpha^2 <= 1e-7 (roughness <= 0.0178) is a perfect mirror weighted F(wi.n).
// Sampling: GGX visible normals (Heitz 2018), pdf = D_wi(m) / (4 wo.m); the estimate for closure picking is
// F(wi.n), as Cycles' sample weight. Only wi.z > 0 and wo.z > 0 scatter. The host applies the Principled
// node's specular weight (1 - transmission (1 - metallic)) as the closure weight (render/principled.cpp).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>

#include "closures/principled_reflection.h"
#include "core/closure.h"
#include "glimmer/microfacet.h"

namespace glimmer::plugin {

namespace principled_specular {

// Disney's `specular` scales the dielectric normal-incidence reflectance: F0 = 0.08 specular (Burley 2012 sec. 5.6).
inline constexpr float kSpecularToF0 = 0.08f;
// F0 is kept below 1 so that the implied IOR stays finite (specular < 12.4).
inline constexpr float kMaxF0 = 0.99f;

// The dielectric normal-incidence reflectance of `specular`.
inline float specular_f0(float specular) { return std::clamp(kSpecularToF0 * specular, 0.0f, kMaxF0); }

// The IOR whose dielectric Fresnel at normal incidence is f0: ((eta - 1) / (eta + 1))^2 = f0.
inline float ior_from_f0(float f0) { return 2.0f / (1.0f - std::sqrt(f0)) - 1.0f; }

// The colour at normal incidence (Cycles 3.4's cspec0), saturated as Cycles' fresnel setup does.
inline Spectrum cspec0(const Spectrum &base_color, float metallic, float specular, float specular_tint) {
  const float lum = 0.3f * base_color.x + 0.6f * base_color.y + 0.1f * base_color.z;
  const Spectrum tint = lum > 0.0f ? base_color / lum : Spectrum(1.0f);
  const Spectrum dielectric = kSpecularToF0 * specular * (Spectrum(1.0f - specular_tint) + tint * specular_tint);
  const Spectrum c = dielectric * (1.0f - metallic) + base_color * metallic;
  return {saturate(c.x), saturate(c.y), saturate(c.z)};
}

// F at cos_h = wo.m: cspec0 blended toward white by the normalised dielectric Fresnel of eta (F0 = f0).
inline Spectrum interpolated_fresnel(float cos_h, float eta, float f0, const Spectrum &c0) {
  const float t = (microfacet::fresnel_dielectric(cos_h, eta) - f0) / (1.0f - f0);
  return c0 * (1.0f - t) + Spectrum(t);
}

}  // namespace principled_specular

class PrincipledSpecularClosure : public OneLobeClosure<PrincipledSpecularClosure> {
 public:
  static constexpr const char *kName = "principled_specular";
  static constexpr const char *kDoc =
      "Cycles 3.4 Principled specular: GGX (alpha = roughness^2, separable Smith G) with Fresnel interpolated from "
      "cspec0 = mix(0.08 specular mix(1, tint, specular_tint), base_color, metallic) toward 1 following the "
      "dielectric Fresnel of the IOR with F0 = 0.08 specular.";
  static constexpr uint32_t kFlags = 0;

  static std::span<const GlimmerParamSpec> params() {
    static const std::array<GlimmerParamSpec, 5> schema{{
        {"base_color", GLIMMER_PARAM_COLOR, {0.8f, 0.8f, 0.8f}, 0.0f, 1.0f, nullptr, nullptr,
         "Principled base colour: the metal's cspec0 and the specular tint's hue", GLIMMER_PARAM_VARYING},
        {"metallic", GLIMMER_PARAM_FLOAT, {0.0f, 0, 0}, 0.0f, 1.0f, nullptr, nullptr,
         "mixes cspec0 from the dielectric 0.08 specular (0) to base_color (1)", GLIMMER_PARAM_VARYING},
        {"specular", GLIMMER_PARAM_FLOAT, {0.5f, 0, 0}, 0.0f, 12.0f, nullptr, nullptr,
         "dielectric F0 = 0.08 specular; the Fresnel curve's IOR 2 / (1 - sqrt(F0)) - 1", GLIMMER_PARAM_VARYING},
        {"specular_tint", GLIMMER_PARAM_FLOAT, {0.0f, 0, 0}, 0.0f, 1.0f, nullptr, nullptr,
         "tints the dielectric F0 toward the base colour's hue (base_color / luminance)", GLIMMER_PARAM_VARYING},
        {"roughness", GLIMMER_PARAM_FLOAT, {0.5f, 0, 0}, 0.0f, 1.0f, nullptr, nullptr,
         "Principled roughness; GGX alpha = roughness^2 (alpha^2 <= 1e-7: mirror)", GLIMMER_PARAM_VARYING},
    }};
    return schema;
  }

  struct Lobe {
    float alpha = 0.25f;
    bool singular = false;
    float f0 = 0.04f, eta = 1.5f;
    Spectrum c0{0.04f};

    void build(const Spectrum &base_color, float metallic, float specular, float specular_tint, float roughness) {
      roughness = std::clamp(roughness, 0.0f, 1.0f);
      alpha = std::clamp(roughness * roughness, microfacet::kMinAlpha, 1.0f);
      singular = roughness * roughness * roughness * roughness <= principled_reflection::kSingularAlpha2;
      f0 = principled_specular::specular_f0(specular);
      eta = principled_specular::ior_from_f0(f0);
      c0 = principled_specular::cspec0(base_color, saturate(metallic), std::max(specular, 0.0f),
                                       saturate(specular_tint));
    }

    Spectrum fresnel(float cos_h) const { return principled_specular::interpolated_fresnel(cos_h, eta, f0, c0); }

    LocalEval eval(const Vec3 &wi, const Vec3 &wo) const {
      Vec3 m;
      if (singular || !(wi.z > 0.0f) || !(wo.z > 0.0f) || !microfacet::half_vector_reflect(wi, wo, m)) return {};
      const float cos_om = dot(wo, m);
      if (!(cos_om > 0.0f)) return {};
      const auto ggx = microfacet::Distribution::GGX;
      const float D = microfacet::D(ggx, m, alpha, alpha);
      const float G1_i = microfacet::G1(ggx, wi, alpha, alpha), G1_o = microfacet::G1(ggx, wo, alpha, alpha);
      LocalEval e;
      e.f_cos = fresnel(cos_om) * (D * G1_i * G1_o / (4.0f * wi.z));
      e.pdf = microfacet::visible_D(ggx, wi, m, alpha, alpha) / (4.0f * cos_om);
      return e;
    }

    bool sample(const Vec3 &wi, const Vec3 &rand, LocalSample &out) const {
      if (!(wi.z > 0.0f)) return false;
      if (singular) return principled_reflection::sample_mirror(wi, fresnel(wi.z), out);
      const Vec3 m =
          microfacet::sample_visible_normal(microfacet::Distribution::GGX, wi, alpha, alpha, rand.x, rand.y);
      return principled_reflection::sample_reflection_about(*this, wi, m, alpha, out);
    }

    Spectrum albedo(const Vec3 &wi) const { return fresnel(clamp(wi.z, 0.0f, 1.0f)); }
  };

  static std::unique_ptr<PrincipledSpecularClosure> create(const ParamReader &p) {
    auto c = std::make_unique<PrincipledSpecularClosure>();
    c->base_color_ = p.get_color("base_color");
    c->metallic_ = p.get_float("metallic");
    c->specular_ = p.get_float("specular");
    c->specular_tint_ = p.get_float("specular_tint");
    c->roughness_ = p.get_float("roughness");
    c->param_ = {p.index("base_color"), p.index("metallic"), p.index("specular"), p.index("specular_tint"),
                 p.index("roughness")};
    c->lobe_.build(c->base_color_, c->metallic_, c->specular_, c->specular_tint_, c->roughness_);
    return c;
  }

  const Lobe &constant_lobe() const { return lobe_; }
  void build_lobe_at(const ShadingPoint &sp, Lobe &lobe) const {
    lobe.build(sp.param_color(param_[0], base_color_), sp.param_float(param_[1], metallic_),
               sp.param_float(param_[2], specular_), sp.param_float(param_[3], specular_tint_),
               sp.param_float(param_[4], roughness_));
  }

 private:
  Spectrum base_color_{0.8f};
  float metallic_ = 0.0f, specular_ = 0.5f, specular_tint_ = 0.0f, roughness_ = 0.5f;
  std::array<uint32_t, 5> param_{};
  Lobe lobe_;
};

}  // namespace glimmer::plugin
