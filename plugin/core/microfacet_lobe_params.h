// The parameters microfacet_conductor and microfacet_dielectric share:
// distribution "ggx|beckmann|multi_ggx|sharp", Cycles roughness and 3.4
// anisotropy, read at create() into the lobe's alphas (and again per shading
// point when roughness or anisotropy is varying).
#pragma once

#include <algorithm>
#include <cmath>

#include "core/closure.h"
#include "core/params.h"
#include "glimmer/microfacet.h"

namespace glimmer::plugin {

// Index of the choice in the "distribution" enum.
enum MicrofacetMode { kGgx = 0, kBeckmann = 1, kMultiGgx = 2, kSharp = 3 };

struct MicrofacetLobeParams {
  MicrofacetMode mode = kGgx;
  microfacet::Distribution distribution = microfacet::Distribution::GGX;
  float alpha_x = 0.0f, alpha_y = 0.0f;
  float alpha_table = 0.0f;  // isotropic alpha used for the energy tables: min(sqrt(ax ay), 1)

  // The lobe for given roughness and anisotropy (constant, or varying per shading point).
  static MicrofacetLobeParams make(MicrofacetMode mode, float roughness, float anisotropy) {
    MicrofacetLobeParams lobe;
    lobe.mode = mode;
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
  float roughness = 0.5f, anisotropy = 0.0f;
  uint32_t roughness_param = 0, anisotropy_param = 0;

  static MicrofacetLobeInputs parse(const ParamReader &p) {
    MicrofacetLobeInputs in;
    in.mode = static_cast<MicrofacetMode>(p.get_enum("distribution"));
    in.roughness = p.get_float("roughness");
    in.anisotropy = p.get_float("anisotropy");
    in.roughness_param = p.index("roughness");
    in.anisotropy_param = p.index("anisotropy");
    return in;
  }
  MicrofacetLobeParams constant() const { return MicrofacetLobeParams::make(mode, roughness, anisotropy); }
  MicrofacetLobeParams at(const ShadingPoint &sp) const {
    return MicrofacetLobeParams::make(mode, sp.param_float(roughness_param, roughness),
                                      sp.param_float(anisotropy_param, anisotropy));
  }
};

}  // namespace glimmer::plugin
