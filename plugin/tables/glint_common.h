// Pieces shared by the two glint closures (glint.cpp and glint_jakob14.cpp):
// the particle-field parameters both take, the per-glint weight W of the BRDF
// and the smooth-lobe sampler whose density pdf() returns exactly.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>

#include <emmintrin.h>

#include "core/params.h"
#include "glimmer/closure_abi.h"
#include "glimmer/math.h"
#include "glimmer/microfacet.h"
#include "glimmer/sampling.h"
#include "tables/glint_particles.h"
#include "tables/glint_tables.h"

// Finiteness is tested as x - x == 0 here (ParticleField::valid_footprint), which -ffinite-math-only folds to true.
#if defined(__FINITE_MATH_ONLY__) && __FINITE_MATH_ONLY__
#error "glint_common.h needs IEEE infinities and NaNs (no -ffinite-math-only / -ffast-math)"
#endif

namespace glimmer::plugin::glint {

namespace mf = glimmer::microfacet;

// ---- Table coordinates -------------------------------------------------------
// acos in degrees, |error| < 0.004 degrees (Abramowitz & Stegun 4.4.45): far
// below the 1-degree table bins, and 3x cheaper than std::acos. |x| > 1 and
// NaN are read as |x| = 1 (a NaN x gives 180).
inline float fast_acos_deg(float x) {
  const float ax = std::fabs(x), a = ax < 1.0f ? ax : 1.0f;  // comparisons: std::fmin is a library call
  const float r = std::sqrt(1.0f - a) * (1.5707288f + a * (-0.2121144f + a * (0.0742610f - 0.0187293f * a)));
  return (x >= 0.0f ? r : kPi - r) * kRadToDeg;
}

// Table coordinates of (wi, wo) in degrees: polar angles and the folded
// azimuth difference; aligned with a fourth float (unused, any value) so the
// three are one SSE load (lanes()) for the table's cell and the peak bound.
struct alignas(16) TableCoords {
  float theta_i, theta_o, dphi;
  float unused = 0.0f;
  __m128 lanes() const { return _mm_load_ps(&theta_i); }
};

// cos of the azimuth difference of wi and wo (1 when either is along z).
inline float cos_azimuth_difference(const Vec3 &wi, const Vec3 &wo) {
  const float denom2 = (wi.x * wi.x + wi.y * wi.y) * (wo.x * wo.x + wo.y * wo.y);
  return denom2 > 1e-24f ? (wi.x * wo.x + wi.y * wo.y) / std::sqrt(denom2) : 1.0f;
}

// The three fast_acos_deg in scalar code (the reference of table_coords).
inline TableCoords table_coords_scalar(const Vec3 &wi, const Vec3 &wo) {
  return {fast_acos_deg(wi.z), fast_acos_deg(wo.z), fast_acos_deg(cos_azimuth_difference(wi, wo))};
}

// The same three fast_acos_deg in the lanes of one SSE register: the same
// float operations in the same order (no fused multiply-add in this build),
// so the same bits as table_coords_scalar (tests/closures/test_glint.cpp,
// GlintCoords.*), with one square root instead of three.
inline TableCoords table_coords(const Vec3 &wi, const Vec3 &wo) {
  const __m128 x = _mm_setr_ps(wi.z, wo.z, cos_azimuth_difference(wi, wo), 0.0f);
  const __m128 one = _mm_set1_ps(1.0f);
  const __m128 ax = _mm_andnot_ps(_mm_set1_ps(-0.0f), x);
  const __m128 a = _mm_min_ps(ax, one);  // ax < 1 ? ax : 1, as the scalar select (NaN -> 1)
  __m128 poly = _mm_sub_ps(_mm_set1_ps(0.0742610f), _mm_mul_ps(_mm_set1_ps(0.0187293f), a));
  poly = _mm_add_ps(_mm_set1_ps(-0.2121144f), _mm_mul_ps(a, poly));
  poly = _mm_add_ps(_mm_set1_ps(1.5707288f), _mm_mul_ps(a, poly));
  const __m128 r = _mm_mul_ps(_mm_sqrt_ps(_mm_sub_ps(one, a)), poly);
  const __m128 upper = _mm_cmpge_ps(x, _mm_setzero_ps());  // x >= 0 (false for NaN)
  const __m128 folded = _mm_sub_ps(_mm_set1_ps(kPi), r);
  const __m128 angle = _mm_or_ps(_mm_and_ps(upper, r), _mm_andnot_ps(upper, folded));
  TableCoords c;
  _mm_store_ps(&c.theta_i, _mm_mul_ps(angle, _mm_set1_ps(kRadToDeg)));  // lane 3: acos(0) in degrees
  return c;
}

// ---- The particle field ------------------------------------------------------
// Both closures describe the same surface: N particles per unit of scaled uv
// area whose normals follow D(m) cos(theta_m) of a GGX or Beckmann base, seen
// through a query cone of half-angle gamma. The schema entries are declared
// once here; each closure words three of the docs for its own use.
struct ParticleFieldDocs {
  const char *roughness;
  const char *gamma;
  const char *color;
};

inline constexpr size_t kParticleFieldParamCount = 7;

// The schema entries of the particle field followed by a closure's own
// `extra` entries (N of them). constexpr, so a closure's schema can be a
// constant-initialised static (no guard and no call per shading point).
template <size_t N = 0>
constexpr std::array<GlimmerParamSpec, kParticleFieldParamCount + N> particle_field_params(
    const ParticleFieldDocs &docs, const std::array<GlimmerParamSpec, N> &extra = {}) {
  std::array<GlimmerParamSpec, kParticleFieldParamCount + N> schema{{
      {"distribution", GLIMMER_PARAM_ENUM, {0, 0, 0}, 0, 0, "ggx|beckmann", "ggx",
       "base microfacet distribution of the particle normals", 0},
      {"roughness", GLIMMER_PARAM_FLOAT, {0.4f, 0, 0}, 0.0f, 1.0f, nullptr, nullptr, docs.roughness, 0},
      {"gamma", GLIMMER_PARAM_FLOAT, {2.0f, 0, 0}, 0.1f, 10.0f, nullptr, nullptr, docs.gamma, 0},
      {"density", GLIMMER_PARAM_FLOAT, {1e6f, 0, 0}, 1.0f, 1e12f, nullptr, nullptr,
       "particles per unit of scaled uv area", 0},
      {"uv_scale", GLIMMER_PARAM_FLOAT, {1.0f, 0, 0}, 1e-4f, 1e6f, nullptr, nullptr,
       "scale of the uv coordinates the particles live in (uv * uv_scale)", 0},
      {"seed", GLIMMER_PARAM_INT, {0, 0, 0}, 0.0f, 2147483648.0f, nullptr, nullptr,
       "random seed of the particle field (integer in [0, 2^31], exact)", 0},
      {"color", GLIMMER_PARAM_COLOR, {1, 1, 1}, 0.0f, 1.0f, nullptr, nullptr, docs.color, 0},
  }};
  for (size_t i = 0; i < N; ++i) schema[kParticleFieldParamCount + i] = extra[i];
  return schema;
}

// The validated particle-field parameters of one closure instance.
struct ParticleField {
  // Smallest alpha the 1-degree tables resolve (roughness 0.15).
  static constexpr float kMinAlpha = 0.0225f;

