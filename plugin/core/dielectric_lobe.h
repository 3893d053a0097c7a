// The rough dielectric interface of Walter et al. 2007 at one shading point:
// eval / sample / albedo in the local frame, both sides, TIR, and the
// multi_ggx energy compensation f = f_ss / E(mu, alpha, eta). Shared by
// microfacet_dielectric (plugin/closures/microfacet_dielectric.cpp, which
// documents the equations) and frosted_glass (its interfaces in path mode).
#pragma once

#include <algorithm>
#include <cmath>

#include "core/closure.h"
#include "core/microfacet_lobe_params.h"
#include "glimmer/microfacet.h"
#include "tables/microfacet_energy.h"

namespace glimmer::plugin {

namespace mf = glimmer::microfacet;

// Everything eval/sample need at one shading point.
struct DielectricLobe {
  MicrofacetMode mode = kGgx;
  mf::Distribution dist = mf::Distribution::GGX;
  mf::Shadowing shadowing = mf::Shadowing::HeightCorrelated;
  float ax = 0.25f, ay = 0.25f, alpha_table = 0.25f, ior = 1.45f;
  bool refraction_only = false, compensate = false;
  // E(mu) at this alpha for eta = ior and 1 / ior: built whole for an instance
  // (shared by the render threads) and, per shading point, only when multi_ggx
  // compensation needs them in eval, then filled node by node as lookups need
  // them (tables::GlassRow; the same values as a whole row, bit for bit).
  bool has_rows = false;
  tables::GlassRow e_outside, e_inside;

  // instance_lobe: the lobe of a closure instance (rows always, built whole, read by every thread); else
  // the lobe of one shading point (rows only for multi_ggx, filled lazily by its own thread).
  void build(const MicrofacetLobeParams &lobe, float ior_in, bool refraction_only_in, bool instance_lobe) {
    mode = lobe.mode;
    dist = lobe.distribution;
    shadowing = lobe.shadowing;
    ax = lobe.alpha_x;
    ay = lobe.alpha_y;
    alpha_table = lobe.alpha_table;
    // ior is kept 1e-4 away from 1 (at exactly 1 the transmission lobe is a delta).
    if (std::fabs(ior_in - 1.0f) < 1e-4f) ior_in = ior_in < 1.0f ? 1.0f - 1e-4f : 1.0f + 1e-4f;
    ior = ior_in;
    refraction_only = refraction_only_in;
    compensate = mode == kMultiGgx && !refraction_only;
    has_rows = instance_lobe || compensate;
    if (has_rows && instance_lobe) {
      e_outside.build(alpha_table, ior);
      e_inside.build(alpha_table, 1.0f / ior);
    } else if (has_rows) {
      e_outside.set(alpha_table, ior);
      e_inside.set(alpha_table, 1.0f / ior);
    }
  }

  float g2(const Vec3 &wi, const Vec3 &wo) const { return mf::G2(dist, wi, wo, ax, ay, shadowing); }
  // g2 for many wo at one wi (the pane walk's resampled events): wi's part once, g2_at(incidence(wi), wo) ==
  // g2(wi, wo) bit for bit.
  float g2_incidence(const Vec3 &wi) const {
    return shadowing == mf::Shadowing::Separable ? mf::G1(dist, wi, ax, ay) : mf::G2_incidence(dist, wi, ax, ay);
  }
  float g2_at(float incidence, const Vec3 &wo) const {
    return shadowing == mf::Shadowing::Separable ? incidence * mf::G1(dist, wo, ax, ay)
                                                 : mf::G2_from_incidence(dist, incidence, wo, ax, ay);
  }

  // The reflection's half vector wh, its symmetric cosine cos_ih = wi.wh and Fresnel F(cos_ih) for wo.z > 0, wi.z > 0
  // in the side-local frame; false where eval_local gives nothing (a degenerate half vector, cos_ih <= 0). With
  // reflection_pdf and reflected: one formula for eval_local's reflection, sample()'s reflection branch and
  // sample_reflection (session 39, frostedpane39). The same values bit for bit; the callers' machine code moved
  // (eval_local, sample, sample_reflection, the microfacet_dielectric adapter's eval), measured a little cheaper:
  // docs/history/frosted_glass_sessions.md "Session 39 (frostedpane39)".
  [[gnu::always_inline]] static bool reflection_half(const Vec3 &wi, const Vec3 &wo, float eta, Vec3 &wh, float &cos_ih,
                                                     float &F) {
    if (!mf::half_vector_reflect(wi, wo, wh)) return false;
    // Symmetric cosine (wi.wh = wo.wh exactly; averaging keeps f reciprocal to rounding).
    cos_ih = 0.5f * (dot(wi, wh) + dot(wo, wh));
    if (!(cos_ih > 0.0f)) return false;
    F = mf::fresnel_dielectric(cos_ih, eta);
    return true;
  }
  // sample()'s reflection pdf: F visible_D(wi, wh) / (4 cos_ih) (the visible normal's density, the reflect branch's
  // probability F, the reflection's Jacobian 1 / (4 cos_ih)).
  [[gnu::always_inline]] float reflection_pdf(const Vec3 &wi, const Vec3 &wh, float cos_ih, float F) const {
    return F * mf::visible_D(dist, wi, wh, ax, ay) / (4.0f * cos_ih);
  }
  // sample()'s reflection of wi about the visible normal m (sample_reflection's too: the same wo bit for bit).
  [[gnu::always_inline]] static Vec3 reflected(const Vec3 &wi, const Vec3 &m) {
    return normalize(mf::reflect_about(wi, m));
  }

