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
#include <OpenImageIO/imageio.h>

#include <cmath>

#include "render/convergence.h"
#include "render_test_util.h"

namespace glimmer::test {
namespace {

// A unit UV sphere (smooth, exact normals) 4 units in front of the camera; the 0.3 rad view
// keeps every pixel on the sphere (corner ray 0.21 rad < asin(1/4) = 0.25 rad).
const char *kWhiteWorld = "<background name=\"bg\" color=\"1 1 1\" strength=\"1\" />"
                          "<connect from=\"bg background\" to=\"output surface\" />";

std::string white_world_sphere(const std::string &name, const std::string &shader_nodes,
                               const std::string &integrator_attributes, const std::string &world_nodes = kWhiteWorld) {
  return write_file(name, "<cycles>\n<camera width=\"32\" height=\"32\" fov=\"0.3\" />\n<camera />\n"
                          "<integrator sample_clamp_direct=\"0\" sample_clamp_indirect=\"0\" filter_glossy=\"0\" " +
                              integrator_attributes + " />\n"
                          "<background>" + world_nodes + "</background>\n"
                          "<shader name=\"s\">" + shader_nodes + "</shader>\n"
                          "<state shader=\"s\" interpolation=\"smooth\">" + uv_sphere_mesh(48, 96, 4.0) +
                              "</state>\n</cycles>\n");
}

// A white world through an environment texture: the same radiance, but spatially varying for the renderer,
// so it is a light (importance-sampled, MIS) whatever the closures.
std::string textured_white_world() {
  const std::string env = (temp_dir() / "white_env.exr").string();
  const std::vector<float> ones(4 * 2 * 3, 1.0f);
  auto out = OIIO::ImageOutput::create(env);
  EXPECT_TRUE(out->open(env, OIIO::ImageSpec(4, 2, 3, OIIO::TypeDesc::FLOAT)) &&
              out->write_image(OIIO::TypeDesc::FLOAT, ones.data()) && out->close());
  return "<environment_texture name=\"env\" filename=\"" + env + "\" /><background name=\"bg\" strength=\"1\" />"
         "<connect from=\"env color\" to=\"bg color\" /><connect from=\"bg background\" to=\"output surface\" />";
}

render::ConvergenceResult convergence_of(const std::string &label, const std::string &shader_nodes,
                                         const std::string &integrator_attributes = "",
                                         const std::string &world_nodes = kWhiteWorld,
                                         std::vector<int> ladder = {16, 32, 64, 128, 256}, int reference_samples = 2048) {
  const scene::Scene scene =
      scene::load_scene(white_world_sphere(label + ".xml", shader_nodes, integrator_attributes, world_nodes));
  render::ConvergenceOptions opt;
  opt.ladder = std::move(ladder);
  opt.reference_samples = reference_samples;
  const render::ConvergenceResult r = render::measure_convergence(scene, plugin(), opt);
  std::printf("[convergence] %-26s", label.c_str());
  for (const auto &p : r.points) std::printf(" %d:%.5f", p.samples, p.rmse);
  std::printf("  slope %.3f\n", r.slope_spp);
  return r;
}
double slope_of(const std::string &label, const std::string &shader_nodes, const std::string &integrator_attributes = "",
                const std::string &world_nodes = kWhiteWorld) {
  return convergence_of(label, shader_nodes, integrator_attributes, world_nodes).slope_spp;
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
  // Diffuse under a world that is a light (a constant world is not, see WorldSampling below).
  EXPECT_LT(slope_of("diffuse_world_light", kDiffuse, "", textured_white_world()), -0.8);
  EXPECT_LT(slope_of("conductor_multi_ggx", kMultiGgx), ggx + 0.1);
  EXPECT_LT(slope_of("mix_diffuse_ggx", kMix), ggx + 0.1);
  const std::string one_event = "max_bounce=\"0\"";
  EXPECT_LT(slope_of("glass_ggx_one_event", kGlassGgx, one_event), ggx + 0.1);
  EXPECT_LT(slope_of("glass_multi_ggx_one_event", kGlassMultiGgx, one_event), ggx + 0.1);
}

// A constant-colour world with only diffuse closures is not a light (as Cycles' automatic world sampling
// decides): with MIS the image is bit-identical to BSDF-only sampling, and its error is far below that of the
// same white world as a light. Negative controls: with a glossy closure, or through an environment texture
// (spatially varying for the renderer), the world is a light and the MIS image differs. Light-only sampling
// keeps the constant world as a light and agrees in expectation.
TEST(WorldSampling, ConstantWorldIsALightOnlyWhereThatHelps) {
  auto render = [](const std::string &path, render::LightStrategy strategy, int seed) {
    render::RenderOptions opt;
    opt.samples = 16;
    opt.seed = seed;
    opt.aovs = false;
    opt.strategy = strategy;
    return render_scene(path, opt);
  };
  const std::string constant = white_world_sphere("world_constant.xml", kDiffuse, "");
  const auto mis = render(constant, render::LightStrategy::MIS, 1);
  EXPECT_EQ(mis.combined, render(constant, render::LightStrategy::BsdfOnly, 1).combined);

  const std::string glossy = white_world_sphere("world_constant_ggx.xml", kGgx, "");
  EXPECT_NE(render(glossy, render::LightStrategy::MIS, 1).combined,
            render(glossy, render::LightStrategy::BsdfOnly, 1).combined);
  const std::string textured = white_world_sphere("world_textured.xml", kDiffuse, "", textured_white_world());
  EXPECT_NE(render(textured, render::LightStrategy::MIS, 1).combined,
            render(textured, render::LightStrategy::BsdfOnly, 1).combined);

  const auto light_only = render(constant, render::LightStrategy::LightOnly, 2);
  EXPECT_GT(mean_channel(light_only, 1), 0.5);
  for (int c = 0; c < 3; ++c) EXPECT_LT(std::fabs(difference_z(mis, light_only, c, 0, 0, mis.width, mis.height)), 4.5);

  // Measured 0.0022 vs 0.025 at 16 spp.
  const double bsdf_only = convergence_of("diffuse_bsdf_only_world", kDiffuse, "", kWhiteWorld, {16, 32}, 512).points[0].rmse;
  const double as_light =
      convergence_of("diffuse_world_as_light", kDiffuse, "", textured_white_world(), {16, 32}, 512).points[0].rmse;
  EXPECT_LT(bsdf_only, 0.25 * as_light);
}

}  // namespace
}  // namespace glimmer::test
