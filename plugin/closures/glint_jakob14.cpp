// glint_jakob14 (XML node glint_jakob14_bsdf): the reference discrete
// stochastic microfacet BRDF of Jakob, Hasan, Yan, Lawrence, Ramamoorthi,
// Marschner 2014, "Discrete Stochastic Microfacet Models" (SIGGRAPH), with
// the same parameters, particle density and BRDF normalisation as `glint`, so
// the two converge to the same mean. Exact and slow: for tests and the
// time-vs-error benchmark.
//
// The particle set and its pruned count query are the 4D hierarchy of
// tables/glint_hierarchy.h (Jakob 2014 sec. 4-5), validated against brute
// force enumeration of every particle in tests/closures/test_glint_hierarchy.cpp.
//
// BRDF: f cos_o = W(wi, wo) K / (N a(A) sigma_gamma), the same estimator as
// glint's unfiltered mode (glint.cpp eq. 2). Sampling and pdf: the same exact
// smooth-lobe mixture as glint (tables/glint_common.h).
#include <memory>

#include "core/closure.h"
#include "glimmer/microfacet.h"
#include "glimmer/rng.h"
#include "tables/glint_common.h"
#include "tables/glint_hierarchy.h"

namespace glimmer::plugin {

namespace mf = glimmer::microfacet;

class GlintJakob14Closure {
 public:
  static constexpr const char *kName = "glint_jakob14";
  static constexpr const char *kDoc =
      "Reference glints: Jakob et al. 2014 discrete stochastic microfacets, 4D hierarchy (slow, exact).";
  static constexpr uint32_t kFlags = GLIMMER_CLOSURE_REFERENCE;
  static std::span<const GlimmerParamSpec> params() {
    static const auto schema = glint::particle_field_params(
        {"base roughness (alpha = roughness^2); values below 0.15 are treated as 0.15 (as glint)",
         "query cone half-angle in degrees", "particle reflectance at normal incidence (Schlick Fresnel F0)"});
    return schema;
  }

  static std::unique_ptr<GlintJakob14Closure> create(const ParamReader &p) {
    auto c = std::make_unique<GlintJakob14Closure>();
    c->field_ = glint::ParticleField::parse(p);
    c->gamma_ = c->field_.gamma_deg * (kPi / 180.0f);
    c->cone_solid_angle_ = kTwoPi * (1.0f - std::cos(c->gamma_));
    c->hierarchy_ = glint::ParticleHierarchy(c->field_.distribution, c->field_.alpha, c->field_.density, c->field_.seed);
    return c;
  }

  Spectrum glint_f_cos(const GlimmerShadingContext *ctx, const Vec3 &wi, const Vec3 &wo) const {
    Spectrum weight;
    if (!glint::glint_weight(field_.distribution, field_.alpha, field_.color, wi, wo, weight)) return Spectrum(0.0f);
    const glint::ParticleQuery q = glint::ParticleQuery::make(field_.footprint(ctx), wi, wo, gamma_);
    const uint64_t k = hierarchy_.count(q).count;
    if (k == 0) return Spectrum(0.0f);
    const double scale =
        static_cast<double>(k) / (static_cast<double>(field_.density) * q.fp.area() * cone_solid_angle_);
    return weight * static_cast<float>(scale);
  }

  float sampling_alpha() const {
    const float widen = 0.5f * gamma_;
    return std::sqrt(field_.alpha * field_.alpha + widen * widen);
  }

  LocalEval eval(const ShadingPoint &sp, const Vec3 &wo) const {
    LocalEval e;
    e.f_cos = glint_f_cos(sp.ctx, sp.wi, wo);
    e.pdf = glint::smooth_lobe_pdf(sampling_alpha(), sp.wi, wo);
    return e;
  }

  bool sample(const ShadingPoint &sp, const Vec3 &rand, LocalSample &out) const {
    const float alpha_w = sampling_alpha();
    if (!glint::sample_smooth_lobe(alpha_w, sp.wi, rand, out.wo)) return false;
    out.pdf = glint::smooth_lobe_pdf(alpha_w, sp.wi, out.wo);
    out.f_cos = glint_f_cos(sp.ctx, sp.wi, out.wo);
    out.roughness = alpha_w;  // alpha units, as the conductor reports
    out.label = GLIMMER_LABEL_REFLECT | GLIMMER_LABEL_GLOSSY;
    return out.pdf > 0.0f;
  }

  Spectrum albedo(const ShadingPoint &) const { return field_.color; }

 private:
  glint::ParticleField field_;
  glint::ParticleHierarchy hierarchy_;
  float gamma_ = 0.035f;  // radians
  float cone_solid_angle_ = 1.0f;
};

GLIMMER_REGISTER_CLOSURE(GlintJakob14Closure)

}  // namespace glimmer::plugin
