// Frosted glass (XML frosted_glass_bsdf; the Blender Frosted Glass node),
// issue 12. A solid object of rough glass: every interface the path meets is
// the exact rough dielectric of Walter et al. 2007 (eq. 20 reflection, eq. 21
// transmission; GGX, visible-normal sampling) with the same multiple-scattering
// energy compensation as microfacet_dielectric's multi_ggx (f = f_ss / E(mu,
// alpha, eta), so a lossless interface conserves energy from both sides). The
// interface itself is core/dielectric_lobe.h, shared with microfacet_dielectric.
//
// method=path: the reference estimator, the path tracer refracts through both
// interfaces stochastically. (The de Rousiers 2012 spherical-Gaussian estimator,
// method=sg / auto, is not implemented yet: the enum lists only what exists.)
//
// colour tints transmitted light at each interface crossing (a solid object
// seen through two interfaces gives colour^2; front reflection stays white);
// it is applied as a factor on f, so reciprocity and sampling are unchanged.
// roughness, ior and colour are varying (textures).
#include <array>

#include "core/closure.h"
#include "core/dielectric_lobe.h"
#include "core/microfacet_lobe_params.h"

namespace glimmer::plugin {

class FrostedGlassClosure {
 public:
  static constexpr const char *kName = "frosted_glass";
  static constexpr const char *kDoc =
      "Frosted (rough) glass object: Walter 2007 rough dielectric interfaces with multi-GGX energy compensation, "
      "tinted transmission; method=path is the exact path-traced reference.";
  static constexpr uint32_t kFlags = GLIMMER_CLOSURE_TRANSMISSIVE;

  static std::span<const GlimmerParamSpec> params() {
    static const std::array<GlimmerParamSpec, 4> schema{{
        {"color", GLIMMER_PARAM_COLOR, {1.0f, 1.0f, 1.0f}, 0.0f, 1.0f, nullptr, nullptr,
         "transmission tint per interface crossing (linear RGB in [0, 1])", GLIMMER_PARAM_VARYING},
        {"roughness", GLIMMER_PARAM_FLOAT, {0.3f, 0, 0}, 0.0f, 1.0f, nullptr, nullptr,
         "Cycles roughness in [0, 1] of both interfaces; alpha = roughness^2", GLIMMER_PARAM_VARYING},
        {"ior", GLIMMER_PARAM_FLOAT, {1.5f, 0, 0}, 1e-3f, 1e3f, nullptr, nullptr,
         "index of refraction n_inside / n_outside (> 0)", GLIMMER_PARAM_VARYING},
        {"method", GLIMMER_PARAM_ENUM, {0, 0, 0}, 0.0f, 0.0f, "path", "path",
         "transmission estimator: path = exact stochastic refraction at every interface (reference)", 0},
    }};
    return schema;
  }

  static std::unique_ptr<FrostedGlassClosure> create(const ParamReader &p) {
    auto c = std::make_unique<FrostedGlassClosure>();
    c->color_ = p.get_color("color");
    c->roughness_ = p.get_float("roughness");
    c->ior_ = p.get_float("ior");
    c->color_param_ = p.index("color");
    c->roughness_param_ = p.index("roughness");
    c->ior_param_ = p.index("ior");
    c->lobe_.build(interface_params(c->roughness_), c->ior_, false, true);
    return c;
  }

  LocalEval eval(const ShadingPoint &sp, const Vec3 &wo) const {
    DielectricLobe scratch;
    LocalEval e = lobe_at(sp, scratch).eval(sp.wi, wo);
    if (wo.z * sp.wi.z < 0.0f) e.f_cos *= color_at(sp);
    return e;
  }

  bool sample(const ShadingPoint &sp, const Vec3 &rand, LocalSample &out) const {
    DielectricLobe scratch;
    if (!lobe_at(sp, scratch).sample(sp.wi, rand, out)) return false;
    if (out.label & GLIMMER_LABEL_TRANSMIT) out.f_cos *= color_at(sp);
    return true;
  }

  // R + T with the tint on T is not tabulated: the lossless interface's albedo
  // (1 with compensation) is an upper bound; the tint is the host's to see in
  // the sample weights.
  Spectrum albedo(const ShadingPoint &sp) const {
    DielectricLobe scratch;
    return lobe_at(sp, scratch).albedo(sp.wi);
  }

 private:
  // Both interfaces: isotropic GGX with multiple-scattering compensation.
  static MicrofacetLobeParams interface_params(float roughness) {
    return MicrofacetLobeParams::make(kMultiGgx, roughness, 0.0f);
  }

  const DielectricLobe &lobe_at(const ShadingPoint &sp, DielectricLobe &scratch) const {
    if (!sp.varies()) return lobe_;
    scratch.build(interface_params(sp.param_float(roughness_param_, roughness_)), sp.param_float(ior_param_, ior_),
                  false, false);
    return scratch;
  }

  Spectrum color_at(const ShadingPoint &sp) const { return sp.param_color(color_param_, color_); }

  Spectrum color_{1.0f};
  float roughness_ = 0.3f, ior_ = 1.5f;
  uint32_t color_param_ = 0, roughness_param_ = 0, ior_param_ = 0;
  DielectricLobe lobe_;
};

GLIMMER_REGISTER_CLOSURE(FrostedGlassClosure)

}  // namespace glimmer::plugin
