// The Principled BSDF's clearcoat lobe as Blender 3.4 Cycles evaluates it
// (CLOSURE_BSDF_MICROFACET_GGX_CLEARCOAT_ID in kernel/closure/bsdf_microfacet.h, set up by svm_closure.h):
//
//   f(wi, wo) = F(wo.m) D(m) G1(wi) G1(wo) / (4 |wi.n| |wo.n|),   m = normalize(wi + wo)   (Walter 2007 eq. 20)
//
//  - D: Burley 2012 ("Physically-Based Shading at Disney", appendix B.2, eq. 4 with gamma = 1), GTR1 "Berry":
//      D(m) = (a^2 - 1) / (pi ln(a^2) (1 + (a^2 - 1) cos^2 theta_m)),   a = roughness^2 (Cycles' clearcoat_roughness
//    squared, clamped to 1; D = 1 / pi at a = 1). Written with L = ln(a^2) as expm1(L) / (pi L (a^2 cos^2 + sin^2)),
//    which stays accurate for a near 1 and for a sharp peak (no 1 - cos^2 cancellation).
//  - G1: Smith masking of GGX at the FIXED alpha 0.25 (Cycles: "alpha2 = 0.0625"; Walter 2007 eq. 34), separable.
//  - F: exact dielectric Fresnel of IOR 1.5 at the microfacet. Cycles' interpolate_fresnel_color with
//    cspec0 = F0 = 0.04 reduces to exactly that.
//  - The Principled node's weight 0.25 * clearcoat is the closure weight the host applies (render/principled.cpp).
//
// Sampling inverts the CDF of D(m) cos theta_m (Burley 2012 eq. 5):
//   cos^2 theta_m = (1 - a^(2u)) / (1 - a^2) = expm1(u L) / expm1(L),  phi = 2 pi v,
// wo = reflect(wi, m), pdf(wo) = D(m) cos theta_m / (4 |wo.m|). (Cycles 3.4 samples GGX visible normals here but
// reports this GTR1 density: its sample weights are biased; this closure's are exact, see docs/scene-format.md.)
// Like Cycles, a^2 <= 1e-7 is a perfect mirror weighted F(wi.n). Only wi.z > 0 and wo.z > 0 scatter.
#pragma once

#include <array>
#include <cmath>

#include "closures/principled_reflection.h"
#include "core/closure.h"
#include "glimmer/microfacet.h"

namespace glimmer::plugin {

namespace clearcoat {

// The coat's dielectric (Cycles 3.4: bsdf->ior = 1.5, f0 = 0.04).
inline constexpr float kIor = 1.5f;
// The fixed alpha of the coat's Smith G (Cycles 3.4: alpha2 = 0.0625).
inline constexpr float kShadowingAlpha = 0.25f;

// GTR1 D(m) for a unit m with m.z > 0, alpha in (0, 1].
inline float gtr1_D(const Vec3 &m, float alpha) {
  if (!(m.z > 0.0f)) return 0.0f;
  const double a2 = double(alpha) * alpha;
  const double L = std::log(a2);
  const double scale = L < 0.0 ? std::expm1(L) / L : 1.0;  // (a^2 - 1) / ln(a^2) -> 1 at a = 1
  const double t = a2 * double(m.z) * m.z + (double(m.x) * m.x + double(m.y) * m.y);
  return t > 0.0 ? static_cast<float>(scale / (kPi * t)) : 0.0f;
}

// m with density D(m) cos theta_m (exact CDF inversion) for u, v in [0, 1).
inline Vec3 sample_gtr1(float alpha, float u, float v) {
  const double L = std::log(double(alpha) * alpha);
  double cos2, sin2;
  if (L < 0.0) {
    const double denom = std::expm1(L);
    cos2 = std::expm1(u * L) / denom;
    sin2 = std::exp(u * L) * std::expm1((1.0 - u) * L) / denom;  // 1 - cos2 without cancellation
  } else {
    cos2 = u;
    sin2 = 1.0 - u;
  }
  const double phi = 2.0 * M_PI * v;
  const double s = std::sqrt(std::max(0.0, sin2));
  return {static_cast<float>(s * std::cos(phi)), static_cast<float>(s * std::sin(phi)),
          static_cast<float>(std::sqrt(std::clamp(cos2, 0.0, 1.0)))};
}

// Smith G1 of the coat (GGX at alpha 0.25), w.z > 0.
inline float coat_G1(const Vec3 &w) {
  return microfacet::G1(microfacet::Distribution::GGX, w, kShadowingAlpha, kShadowingAlpha);
}

// Dielectric Fresnel of the coat at cos_i.
inline float coat_fresnel(float cos_i) { return microfacet::fresnel_dielectric(cos_i, kIor); }

// Cycles' mapping: alpha = saturate(roughness^2), kept >= the shared minimum alpha.
inline float roughness_to_alpha(float roughness) {
  return std::clamp(roughness * roughness, microfacet::kMinAlpha, 1.0f);
}

}  // namespace clearcoat

class ClearcoatClosure : public OneLobeClosure<ClearcoatClosure> {
 public:
  static constexpr const char *kName = "clearcoat";
  static constexpr const char *kDoc =
      "Cycles 3.4 Principled clearcoat lobe: GTR1 (Berry) D with alpha = roughness^2, Smith G of GGX at the fixed "
      "alpha 0.25, dielectric Fresnel IOR 1.5 at the microfacet; the host weights it 0.25 * clearcoat.";
  static constexpr uint32_t kFlags = 0;

