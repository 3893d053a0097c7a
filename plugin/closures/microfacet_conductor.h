// Rough conductor (Cycles' glossy_bsdf): anisotropic GGX or Beckmann
// microfacet reflection (Walter et al. 2007 eq. 20),
//   f(wi, wo) = F(wi.wh) D(wh) G2(wi, wo) / (4 |wi.n| |wo.n|),
// with Schlick's Fresnel from the normal-incidence colour f0 (f0 = 1 is
// Fresnel-free, as Cycles' glossy BSDF), height-correlated Smith G2 (Heitz 2014
// eq. 99) and visible-normal sampling (Heitz 2018; Heitz & d'Eon 2014).
// The tangent comes from the shading context (ctx->T = x axis, alpha_x).
//
// distribution=multi_ggx adds the multiple-scattering lobe (Kulla & Conty
// 2017 shape, Hill 2022 Fresnel-split energy):
//   f_ms(wi, wo) = E_Fms(mu_i, alpha, f0) (1 - E(mu_o)) / (pi (1 - E_avg)),
// which integrates over wo to E_Fms(mu_i, alpha, f0): the energy the Heitz 2016
// random walk scatters after >= 2 bounces with Schlick Fresnel. With a
// bounce_tint c (Cycles' Multiscatter GGX colour, whose walk multiplies every
// bounce by c), E_Fms is replaced by T(c) / c, the walk's energy of k >= 2
// bounces weighted c^(k-1) (the host applies the first c). Tables:
// plugin/tables/microfacet_energy_data.cpp (`glimmer precompute energy`),
// looked up at alpha = sqrt(alpha_x alpha_y).
// distribution=sharp is a perfect mirror (singular).
// Like Cycles, only wi.z > 0 and wo.z > 0 scatter (the host orients N to wi).
// roughness, anisotropy and f0 are varying (textures): the lobe (alphas and
// table rows) is rebuilt at a shading point that gives per-point values.
#pragma once

#include <algorithm>
#include <array>
#include <bit>

#include "core/closure.h"
#include "core/microfacet_lobe_params.h"
#include "glimmer/microfacet.h"
#include "glimmer/rng.h"
#include "glimmer/sampling.h"
#include "tables/microfacet_energy.h"

namespace glimmer::plugin {

namespace mf = glimmer::microfacet;

// One uniform number u made into two for a 2D warp, keeping stratification: the top 24 bits of u are
// de-interleaved (Morton / Z-order) into two 12-bit numbers, so that N numbers stratified in 1D (one per interval of
// 1 / N) land in distinct cells of a 2D grid of about sqrt(N) x sqrt(N); the position inside the 1 / 4096 cell
// comes from the bits of `jitter` (a hash; it only moves a point within its cell). Both results are uniform when u
// is (exactly, up to u's 24-bit resolution).
inline std::array<float, 2> split_uniform(float u, uint32_t jitter) {
  constexpr float kCells = 4096.0f;  // 2^12 cells per axis: 24 bits of a float in [0, 1)
  const uint32_t bits = std::min(static_cast<uint32_t>(u * 16777216.0f), 16777215u);
  auto compact = [](uint32_t x) {  // every other bit of x (bits 0, 2, 4, ...) packed into the low 12 bits
    x &= 0x555555u;
    x = (x | (x >> 1)) & 0x333333u;
    x = (x | (x >> 2)) & 0x0f0f0fu;
    x = (x | (x >> 4)) & 0x00ff00ffu;
    x = (x | (x >> 8)) & 0x0000ffffu;
    return x;
  };
  const float jx = static_cast<float>(jitter & 0xffffu) * (1.0f / 65536.0f);
  const float jy = static_cast<float>(jitter >> 16) * (1.0f / 65536.0f);
  constexpr float kBelowOne = 0x1.fffffep-1f;
  return {std::min((static_cast<float>(compact(bits >> 1)) + jx) / kCells, kBelowOne),
          std::min((static_cast<float>(compact(bits)) + jy) / kCells, kBelowOne)};
}

class MicrofacetConductorClosure : public OneLobeClosure<MicrofacetConductorClosure> {
 public:
  static constexpr const char *kName = "microfacet_conductor";
  static constexpr const char *kDoc =
      "Rough conductor (Cycles glossy_bsdf): GGX/Beckmann anisotropic microfacet reflection, Schlick Fresnel from f0, "
      "multi_ggx adds multiple-scattering energy compensation.";
  static constexpr uint32_t kFlags = 0;

