// The principled_diffuse closure (Cycles 3.4's Principled diffuse, plugin/closures/principled_diffuse.h): its value
// against Burley's published formula written independently in double (with the half vector, as the paper states
// it; negative control: plain Lambert fails), and the standard closure checks: furnace vs quadrature of eval,
// chi2, eval/pdf consistency, reciprocity, stress (grazing 1e-6, roughness 0..1).
#include <cmath>

#include "closures/closure_checks.h"
#include "closures/principled_diffuse.h"

namespace glimmer::test {
namespace {

// Burley 2015 ("Extending the Disney BRDF to a BSDF with Integrated Subsurface Scattering", sec. 2.3):
//   f_d = c / pi (1 - F_L / 2)(1 - F_V / 2) + c / pi R_R (F_L + F_V + F_L F_V (R_R - 1)),
//   F = (1 - cos)^5, R_R = 2 roughness cos^2 theta_d, theta_d the angle between wo and h = normalize(wi + wo).
double burley_f(const Vec3 &wi, const Vec3 &wo, double roughness, double color) {
  const double hx = double(wi.x) + wo.x, hy = double(wi.y) + wo.y, hz = double(wi.z) + wo.z;
  const double len = std::sqrt(hx * hx + hy * hy + hz * hz);
  const double cos_d = (wo.x * hx + wo.y * hy + wo.z * hz) / len;
  const double f_l = std::pow(1.0 - wo.z, 5.0), f_v = std::pow(1.0 - wi.z, 5.0);
  const double rr = 2.0 * roughness * cos_d * cos_d;
  return color / M_PI * ((1.0 - 0.5 * f_l) * (1.0 - 0.5 * f_v) + rr * (f_l + f_v + f_l * f_v * (rr - 1.0)));
}

// The largest relative |f cos / (burley_f cos) - 1| of `closure` (which has colour 0.6) over a set of directions.
double worst_relative_error(const host::ClosureInstance &closure, double roughness) {
  double worst = 0.0;
  for (const auto &[wi, wo] : value_check_pairs()) {
    Spectrum f;
    float pdf = 0.0f;
    closure.eval(host::make_local_context(wi), wo, f, pdf);
    const double expected = burley_f(wi, wo, roughness, 0.6) * wo.z;
    worst = std::max(worst, std::fabs(f[0] / expected - 1.0));
    EXPECT_NEAR(pdf, wo.z / M_PI, 1e-6);
  }
  return worst;
}

TEST(PrincipledDiffuse, ValueEqualsBurleyFormula) {
  for (const char *roughness : {"0", "0.3", "0.5", "1"}) {
    const auto diffuse = make_closure("principled_diffuse", {{"color", "0.6,0.6,0.6"}, {"roughness", roughness}});
    EXPECT_LT(worst_relative_error(*diffuse, std::stod(roughness)), 2e-5) << "roughness " << roughness;
  }
}

TEST(PrincipledDiffuseNegativeControl, LambertFailsBurleyFormula) {
  const auto lambert = make_closure("diffuse", {{"color", "0.6,0.6,0.6"}});
  for (double roughness : {0.0, 0.5, 1.0}) EXPECT_GT(worst_relative_error(*lambert, roughness), 0.1);
}

TEST(PrincipledDiffuse, FurnaceMatchesQuadratureOfEval) {
  for (const char *roughness : {"0", "0.5", "1"}) {
    const auto diffuse = make_closure("principled_diffuse", {{"color", "0.9,0.5,0.2"}, {"roughness", roughness}});
    for (const auto &[label, wi] : standard_wi()) {
      SCOPED_TRACE(std::string("roughness ") + roughness + " at " + label);
      EXPECT_CLOSURE_FURNACE_MATCHES_QUADRATURE(*diffuse, wi, 1e-5);
    }
  }
}

TEST(PrincipledDiffuse, RetroReflectionBrightensGrazingViewsWithRoughness) {
  // The published behaviour (Burley 2012 sec. 5.3): at grazing view a smooth surface darkens (by up to
  // 1 - F_V / 2 = 0.5) and a rough one brightens (retro-reflection).
  const Vec3 grazing = direction_at_cos(0.05);
  const auto smooth = make_closure("principled_diffuse", {{"color", "1,1,1"}, {"roughness", "0"}});
  const auto rough = make_closure("principled_diffuse", {{"color", "1,1,1"}, {"roughness", "1"}});
  const double a_smooth = lab::albedo_quadrature(*smooth, host::make_local_context(grazing))[0];
  const double a_rough = lab::albedo_quadrature(*rough, host::make_local_context(grazing))[0];
  std::printf("principled diffuse albedo at cos 0.05: roughness 0 %.4f, roughness 1 %.4f\n", a_smooth, a_rough);
  EXPECT_LT(a_smooth, 0.75);
  EXPECT_GT(a_rough, a_smooth + 0.2);
}

TEST(PrincipledDiffuse, Chi2SampleMatchesPdf) {
  std::vector<Chi2Config> configs;
  for (const char *roughness : {"0", "1"}) {
    const auto diffuse = make_closure("principled_diffuse", {{"color", "0.9,0.5,0.2"}, {"roughness", roughness}});
    for (const auto &[label, wi] : standard_wi())
      configs.push_back({std::string("roughness ") + roughness + " " + label, diffuse, wi});
  }
  for (const auto &r : expect_chi2_family(configs)) {
    EXPECT_NEAR(r.pdf_integral, 1.0, 1e-5);
    std::printf("principled_diffuse chi2: %s\n", r.message.substr(0, r.message.find(" Worst")).c_str());
  }
}

TEST(PrincipledDiffuse, SampleAgreesWithEval) {
  for (const char *roughness : {"0", "0.5", "1"}) {
    const auto diffuse = make_closure("principled_diffuse", {{"color", "0.9,0.5,0.2"}, {"roughness", roughness}});
    for (const auto &[label, wi] : standard_wi()) {
      SCOPED_TRACE(std::string("roughness ") + roughness + " at " + label);
      EXPECT_CLOSURE_CONSISTENT(*diffuse, wi);
    }
  }
}

TEST(PrincipledDiffuse, Reciprocal) {
  for (const char *roughness : {"0", "0.5", "1"}) {
    const auto diffuse = make_closure("principled_diffuse", {{"color", "0.9,0.5,0.2"}, {"roughness", roughness}});
    lab::ReciprocityOptions options;
    options.pairs = 50000;
    options.tolerance = 1e-5;
    EXPECT_CLOSURE_RECIPROCAL(*diffuse, options);
  }
}

TEST(PrincipledDiffuse, StressNoInvalidValues) {
  std::vector<std::shared_ptr<host::ClosureInstance>> closures;
  for (const char *roughness : {"0", "1e-6", "0.25", "0.5", "0.75", "1"})
    for (const char *color : {"0,0,0", "1,1,1", "0.3,0.6,0.9"})
      closures.push_back(make_closure("principled_diffuse", {{"color", color}, {"roughness", roughness}}));
  expect_stress_and_grazing_clean(closures);
}

}  // namespace
}  // namespace glimmer::test