  mf::Distribution distribution = mf::Distribution::GGX;
  float alpha = 0.16f;      // max(roughness^2, kMinAlpha)
  float gamma_deg = 2.0f;   // query cone half-angle, degrees
  float density = 1e6f;     // N, particles per unit of scaled uv area
  float uv_scale = 1.0f;
  uint32_t seed = 0;
  Spectrum color{1.0f};     // Schlick F0

  static ParticleField parse(const ParamReader &p) {
    ParticleField f;
    f.distribution = p.get_enum("distribution") == 0 ? mf::Distribution::GGX : mf::Distribution::Beckmann;
    f.alpha = std::max(sqr(p.get_float("roughness")), kMinAlpha);
    f.gamma_deg = p.get_float("gamma");
    f.density = p.get_float("density");
    f.uv_scale = p.get_float("uv_scale");
    f.seed = static_cast<uint32_t>(p.get_int64("seed"));  // ABI 2.2 integer payload: exact beyond 2^24
    f.color = p.get_color("color");
    return f;
  }

  // The pixel footprint in scaled uv: the parallelogram of the context's uv
  // differentials around its uv. A non-finite uv is queried at the origin; a
  // zero, huge or non-finite footprint becomes a point query (a 1/N square).
  Footprint footprint(const GlimmerShadingContext *ctx) const {
    double area;
    return footprint(ctx, area);
  }
  // The same and its area (f.area(), from valid_footprint's own test: computed once per eval).
  Footprint footprint(const GlimmerShadingContext *ctx, double &area) const {
    Footprint f;
    const double s = uv_scale;
    f.cx = ctx->uv[0] * s;
    f.cy = ctx->uv[1] * s;
    f.ax = ctx->duv_dx[0] * s;
    f.ay = ctx->duv_dx[1] * s;
    f.bx = ctx->duv_dy[0] * s;
    f.by = ctx->duv_dy[1] * s;
    return valid_footprint(f, area);
  }