  // f * |cos(wo)| and pdf in the side-local frame (wi.z > 0, eta = n_wo_side / n_wi_side).
  LocalEval eval_local(const Vec3 &wi, const Vec3 &wo, float eta) const {
    LocalEval e;
    if (wo.z > 0.0f) {
      if (refraction_only) return {};
      Vec3 wh;
      float cos_ih, F;
      if (!reflection_half(wi, wo, eta, wh, cos_ih, F)) return {};
      const float d = mf::D(dist, wh, ax, ay);
      const float g = g2(wi, wo);
      e.f_cos = Spectrum(F * d * g / (4.0f * wi.z));
      e.pdf = reflection_pdf(wi, wh, cos_ih, F);
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
      const float g = g2(wi, wo);
      const float jac = mf::jacobian_transmit(wo, wh, eta, len2);  // eta^2 |wo.h| / (wi.h + eta wo.h)^2
      e.f_cos = Spectrum(T * d * g * cos_ih * jac / wi.z);
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

  // The visible microfacet normal m drawn with (u, v) for wi (the side-local frame, wi.z > 0); returns its Fresnel
  // reflectance F at the side's relative IOR eta. sample's rough draw, and frosted_glass's pane walk (the exact front
  // grid, the first far-face event's two branches, the resampled events' candidates): one formula.
  // always_inline (and m an out-parameter): sample's machine code is what it was before this function existed.
  [[gnu::always_inline]] float visible_facet(const Vec3 &wi, float eta, float u, float v, Vec3 &m) const {
    m = mf::sample_visible_normal(dist, wi, ax, ay, u, v);
    return mf::fresnel_dielectric(dot(wi, m), eta);
  }
  // visible_facet for several draws at one wi: wi_std = mf::ggx_stretched_incidence(wi, ax, ay) computed once (read
  // for GGX only); the same m and F bit for bit. cos_t (if given): Fresnel's |cos| of the refracted angle (0 for
  // TIR), which mf::refract(wi, m, eta, ...) computes again by the same operations (the resampled events reuse it:
  // mf::refract_with_cos_t; session 39, frostedpane39).
  [[gnu::always_inline]] float visible_facet_at(const Vec3 &wi, const Vec3 &wi_std, float eta, float u, float v,
                                                Vec3 &m, float *cos_t = nullptr) const {
    m = dist == mf::Distribution::GGX ? mf::sample_ggx_visible_normal_std(wi_std, ax, ay, u, v)
                                      : mf::sample_visible_normal(dist, wi, ax, ay, u, v);
    return mf::fresnel_dielectric(dot(wi, m), eta, cos_t);
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
      Vec3 m;
      const float F = visible_facet(wi, eta, rand.x, rand.y, m);
      Vec3 wo;
      bool reflect;
      if (refraction_only) {
        if (!mf::refract(wi, m, eta, wo)) return false;
        reflect = false;
      } else if (rand.z < F) {
        wo = reflected(wi, m);
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

  // sample()'s reflections alone (frosted_glass's sampled internal reflections draw until one reflects): true exactly
  // where sample(wi_in, rand, out) succeeds with a reflection, and then wo == out.wo bit for bit. A draw that
  // transmits (or fails) returns false at once: no refraction, weight or compensation is made for it, and a reflection
  // makes only its pdf (sample's acceptance, pdf > 0: eval_local's reflection pdf, the same operations).
  bool sample_reflection(const Vec3 &wi_in, const Vec3 &rand, Vec3 &wo_out) const {
    if (mode == kSharp || refraction_only) {  // not the walk's lobes: sample() itself
      LocalSample s;
      if (!sample(wi_in, rand, s) || !(s.label & GLIMMER_LABEL_REFLECT)) return false;
      wo_out = s.wo;
      return true;
    }
    if (wi_in.z == 0.0f) return false;
    const bool outside = wi_in.z > 0.0f;
    const float eta = outside ? ior : 1.0f / ior;
    const Vec3 wi = outside ? wi_in : mf::flip_z_local(wi_in);
    Vec3 m;
    const float F = visible_facet(wi, eta, rand.x, rand.y, m);
    if (!(rand.z < F)) return false;  // sample() refracts (or fails): not a reflection
    const Vec3 wo = reflected(wi, m);
    if (!(wo.z > 0.0f)) return false;
    Vec3 wh;  // eval_local's reflection pdf from here (sample's acceptance: pdf > 0)
    float cos_ih, F_h;
    if (!reflection_half(wi, wo, eta, wh, cos_ih, F_h) || !(reflection_pdf(wi, wh, cos_ih, F_h) > 0.0f)) return false;
    wo_out = outside ? wo : mf::flip_z_local(wo);
    return true;
  }

  Spectrum albedo(const Vec3 &wi) const {
    if (mode == kSharp || compensate) return Spectrum(1.0f);
    const float mu = std::fabs(wi.z);
    const float eta = wi.z > 0.0f ? ior : 1.0f / ior;
    return Spectrum(compensation(mu, eta));
  }
};

}  // namespace glimmer::plugin