  static std::span<const GlimmerParamSpec> params() {
    static const std::array<GlimmerParamSpec, 6> schema{{
        {"distribution", GLIMMER_PARAM_ENUM, {0, 0, 0}, 0.0f, 0.0f, "ggx|beckmann|multi_ggx|sharp", "ggx",
         "microfacet distribution; multi_ggx = GGX with multiple-scattering energy compensation; sharp = mirror", 0},
        {"roughness", GLIMMER_PARAM_FLOAT, {0.5f, 0, 0}, 0.0f, 1.0f, nullptr, nullptr,
         "Cycles roughness in [0, 1]; alpha = roughness^2", GLIMMER_PARAM_VARYING},
        {"anisotropy", GLIMMER_PARAM_FLOAT, {0.0f, 0, 0}, -1.0f, 1.0f, nullptr, nullptr,
         "anisotropy in [-1, 1] (Cycles 3.4 mapping: A > 0 gives alpha_x = a (1 - A), alpha_y = a / (1 - A); tangent = x)",
         GLIMMER_PARAM_VARYING},
        {"f0", GLIMMER_PARAM_COLOR, {1.0f, 1.0f, 1.0f}, 0.0f, 1.0f, nullptr, nullptr,
         "normal-incidence reflectance per RGB channel (Schlick Fresnel); 1,1,1 = Fresnel-free", GLIMMER_PARAM_VARYING},
        {"bounce_tint", GLIMMER_PARAM_COLOR, {1.0f, 1.0f, 1.0f}, 0.0f, 1.0f, nullptr, nullptr,
         "multi_ggx only: per-bounce tint c of the multiple-scattering walk, as Cycles' Multiscatter GGX colour (k "
         "bounces -> c^k); the first factor c is the closure weight the host applies, the closure adds c^(k-1)", 0},
        kShadowingParam,
    }};
    return schema;
  }

  // Everything eval/sample need at one shading point: the alphas, Fresnel f0
  // and the energy-table rows at this alpha and f0.
  struct Lobe {
    MicrofacetMode mode = kGgx;
    mf::Distribution dist = mf::Distribution::GGX;
    mf::Shadowing shadowing = mf::Shadowing::HeightCorrelated;
    float ax = 0.25f, ay = 0.25f, alpha_table = 0.25f, e_avg = 1.0f;
    Spectrum f0{1.0f};
    bool white = true;
    // E(mu), E_Fms(mu) at this alpha and f0; built for the instance and, per
    // shading point, only for multi_ggx (whose eval needs them).
    bool has_rows = false;
    tables::ConductorRows rows;

    void build(const MicrofacetLobeParams &lobe, const Spectrum &f0_in, const Spectrum &bounce_tint, bool need_rows) {
      mode = lobe.mode;
      dist = lobe.distribution;
      shadowing = lobe.shadowing;
      ax = lobe.alpha_x;
      ay = lobe.alpha_y;
      alpha_table = lobe.alpha_table;
      f0 = f0_in;
      white = f0.x == 1.0f && f0.y == 1.0f && f0.z == 1.0f;
      has_rows = need_rows || mode == kMultiGgx;
      if (has_rows) rows.build(alpha_table, f0, bounce_tint);
      e_avg = mode == kMultiGgx ? tables::ggx_E_avg(alpha_table) : 1.0f;
      if (mode == kMultiGgx) build_ms_density();
    }

    float g2(const Vec3 &wi, const Vec3 &wo) const { return mf::G2(dist, wi, wo, ax, ay, shadowing); }
    Spectrum fresnel(float cos_i) const { return white ? Spectrum(1.0f) : mf::fresnel_schlick(cos_i, f0); }

