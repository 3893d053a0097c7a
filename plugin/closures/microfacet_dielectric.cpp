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
// Sides: wi.z > 0 is outside (eta = ior), wi.z < 0 inside (eta = 1 / ior); the
// inside is handled by mirroring z. ior is clamped away from 1 by 1e-4 (at
// exactly 1 the transmission lobe is a delta).
// mode=glass: reflection + transmission, chosen with probability F;
// mode=refraction: transmission only and Fresnel-free (Cycles' refraction
// BSDF): microfacets in total internal reflection absorb.
// distribution=multi_ggx (glass mode): albedo scaling by the single-scatter
// R + T albedo, f = f_ss / E(mu_i, alpha, eta) (tables for eta and 1/eta,
// plugin/tables/microfacet_energy_data.cpp): a lossless interface then
// conserves energy. sharp: smooth interface (singular).
#include <array>

#include "core/closure.h"
#include "core/microfacet_lobe_params.h"
#include "glimmer/microfacet.h"
#include "tables/microfacet_energy.h"

namespace glimmer::plugin {

namespace mf = glimmer::microfacet;

class MicrofacetDielectricClosure {
 public:
  static constexpr const char *kName = "microfacet_dielectric";
  static constexpr const char *kDoc =
      "Rough dielectric (Walter 2007; Cycles glass_bsdf / refraction_bsdf): GGX/Beckmann reflection + transmission, "
      "both sides, TIR; multi_ggx compensates multiple-scattering energy.";
  static constexpr uint32_t kFlags = GLIMMER_CLOSURE_TRANSMISSIVE;


  static std::span<const GlimmerParamSpec> params() {
    static const std::array<GlimmerParamSpec, 5> schema{{
        {"distribution", GLIMMER_PARAM_ENUM, {0, 0, 0}, 0.0f, 0.0f, "ggx|beckmann|multi_ggx|sharp", "ggx",
         "microfacet distribution; multi_ggx = GGX with energy compensation; sharp = smooth interface"},
        {"roughness", GLIMMER_PARAM_FLOAT, {0.5f, 0, 0}, 0.0f, 1.0f, nullptr, nullptr,
         "Cycles roughness in [0, 1]; alpha = roughness^2"},
        {"ior", GLIMMER_PARAM_FLOAT, {1.45f, 0, 0}, 1e-3f, 1e3f, nullptr, nullptr,
         "relative index of refraction n_inside / n_outside (> 0; < 1 for a bubble)"},
        {"mode", GLIMMER_PARAM_ENUM, {0, 0, 0}, 0.0f, 0.0f, "glass|refraction", "glass",
         "glass = reflection + transmission; refraction = transmission only (Fresnel-free)"},
        {"anisotropy", GLIMMER_PARAM_FLOAT, {0.0f, 0, 0}, -1.0f, 1.0f, nullptr, nullptr,
         "anisotropy in [-1, 1] (Cycles 3.4 mapping, tangent from the shading context)"},
    }};
    return schema;
  }

  static std::unique_ptr<MicrofacetDielectricClosure> create(const ParamReader &p) {
    auto c = std::make_unique<MicrofacetDielectricClosure>();
    const MicrofacetLobeParams lobe = MicrofacetLobeParams::parse(p);
    c->mode_ = lobe.mode;
    c->dist_ = lobe.distribution;
    c->ax_ = lobe.alpha_x;
    c->ay_ = lobe.alpha_y;
    c->alpha_table_ = lobe.alpha_table;
    float ior = p.get_float("ior");
    if (std::fabs(ior - 1.0f) < 1e-4f) ior = ior < 1.0f ? 1.0f - 1e-4f : 1.0f + 1e-4f;
    c->ior_ = ior;
    c->refraction_only_ = p.get_enum("mode") == 1;
    c->compensate_ = c->mode_ == kMultiGgx && !c->refraction_only_;
    c->e_outside_.build(c->alpha_table_, c->ior_);
    c->e_inside_.build(c->alpha_table_, 1.0f / c->ior_);
    return c;
  }

  // f * |cos(wo)| and pdf in the side-local frame (wi.z > 0, eta = n_wo_side / n_wi_side).
  LocalEval eval_local(const Vec3 &wi, const Vec3 &wo, float eta) const {
    LocalEval e;
    if (wo.z > 0.0f) {
      if (refraction_only_) return {};
      Vec3 wh;
      if (!mf::half_vector_reflect(wi, wo, wh)) return {};
      // Symmetric cosine (wi.wh = wo.wh exactly; averaging keeps f reciprocal to rounding).
      const float cos_ih = 0.5f * (dot(wi, wh) + dot(wo, wh));
      if (!(cos_ih > 0.0f)) return {};
      const float F = mf::fresnel_dielectric(cos_ih, eta);
      const float d = mf::D(dist_, wh, ax_, ay_);
      const float g2 = mf::G2(dist_, wi, wo, ax_, ay_);
      e.f_cos = Spectrum(F * d * g2 / (4.0f * wi.z));
      e.pdf = F * mf::visible_D(dist_, wi, wh, ax_, ay_) / (4.0f * cos_ih);
    } else if (wo.z < 0.0f) {
      Vec3 wh;
      float len2;
      if (!mf::half_vector_transmit(wi, wo, eta, wh, &len2)) return {};
      const float cos_ih = dot(wi, wh), cos_oh = dot(wo, wh);
      if (!(cos_ih > 0.0f) || !(cos_oh < 0.0f)) return {};
      // Fresnel of the refraction pair itself (reciprocal; equal to F(cos_ih) up to rounding).
      const float F = mf::fresnel_dielectric_pair(cos_ih, -cos_oh, eta);
      const float T = refraction_only_ ? (F < 1.0f ? 1.0f : 0.0f) : 1.0f - F;
      if (!(T > 0.0f)) return {};
      const float d = mf::D(dist_, wh, ax_, ay_);
      const float g2 = mf::G2(dist_, wi, wo, ax_, ay_);
      const float jac = mf::jacobian_transmit(wo, wh, eta, len2);  // eta^2 |wo.h| / (wi.h + eta wo.h)^2
      e.f_cos = Spectrum(T * d * g2 * cos_ih * jac / wi.z);
      e.pdf = T * mf::visible_D(dist_, wi, wh, ax_, ay_) * jac;
    }
    if (compensate_) e.f_cos /= compensation(wi.z, eta);
    return e;
  }

