// The parameters microfacet_conductor and microfacet_dielectric share:
// distribution "ggx|beckmann|multi_ggx|sharp", Cycles roughness and 3.4
// anisotropy, read once at create() into the lobe's alphas.
#pragma once

#include <algorithm>
#include <cmath>

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

  static MicrofacetLobeParams parse(const ParamReader &p) {
    MicrofacetLobeParams lobe;
    lobe.mode = static_cast<MicrofacetMode>(p.get_enum("distribution"));
    lobe.distribution = lobe.mode == kBeckmann ? microfacet::Distribution::Beckmann : microfacet::Distribution::GGX;
    const microfacet::Alpha a = microfacet::roughness_to_alpha(p.get_float("roughness"), p.get_float("anisotropy"));
    lobe.alpha_x = a.x;
    lobe.alpha_y = a.y;
    lobe.alpha_table = std::min(std::sqrt(a.x * a.y), 1.0f);
    return lobe;
  }
};

}  // namespace glimmer::plugin
