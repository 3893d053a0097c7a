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
// docs/architecture.md "Sample dimensions"); `make stress` runs the slopes to 1024 spp and full-depth
// glass at the Monte Carlo rate. Also: the slope fit itself, and that a surface behind a transparent one
// draws its own sample sets.
#include <OpenImageIO/imageio.h>

#include <cmath>
#include <fstream>
#include <iterator>

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
// The spp ladder and reference of one run of the slope checks.
struct Ladder {
  std::vector<int> samples;
  int reference_samples;
};
const Ladder kFastLadder{{16, 32, 64, 128, 256}, 2048};

double slope_of(const std::string &label, const std::string &shader_nodes, const std::string &integrator_attributes = "",
                const std::string &world_nodes = kWhiteWorld, const Ladder &ladder = kFastLadder) {
  return convergence_of(label, shader_nodes, integrator_attributes, world_nodes, ladder.samples,
                        ladder.reference_samples)
      .slope_spp;
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

// Camera, one BSDF sample and one light sample are each a 2D integral: QMC rate. The slopes are compared
// with plain GGX's.
void expect_qmc_slopes(const Ladder &ladder) {
  const double ggx = slope_of("conductor_ggx", kGgx, "", kWhiteWorld, ladder);
  EXPECT_LT(ggx, -0.8);
  // Diffuse under a world that is a light (a constant world is not, see WorldSampling below).
  EXPECT_LT(slope_of("diffuse_world_light", kDiffuse, "", textured_white_world(), ladder), -0.8);
  // multi_ggx through a textured (light) world: the world is MIS-combined with the conductor's samples, so it
  // keeps the lobe mixture, whose lobe choice must keep the QMC rate (a rejection sampler's curved accept /
  // reject boundary in the 3D sample cube lost it: -0.69, docs/microfacet.md).
  const render::ConvergenceResult mixture = convergence_of("conductor_multi_ggx_world_light", kMultiGgx, "",
                                                           textured_white_world(), ladder.samples, ladder.reference_samples);
  EXPECT_LT(mixture.slope_spp, ggx + 0.1);
  // In the constant white world (no lamp) nothing is combined: the conductor samples exactly, the world is not a
  // light (WorldSampling below) and the weight is 1 up to the tables' error, so there is no rate to fit (issue 13:
  // this line asserted the mixture's slope here before; measured 0.00028 / 0.00027 / 0.00100 / 0.00101 / 0.00076
  // at 16..256 spp, the residual being rare paths lost under the faceted sphere, in the reference too). It must
  // beat the mixture at every sample count.
  const render::ConvergenceResult exact =
      convergence_of("conductor_multi_ggx", kMultiGgx, "", kWhiteWorld, ladder.samples, ladder.reference_samples);
  for (size_t i = 0; i < exact.points.size(); ++i)
    EXPECT_LT(exact.points[i].rmse, mixture.points[i].rmse) << exact.points[i].samples << " spp";
  EXPECT_LT(slope_of("mix_diffuse_ggx", kMix, "", kWhiteWorld, ladder), ggx + 0.1);
  const std::string one_event = "max_bounce=\"0\"";
  EXPECT_LT(slope_of("glass_ggx_one_event", kGlassGgx, one_event, kWhiteWorld, ladder), ggx + 0.1);
  EXPECT_LT(slope_of("glass_multi_ggx_one_event", kGlassMultiGgx, one_event, kWhiteWorld, ladder), ggx + 0.1);
}

TEST(Convergence, WhiteWorldSphereSlopes) { expect_qmc_slopes(kFastLadder); }

// make stress: the same slopes up to 1024 spp against 8192, and full-depth glass, whose many-bounce paths
// converge at the Monte Carlo rate (about -0.5, docs/architecture.md): a bias or a correlation between
// sample sets would flatten it toward 0.
TEST(Convergence, StressWhiteWorldSphereSlopesTo1024Spp) {
  if (stress_scale() == 1) GTEST_SKIP() << "make stress only";
  const Ladder longer{{16, 32, 64, 128, 256, 512, 1024}, 8192};
  expect_qmc_slopes(longer);
  EXPECT_LT(slope_of("glass_ggx_full_depth", kGlassGgx, "", kWhiteWorld, longer), -0.4);
  EXPECT_LT(slope_of("glass_multi_ggx_full_depth", kGlassMultiGgx, "", kWhiteWorld, longer), -0.4);
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
  // The isotropic multi_ggx conductor samples with weight = albedo where no light is MIS-combined with it
  // (docs/microfacet.md), so the constant world is not a light there either (measured per closure instance,
  // samples_with_constant_weight). Negative controls: the anisotropic multi_ggx conductor mixes its two lobes
  // and multi_ggx glass weighs G2 / G1 / E: their weights vary, the world is a light.
  const std::string exact = white_world_sphere("world_constant_multi_ggx.xml", kMultiGgx, "");
  EXPECT_EQ(render(exact, render::LightStrategy::MIS, 1).combined,
            render(exact, render::LightStrategy::BsdfOnly, 1).combined);
  const std::string glass = white_world_sphere("world_constant_glass_multi_ggx.xml", kGlassMultiGgx, "");
  EXPECT_NE(render(glass, render::LightStrategy::MIS, 1).combined,
            render(glass, render::LightStrategy::BsdfOnly, 1).combined);
  const std::string anisotropic = white_world_sphere(
      "world_constant_multi_ggx_aniso.xml",
      "<glossy_bsdf name=\"b\" distribution=\"multi_ggx\" roughness=\"0.9\" anisotropy=\"0.5\" color=\"1 1 1\" />"
      "<connect from=\"b bsdf\" to=\"output surface\" />",
      "");
  EXPECT_NE(render(anisotropic, render::LightStrategy::MIS, 1).combined,
            render(anisotropic, render::LightStrategy::BsdfOnly, 1).combined);
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
  const double multi_bsdf_only =
      convergence_of("multi_ggx_bsdf_only_world", kMultiGgx, "", kWhiteWorld, {16, 32}, 512).points[0].rmse;
  const double multi_as_light =
      convergence_of("multi_ggx_world_as_light", kMultiGgx, "", textured_white_world(), {16, 32}, 512).points[0].rmse;
  EXPECT_LT(multi_bsdf_only, 0.1 * multi_as_light);
}

// The choice is reported (`glimmer render --stats`: world_sampling=) and depends on the other lights: with a
// lamp in the scene the lamp is MIS-combined with the multi_ggx conductor's BSDF samples, so the conductor keeps
// the lobe mixture (its weight varies) and the constant world stays a light; without it, BSDF rays only.
TEST(WorldSampling, ExactMultiGgxOnlyWhereNoLightIsCombined) {
  auto world_sampling = [](const std::string &path) {
    std::string log;
    EXPECT_EQ(0, run_cli("render '" + path + "' -o '" + (temp_dir() / "world_choice.exr").string() +
                             "' --samples 1 --stats --quiet",
                         log))
        << log;
    const size_t at = log.find("world_sampling=");
    return at == std::string::npos ? std::string("missing") : log.substr(at + 15, log.find_first_of(" \n", at) - at - 15);
  };
  EXPECT_EQ("bsdf_only", world_sampling(white_world_sphere("choice_multi_ggx.xml", kMultiGgx, "")));
  EXPECT_EQ("bsdf_only", world_sampling(white_world_sphere("choice_diffuse.xml", kDiffuse, "")));
  EXPECT_EQ("light", world_sampling(white_world_sphere("choice_ggx.xml", kGgx, "")));
  std::ifstream in(white_world_sphere("choice_multi_ggx_lamp.xml", kMultiGgx, ""));
  std::string xml((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  xml.replace(xml.find("</cycles>"), 9, "<light light_type=\"point\" co=\"0 3 4\" strength=\"100 100 100\" />\n</cycles>\n");
  EXPECT_EQ("light", world_sampling(write_file("choice_multi_ggx_lamp.xml", xml)));
}

// Every surface a path meets draws from its own sample sets, transparent pass-throughs included: two
// half-transparent veils (mix 0.5 of transparent and white diffuse) in front of an emissive wall of
// radiance 1, black world, max_bounce 0. Light reaches the camera only through both veils' transparent
// parts: 0.5 x 0.5 x 1 = 0.25 (the diffuse parts face the camera, the wall is behind them, and with no
// bounce after a diffuse scatter only an emitter it hits directly would count).
// Negative control, measured: when the second veil reused the first one's set (the pass-through is not a
// bounce), its x was the x < 0.5 that had picked transparency, so it picked transparency again: 0.5.
TEST(SampleDimensions, SurfaceBehindATransparentOneDrawsFreshNumbers) {
  const std::string veil = "<transparent_bsdf name=\"t\" color=\"1 1 1\" /><diffuse_bsdf name=\"d\" color=\"1 1 1\" />"
                           "<mix_closure name=\"m\" fac=\"0.5\" /><connect from=\"t bsdf\" to=\"m closure1\" />"
                           "<connect from=\"d bsdf\" to=\"m closure2\" /><connect from=\"m closure\" to=\"output surface\" />";
  const std::string path = write_file(
      "two_veils.xml",
      "<cycles>\n<camera width=\"16\" height=\"16\" fov=\"0.5\" />\n<camera />\n<integrator max_bounce=\"0\" />\n"
      "<shader name=\"glow\"><emission name=\"e\" color=\"1 1 1\" strength=\"1\" />"
      "<connect from=\"e emission\" to=\"output surface\" /></shader>\n"
      "<shader name=\"veil\">" + veil + "</shader>\n"
      "<state shader=\"veil\"><mesh P=\"-1 -1 2  1 -1 2  1 1 2  -1 1 2\" nverts=\"4\" verts=\"0 1 2 3\" /></state>\n"
      "<state shader=\"veil\"><mesh P=\"-2 -2 3  2 -2 3  2 2 3  -2 2 3\" nverts=\"4\" verts=\"0 1 2 3\" /></state>\n"
      "<state shader=\"glow\"><mesh P=\"-3 -3 4  3 -3 4  3 3 4  -3 3 4\" nverts=\"4\" verts=\"0 1 2 3\" /></state>\n"
      "</cycles>\n");
  render::RenderOptions opt;
  opt.samples = 64;
  opt.aovs = false;
  const auto r = render_scene(path, opt);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(mean_channel(r, c, 4, 4, 12, 12), 0.25, 0.03) << "channel " << c;
}

}  // namespace
}  // namespace glimmer::test