  // Single-scatter R + T albedo at mu on the side whose relative IOR is eta.
  float compensation(float mu, float eta) const {
    return std::max(eta == ior_ ? e_outside_(mu) : e_inside_(mu), 1e-3f);
  }

  LocalEval eval(const ShadingPoint &sp, const Vec3 &wo) const {
    if (mode_ == kSharp || sp.wi.z == 0.0f) return {};
    const bool outside = sp.wi.z > 0.0f;
    const float eta = outside ? ior_ : 1.0f / ior_;
    return outside ? eval_local(sp.wi, wo, eta) : eval_local(mf::flip_z_local(sp.wi), mf::flip_z_local(wo), eta);
  }

  bool sample(const ShadingPoint &sp, const Vec3 &rand, LocalSample &out) const {
    if (sp.wi.z == 0.0f) return false;
    const bool outside = sp.wi.z > 0.0f;
    const float eta = outside ? ior_ : 1.0f / ior_;
    const Vec3 wi = outside ? sp.wi : mf::flip_z_local(sp.wi);
    if (mode_ == kSharp) {
      const Vec3 n(0.0f, 0.0f, 1.0f);
      const float F = mf::fresnel_dielectric(wi.z, eta);
      Vec3 wt;
      const bool can_refract = mf::refract(wi, n, eta, wt);
      const bool reflect = refraction_only_ ? false : (rand.z < F || !can_refract);
      if (!reflect && !can_refract) return false;
      out.wo = reflect ? Vec3(-wi.x, -wi.y, wi.z) : wt;
      out.f_cos = Spectrum(1.0f);  // F / F or (1 - F) / (1 - F); refraction-only: Fresnel-free
      out.pdf = 1.0f;
      out.eta = reflect ? 1.0f : eta;
      out.label = (reflect ? GLIMMER_LABEL_REFLECT : GLIMMER_LABEL_TRANSMIT) | GLIMMER_LABEL_SINGULAR;
    } else {
      const Vec3 m = mf::sample_visible_normal(dist_, wi, ax_, ay_, rand.x, rand.y);
      const float F = mf::fresnel_dielectric(dot(wi, m), eta);
      Vec3 wo;
      bool reflect;
      if (refraction_only_) {
        if (!mf::refract(wi, m, eta, wo)) return false;
        reflect = false;
      } else if (rand.z < F) {
        wo = normalize(mf::reflect_about(wi, m));
        reflect = true;
      } else {
        if (!mf::refract(wi, m, eta, wo)) return false;
        reflect = false;
      }
      if (reflect ? !(wo.z > 0.0f) : !(wo.z < 0.0f)) return false;
      const LocalEval e = eval_local(wi, wo, eta);
      out.wo = wo;
      out.f_cos = e.f_cos;
      out.pdf = e.pdf;
      out.roughness = std::sqrt(ax_ * ay_);
      out.eta = reflect ? 1.0f : eta;
      out.label = (reflect ? GLIMMER_LABEL_REFLECT : GLIMMER_LABEL_TRANSMIT) | GLIMMER_LABEL_GLOSSY;
      if (!(out.pdf > 0.0f)) return false;
    }
    if (!outside) out.wo = mf::flip_z_local(out.wo);
    return true;
  }

  Spectrum albedo(const ShadingPoint &sp) const {
    if (mode_ == kSharp || compensate_) return Spectrum(1.0f);
    const float mu = std::fabs(sp.wi.z);
    const float eta = sp.wi.z > 0.0f ? ior_ : 1.0f / ior_;
    return Spectrum(compensation(mu, eta));
  }

 private:
  MicrofacetMode mode_ = kGgx;
  mf::Distribution dist_ = mf::Distribution::GGX;
  float ax_ = 0.25f, ay_ = 0.25f, alpha_table_ = 0.25f, ior_ = 1.45f;
  bool refraction_only_ = false, compensate_ = false;
  tables::GlassRow e_outside_{}, e_inside_{};  // E(mu) at this alpha for eta = ior and 1 / ior
};

GLIMMER_REGISTER_CLOSURE(MicrofacetDielectricClosure)

}  // namespace glimmer::plugin
