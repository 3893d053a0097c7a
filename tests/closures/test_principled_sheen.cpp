// The principled_sheen closure (Cycles 3.4's Principled sheen, plugin/closures/principled_sheen.h): its value
// against Burley 2012's sheen written independently in double (Schlick weight at the half vector, (1 - wo.h)^5;
// negative control: the weight at the normal, (1 - N.wo)^5, fails the same check), its colour against
// sheen * mix(1, base / luminance, sheen_tint), and the standard closure checks: furnace vs quadrature of eval,
// chi2, eval/pdf consistency, reciprocity, stress (grazing 1e-6).
#include <cmath>

#include "closures/closure_checks.h"
#include "closures/principled_sheen.h"

namespace glimmer::test {
namespace {

// Burley 2012 sec. 5.3 / disney.brdf: f_sheen = C_sheen F_H, F_H = (1 - cos theta_d)^5, theta_d the angle between
// wo and h = normalize(wi + wo) (no 1/pi). Returns f cos theta_o / C_sheen.
double sheen_f_cos(const Vec3 &wi, const Vec3 &wo) {
  const double hx = double(wi.x) + wo.x, hy = double(wi.y) + wo.y, hz = double(wi.z) + wo.z;
  const double cos_d = (wo.x * hx + wo.y * hy + wo.z * hz) / std::sqrt(hx * hx + hy * hy + hz * hz);
  return std::pow(1.0 - cos_d, 5.0) * wo.z;
}
// The wrong weight (at the normal instead of the half vector): the negative control's formula.
double normal_weight_f_cos(const Vec3 &, const Vec3 &wo) { return std::pow(1.0 - wo.z, 5.0) * wo.z; }

// C_sheen per channel, in double: sheen (1 - tint + tint base / Y), Y the Rec.709 luminance.
std::array<double, 3> sheen_color(const std::array<double, 3> &base, double sheen, double tint) {
  const double y = 0.2126 * base[0] + 0.7152 * base[1] + 0.0722 * base[2];
  std::array<double, 3> c{};
  for (int i = 0; i < 3; ++i) c[i] = sheen * (1.0 - tint + tint * (y > 0.0 ? base[i] / y : 1.0));
  return c;
}

// The largest |f cos - C formula| / C over a set of direction pairs (C the expected colour per channel).
double worst_error(const host::ClosureInstance &closure, const std::array<double, 3> &color,
                   double (*formula)(const Vec3 &, const Vec3 &)) {
  double worst = 0.0;
  for (const auto &[wi, wo] : value_check_pairs()) {
    Spectrum f;
    float pdf = 0.0f;
    closure.eval(host::make_local_context(wi), wo, f, pdf);
    for (int i = 0; i < 3; ++i) worst = std::max(worst, std::fabs(f[i] / color[i] - formula(wi, wo)));
    EXPECT_NEAR(pdf, wo.z / M_PI, 1e-6);
  }
  return worst;
}

TEST(PrincipledSheen, ValueEqualsBurleySheen) {
  const auto grey = make_closure("principled_sheen", {{"base_color", "0.5,0.5,0.5"}, {"sheen", "1"}});
  EXPECT_LT(worst_error(*grey, {1, 1, 1}, sheen_f_cos), 1e-5);
  const auto tinted = make_closure("principled_sheen",
                                   {{"base_color", "0.9,0.5,0.2"}, {"sheen", "0.7"}, {"sheen_tint", "0.6"}});
  EXPECT_LT(worst_error(*tinted, sheen_color({0.9, 0.5, 0.2}, 0.7, 0.6), sheen_f_cos), 1e-5);
  const auto black = make_closure("principled_sheen", {{"base_color", "0,0,0"}, {"sheen", "1"}, {"sheen_tint", "1"}});
  EXPECT_LT(worst_error(*black, {1, 1, 1}, sheen_f_cos), 1e-5);  // Cycles' tint 1 for a black base
}

TEST(PrincipledSheenNegativeControl, WeightAtTheNormalFailsBurleySheen) {
  const auto grey = make_closure("principled_sheen", {{"base_color", "0.5,0.5,0.5"}, {"sheen", "1"}});
  EXPECT_GT(worst_error(*grey, {1, 1, 1}, normal_weight_f_cos), 0.05);
}

TEST(PrincipledSheenNegativeControl, UntintedColourFailsTintedReference) {
  const auto untinted = make_closure("principled_sheen",
                                     {{"base_color", "0.9,0.5,0.2"}, {"sheen", "0.7"}, {"sheen_tint", "0"}});
  EXPECT_GT(worst_error(*untinted, sheen_color({0.9, 0.5, 0.2}, 0.7, 0.6), sheen_f_cos), 0.01);
}

TEST(PrincipledSheen, FurnaceMatchesQuadratureOfEval) {
  const auto sheen = make_closure("principled_sheen",
                                  {{"base_color", "0.9,0.5,0.2"}, {"sheen", "1"}, {"sheen_tint", "0.5"}});
  for (const auto &[label, wi] : standard_wi()) {
    SCOPED_TRACE(label);
    EXPECT_CLOSURE_FURNACE_MATCHES_QUADRATURE(*sheen, wi, 1e-5);
  }
}

TEST(PrincipledSheen, Chi2SampleMatchesPdf) {
  const auto sheen = make_closure("principled_sheen", {{"base_color", "0.9,0.5,0.2"}, {"sheen", "1"}});
  std::vector<Chi2Config> configs;
  for (const auto &[label, wi] : standard_wi()) configs.push_back({label, sheen, wi});
  for (const auto &r : expect_chi2_family(configs)) {
    EXPECT_NEAR(r.pdf_integral, 1.0, 1e-5);
    std::printf("principled_sheen chi2: %s\n", r.message.substr(0, r.message.find(" Worst")).c_str());
  }
}

TEST(PrincipledSheen, SampleAgreesWithEval) {
  const auto sheen = make_closure("principled_sheen",
                                  {{"base_color", "0.9,0.5,0.2"}, {"sheen", "1"}, {"sheen_tint", "0.5"}});
  for (const auto &[label, wi] : standard_wi()) {
    SCOPED_TRACE(label);
    EXPECT_CLOSURE_CONSISTENT(*sheen, wi);
  }
}

TEST(PrincipledSheen, Reciprocal) {
  const auto sheen = make_closure("principled_sheen",
                                  {{"base_color", "0.9,0.5,0.2"}, {"sheen", "1"}, {"sheen_tint", "0.5"}});
  lab::ReciprocityOptions options;
  options.pairs = 50000;  // the lab's default tolerance 1e-4: (1 - cos theta_d)^5 amplifies the float rounding of
                          // wi and wo when they nearly coincide (measured worst 1.4e-5)
  EXPECT_CLOSURE_RECIPROCAL(*sheen, options);
}

TEST(PrincipledSheen, StressNoInvalidValues) {
  std::vector<std::shared_ptr<host::ClosureInstance>> closures;
  for (const char *tint : {"0", "0.5", "1"})
    for (const char *color : {"0,0,0", "1,1,1", "0.3,0.6,0.9", "0,0,1"})
      closures.push_back(
          make_closure("principled_sheen", {{"base_color", color}, {"sheen", "1"}, {"sheen_tint", tint}}));
  expect_stress_and_grazing_clean(closures);
}

}  // namespace
}  // namespace glimmer::test
