// Convergence of the sampler on smooth integrands: a sphere filling the frame
// under a constant white world, one closure per scene. With the discrete
// choices (closure in a mixture, single- vs multiple-scattering lobe, reflect
// vs refract) reusing the stratified sample they split, RMSE falls with spp as
// fast for multi_ggx, the 50/50 mix and glass as for plain GGX (about -1); a
// choice drawn from another dimension set decorrelates it and falls back to
// -0.5 (measured before the change: multi_ggx -0.50, mix -0.50, glass at one
// scattering event -0.5). Glass is measured at one scattering event
// (max_bounce 0): paths inside the glass are many-bounce, high-dimensional
// integrals that no padded sampler stratifies (full depth: about -0.55, see
// docs/architecture.md "Sample dimensions"). Also: the slope fit itself.
#include <cmath>

#include "render/convergence.h"
#include "render_test_util.h"

namespace glimmer::test {
namespace {

// A unit UV sphere (smooth, exact normals) 4 units in front of the camera; the 0.3 rad view
// keeps every pixel on the sphere (corner ray 0.21 rad < asin(1/4) = 0.25 rad).
std::string white_world_sphere(const std::string &name, const std::string &shader_nodes,
                               const std::string &integrator_attributes) {
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
                          "<integrator sample_clamp_direct=\"0\" sample_clamp_indirect=\"0\" filter_glossy=\"0\" " +
                              integrator_attributes + " />\n"
                          "<background><background name=\"bg\" color=\"1 1 1\" strength=\"1\" />"
                          "<connect from=\"bg background\" to=\"output surface\" /></background>\n"
                          "<shader name=\"s\">" + shader_nodes + "</shader>\n"
                          "<state shader=\"s\" interpolation=\"smooth\"><mesh P=\"" + P + "\" N=\"" + N + "\" nverts=\"" +
                              nverts + "\" verts=\"" + verts + "\" /></state>\n</cycles>\n");
}

double slope_of(const std::string &label, const std::string &shader_nodes, const std::string &integrator_attributes = "") {
  const scene::Scene scene = scene::load_scene(white_world_sphere(label + ".xml", shader_nodes, integrator_attributes));
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
const char *kMultiGgx = "<glossy_bsdf name=\"b\" distribution=\"multi_ggx\" roughness=\"0.9\" color=\"1 1 1\" />"
                        "<connect from=\"b bsdf\" to=\"output surface\" />";
const char *kGlassGgx = "<glass_bsdf name=\"b\" distribution=\"ggx\" roughness=\"0.6\" IOR=\"1.5\" color=\"1 1 1\" />"
                        "<connect from=\"b bsdf\" to=\"output surface\" />";
const char *kGlassMultiGgx = "<glass_bsdf name=\"b\" distribution=\"multi_ggx\" roughness=\"0.6\" IOR=\"1.5\" "
                             "color=\"1 1 1\" /><connect from=\"b bsdf\" to=\"output surface\" />";
const char *kDiffuse = "<diffuse_bsdf name=\"b\" color=\"0.8 0.8 0.8\" /><connect from=\"b bsdf\" to=\"output surface\" />";

const char *kMix = "<diffuse_bsdf name=\"d\" color=\"0.8 0.8 0.8\" />"
                   "<glossy_bsdf name=\"g\" distribution=\"ggx\" roughness=\"0.9\" color=\"1 1 1\" />"
                   "<mix_closure name=\"m\" fac=\"0.5\" /><connect from=\"d bsdf\" to=\"m closure1\" />"
                   "<connect from=\"g bsdf\" to=\"m closure2\" /><connect from=\"m closure\" to=\"output surface\" />";

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

// Camera, one BSDF sample and one light sample are each a 2D integral: QMC rate. One test: the slopes
// are compared with plain GGX's.
TEST(Convergence, WhiteWorldSphereSlopes) {
  const double ggx = slope_of("conductor_ggx", kGgx);
  EXPECT_LT(ggx, -0.8);
  EXPECT_LT(slope_of("diffuse", kDiffuse), -0.8);
  EXPECT_LT(slope_of("conductor_multi_ggx", kMultiGgx), ggx + 0.1);
  EXPECT_LT(slope_of("mix_diffuse_ggx", kMix), ggx + 0.1);
  const std::string one_event = "max_bounce=\"0\"";
  EXPECT_LT(slope_of("glass_ggx_one_event", kGlassGgx, one_event), ggx + 0.1);
  EXPECT_LT(slope_of("glass_multi_ggx_one_event", kGlassMultiGgx, one_event), ggx + 0.1);
}

}  // namespace
}  // namespace glimmer::test
