// Reference: Heitz, Hanika, d'Eon, Dachsbacher 2016, "Multiple-Scattering
// Microfacet BSDFs with the Smith Model". The GGX microsurface is treated as
// a volume and light performs a random walk on it (glimmer/microfacet_walk.h):
// all scattering orders, exact for the Smith model; slow. For tests and
// benchmarks of the energy compensation (distribution=multi_ggx).
//  - type=conductor: Schlick Fresnel from f0 at every bounce (f0 = 1 Fresnel-free).
//  - type=dielectric: exact Fresnel, reflection/refraction chosen by F,
//    both sides (wi.z < 0 is inside: `backfacing`, in the interface frame of
//    core/closure.h; relative IOR ior = n_inside / n_outside).
// eval() is STOCHASTIC: an unbiased estimate of f * |cos(wo)| from `eval_walks`
// next-event random walks seeded by hash(ctx->path_seed, wo) (deterministic).
// sample() returns the walk's exit direction with f_cos / pdf equal to the
// walk's throughput; pdf is an unbiased estimate of the Fresnel-free walk's
// exit density (eval_walks walks of their own, independent of eval's f), floored
// at 1e-6 so MIS weights stay finite.
// GGX only.
#pragma once

#include <array>
#include <bit>

#include "core/closure.h"
#include "glimmer/microfacet_walk.h"
#include "glimmer/rng.h"

namespace glimmer::plugin {

namespace mf = glimmer::microfacet;

class MicrofacetRandomWalkClosure {
 public:
  static constexpr const char *kName = "microfacet_random_walk";
  static constexpr const char *kDoc =
      "Reference multiple-scattering GGX microsurface (Heitz 2016 random walk), conductor or dielectric; stochastic "
      "eval; slow.";
  static constexpr uint32_t kFlags =
      GLIMMER_CLOSURE_STOCHASTIC_EVAL | GLIMMER_CLOSURE_REFERENCE | GLIMMER_CLOSURE_TRANSMISSIVE;

  static std::span<const GlimmerParamSpec> params() {
    static const std::array<GlimmerParamSpec, 6> schema{{
        {"type", GLIMMER_PARAM_ENUM, {0, 0, 0}, 0.0f, 0.0f, "conductor|dielectric", "conductor",
         "microsurface material", 0},
        {"roughness", GLIMMER_PARAM_FLOAT, {0.5f, 0, 0}, 0.0f, 1.0f, nullptr, nullptr,
         "Cycles roughness in [0, 1]; alpha = roughness^2", 0},
        {"anisotropy", GLIMMER_PARAM_FLOAT, {0.0f, 0, 0}, -1.0f, 1.0f, nullptr, nullptr,
         "anisotropy in [-1, 1] (Cycles 3.4 mapping)", 0},
        {"f0", GLIMMER_PARAM_COLOR, {1.0f, 1.0f, 1.0f}, 0.0f, 1.0f, nullptr, nullptr,
         "conductor: normal-incidence reflectance (Schlick); 1,1,1 = Fresnel-free", 0},
        {"ior", GLIMMER_PARAM_FLOAT, {1.45f, 0, 0}, 1e-3f, 1e3f, nullptr, nullptr,
         "dielectric: relative IOR n_inside / n_outside", 0},
        {"eval_walks", GLIMMER_PARAM_INT, {1.0f, 0, 0}, 1.0f, 4096.0f, nullptr, nullptr,
         "random walks averaged per eval() (variance vs cost)", 0},
    }};
    return schema;
  }

  static std::unique_ptr<MicrofacetRandomWalkClosure> create(const ParamReader &p) {
    auto c = std::make_unique<MicrofacetRandomWalkClosure>();
    c->dielectric_ = p.get_enum("type") == 1;
    const mf::Alpha a = mf::roughness_to_alpha(p.get_float("roughness"), p.get_float("anisotropy"));
    c->surface_ = mf::WalkSurface{a.x, a.y};
    c->f0_ = p.get_color("f0");
    float ior = p.get_float("ior");
    if (std::fabs(ior - 1.0f) < 1e-4f) ior = ior < 1.0f ? 1.0f - 1e-4f : 1.0f + 1e-4f;
    c->ior_ = ior;
    c->eval_walks_ = p.get_int("eval_walks");
    return c;
  }

