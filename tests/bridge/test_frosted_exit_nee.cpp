// Light sampling at the exit of frosted_glass method=sg (closure ABI 2.4 exit lobes; the renderer's stage
// integrate_exit_lobe, docs/frosted_glass.md "Light sampling at the exit"). A frosted slab (the
// sphere mesh flattened to 0.16, roughness 0.3, IOR 1.5) with a small area light (0.1 x 0.1) 0.5 behind it and
// a dim sky, rendered with method=sg with and without next-event estimation + MIS at the exit point:
//  - the same image in expectation (an unbiased change of estimator): the mean difference over the slab, per
//    channel, within 4 standard errors of the two renders' noise (two seeds each);
//  - lower noise: the per-pixel standard deviation of the difference of two seeds, with NEE over without
//    (reported; asserted < 0.8);
//  - with the exit NEE on, the same image for 1 and 4 threads and tiles of 5 and 16 pixels.
#include "render_test_util.h"

namespace glimmer::test {
namespace {

const std::string kSphere = std::string(GLIMMER_TEST_SOURCE_DIR) + "/examples/sphere.obj";

std::string slab_scene() {
  const std::string xml =
      "<cycles>\n<camera width=\"24\" height=\"24\" fov=\"0.45\" />\n"
      "<transform translate=\"0 -5 1\" rotate=\"90 1 0 0\" scale=\"1 1 -1\"><camera /></transform>\n"
      "<integrator max_bounce=\"32\" max_transmission_bounce=\"32\" sample_clamp_direct=\"0\" "
      "sample_clamp_indirect=\"0\" />\n"
      "<background><background name=\"bg\" color=\"0.3 0.35 0.45\" strength=\"1\" />"
      "<connect from=\"bg background\" to=\"output surface\" /></background>\n"
      "<shader name=\"glass\"><frosted_glass_bsdf name=\"g\" roughness=\"0.3\" ior=\"1.5\" method=\"sg\" />"
      "<connect from=\"g bsdf\" to=\"output surface\" /></shader>\n"
      "<shader name=\"lamp\"><emission name=\"e\" color=\"1 0.9 0.7\" strength=\"1\" />"
      "<connect from=\"e emission\" to=\"output surface\" /></shader>\n"
      "<state shader=\"lamp\"><light light_type=\"area\" co=\"0.1 0.6 1.1\" dir=\"0 -1 0\" axisu=\"1 0 0\" "
      "axisv=\"0 0 1\" sizeu=\"0.1\" sizev=\"0.1\" strength=\"300 300 300\" /></state>\n"
      "<transform translate=\"0 0 1\" scale=\"0.95 0.08 0.95\"><state shader=\"glass\" interpolation=\"smooth\">"
      "<mesh src=\"" +
      kSphere +
      "\" /></state></transform>\n"
      "</cycles>\n";
  return write_file("frosted_exit_nee.xml", xml);
}

render::RenderResult render_slab(const std::string &path, bool exit_nee, int seed, int samples = 256,
                                 bool exit_lamps = false) {
  render::RenderOptions opt;
  opt.samples = samples;
  opt.seed = seed;
  opt.exit_lobe_nee = exit_nee;
  opt.exit_lobe_lamps = exit_lamps;
  return render_scene(path, opt);
}

// Per-pixel differences a - b (channel average) over the slab's pixels (the central 16 x 16).
std::vector<double> differences(const render::RenderResult &a, const render::RenderResult &b) {
  std::vector<double> d;
  for (int y = 4; y < 20; ++y)
    for (int x = 4; x < 20; ++x) {
      double s = 0.0;
      for (int c = 0; c < 3; ++c) {
        const size_t i = 4 * (static_cast<size_t>(y) * a.width + x) + c;
        s += static_cast<double>(a.combined[i]) - b.combined[i];
      }
      d.push_back(s / 3.0);
    }
  return d;
}
double standard_deviation(const std::vector<double> &v) {
  return mean_and_standard_error(v).standard_error * std::sqrt(static_cast<double>(v.size()));
}

// Mean difference (a1 + a2 - b1 - b2) / 2 per channel over the slab in standard errors: the worst |z|.
double worst_mean_z(const render::RenderResult &a1, const render::RenderResult &a2, const render::RenderResult &b1,
                    const render::RenderResult &b2) {
  double worst_z = 0.0;
  for (int c = 0; c < 3; ++c) {
    std::vector<double> d;
    for (int y = 4; y < 20; ++y)
      for (int x = 4; x < 20; ++x) {
        const size_t i = 4 * (static_cast<size_t>(y) * a1.width + x) + c;
        d.push_back(0.5 * (double(a1.combined[i]) + a2.combined[i] - b1.combined[i] - b2.combined[i]));
      }
    const MeanAndError e = mean_and_standard_error(d);
    worst_z = std::max(worst_z, std::fabs(e.mean / e.standard_error));
  }
  return worst_z;
}

TEST(FrostedExitNee, SameImageWithLowerNoise) {
  const std::string path = slab_scene();
  const auto nee1 = render_slab(path, true, 1), nee2 = render_slab(path, true, 2);
  const auto plain1 = render_slab(path, false, 3), plain2 = render_slab(path, false, 4);
  EXPECT_EQ(nee1.nan_samples + nee2.nan_samples + plain1.nan_samples + plain2.nan_samples, 0u);
  // The exit NEE ran: with the same seed the image differs.
  EXPECT_NE(render_slab(path, false, 1, 16).combined, render_slab(path, true, 1, 16).combined);
  // Noise: the spread of the difference of two seeds (2 x the per-pixel variance of one render).
  const double noise_nee = standard_deviation(differences(nee1, nee2));
  const double noise_plain = standard_deviation(differences(plain1, plain2));
  const double ratio = noise_nee / noise_plain;
  // Expectation: (nee1 + nee2) - (plain1 + plain2), every channel over the slab within 4 standard errors.
  const double worst_z = worst_mean_z(nee1, nee2, plain1, plain2);
  EXPECT_LT(worst_z, 4.0) << "mean difference with / without exit NEE";
  const double mean_nee = mean_channel(nee1, 0, 4, 4, 20, 20), mean_plain = mean_channel(plain1, 0, 4, 4, 20, 20);
  std::printf(
      "[frosted exit nee] slab + small light behind, sg, 256 spp, 24x24: mean (red, centre) with exit NEE "
      "%.4f, without %.4f; worst |z| of the difference %.2f; per-pixel noise with / without %.4f / %.4f = "
      "%.3f (equal-spp variance ratio %.3f)\n",
      mean_nee, mean_plain, worst_z, noise_nee, noise_plain, ratio, ratio * ratio);
  EXPECT_LT(ratio, 0.8);
}

// The lamp integrated against the exit lobe (RenderOptions::exit_lobe_lamps, LightSet::lamp_through_lobe) instead
// of one light sample at the exit: the same image in expectation (both unbiased for the lobe), lower noise.
TEST(FrostedExitLamps, SameImageWithLowerNoise) {
  const std::string path = slab_scene();
  const auto lamps1 = render_slab(path, true, 1, 256, true), lamps2 = render_slab(path, true, 2, 256, true);
  const auto nee1 = render_slab(path, true, 3), nee2 = render_slab(path, true, 4);
  EXPECT_EQ(lamps1.nan_samples + lamps2.nan_samples, 0u);
  EXPECT_NE(render_slab(path, true, 1, 16, true).combined, render_slab(path, true, 1, 16).combined);
  const double noise_lamps = standard_deviation(differences(lamps1, lamps2));
  const double noise_nee = standard_deviation(differences(nee1, nee2));
  const double ratio = noise_lamps / noise_nee;
  const double worst_z = worst_mean_z(lamps1, lamps2, nee1, nee2);
  EXPECT_LT(worst_z, 4.0);
  std::printf(
      "[frosted exit lamps] slab + small light behind, sg, 256 spp, 24x24: mean (red, centre) lamps through the lobe "
      "%.4f, one light sample %.4f; worst |z| of the difference %.2f; per-pixel noise %.4f / %.4f = %.3f\n",
      mean_channel(lamps1, 0, 4, 4, 20, 20), mean_channel(nee1, 0, 4, 4, 20, 20), worst_z, noise_lamps, noise_nee,
      ratio);
  EXPECT_LT(ratio, 0.8);
}

TEST(FrostedExitNee, DeterministicAcrossThreadsAndTiles) {
  const std::string path = slab_scene();
  render::RenderOptions opt;
  opt.samples = 8;
  EXPECT_EQ(render_scene_with(path, opt, 1, 5).combined, render_scene_with(path, opt, 4, 16).combined);
}

}  // namespace
}  // namespace glimmer::test