    // Probability of the multiple-scattering lobe: its Fresnel-free share 1 - E(mu_i) (the mass the
    // single-scattering lobe misses, F = 1).
    float ms_probability(float mu_i) const {
      if (mode != kMultiGgx || !(e_avg < 1.0f)) return 0.0f;
      return clamp(1.0f - rows.E(mu_i), 0.0f, 1.0f);
    }

    // The multiple-scattering lobe is sampled in mu_o = cos(theta_o) from the density proportional to its shape
    // g(mu) = (1 - E(mu)) mu, interpolated linearly between kMsNodes + 1 evenly spaced nodes (g(0) = 0) and
    // inverted exactly per interval; phi uniform. f_ms cos / q then differs from the constant E_Fms(mu_i) only by
    // the interpolation error of g (below 1e-3 relative at 64 intervals), where cosine sampling left a 1 - E(mu_o)
    // factor in the weight.
    static constexpr int kMsNodes = 64;
    std::array<float, kMsNodes + 1> ms_g{};    // g at mu = k / kMsNodes, divided by its integral
    std::array<float, kMsNodes + 1> ms_cdf{};  // integral of the normalised g up to node k
    void build_ms_density() {
      for (int k = 0; k <= kMsNodes; ++k) {
        const float mu = static_cast<float>(k) / kMsNodes;
        ms_g[k] = std::max(1.0f - rows.E(mu), 1e-4f) * mu;
      }
      double acc = 0.0;
      ms_cdf[0] = 0.0f;
      for (int k = 0; k < kMsNodes; ++k) {
        acc += 0.5 * (static_cast<double>(ms_g[k]) + ms_g[k + 1]) / kMsNodes;
        ms_cdf[k + 1] = static_cast<float>(acc);
      }
      for (int k = 0; k <= kMsNodes; ++k) {
        ms_g[k] = static_cast<float>(ms_g[k] / acc);
        ms_cdf[k] = static_cast<float>(ms_cdf[k] / acc);
      }
      ms_cdf[kMsNodes] = 1.0f;
    }
    // Solid-angle density of the multiple-scattering lobe's sampling at cos(theta_o) = mu.
    float ms_pdf(float mu) const {
      if (!(mu > 0.0f)) return 0.0f;
      const float x = std::min(mu, 1.0f) * kMsNodes;
      const int k = std::min(static_cast<int>(x), kMsNodes - 1);
      const float t = x - static_cast<float>(k);
      return ((1.0f - t) * ms_g[k] + t * ms_g[k + 1]) * (0.5f * kInvPi);
    }
    // Inverts the piecewise-linear CDF: in interval k the normalised density is g_k (1 - t) + g_k+1 t over
    // dmu = dt / kMsNodes, so the fraction s of the interval's mass below t solves
    // g_k t + (g_k+1 - g_k) t^2 / 2 = s (g_k + g_k+1) / 2 (root in the cancellation-free form).
    Vec3 sample_ms(float u, float v) const {
      const int k = std::clamp(
          static_cast<int>(std::upper_bound(ms_cdf.begin(), ms_cdf.end(), u) - ms_cdf.begin()) - 1, 0, kMsNodes - 1);
      const float width = ms_cdf[k + 1] - ms_cdf[k];
      const float s = width > 0.0f ? std::clamp((u - ms_cdf[k]) / width, 0.0f, 1.0f) : 0.5f;
      const float g0 = ms_g[k], g1 = ms_g[k + 1];
      const float root = g0 + std::sqrt(std::max(g0 * g0 + (g1 * g1 - g0 * g0) * s, 0.0f));
      const float t = root > 0.0f ? std::clamp(s * (g0 + g1) / root, 0.0f, 1.0f) : s;
      const float mu = std::max((static_cast<float>(k) + t) / kMsNodes, 1e-6f);
      const float sin_theta = safe_sqrt(1.0f - mu * mu), phi = kTwoPi * v;
      return {sin_theta * std::cos(phi), sin_theta * std::sin(phi), mu};
    }

