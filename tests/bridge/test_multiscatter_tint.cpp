// Cycles' Multiscatter GGX glossy colour c tints every bounce of the microfacet
// walk (k bounces -> c^k). The host passes a constant colour to the closure as
// bounce_tint (and keeps it as the weight): a facing quad under a uniform white
// environment must render the tinted walk's albedo sum_k p_k c^k, computed here
// by brute force with Heitz 2016 walks. A textured colour cannot be passed to a
// per-material closure: the host warns.
#include <OpenImageIO/imageio.h>

#include "glimmer/microfacet_walk.h"
#include "render_test_util.h"

namespace glimmer::test {
namespace {

namespace mf = glimmer::microfacet;

std::string quad_scene(const std::string &name, const std::string &shader_nodes) {
  return write_file(name,
                    "<cycles>\n<camera width=\"16\" height=\"16\" fov=\"0.05\" />\n<camera />\n"
                    "<integrator sample_clamp_direct=\"0\" sample_clamp_indirect=\"0\" />\n"
                    "<background><background name=\"bg\" color=\"1 1 1\" strength=\"1\" />"
                    "<connect from=\"bg background\" to=\"output surface\" /></background>\n"
                    "<shader name=\"s\">" + shader_nodes + "<connect from=\"g bsdf\" to=\"output surface\" /></shader>\n"
                    "<state shader=\"s\"><mesh P=\"-1.2 -1.2 3  1.2 -1.2 3  1.2 1.2 3  -1.2 1.2 3\" nverts=\"4\" "
                    "verts=\"0 1 2 3\" UV=\"0 0 1 0 1 1 0 1\" /></state>\n</cycles>\n");
}

TEST(MultiscatterTint, FacingQuadRendersTheTintedWalkAlbedo) {
  const Spectrum colour(0.8f, 0.5f, 0.2f);
  const float roughness = 0.9f, alpha = roughness * roughness;
  const auto r = render_scene(quad_scene("tint.xml", "<glossy_bsdf name=\"g\" distribution=\"multi_ggx\" roughness=\"0.9\" "
                                                     "color=\"0.8 0.5 0.2\" />"),
                              [] {
                                render::RenderOptions opt;
                                opt.samples = 64;
                                return opt;
                              }());
  EXPECT_EQ(r.nan_samples, 0u);
  // Reference: walks at normal incidence (the 0.05 rad view cone keeps mu > 0.9997).
  mf::WalkRng rng(11);
  const long walks = 2000000;
  double reference[3] = {0, 0, 0}, untinted_model[3];
  const Vec3 wi(0.0f, 0.0f, 1.0f);
  for (long n = 0; n < walks; ++n) {
    int order = 0;
    mf::walk_conductor(wi, mf::WalkSurface{alpha, alpha}, rng, order, [](float) {});
    if (order == 0) continue;
    for (int k = 0; k < 3; ++k) reference[k] += std::pow(double(colour[k]), order);
  }
  for (int k = 0; k < 3; ++k) {
    reference[k] /= walks;
    untinted_model[k] = colour[k];  // colour x (E + E_ms(white)) = colour x 1
    const MeanAndError e = mean_and_standard_error(channel_values(r, k));
    const double m = e.mean, se = e.standard_error;
    std::printf("[multiscatter tint] channel %d colour %.1f: render %.5f +- %.5f, tinted walk %.5f, colour-once %.5f\n", k,
                colour[k], m, se, reference[k], untinted_model[k]);
    EXPECT_LT(std::fabs(m - reference[k]), 0.01 * reference[k] + 4.5 * se) << "channel " << k;
  }
  // The test tells the two models apart: tinting once is > 5 % brighter for colour 0.5 and 0.2.
  EXPECT_GT(untinted_model[1] / reference[1], 1.05);
  EXPECT_GT(untinted_model[2] / reference[2], 1.05);
}

TEST(MultiscatterTint, TexturedColourWarns) {
  const std::string img = (temp_dir() / "tint.png").string();
  {
    auto out = OIIO::ImageOutput::create(img);
    const float rgb[3] = {0.5f, 0.5f, 0.5f};
    ASSERT_TRUE(out->open(img, OIIO::ImageSpec(1, 1, 3, OIIO::TypeDesc::UINT8)) &&
                out->write_image(OIIO::TypeDesc::FLOAT, rgb) && out->close());
  }
  const std::string path = quad_scene("tint_textured.xml",
                                      "<image_texture name=\"t\" filename=\"" + img +
                                          "\" /><glossy_bsdf name=\"g\" distribution=\"multi_ggx\" roughness=\"0.9\" />"
                                          "<connect from=\"t color\" to=\"g color\" />");
  const scene::Scene scene = scene::load_scene(path);
  render::RenderOptions opt;
  opt.samples = 1;
  render::Renderer renderer(scene, plugin(), opt);
  (void)renderer.render();
  bool found = false;
  for (const auto &w : renderer.warnings())
    found = found || (w.find("tint_textured.xml:") != std::string::npos &&
                      w.find("multi_ggx tints the multiple-scattering energy once") != std::string::npos);
  EXPECT_TRUE(found);
}

}  // namespace
}  // namespace glimmer::test
