// Emission: radiance color * strength toward both sides; eval/sample describe
// the normalized emitted-power distribution |cos| / (2 pi) over the sphere.
#include "closures/closure_checks.h"

namespace glimmer::test {
namespace {

TEST(Emission, EmitsColourTimesStrengthTowardEverySide) {
  const auto emission = make_closure("emission", {{"color", "0.5,1,2"}, {"strength", "3"}});
  for (const Vec3 wi : {Vec3(0, 0, 1), Vec3(0.6f, 0.0f, 0.8f), direction_at_cos(1e-6), Vec3(0.6f, 0.0f, -0.8f)}) {
    const Spectrum e = emission->emit(host::make_local_context(wi));
    EXPECT_FLOAT_EQ(e.x, 1.5f);
    EXPECT_FLOAT_EQ(e.y, 3.0f);
    EXPECT_FLOAT_EQ(e.z, 6.0f);
  }
}

TEST(Emission, DistributionIsNormalized) {
  const auto emission = make_closure("emission", {{"color", "1,1,1"}, {"strength", "5"}});
  for (const auto &[label, wi] : standard_wi()) {
    SCOPED_TRACE(label);
    EXPECT_CLOSURE_FURNACE(*emission, wi, Spectrum(1.0f), 1e-5);
    const Spectrum reference = lab::albedo_quadrature(*emission, host::make_local_context(wi));
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(reference[c], 1.0, 1e-5);
  }
}

TEST(Emission, Chi2SampleMatchesPdfOverBothHemispheres) {
  const auto emission = make_closure("emission");
  std::vector<Chi2Config> configs;
  for (const auto &[label, wi] : standard_wi()) configs.push_back({label, emission, wi});
  const auto results = expect_chi2_family(configs);
  for (const auto &r : results) {
    EXPECT_NEAR(r.pdf_integral, 1.0, 1e-5);
    // sample() may reject a direction exactly on the horizon (probability ~1e-6).
    EXPECT_GE(r.sampled_fraction, 1.0 - 1e-5);
    std::printf("emission chi2: %s\n", r.message.substr(0, r.message.find(" Worst")).c_str());
  }
  // Half of the samples go below the surface.
  const lab::FurnaceResult f = lab::furnace(*emission, host::make_local_context(Vec3(0, 0, 1)), 100000, 3);
  EXPECT_NEAR(double(f.transmission_count) / double(f.samples), 0.5, 0.01);
}

TEST(Emission, SampleAgreesWithEval) {
  const auto emission = make_closure("emission");
  for (const auto &[label, wi] : standard_wi()) {
    SCOPED_TRACE(label);
    EXPECT_CLOSURE_CONSISTENT(*emission, wi);
  }
}

TEST(Emission, ConstantDistributionIsReciprocal) {
  const auto emission = make_closure("emission");
  lab::ReciprocityOptions options;
  options.transmission = true;
  options.tolerance = 1e-5;
  EXPECT_CLOSURE_RECIPROCAL(*emission, options);
}

TEST(Emission, StressNoInvalidValues) {
  const auto dark = make_closure("emission", {{"strength", "0"}});
  const auto bright = make_closure("emission", {{"color", "1e6,1e6,1e6"}, {"strength", "1e9"}});
  const auto plain = make_closure("emission");
  EXPECT_CLOSURE_STRESS_CLEAN({dark.get(), bright.get(), plain.get()});
}

// Negative control for the sphere-wide histogram: a sampler that never
// emits downward while eval() still claims both sides must fail.
uint32_t upper_only_sample(const GlimmerInstance *instance, const GlimmerShadingContext *ctx, const float rand3[3],
                           GlimmerSample *out) {
  const float upper[3] = {rand3[0], rand3[1], 0.25f};
  return TamperedType::original().sample(instance, ctx, upper, out);
}

TEST(EmissionNegativeControl, Chi2RejectsOneSidedSampler) {
  TamperedType tampered(closure_type("emission"));
  tampered.type().sample = &upper_only_sample;
  const auto broken = make_closure(tampered.type());
  const auto r = lab::chi2_test(*broken, host::make_local_context(Vec3(0, 0, 1)));
  EXPECT_FALSE(r.passed) << r.message;
  std::printf("negative control: %s\n", r.message.substr(0, r.message.find(" Worst")).c_str());
  EXPECT_NEAR(r.pdf_integral, 1.0, 1e-5);
}

}  // namespace
}  // namespace glimmer::test