    // Multiple-scattering lobe f_ms * cos(wo).
    Spectrum ms_eval(float mu_i, float mu_o) const {
      const float denom = kPi * (1.0f - e_avg);
      if (!(denom > 1e-7f)) return Spectrum(0.0f);
      const float shape = std::max(1.0f - rows.E(mu_o), 0.0f) / denom;
      return rows.E_Fms(mu_i) * (shape * mu_o);
    }

    // Single-scatter f * cos(wo) and the visible-normal pdf, given wh; f_cos_white is f * cos(wo) at F = 1.
    LocalEval single_eval(const Vec3 &wi, const Vec3 &wo, const Vec3 &wh, float &f_cos_white) const {
      f_cos_white = 0.0f;
      const float cos_ih = dot(wi, wh);
      if (!(cos_ih > 0.0f)) return {};
      const float d = mf::D(dist, wh, ax, ay);
      f_cos_white = d * g2(wi, wo) / (4.0f * wi.z);
      LocalEval e;
      e.f_cos = fresnel(cos_ih) * f_cos_white;
      e.pdf = mf::visible_D(dist, wi, wh, ax, ay) / (4.0f * cos_ih);
      return e;
    }

    // Which sampler: isotropic multi_ggx at a vertex whose BSDF samples no light strategy is MIS-combined with
    // (`uncombined`, the host's GLIMMER_SAMPLING_UNCOMBINED) is sampled exactly in proportion to its Fresnel-free
    // f cos (sample_exact: constant weight, but a discontinuous warp in the 3D sample cube, which costs QMC
    // convergence wherever MIS with a light reweights the samples; docs/microfacet.md). Elsewhere the lobe
    // mixture. The table's E(mu_i) is the single-scattering albedo of the isotropic lobe only, so anisotropic
    // lobes always use the mixture.
    bool exact_sampling(bool uncombined) const { return uncombined && mode == kMultiGgx && ax == ay && e_avg < 1.0f; }

    // f cos and the pdf of the sampler `uncombined` selects (exact_sampling).
    LocalEval eval(const Vec3 &wi, const Vec3 &wo, bool uncombined) const {
      if (mode == kSharp || !(wi.z > 0.0f) || !(wo.z > 0.0f)) return {};
      Vec3 wh;
      LocalEval e;
      float f_ss_white = 0.0f;
      if (mf::half_vector_reflect(wi, wo, wh)) e = single_eval(wi, wo, wh, f_ss_white);
      const float p_ms = ms_probability(wi.z);
      if (p_ms > 0.0f) {
        e.f_cos += ms_eval(wi.z, wo.z);
        // Exact sampling: accepted visible normals have the density f_ss cos at F = 1, D G2 / (4 mu_i); the
        // rejected mass 1 - E(mu_i) goes to the compensation lobe's density.
        e.pdf = exact_sampling(uncombined) ? f_ss_white + p_ms * ms_pdf(wo.z) : (1.0f - p_ms) * e.pdf + p_ms * ms_pdf(wo.z);
      }
      return e;
    }

    // Isotropic multi_ggx (Fresnel-free f cos integrates to 1 over wo, so f cos is itself a density): a visible
    // normal from (rand.x, rand.y) reflects wi to wo with density G1(wi) D / (4 mu_i) (Heitz 2018 eq. 17 with the
    // reflection Jacobian 1 / (4 wi.wh)); accepting it with probability G2(wi, wo) / G1(wi) <= 1 on rand.z
    // leaves exactly f_ss cos at F = 1, and the rejected mass is 1 - E(mu_i), the compensation lobe's mass, from
    // which the rejected samples draw. On rejection rand.z rescaled to the rejected range is a fresh uniform
    // number, split into the two numbers (mu_o, phi) of the compensation lobe by split_uniform (stratified in 2D).
    // The sample weight is then 1 for F = 1 (up to the tables' error) and the Fresnel average otherwise.
    Vec3 sample_exact(const Vec3 &wi, const Vec3 &rand) const {
      const Vec3 m = mf::sample_visible_normal(dist, wi, ax, ay, rand.x, rand.y);
      const Vec3 wo = normalize(mf::reflect_about(wi, m));
      const float accept = wo.z > 0.0f ? g2(wi, wo) / mf::G1(dist, wi, ax, ay) : 0.0f;
      float u = rand.z;
      if (choose_and_rescale(accept, u)) return wo;
      const std::array<float, 2> uv = split_uniform(u, hash_u32x3(std::bit_cast<uint32_t>(rand.x),
                                                                  std::bit_cast<uint32_t>(rand.y),
                                                                  std::bit_cast<uint32_t>(rand.z)));
      return sample_ms(uv[0], uv[1]);
    }