  // Unbiased estimate of f * |cos(wo)| (and with white = true the Fresnel-free value).
  Spectrum estimate(const Vec3 &wi, const Vec3 &wo, uint32_t seed, bool white) const {
    mf::WalkRng rng(seed);
    Spectrum sum(0.0f);
    for (int n = 0; n < eval_walks_; ++n) {
      if (dielectric_) {
        sum += Spectrum(mf::walk_dielectric_eval(wi, wo, ior_, surface_, rng));
      } else if (white) {
        sum += mf::walk_conductor_eval(wi, wo, surface_, rng, [](float) { return Spectrum(1.0f); });
      } else {
        sum += mf::walk_conductor_eval(wi, wo, surface_, rng,
                                       [this](float c) { return mf::fresnel_schlick(c, f0_); });
      }
    }
    return sum / float(eval_walks_);
  }

  LocalEval eval(const ShadingPoint &sp, const Vec3 &wo) const {
    const Vec3 &wi = sp.wi;
    if (!dielectric_ && (!(wi.z > 0.0f) || !(wo.z > 0.0f))) return {};
    LocalEval e;
    e.f_cos = estimate(wi, wo, sp.seed_for(wo), false);
    e.pdf = pdf_estimate(wi, wo, sp);
    return e;
  }
  // The exit density of the (Fresnel-free) walk is its f * cos, estimated by walks independent of eval's f
  // (their own seed): the host's MIS weight is a function of this estimate, and f * w(pdf) is unbiased only if f
  // and pdf are independent (one shared walk made a frosted pane 14 % dark under MIS). sample() reports the same
  // estimate, so the two strategies' expected weights sum to one.
  float pdf_estimate(const Vec3 &wi, const Vec3 &wo, const ShadingPoint &sp) const {
    const uint32_t seed = hash_u32x2(sp.seed_for(wo), 0x9e3779b9u);
    return dielectric_ ? estimate(wi, wo, seed, false).x : average(estimate(wi, wo, seed, true));
  }

  bool sample(const ShadingPoint &sp, const Vec3 &rand, LocalSample &out) const {
    const Vec3 &wi = sp.wi;
    if (wi.z == 0.0f || (!dielectric_ && !(wi.z > 0.0f))) return false;
    mf::WalkRng rng(sp.seed_for(rand));
    int order = 0;
    Spectrum throughput(1.0f);
    Vec3 wo;
    if (dielectric_) {
      wo = mf::walk_dielectric(wi, ior_, surface_, rng, order);
    } else {
      wo = mf::walk_conductor(wi, surface_, rng, order,
                              [&](float c) { throughput *= mf::fresnel_schlick(c, f0_); });
    }
    if (order == 0 || !is_finite(wo) || wo.z == 0.0f) return false;
    const bool transmit = (wo.z > 0.0f) != (wi.z > 0.0f);
    out.wo = wo;
    out.pdf = std::max(pdf_estimate(wi, wo, sp), 1e-6f);
    out.f_cos = throughput * out.pdf;
    out.roughness = std::sqrt(surface_.ax * surface_.ay);
    out.eta = transmit ? (wi.z > 0.0f ? ior_ : 1.0f / ior_) : 1.0f;
    out.label = (transmit ? GLIMMER_LABEL_TRANSMIT : GLIMMER_LABEL_REFLECT) | GLIMMER_LABEL_GLOSSY;
    return true;
  }

 private:
  bool dielectric_ = false;
  mf::WalkSurface surface_;
  Spectrum f0_{1.0f};
  float ior_ = 1.45f;
  int eval_walks_ = 1;
};

}  // namespace glimmer::plugin
