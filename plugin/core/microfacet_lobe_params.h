// The parameters microfacet_conductor and microfacet_dielectric share:
// distribution "ggx|beckmann|multi_ggx|sharp", Cycles roughness and 3.4
// anisotropy, read at create() into the lobe's alphas (and again per shading
// point when roughness or anisotropy is varying), and the Smith shadowing model.
#pragma once

#include <algorithm>
#include <cmath>

#include "core/closure.h"
#include "core/params.h"
#include "glimmer/microfacet.h"

namespace glimmer::plugin {

// Index of the choice in the "distribution" enum.
enum MicrofacetMode { kGgx = 0, kBeckmann = 1, kMultiGgx = 2, kSharp = 3 };

// The `shadowing` parameter both closures declare (one spec): the Smith G2 model of the single-scattering lobe.
inline constexpr GlimmerParamSpec kShadowingParam{
    "shadowing", GLIMMER_PARAM_ENUM, {0, 0, 0}, 0.0f, 0.0f, "height_correlated|separable", "height_correlated",
    "Smith masking-shadowing: height_correlated G2 = 1 / (1 + Lambda_i + Lambda_o) (Cycles 4.x) or separable "
    "G1(wi) G1(wo) (Cycles 3.4, darker at grazing angles); multi_ggx needs height_correlated (its energy tables)",
    0};

struct MicrofacetLobeParams {
  MicrofacetMode mode = kGgx;
  microfacet::Distribution distribution = microfacet::Distribution::GGX;
  microfacet::Shadowing shadowing = microfacet::Shadowing::HeightCorrelated;
  float alpha_x = 0.0f, alpha_y = 0.0f;
  float alpha_table = 0.0f;  // isotropic alpha used for the energy tables: min(sqrt(ax ay), 1)

  // The lobe for given roughness and anisotropy (constant, or varying per shading point).
  static MicrofacetLobeParams make(MicrofacetMode mode, float roughness, float anisotropy,
                                   microfacet::Shadowing shadowing = microfacet::Shadowing::HeightCorrelated) {
    MicrofacetLobeParams lobe;
    lobe.mode = mode;
    lobe.shadowing = shadowing;
    lobe.distribution = lobe.mode == kBeckmann ? microfacet::Distribution::Beckmann : microfacet::Distribution::GGX;
    const microfacet::Alpha a = microfacet::roughness_to_alpha(roughness, anisotropy);
    lobe.alpha_x = a.x;
    lobe.alpha_y = a.y;
    lobe.alpha_table = std::min(std::sqrt(a.x * a.y), 1.0f);
    return lobe;
  }
};

// The lobe's parameters as given at create() and their schema indices: the
// lobe at a shading point uses the per-point roughness / anisotropy when the
// host lists them (GLIMMER_PARAM_VARYING).
struct MicrofacetLobeInputs {
  MicrofacetMode mode = kGgx;
  microfacet::Shadowing shadowing = microfacet::Shadowing::HeightCorrelated;
  float roughness = 0.5f, anisotropy = 0.0f;
  uint32_t roughness_param = 0, anisotropy_param = 0;

  static MicrofacetLobeInputs parse(const ParamReader &p) {
    MicrofacetLobeInputs in;
    in.mode = static_cast<MicrofacetMode>(p.get_enum("distribution"));
    in.shadowing = p.get_enum("shadowing") == 1 ? microfacet::Shadowing::Separable
                                                 : microfacet::Shadowing::HeightCorrelated;
    // The multi_ggx energy tables (E, E_avg, E_Fms, glass R + T) are integrals of the height-correlated lobe.
    if (in.mode == kMultiGgx && in.shadowing == microfacet::Shadowing::Separable)
      throw ParamError(p.closure_name() + ": shadowing = 'separable' cannot be combined with distribution = "
                       "'multi_ggx' (its energy compensation tables are computed with the height-correlated G2); "
                       "use distribution = 'ggx' for Cycles 3.4's separable GGX");
    in.roughness = p.get_float("roughness");
    in.anisotropy = p.get_float("anisotropy");
    in.roughness_param = p.index("roughness");
    in.anisotropy_param = p.index("anisotropy");
    return in;
  }
  MicrofacetLobeParams constant() const { return MicrofacetLobeParams::make(mode, roughness, anisotropy, shadowing); }
  MicrofacetLobeParams at(const ShadingPoint &sp) const {
    return MicrofacetLobeParams::make(mode, sp.param_float(roughness_param, roughness),
                                      sp.param_float(anisotropy_param, anisotropy), shadowing);
  }
};

}  // namespace glimmer::plugin