  static std::span<const GlimmerParamSpec> params() {
    static const std::array<GlimmerParamSpec, 1> schema{{
        {"roughness", GLIMMER_PARAM_FLOAT, {0.03f, 0, 0}, 0.0f, 1.0f, nullptr, nullptr,
         "Cycles clearcoat_roughness in [0, 1]; GTR1 alpha = roughness^2 (alpha^2 <= 1e-7: mirror)",
         GLIMMER_PARAM_VARYING},
    }};
    return schema;
  }

  struct Lobe {
    float alpha = 0.03f * 0.03f;
    bool singular = false;

    void build(float roughness) {
      alpha = clearcoat::roughness_to_alpha(roughness);
      singular = alpha * alpha <= principled_reflection::kSingularAlpha2;
    }

    LocalEval eval(const Vec3 &wi, const Vec3 &wo) const {
      Vec3 m;
      if (singular || !(wi.z > 0.0f) || !(wo.z > 0.0f) || !microfacet::half_vector_reflect(wi, wo, m)) return {};
      const float cos_om = dot(wo, m);
      if (!(cos_om > 0.0f)) return {};
      const float D = clearcoat::gtr1_D(m, alpha);
      const float G = clearcoat::coat_G1(wi) * clearcoat::coat_G1(wo);
      LocalEval e;
      e.f_cos = Spectrum(clearcoat::coat_fresnel(cos_om) * D * G / (4.0f * wi.z));
      e.pdf = D * m.z / (4.0f * cos_om);
      return e;
    }

    bool sample(const Vec3 &wi, const Vec3 &rand, LocalSample &out) const {
      if (!(wi.z > 0.0f)) return false;
      if (singular) return principled_reflection::sample_mirror(wi, Spectrum(clearcoat::coat_fresnel(wi.z)), out);
      const Vec3 m = clearcoat::sample_gtr1(alpha, rand.x, rand.y);
      return principled_reflection::sample_reflection_about(*this, wi, m, alpha, out);
    }

    // Estimate for closure picking and the Albedo pass: the coat's Fresnel at wi (Cycles' sample weight uses the
    // same F(wi.n)).
    Spectrum albedo(const Vec3 &wi) const { return Spectrum(clearcoat::coat_fresnel(clamp(wi.z, 0.0f, 1.0f))); }
  };

  static std::unique_ptr<ClearcoatClosure> create(const ParamReader &p) {
    auto c = std::make_unique<ClearcoatClosure>();
    c->roughness_ = p.get_float("roughness");
    c->roughness_param_ = p.index("roughness");
    c->lobe_.build(c->roughness_);
    return c;
  }

  const Lobe &constant_lobe() const { return lobe_; }
  void build_lobe_at(const ShadingPoint &sp, Lobe &lobe) const {
    lobe.build(sp.param_float(roughness_param_, roughness_));
  }

 private:
  float roughness_ = 0.03f;
  uint32_t roughness_param_ = 0;
  Lobe lobe_;
};

}  // namespace glimmer::plugin
