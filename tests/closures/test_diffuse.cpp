// Lambertian diffuse: the standard closure checks, plus negative controls that
// prove each check fails for a deliberately broken closure.
#include <cmath>

#include "closures/closure_checks.h"

namespace glimmer::test {
namespace {

const Spectrum kColor(0.5f, 0.25f, 0.8f);

TEST(Diffuse, FurnaceEqualsColourAndQuadratureReference) {
  for (const auto &[color_text, color] : {std::pair<const char *, Spectrum>{"1,1,1", Spectrum(1.0f)},
                                          std::pair<const char *, Spectrum>{"0.5,0.25,0.8", kColor}}) {
    const auto diffuse = make_closure("diffuse", {{"color", color_text}});
    for (const auto &[label, wi] : standard_wi()) {
      SCOPED_TRACE(std::string(color_text) + " at " + label);
      // f = color / pi integrates to color: the sampled weights must give it
      // to float rounding.
      EXPECT_CLOSURE_FURNACE(*diffuse, wi, color, 1e-5);
      // Brute-force reference from eval() alone (Simpson over the sphere).
      const Spectrum reference = lab::albedo_quadrature(*diffuse, host::make_local_context(wi));
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(reference[c], color[c], 1e-5);
      EXPECT_CLOSURE_FURNACE_MATCHES_QUADRATURE(*diffuse, wi, 1e-5);
    }
  }
}

TEST(Diffuse, Chi2SampleMatchesPdf) {
  const auto diffuse = make_closure("diffuse", {{"color", "0.5,0.25,0.8"}});
  std::vector<Chi2Config> configs;
  for (const auto &[label, wi] : standard_wi()) configs.push_back({label, diffuse, wi});
  const auto results = expect_chi2_family(configs);
  for (const auto &r : results) {
    // Nothing is absorbed: the pdf integrates to 1 and every sample is histogrammed.
    EXPECT_NEAR(r.pdf_integral, 1.0, 1e-5);
    // sample() may reject a direction exactly on the horizon (probability ~1e-6).
    EXPECT_GE(r.sampled_fraction, 1.0 - 1e-5);
    std::printf("diffuse chi2: %s\n", r.message.substr(0, r.message.find(" Worst")).c_str());
  }
}

TEST(Diffuse, SampleAgreesWithEval) {
  const auto diffuse = make_closure("diffuse", {{"color", "0.5,0.25,0.8"}});
  for (const auto &[label, wi] : standard_wi()) {
    SCOPED_TRACE(label);
    EXPECT_CLOSURE_CONSISTENT(*diffuse, wi);
  }
}

TEST(Diffuse, Reciprocal) {
  const auto diffuse = make_closure("diffuse", {{"color", "0.5,0.25,0.8"}});
  lab::ReciprocityOptions options;
  options.pairs = 100000;
  options.tolerance = 1e-5;
  EXPECT_CLOSURE_RECIPROCAL(*diffuse, options);
}

TEST(Diffuse, NoLightBelowTheSurface) {
  const auto diffuse = make_closure("diffuse", {{"color", "1,1,1"}});
  Spectrum f;
  float pdf = 1.0f;
  diffuse->eval(host::make_local_context(Vec3(0, 0, 1)), Vec3(0.6f, 0.0f, -0.8f), f, pdf);
  EXPECT_EQ(max_component(f), 0.0f);
  EXPECT_EQ(pdf, 0.0f);
}

TEST(Diffuse, StressNoInvalidValues) {
  const auto black = make_closure("diffuse", {{"color", "0,0,0"}});
  const auto white = make_closure("diffuse", {{"color", "1,1,1"}});
  const auto coloured = make_closure("diffuse", {{"color", "0.3,0.6,0.9"}});
  EXPECT_CLOSURE_STRESS_CLEAN({black.get(), white.get(), coloured.get()});
}

// ---- Negative controls: each check must fail for a broken closure. ---------

// pdf reshaped by (1 + 0.3 x): still integrates to 1 (x is odd over the
// hemisphere), but no longer matches the sampled density.
void skewed_pdf_eval(const GlimmerInstance *instance, const GlimmerShadingContext *ctx, GlimmerVec3 wo,
                     float out_eval[3], float *out_pdf) {
  TamperedType::original().eval(instance, ctx, wo, out_eval, out_pdf);
  *out_pdf *= 1.0f + 0.3f * wo.x;
}

TEST(DiffuseNegativeControl, Chi2RejectsSkewedPdf) {
  TamperedType tampered(closure_type("diffuse"));
  tampered.type().eval = &skewed_pdf_eval;
  const auto broken = make_closure(tampered.type(), {{"color", "1,1,1"}});
  lab::Chi2Options options;
  options.test_count = static_cast<int>(standard_wi().size());
  const auto r = lab::chi2_test(*broken, host::make_local_context(Vec3(0.3f, 0.0f, 0.95f)), options);
  EXPECT_FALSE(r.passed) << r.message;
  std::printf("negative control: %s\n", r.message.substr(0, r.message.find(" Worst")).c_str());
  EXPECT_LT(r.p_value, 1e-6) << r.message;
  EXPECT_NEAR(r.pdf_integral, 1.0, 1e-4);  // the skew keeps the normalisation
}

// Sampler warped by u1 -> u1^1.1 while still claiming the cosine pdf.
uint32_t warped_sample(const GlimmerInstance *instance, const GlimmerShadingContext *ctx, const float rand3[3],
                       GlimmerSample *out) {
  const float warped[3] = {std::pow(rand3[0], 1.1f), rand3[1], rand3[2]};
  return TamperedType::original().sample(instance, ctx, warped, out);
}

TEST(DiffuseNegativeControl, Chi2RejectsWarpedSampler) {
  TamperedType tampered(closure_type("diffuse"));
  tampered.type().sample = &warped_sample;
  const auto broken = make_closure(tampered.type(), {{"color", "1,1,1"}});
  lab::Chi2Options options;
  options.test_count = static_cast<int>(standard_wi().size());
  const auto r = lab::chi2_test(*broken, host::make_local_context(Vec3(0, 0, 1)), options);
  EXPECT_FALSE(r.passed) << r.message;
  std::printf("negative control: %s\n", r.message.substr(0, r.message.find(" Worst")).c_str());
}

// pdf 1 % too large everywhere: integrates to 1.01 > 1.
void inflated_pdf_eval(const GlimmerInstance *instance, const GlimmerShadingContext *ctx, GlimmerVec3 wo,
                       float out_eval[3], float *out_pdf) {
  TamperedType::original().eval(instance, ctx, wo, out_eval, out_pdf);
  *out_pdf *= 1.01f;
}

TEST(DiffuseNegativeControl, Chi2RejectsPdfIntegratingAboveOne) {
  TamperedType tampered(closure_type("diffuse"));
  tampered.type().eval = &inflated_pdf_eval;
  const auto broken = make_closure(tampered.type(), {{"color", "1,1,1"}});
  const auto r = lab::chi2_test(*broken, host::make_local_context(Vec3(0, 0, 1)));
  EXPECT_FALSE(r.passed) << r.message;
  std::printf("negative control: %s\n", r.message.substr(0, r.message.find(" Worst")).c_str());
  EXPECT_NEAR(r.pdf_integral, 1.01, 1e-4);
}

// pdf 2 % too small everywhere while sample() never absorbs: the chi2
// statistic barely notices, the normalisation check must.
void deflated_pdf_eval(const GlimmerInstance *instance, const GlimmerShadingContext *ctx, GlimmerVec3 wo,
                       float out_eval[3], float *out_pdf) {
  TamperedType::original().eval(instance, ctx, wo, out_eval, out_pdf);
  *out_pdf *= 0.98f;
}

TEST(DiffuseNegativeControl, Chi2RejectsPdfBelowSampledFraction) {
  TamperedType tampered(closure_type("diffuse"));
  tampered.type().eval = &deflated_pdf_eval;
  const auto broken = make_closure(tampered.type(), {{"color", "1,1,1"}});
  const auto r = lab::chi2_test(*broken, host::make_local_context(Vec3(0, 0, 1)));
  EXPECT_FALSE(r.passed) << r.message;
  std::printf("negative control: %s\n", r.message.substr(0, r.message.find(" Worst")).c_str());
  EXPECT_NEAR(r.pdf_integral, 0.98, 1e-4);
}

// Loses 0.5 % of the energy in sample() and eval().
uint32_t lossy_sample(const GlimmerInstance *instance, const GlimmerShadingContext *ctx, const float rand3[3],
                      GlimmerSample *out) {
  const uint32_t label = TamperedType::original().sample(instance, ctx, rand3, out);
  for (float &v : out->eval) v *= 0.995f;
  return label;
}

TEST(DiffuseNegativeControl, FurnaceRejectsLossyClosure) {
  TamperedType tampered(closure_type("diffuse"));
  tampered.type().sample = &lossy_sample;
  const auto broken = make_closure(tampered.type(), {{"color", "1,1,1"}});
  EXPECT_FALSE(furnace_matches(*broken, Vec3(0.3f, 0.0f, 0.95f), Spectrum(1.0f), 1e-5));
  // eval() still integrates to 1, so the quadrature reference exposes it too.
  EXPECT_FALSE(furnace_matches_quadrature(*broken, Vec3(0.3f, 0.0f, 0.95f), 1e-4));
}

// sample() reports a pdf 1 % off the one eval() gives.
uint32_t mismatched_pdf_sample(const GlimmerInstance *instance, const GlimmerShadingContext *ctx,
                               const float rand3[3], GlimmerSample *out) {
  const uint32_t label = TamperedType::original().sample(instance, ctx, rand3, out);
  out->pdf *= 1.01f;
  return label;
}

TEST(DiffuseNegativeControl, ConsistencyRejectsMismatchedPdf) {
  TamperedType tampered(closure_type("diffuse"));
  tampered.type().sample = &mismatched_pdf_sample;
  const auto broken = make_closure(tampered.type(), {{"color", "1,1,1"}});
  EXPECT_FALSE(consistent(*broken, Vec3(0, 0, 1)));
}

// f depends on the viewing angle only: f(wi, wo) != f(wo, wi).
void one_sided_eval(const GlimmerInstance *instance, const GlimmerShadingContext *ctx, GlimmerVec3 wo,
                    float out_eval[3], float *out_pdf) {
  TamperedType::original().eval(instance, ctx, wo, out_eval, out_pdf);
  for (int c = 0; c < 3; ++c) out_eval[c] *= 1.0f + 0.1f * ctx->wi.z;
}

TEST(DiffuseNegativeControl, ReciprocityRejectsNonReciprocalClosure) {
  TamperedType tampered(closure_type("diffuse"));
  tampered.type().eval = &one_sided_eval;
  const auto broken = make_closure(tampered.type(), {{"color", "1,1,1"}});
  EXPECT_FALSE(reciprocal(*broken));
}

// NaN at grazing viewing angles and a negative pdf below the horizon.
void fragile_eval(const GlimmerInstance *instance, const GlimmerShadingContext *ctx, GlimmerVec3 wo,
                  float out_eval[3], float *out_pdf) {
  TamperedType::original().eval(instance, ctx, wo, out_eval, out_pdf);
  if (std::fabs(ctx->wi.z) < 1e-4f) out_eval[0] = std::nanf("");
  if (ctx->wi.z < -0.5f) *out_pdf = -1.0f;
}

TEST(DiffuseNegativeControl, StressFindsNaNAndNegativeValues) {
  TamperedType tampered(closure_type("diffuse"));
  tampered.type().eval = &fragile_eval;
  const auto broken = make_closure(tampered.type(), {{"color", "1,1,1"}});
  lab::StressOptions options;
  options.calls = 20000;
  const lab::StressResult r = lab::stress(*broken, options);
  EXPECT_GT(r.eval_nan, 0u);
  EXPECT_GT(r.eval_negative, 0u);
  EXPECT_FALSE(r.first_failure.empty());
}

}  // namespace
}  // namespace glimmer::test
