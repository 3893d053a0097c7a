// Rough dielectric interface (Cycles' glass_bsdf / refraction_bsdf) after
// Walter et al. 2007, "Microfacet Models for Refraction through Rough Surfaces":
//   reflection   f_r = F D G2 / (4 |wi.n| |wo.n|)                         (eq. 20)
//   transmission f_t = (1 - F) D G2 |wi.h| |wo.h| eta^2 / (|wi.n| |wo.n| (wi.h + eta wo.h)^2)   (eq. 21)
// with eta = n(wo side) / n(wi side), exact dielectric Fresnel (TIR -> F = 1),
// height-correlated G2 and visible-normal sampling of wh (Heitz 2018 /
// Heitz & d'Eon 2014). f_t carries eta^2 (the energy-conserving, radiance form):
// sum of R + T albedo <= 1 from both sides, and reciprocity reads
// f(wi, wo) / n_o^2 = f(wo, wi) / n_i^2.
//
// Sides: in the interface frame (core/closure.h, LocalFrame::Interface) wi.z > 0
// is outside (eta = ior) and wi.z < 0 inside (eta = 1 / ior), i.e. the host's
// `backfacing` decides eta (closure_abi.h); the inside is handled by mirroring z. ior is clamped away from 1 by 1e-4 (at
// exactly 1 the transmission lobe is a delta).
// mode=glass: reflection + transmission, chosen with probability F;
// mode=refraction: transmission only and Fresnel-free (Cycles' refraction
// BSDF): microfacets in total internal reflection absorb.
// distribution=multi_ggx (glass mode): albedo scaling by the single-scatter
// R + T albedo, f = f_ss / E(mu_i, alpha, eta) (tables for eta and 1/eta,
// plugin/tables/microfacet_energy_data.cpp): a lossless interface then
// conserves energy. sharp: smooth interface (singular).
// roughness, ior and anisotropy are varying (textures): the lobe is rebuilt at
// a shading point that gives per-point values.
#pragma once

#include <array>

#include "core/closure.h"
#include "core/dielectric_lobe.h"
#include "core/microfacet_lobe_params.h"
#include "glimmer/microfacet.h"
#include "tables/microfacet_energy.h"

namespace glimmer::plugin {

namespace mf = glimmer::microfacet;

class MicrofacetDielectricClosure : public OneLobeClosure<MicrofacetDielectricClosure> {
 public:
  static constexpr const char *kName = "microfacet_dielectric";
  static constexpr const char *kDoc =
      "Rough dielectric (Walter 2007; Cycles glass_bsdf / refraction_bsdf): GGX/Beckmann reflection + transmission, "
      "both sides, TIR; multi_ggx compensates multiple-scattering energy.";
  static constexpr uint32_t kFlags = GLIMMER_CLOSURE_TRANSMISSIVE;

  static std::span<const GlimmerParamSpec> params() {
    static const std::array<GlimmerParamSpec, 6> schema{{
        {"distribution", GLIMMER_PARAM_ENUM, {0, 0, 0}, 0.0f, 0.0f, "ggx|beckmann|multi_ggx|sharp", "ggx",
         "microfacet distribution; multi_ggx = GGX with energy compensation; sharp = smooth interface", 0},
        {"roughness", GLIMMER_PARAM_FLOAT, {0.5f, 0, 0}, 0.0f, 1.0f, nullptr, nullptr,
         "Cycles roughness in [0, 1]; alpha = roughness^2", GLIMMER_PARAM_VARYING},
        {"ior", GLIMMER_PARAM_FLOAT, {1.45f, 0, 0}, 1e-3f, 1e3f, nullptr, nullptr,
         "relative index of refraction n_inside / n_outside (> 0; < 1 for a bubble)", GLIMMER_PARAM_VARYING},
        {"mode", GLIMMER_PARAM_ENUM, {0, 0, 0}, 0.0f, 0.0f, "glass|refraction", "glass",
         "glass = reflection + transmission; refraction = transmission only (Fresnel-free)", 0},
        {"anisotropy", GLIMMER_PARAM_FLOAT, {0.0f, 0, 0}, -1.0f, 1.0f, nullptr, nullptr,
         "anisotropy in [-1, 1] (Cycles 3.4 mapping, tangent from the shading context)", GLIMMER_PARAM_VARYING},
        kShadowingParam,
    }};
    return schema;
  }

  using Lobe = DielectricLobe;

  static std::unique_ptr<MicrofacetDielectricClosure> create(const ParamReader &p) {
    auto c = std::make_unique<MicrofacetDielectricClosure>();
    c->inputs_ = MicrofacetLobeInputs::parse(p);
    c->ior_param_ = p.index("ior");
    c->ior_ = p.get_float("ior");
    c->lobe_.build(c->inputs_.constant(), c->ior_, p.get_enum("mode") == 1, true);
    return c;
  }

  // The instance's lobe, and the lobe from the per-point values of the varying parameters (OneLobeClosure).
  const Lobe &constant_lobe() const { return lobe_; }
  void build_lobe_at(const ShadingPoint &sp, Lobe &lobe) const {
    lobe.build(inputs_.at(sp), sp.param_float(ior_param_, ior_), lobe_.refraction_only, false);
  }

 private:
  MicrofacetLobeInputs inputs_;
  uint32_t ior_param_ = 0;
  float ior_ = 1.45f;  // as given (before the 1e-4 guard)
  Lobe lobe_;
};

}  // namespace glimmer::plugin