  // A footprint in the particles' plane (scaled units), with the rules
  // above for a non-finite centre and a degenerate parallelogram.
  // The finiteness tests (session 25): x - x is 0 exactly when x is finite (inf - inf and NaN are NaN; this file
  // must not be built with -ffinite-math-only, which would fold it to 0: see the #error above); a non-finite
  // ax, ay, bx or by makes the area inf or NaN (inf times anything is inf or NaN, and so is inf minus inf), which
  // the range test refuses, so the four need no test of their own. GlintCoords.ValidFootprintMatchesTheIsfiniteForm.
  Footprint valid_footprint(Footprint f) const {
    double area;
    return valid_footprint(f, area);
  }
  // The same and the returned footprint's area (f.area()).
  Footprint valid_footprint(Footprint f, double &area) const {
    if (!((f.cx - f.cx) + (f.cy - f.cy) == 0.0)) f.cx = f.cy = 0.0;
    area = f.area();
    if (!(area > 1e-30) || !(area < 1e30)) {
      const double side = 1.0 / std::sqrt(static_cast<double>(density));
      f.ax = side;
      f.ay = 0.0;
      f.bx = 0.0;
      f.by = side;
      area = f.area();
    }
    return f;
  }
};

// Smith G1 and height-correlated G2 from their Lambdas (mf::G1 / mf::G2's formulas; since session 40 every closure's
// Beckmann Lambda is the polynomial, so G1 / G2 of a direction are mf::G1 / mf::G2 themselves).
inline float smith_g1_of(float l) { return std::isfinite(l) ? 1.0f / (1.0f + l) : 0.0f; }
inline float smith_g2_of(float li, float lo) {
  const float s = 1.0f + li + lo;
  return std::isfinite(s) ? 1.0f / s : 0.0f;
}

// The sampling lobe's distribution, whatever the base's: GGX (session 41). For a Beckmann base, GGX visible normals
// at the same alpha are a proposal with the same peak density 1 / (pi alpha^2) and heavier tails (D_Beckmann /
// D_GGX = e^-x (1 + x)^2 <= 4 / e at x = tan^2(theta_h) / alpha^2), drawn and evaluated in closed form, where
// Beckmann's visible normals need an iterative inversion of their CDF (erfcx, an inverse erf) and D an expf. The
// sampler is a proposal only: pdf() returns its density exactly, eval() the Beckmann glint BRDF.
// Measured in the GI scene (examples/glint.xml, floor glint Beckmann 0.5; 8 seeds, 320 x 200, 16 spp): per-pixel
// variance 4.056e-2 vs 4.049e-2 with Beckmann's own visible normals (+0.2 %), image mean equal within 0.1 sd.
inline constexpr mf::Distribution kSamplingDistribution = mf::Distribution::GGX;

// The three Smith Lambdas one isotropic eval needs (issue 10, session 14):
// Lambda(wi) and Lambda(wo) of the base distribution at the base alpha (W's G2) and GGX's Lambda(wi) at the
// sampling lobe's alpha (the pdf's G1; kSamplingDistribution), each of (x, y, |z|) as mf::G1 /
// mf::G2 take them. GGX: in the lanes of one SSE register with the same
// float operations in the same order as mf::ggx_lambda, so the same bits
// (test GlintCoords.PackedLambdasMatchTheScalarForm), one division pair and
// one square root for three; a lane outside the regular case (|z| not > 0,
// alpha^2 tan^2 not finite) sends all three to the scalar mf::lambda.
// Beckmann: the first two in AVX lanes (below) or by the scalar mf::lambda.
struct EvalLambdas {
  float wi, wo;   // the base distribution at the base alpha
  float wi_lobe;  // GGX (the sampling lobe) at the sampling lobe's alpha
};
// Out of line (session 24, glintdark24: the fallback of the lane forms below; with GlintClosure one member larger,
// GCC inlined a copy into glint.cpp's f_cos_and_pdf, 2225 -> 2464 instructions of code, r0.4 area 1e-4 +12 per eval).
[[gnu::noinline]] inline EvalLambdas eval_lambdas_scalar(mf::Distribution dist, float alpha, float alpha_lobe,
                                                         const Vec3 &wi, const Vec3 &wo) {
  const Vec3 ai(wi.x, wi.y, std::fabs(wi.z)), ao(wo.x, wo.y, std::fabs(wo.z));
  return {mf::lambda(dist, ai, alpha, alpha), mf::lambda(dist, ao, alpha, alpha),
          mf::lambda(kSamplingDistribution, ai, alpha_lobe, alpha_lobe)};
}
// alpha2_tan2 = (sqr(ax x) + sqr(ay y)) / sqr(z) of the eval's three Lambdas in SSE lanes: wi at alpha, wo at alpha,
// wi at alpha_lobe (and the third again, discarded); `z` gets |z| per lane for the caller's regular-case test.
// Shared by eval_lambdas (GGX) and eval_lambdas_beckmann_avx2 (inlined into both: the same operations).
[[gnu::always_inline]] inline __m128 eval_alpha2_tan2_lanes(float alpha, float alpha_lobe, const Vec3 &wi,
                                                            const Vec3 &wo, __m128 &z) {
  const __m128 x = _mm_setr_ps(wi.x, wo.x, wi.x, wi.x), y = _mm_setr_ps(wi.y, wo.y, wi.y, wi.y);
  z = _mm_andnot_ps(_mm_set1_ps(-0.0f), _mm_setr_ps(wi.z, wo.z, wi.z, wi.z));
  const __m128 a = _mm_setr_ps(alpha, alpha, alpha_lobe, alpha_lobe);
  const __m128 ax = _mm_mul_ps(a, x), ay = _mm_mul_ps(a, y);
  return _mm_div_ps(_mm_add_ps(_mm_mul_ps(ax, ax), _mm_mul_ps(ay, ay)), _mm_mul_ps(z, z));
}
// GGX's Lambda of alpha2_tan2 per lane, a2 / (2 (1 + sqrt(1 + a2))): mf::ggx_lambda's float operations.
[[gnu::always_inline]] inline __m128 ggx_lambda_lanes(__m128 a2) {
  const __m128 one = _mm_set1_ps(1.0f);
  return _mm_div_ps(a2, _mm_mul_ps(_mm_set1_ps(2.0f), _mm_add_ps(one, _mm_sqrt_ps(_mm_add_ps(one, a2)))));
}
#if GLIMMER_GLINT_WALK_AVX2
// Beckmann's Lambdas of wi and wo (and GGX's of wi at the lobe's alpha, from the same lanes' alpha2_tan2) in the
// lanes of AVX registers (session 22), where
// the walk uses AVX2 (kWalkAvx2): per lane beckmann_lambda_with's steps for
// (x, y, |z|) (alpha2_tan2 in float, a = 1 / sqrt(a2) in double, 0 for
// a >= 4, else the polynomial's two Horner chains and (pe + x po) / a, then
// max(l, 0) to float), the same operations in the same order (no FMA: avx2
// does not enable it), so the same bits as eval_lambdas_scalar; a lane
// outside the regular case (|z| not > 0, a2 not > 0 or not finite) sends all
// three to the scalar form. GlintCoords.BeckmannLambdaLanesMatchTheScalarForm.
[[gnu::target("avx2"), gnu::noinline]] inline EvalLambdas eval_lambdas_beckmann_avx2(float alpha, float alpha_lobe,
                                                                                     const Vec3 &wi, const Vec3 &wo) {
  __m128 z;
  const __m128 a2 = eval_alpha2_tan2_lanes(alpha, alpha_lobe, wi, wo, z);
  const __m128 regular = _mm_and_ps(_mm_and_ps(_mm_cmpgt_ps(z, _mm_setzero_ps()), _mm_cmpgt_ps(a2, _mm_setzero_ps())),
                                    _mm_cmple_ps(a2, _mm_set1_ps(3.4028234664e38f)));
  if (_mm_movemask_ps(regular) != 0xf) return eval_lambdas_scalar(mf::Distribution::Beckmann, alpha, alpha_lobe, wi, wo);
  const __m256d one = _mm256_set1_pd(1.0);
  const __m256d a = _mm256_div_pd(one, _mm256_sqrt_pd(_mm256_cvtps_pd(a2)));
  const __m256d t = _mm256_sub_pd(_mm256_mul_pd(_mm256_set1_pd(0.5), a), one), t2 = _mm256_mul_pd(t, t);
  const double *c = mf::kBeckmannLambdaPoly;
  __m256d pe = _mm256_set1_pd(c[18]), po = _mm256_set1_pd(c[19]);
  for (int k = 16; k >= 0; k -= 2) {
    pe = _mm256_add_pd(_mm256_mul_pd(pe, t2), _mm256_set1_pd(c[k]));
    po = _mm256_add_pd(_mm256_mul_pd(po, t2), _mm256_set1_pd(c[k + 1]));
  }
  __m256d l = _mm256_div_pd(_mm256_add_pd(pe, _mm256_mul_pd(t, po)), a);
  l = _mm256_andnot_pd(_mm256_cmp_pd(a, _mm256_set1_pd(4.0), _CMP_GE_OQ), l);  // a >= 4: 0
  const __m128 lf = _mm256_cvtpd_ps(_mm256_max_pd(_mm256_setzero_pd(), l));   // std::max(l, 0.0): l < 0 -> 0
  alignas(16) float out[4], ggx[4];
  _mm_store_ps(out, lf);
  _mm_store_ps(ggx, ggx_lambda_lanes(a2));
  return {out[0], out[1], ggx[2]};
}
#endif
inline EvalLambdas eval_lambdas(mf::Distribution dist, float alpha, float alpha_lobe, const Vec3 &wi,
                                const Vec3 &wo) {
  // Beckmann: the scalar polynomial (the same polynomial in SSE2 double lanes, two registers for the three Lambdas,
  // measured no fewer instructions per eval: 1133 -> 1138 at footprint area 1); session 22: one AVX register for
  // the three where the walk uses AVX2.
  if (dist != mf::Distribution::GGX) {
#if GLIMMER_GLINT_WALK_AVX2
    if (kWalkAvx2) return eval_lambdas_beckmann_avx2(alpha, alpha_lobe, wi, wo);
#endif
    return eval_lambdas_scalar(dist, alpha, alpha_lobe, wi, wo);
  }
  __m128 z;
  const __m128 a2 = eval_alpha2_tan2_lanes(alpha, alpha_lobe, wi, wo, z);
  const __m128 regular_z = _mm_cmpgt_ps(z, _mm_setzero_ps());
  const __m128 finite = _mm_cmple_ps(a2, _mm_set1_ps(3.4028234664e38f));  // false for inf and NaN
  if (_mm_movemask_ps(_mm_and_ps(regular_z, finite)) != 0xf)
    return eval_lambdas_scalar(dist, alpha, alpha_lobe, wi, wo);
  alignas(16) float out[4];
  _mm_store_ps(out, ggx_lambda_lanes(a2));
  return {out[0], out[1], out[2]};
}

// The visible-normal lobe's density of the reflected direction,
// D_wi(h) / (4 wo.h) = G1(wi) (wi.h) D(h) / (wi.z 4 wo.h) with wi.h = wo.h
// for the reflection half vector: G1(wi) D(h) / (4 wi.z). For wi.z > 0,
// wi.h > 0 (the caller's tests). Differs from the uncancelled form by
// rounding (test GlintCoords.LobeDensityMatchesTheUncancelledForm).
// The lobe is kSamplingDistribution's (GGX) at (ax, ay).
inline float lobe_density_of(float ax, float ay, const Vec3 &wi, const Vec3 &h, float lambda_wi) {
  const float v = smith_g1_of(lambda_wi) * mf::D(kSamplingDistribution, h, ax, ay) / (4.0f * wi.z);
  return std::isfinite(v) ? v : 0.0f;
}
inline float lobe_density(float ax, float ay, const Vec3 &wi, const Vec3 &h) {
  return lobe_density_of(ax, ay, wi, h, mf::lambda(kSamplingDistribution, Vec3(wi.x, wi.y, std::fabs(wi.z)), ax, ay));
}

// W(wi, wo) = F(wi.h) G2(wi, wo) (wi.h) / (cos_i cos_h): the glint BRDF times
// cos(wo) is W times the reflected-direction density (P / sigma for the
// mean, K / (N a sigma) for a count K of reflecting particles). Zero when
// either direction is below the surface.
// Anisotropic base (alpha_x along the tangent, alpha_y along the bitangent);
// the isotropic overload below passes alpha for both.
// The reflection half vector of (wi, wo) (mf::half_vector_reflect), computed
// once per eval for both the weight and the pdf.
struct HalfVector {
  Vec3 h;
  bool valid;
};
inline HalfVector reflection_half_vector(const Vec3 &wi, const Vec3 &wo) {
  HalfVector r;
  r.valid = mf::half_vector_reflect(wi, wo, r.h);
  return r;
}

// W with G2 from `g2()`, called only when the directions and h pass the tests.
// `f0_white`: f0 is (1, 1, 1), where Schlick's F is 1 exactly (f0 + (1 - f0) s = 1 + 0 s), so it is not evaluated:
// the same bits (1 x is x).
template <typename G2>
inline bool glint_weight_with(const Spectrum &f0, const Vec3 &wi, const Vec3 &wo, const HalfVector &half, G2 &&g2,
                              Spectrum &weight, bool f0_white = false) {
  if (!(wi.z > 0.0f) || !(wo.z > 0.0f)) return false;
  if (!half.valid) return false;
  const Vec3 &h = half.h;
  const float wi_h = dot(wi, h);
  if (!(wi_h > 0.0f) || !(h.z > 0.0f)) return false;
  const float g = g2();
  const float s = g * wi_h / (wi.z * h.z);
  weight = f0_white ? Spectrum(s) : mf::fresnel_schlick(wi_h, f0) * s;
  return true;
}
// W with G2 from given Lambdas of wi and wo (eval_lambdas; isotropic).
inline bool glint_weight_of(const Spectrum &f0, bool f0_white, const Vec3 &wi, const Vec3 &wo, const HalfVector &half,
                            float lambda_wi, float lambda_wo, Spectrum &weight) {
  return glint_weight_with(f0, wi, wo, half, [&] { return smith_g2_of(lambda_wi, lambda_wo); }, weight, f0_white);
}
inline bool glint_weight(mf::Distribution dist, float alpha_x, float alpha_y, const Spectrum &f0, const Vec3 &wi,
                         const Vec3 &wo, const HalfVector &half, Spectrum &weight) {
  return glint_weight_with(
      f0, wi, wo, half, [&] { return mf::G2(dist, wi, wo, alpha_x, alpha_y); }, weight);
}
inline bool glint_weight(mf::Distribution dist, float alpha_x, float alpha_y, const Spectrum &f0, const Vec3 &wi,
                         const Vec3 &wo, Spectrum &weight) {
  return glint_weight(dist, alpha_x, alpha_y, f0, wi, wo, reflection_half_vector(wi, wo), weight);
}
inline bool glint_weight(mf::Distribution dist, float alpha, const Spectrum &f0, const Vec3 &wi, const Vec3 &wo,
                         Spectrum &weight) {
  return glint_weight(dist, alpha, alpha, f0, wi, wo, weight);
}

// Sampler: visible normals of the GGX lobe (kSamplingDistribution) at alpha_w (weight 1 - c) mixed
// with cosine sampling (weight c), reflection only.
inline constexpr float kCosineMixture = 0.1f;

// smooth_lobe_pdf_with (below) for wi and wo known to be above the surface (wi.z > 0 and wo.z > 0 tested by the
// caller); the same operations after its test (a copy: written as its tail, GCC rescheduled five other closures'
// functions).
template <typename LobeDensity>
inline float smooth_lobe_pdf_above_with(const Vec3 &wi, const Vec3 &wo, const HalfVector &half,
                                        LobeDensity &&lobe_density_at) {
  float pdf = kCosineMixture * wo.z * kInvPi;
  if (half.valid && dot(wi, half.h) > 0.0f) pdf += (1.0f - kCosineMixture) * lobe_density_at(half.h);
  return pdf;
}
// The mixture's density with the lobe's part from `lobe_density_at(h)`, called only where h is a valid half vector
// facing wi.
template <typename LobeDensity>
inline float smooth_lobe_pdf_with(const Vec3 &wi, const Vec3 &wo, const HalfVector &half,
                                  LobeDensity &&lobe_density_at) {
  if (!(wi.z > 0.0f) || !(wo.z > 0.0f)) return 0.0f;
  float pdf = kCosineMixture * wo.z * kInvPi;
  if (half.valid && dot(wi, half.h) > 0.0f) pdf += (1.0f - kCosineMixture) * lobe_density_at(half.h);
  return pdf;
}
// Anisotropic lobe (alpha_wx, alpha_wy); the isotropic overloads pass alpha_w for both.
inline float smooth_lobe_pdf(float alpha_wx, float alpha_wy, const Vec3 &wi, const Vec3 &wo, const HalfVector &half) {
  return smooth_lobe_pdf_with(wi, wo, half, [&](const Vec3 &h) { return lobe_density(alpha_wx, alpha_wy, wi, h); });
}
// smooth_lobe_pdf for wi and wo known to be above the surface (session 37: the dark test's route in glint.cpp, which
// tested them before its out-of-line call and reloaded them after it to test again).
inline float smooth_lobe_pdf_above(float alpha_wx, float alpha_wy, const Vec3 &wi, const Vec3 &wo,
                                   const HalfVector &half) {
  return smooth_lobe_pdf_above_with(wi, wo, half,
                                    [&](const Vec3 &h) { return lobe_density(alpha_wx, alpha_wy, wi, h); });
}
// The same with Lambda(wi) at the lobe's alpha given (eval_lambdas; isotropic lobe).
inline float smooth_lobe_pdf_of(float alpha_w, const Vec3 &wi, const Vec3 &wo, const HalfVector &half,
                                float lambda_wi) {
  return smooth_lobe_pdf_with(wi, wo, half,
                              [&](const Vec3 &h) { return lobe_density_of(alpha_w, alpha_w, wi, h, lambda_wi); });
}
inline float smooth_lobe_pdf(float alpha_wx, float alpha_wy, const Vec3 &wi, const Vec3 &wo) {
  return smooth_lobe_pdf(alpha_wx, alpha_wy, wi, wo, reflection_half_vector(wi, wo));
}

// The three Lambdas of an isotropic eval (eval_lambdas) and the pdf of the sampling lobe (smooth_lobe_pdf_of at
// GGX's Lambda(wi) at the lobe's alpha), for wi.z > 0 and wo.z > 0 (the caller's tests). Since session 41 the pdf is
// GGX's for every base (no expf), so the Beckmann route no longer computes it inside its AVX2 call (session 28).
struct EvalLambdasPdf {
  EvalLambdas lambdas;
  float pdf;
};
inline EvalLambdasPdf eval_lambdas_and_pdf(mf::Distribution dist, float alpha, float alpha_lobe, const Vec3 &wi,
                                           const Vec3 &wo, const HalfVector &half) {
  const EvalLambdas l = eval_lambdas(dist, alpha, alpha_lobe, wi, wo);
  return {l, smooth_lobe_pdf_of(alpha_lobe, wi, wo, half, l.wi_lobe)};
}

inline float smooth_lobe_pdf(float alpha_w, const Vec3 &wi, const Vec3 &wo) {
  return smooth_lobe_pdf(alpha_w, alpha_w, wi, wo);
}

inline bool sample_smooth_lobe(float alpha_wx, float alpha_wy, const Vec3 &wi, const Vec3 &rand, Vec3 &wo) {
  if (!(wi.z > 0.0f)) return false;
  // Lobe choice on rand.x, rescaled and reused for the direction (keeps the 2D point stratified).
  float u = rand.x;
  if (choose_and_rescale(kCosineMixture, u)) {
    wo = sample_cosine_hemisphere(u, rand.y);
  } else {
    const Vec3 h = mf::sample_visible_normal(kSamplingDistribution, wi, alpha_wx, alpha_wy, u, rand.y);
    wo = mf::reflect_about(wi, h);
  }
  return wo.z > 0.0f;
}
inline bool sample_smooth_lobe(float alpha_w, const Vec3 &wi, const Vec3 &rand, Vec3 &wo) {
  return sample_smooth_lobe(alpha_w, alpha_w, wi, rand, wo);
}

}  // namespace glimmer::plugin::glint