    bool sample(const Vec3 &wi, const Vec3 &rand, LocalSample &out, bool uncombined) const {
      if (!(wi.z > 0.0f)) return false;
      if (mode == kSharp) {
        out.wo = Vec3(-wi.x, -wi.y, wi.z);
        out.f_cos = fresnel(wi.z);
        out.pdf = 1.0f;
        out.roughness = 0.0f;
        out.label = GLIMMER_LABEL_REFLECT | GLIMMER_LABEL_SINGULAR;
        return true;
      }
      if (exact_sampling(uncombined)) {
        out.wo = sample_exact(wi, rand);
      } else {
        // Lobe choice on rand.x, rescaled and reused for the direction (keeps the 2D point stratified).
        float u = rand.x;
        if (choose_and_rescale(ms_probability(wi.z), u)) {
          out.wo = sample_ms(u, rand.y);
        } else {
          const Vec3 m = mf::sample_visible_normal(dist, wi, ax, ay, u, rand.y);
          out.wo = normalize(mf::reflect_about(wi, m));
        }
      }
      if (!(out.wo.z > 0.0f)) return false;
      const LocalEval e = eval(wi, out.wo, uncombined);
      out.f_cos = e.f_cos;
      out.pdf = e.pdf;
      out.roughness = std::sqrt(ax * ay);
      out.label = GLIMMER_LABEL_REFLECT | GLIMMER_LABEL_GLOSSY;
      return out.pdf > 0.0f;
    }

    // Directional albedo estimate (sample weights, Albedo AOV).
    Spectrum albedo(const Vec3 &wi) const {
      const float mu = clamp(wi.z, 0.0f, 1.0f);
      const Spectrum f = fresnel(mu);
      if (mode == kSharp) return f;
      const Spectrum single = f * (has_rows ? rows.E(mu) : tables::ggx_E(mu, alpha_table));
      if (mode != kMultiGgx) return single;
      return single + rows.E_Fms(mu);
    }
  };

  static std::unique_ptr<MicrofacetConductorClosure> create(const ParamReader &p) {
    auto c = std::make_unique<MicrofacetConductorClosure>();
    c->inputs_ = MicrofacetLobeInputs::parse(p);
    c->f0_param_ = p.index("f0");
    c->bounce_tint_ = p.get_color("bounce_tint");
    c->lobe_.build(c->inputs_.constant(), p.get_color("f0"), c->bounce_tint_, true);
    return c;
  }

  // The sampler (and so eval's pdf) depends on whether light sampling is MIS-combined at this vertex.
  LocalEval eval(const ShadingPoint &sp, const Vec3 &wo) const { return lobe_at(sp).eval(sp.wi, wo, sp.uncombined()); }
  bool sample(const ShadingPoint &sp, const Vec3 &rand, LocalSample &out) const {
    return lobe_at(sp).sample(sp.wi, rand, out, sp.uncombined());
  }

  // The instance's lobe, and the lobe from the per-point values of the varying parameters (OneLobeClosure).
  const Lobe &constant_lobe() const { return lobe_; }
  void build_lobe_at(const ShadingPoint &sp, Lobe &lobe) const {
    lobe.build(inputs_.at(sp), sp.param_color(f0_param_, lobe_.f0), bounce_tint_, false);
  }

 private:
  MicrofacetLobeInputs inputs_;
  uint32_t f0_param_ = 0;
  Spectrum bounce_tint_{1.0f};
  Lobe lobe_;
};

}  // namespace glimmer::plugin
