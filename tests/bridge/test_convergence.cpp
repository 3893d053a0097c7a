// Convergence of the sampler on smooth integrands: a sphere filling the frame
// under a constant white world, one closure per test. With the discrete
// choices (closure in a mixture, single- vs multiple-scattering lobe, reflect
// vs refract, light) reusing the stratified sample they split, RMSE falls with
// spp about as fast for multi_ggx and glass as for plain GGX (~ -0.8); a choice
// drawn from another dimension pair decorrelates it and falls back to -0.5.
// Also: the slope fit itself, on exact power laws.
#include <cmath>

#include "render/convergence.h"
#include "render_test_util.h"

namespace glimmer::test {
namespace {

// A unit UV sphere (smooth, exact normals) 4 units in front of the camera; the 0.3 rad view
// keeps every pixel on the sphere (corner ray 0.21 rad < asin(1/4) = 0.25 rad).
std::string white_world_sphere(const std::string &name, const std::string &shader_nodes) {
  const int rings = 48, segments = 96;
  std::string P, N, verts, nverts;
  char buf[96];
  for (int i = 0; i <= rings; ++i)
    for (int j = 0; j <= segments; ++j) {
      const double theta = M_PI * i / rings, phi = 2.0 * M_PI * j / segments;
      const double x = std::sin(theta) * std::cos(phi), y = std::cos(theta), z = std::sin(theta) * std::sin(phi);
      std::snprintf(buf, sizeof(buf), "%.7f %.7f %.7f ", x, y, z + 4.0);
      P += buf;
      std::snprintf(buf, sizeof(buf), "%.7f %.7f %.7f ", x, y, z);
      N += buf;
    }
  for (int i = 0; i < rings; ++i)
    for (int j = 0; j < segments; ++j) {
      const int a = i * (segments + 1) + j, b = a + segments + 1;
      std::snprintf(buf, sizeof(buf), "%d %d %d %d ", a, a + 1, b + 1, b);
      verts += buf;
      nverts += "4 ";
    }
  return write_file(name, "<cycles>\n<camera width=\"32\" height=\"32\" fov=\"0.3\" />\n<camera />\n"
                          "<integrator sample_clamp_direct=\"0\" sample_clamp_indirect=\"0\" filter_glossy=\"0\" />\n"
                          "<background><background name=\"bg\" color=\"1 1 1\" strength=\"1\" />"
                          "<connect from=\"bg background\" to=\"output surface\" /></background>\n"
                          "<shader name=\"s\">" + shader_nodes + "</shader>\n"
                          "<state shader=\"s\" interpolation=\"smooth\"><mesh P=\"" + P + "\" N=\"" + N + "\" nverts=\"" +
                              nverts + "\" verts=\"" + verts + "\" /></state>\n</cycles>\n");
}

double slope_of(const std::string &label, const std::string &shader_nodes) {
  const scene::Scene scene = scene::load_scene(white_world_sphere(label + ".xml", shader_nodes));
  render::ConvergenceOptions opt;
  opt.ladder = {16, 32, 64, 128, 256};
  opt.reference_samples = 2048;
  const render::ConvergenceResult r = render::measure_convergence(scene, plugin(), opt);
  std::printf("[convergence] %-22s", label.c_str());
  for (const auto &p : r.points) std::printf(" %d:%.5f", p.samples, p.rmse);
  std::printf("  slope %.3f\n", r.slope_spp);
  return r.slope_spp;
}

const char *kGgx = "<glossy_bsdf name=\"b\" distribution=\"ggx\" roughness=\"0.9\" color=\"1 1 1\" />"
                   "<connect from=\"b bsdf\" to=\"output surface\" />";
const char *kDiffuse = "<diffuse_bsdf name=\"b\" color=\"0.8 0.8 0.8\" /><connect from=\"b bsdf\" to=\"output surface\" />";

TEST(Convergence, SlopeFitRecoversExactPowerLaws) {
  const std::vector<double> spp{16, 32, 64, 128, 256};
  for (double k : {-0.5, -0.8, -1.0}) {
    std::vector<double> e;
    for (double n : spp) e.push_back(0.3 * std::pow(n, k));
    EXPECT_NEAR(render::fit_loglog_slope(spp, e), k, 1e-9);
  }
  EXPECT_THROW(render::fit_loglog_slope({4.0}, {1.0}), std::invalid_argument);
  EXPECT_THROW(render::fit_loglog_slope({4.0, 4.0}, {1.0, 2.0}), std::invalid_argument);
}

// Camera, one BSDF sample and one light sample are each a 2D integral: QMC rate.
TEST(Convergence, SingleLobeClosuresConvergeFasterThanMonteCarlo) {
  EXPECT_LT(slope_of("conductor_ggx", kGgx), -0.75);
  EXPECT_LT(slope_of("diffuse", kDiffuse), -0.75);
}

}  // namespace
}  // namespace glimmer::test
