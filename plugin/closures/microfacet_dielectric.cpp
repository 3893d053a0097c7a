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
// roughness, ior and anisotropy are varying (textures): the lobe is rebuilt at
// a shading point that gives per-point values.
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
         "microfacet distribution; multi_ggx = GGX with energy compensation; sharp = smooth interface", 0},
        {"roughness", GLIMMER_PARAM_FLOAT, {0.5f, 0, 0}, 0.0f, 1.0f, nullptr, nullptr,
         "Cycles roughness in [0, 1]; alpha = roughness^2", GLIMMER_PARAM_VARYING},
        {"ior", GLIMMER_PARAM_FLOAT, {1.45f, 0, 0}, 1e-3f, 1e3f, nullptr, nullptr,
         "relative index of refraction n_inside / n_outside (> 0; < 1 for a bubble)", GLIMMER_PARAM_VARYING},
        {"mode", GLIMMER_PARAM_ENUM, {0, 0, 0}, 0.0f, 0.0f, "glass|refraction", "glass",
         "glass = reflection + transmission; refraction = transmission only (Fresnel-free)", 0},
        {"anisotropy", GLIMMER_PARAM_FLOAT, {0.0f, 0, 0}, -1.0f, 1.0f, nullptr, nullptr,
         "anisotropy in [-1, 1] (Cycles 3.4 mapping, tangent from the shading context)", GLIMMER_PARAM_VARYING},
    }};
    return schema;
  }

  // Everything eval/sample need at one shading point.
  struct Lobe {
    MicrofacetMode mode = kGgx;
    mf::Distribution dist = mf::Distribution::GGX;
    float ax = 0.25f, ay = 0.25f, alpha_table = 0.25f, ior = 1.45f;
    bool refraction_only = false, compensate = false;
    // E(mu) at this alpha for eta = ior and 1 / ior; built for the instance and,
    // per shading point, only when multi_ggx compensation needs them in eval.
    bool has_rows = false;
    tables::GlassRow e_outside, e_inside;

    void build(const MicrofacetLobeParams &lobe, float ior_in, bool refraction_only_in, bool need_rows) {
      mode = lobe.mode;
      dist = lobe.distribution;
      ax = lobe.alpha_x;
      ay = lobe.alpha_y;
      alpha_table = lobe.alpha_table;
      // ior is kept 1e-4 away from 1 (at exactly 1 the transmission lobe is a delta).
      if (std::fabs(ior_in - 1.0f) < 1e-4f) ior_in = ior_in < 1.0f ? 1.0f - 1e-4f : 1.0f + 1e-4f;
      ior = ior_in;
      refraction_only = refraction_only_in;
      compensate = mode == kMultiGgx && !refraction_only;
      has_rows = need_rows || compensate;
      if (has_rows) {
        e_outside.build(alpha_table, ior);
        e_inside.build(alpha_table, 1.0f / ior);
      }
    }

    // f * |cos(wo)| and pdf in the side-local frame (wi.z > 0, eta = n_wo_side / n_wi_side).
    LocalEval eval_local(const Vec3 &wi, const Vec3 &wo, float eta) const {
      LocalEval e;
      if (wo.z > 0.0f) {
        if (refraction_only) return {};
        Vec3 wh;
        if (!mf::half_vector_reflect(wi, wo, wh)) return {};
        // Symmetric cosine (wi.wh = wo.wh exactly; averaging keeps f reciprocal to rounding).
        const float cos_ih = 0.5f * (dot(wi, wh) + dot(wo, wh));
        if (!(cos_ih > 0.0f)) return {};
        const float F = mf::fresnel_dielectric(cos_ih, eta);
        const float d = mf::D(dist, wh, ax, ay);
        const float g2 = mf::G2(dist, wi, wo, ax, ay);
        e.f_cos = Spectrum(F * d * g2 / (4.0f * wi.z));
        e.pdf = F * mf::visible_D(dist, wi, wh, ax, ay) / (4.0f * cos_ih);
      } else if (wo.z < 0.0f) {
        Vec3 wh;
        float len2;
        if (!mf::half_vector_transmit(wi, wo, eta, wh, &len2)) return {};
        const float cos_ih = dot(wi, wh), cos_oh = dot(wo, wh);
        if (!(cos_ih > 0.0f) || !(cos_oh < 0.0f)) return {};
        // Fresnel of the refraction pair itself (reciprocal; equal to F(cos_ih) up to rounding).
        const float F = mf::fresnel_dielectric_pair(cos_ih, -cos_oh, eta);
        const float T = refraction_only ? (F < 1.0f ? 1.0f : 0.0f) : 1.0f - F;
        if (!(T > 0.0f)) return {};
        const float d = mf::D(dist, wh, ax, ay);
        const float g2 = mf::G2(dist, wi, wo, ax, ay);
        const float jac = mf::jacobian_transmit(wo, wh, eta, len2);  // eta^2 |wo.h| / (wi.h + eta wo.h)^2
        e.f_cos = Spectrum(T * d * g2 * cos_ih * jac / wi.z);
        e.pdf = T * mf::visible_D(dist, wi, wh, ax, ay) * jac;
      }
      if (compensate) e.f_cos /= compensation(wi.z, eta);
      return e;
    }

    // Single-scatter R + T albedo at mu on the side whose relative IOR is eta.
    float compensation(float mu, float eta) const {
      const float e = has_rows ? (eta == ior ? e_outside(mu) : e_inside(mu)) : tables::ggx_glass_E(mu, alpha_table, eta);
      return std::max(e, 1e-3f);
    }

    LocalEval eval(const Vec3 &wi, const Vec3 &wo) const {
      if (mode == kSharp || wi.z == 0.0f) return {};
      const bool outside = wi.z > 0.0f;
      const float eta = outside ? ior : 1.0f / ior;
      return outside ? eval_local(wi, wo, eta) : eval_local(mf::flip_z_local(wi), mf::flip_z_local(wo), eta);
    }

    bool sample(const Vec3 &wi_in, const Vec3 &rand, LocalSample &out) const {
      if (wi_in.z == 0.0f) return false;
      const bool outside = wi_in.z > 0.0f;
      const float eta = outside ? ior : 1.0f / ior;
      const Vec3 wi = outside ? wi_in : mf::flip_z_local(wi_in);
      if (mode == kSharp) {
        const Vec3 n(0.0f, 0.0f, 1.0f);
        const float F = mf::fresnel_dielectric(wi.z, eta);
        Vec3 wt;
        const bool can_refract = mf::refract(wi, n, eta, wt);
        const bool reflect = refraction_only ? false : (rand.z < F || !can_refract);
        if (!reflect && !can_refract) return false;
        out.wo = reflect ? Vec3(-wi.x, -wi.y, wi.z) : wt;
        out.f_cos = Spectrum(1.0f);  // F / F or (1 - F) / (1 - F); refraction-only: Fresnel-free
        out.pdf = 1.0f;
        out.eta = reflect ? 1.0f : eta;
        out.label = (reflect ? GLIMMER_LABEL_REFLECT : GLIMMER_LABEL_TRANSMIT) | GLIMMER_LABEL_SINGULAR;
      } else {
        const Vec3 m = mf::sample_visible_normal(dist, wi, ax, ay, rand.x, rand.y);
        const float F = mf::fresnel_dielectric(dot(wi, m), eta);
        Vec3 wo;
        bool reflect;
        if (refraction_only) {
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
        out.roughness = std::sqrt(ax * ay);
        out.eta = reflect ? 1.0f : eta;
        out.label = (reflect ? GLIMMER_LABEL_REFLECT : GLIMMER_LABEL_TRANSMIT) | GLIMMER_LABEL_GLOSSY;
        if (!(out.pdf > 0.0f)) return false;
      }
      if (!outside) out.wo = mf::flip_z_local(out.wo);
      return true;
    }

    Spectrum albedo(const Vec3 &wi) const {
      if (mode == kSharp || compensate) return Spectrum(1.0f);
      const float mu = std::fabs(wi.z);
      const float eta = wi.z > 0.0f ? ior : 1.0f / ior;
      return Spectrum(compensation(mu, eta));
    }
  };

  static std::unique_ptr<MicrofacetDielectricClosure> create(const ParamReader &p) {
    auto c = std::make_unique<MicrofacetDielectricClosure>();
    c->inputs_ = MicrofacetLobeInputs::parse(p);
    c->ior_param_ = p.index("ior");
    c->ior_ = p.get_float("ior");
    c->lobe_.build(c->inputs_.constant(), c->ior_, p.get_enum("mode") == 1, true);
    return c;
  }

  // The instance's lobe, or `scratch` rebuilt from the per-point values of the varying parameters.
  const Lobe &lobe_at(const ShadingPoint &sp, Lobe &scratch) const {
    if (!sp.varies()) return lobe_;
    scratch.build(inputs_.at(sp), sp.param_float(ior_param_, ior_), lobe_.refraction_only, false);
    return scratch;
  }

  LocalEval eval(const ShadingPoint &sp, const Vec3 &wo) const {
    Lobe scratch;
    return lobe_at(sp, scratch).eval(sp.wi, wo);
  }

  bool sample(const ShadingPoint &sp, const Vec3 &rand, LocalSample &out) const {
    Lobe scratch;
    return lobe_at(sp, scratch).sample(sp.wi, rand, out);
  }

  Spectrum albedo(const ShadingPoint &sp) const {
    Lobe scratch;
    return lobe_at(sp, scratch).albedo(sp.wi);
  }

 private:
  MicrofacetLobeInputs inputs_;
  uint32_t ior_param_ = 0;
  float ior_ = 1.45f;  // as given (before the 1e-4 guard)
  Lobe lobe_;
};

GLIMMER_REGISTER_CLOSURE(MicrofacetDielectricClosure)

}  // namespace glimmer::plugin
