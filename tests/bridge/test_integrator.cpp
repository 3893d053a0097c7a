// Integrator tests: white furnace, MIS consistency (light sampling vs BSDF
// sampling vs MIS agree within measured noise), determinism across thread
// counts and tile sizes, no non-finite pixels.
#include <OpenImageIO/imageio.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cstring>

#include "render_test_util.h"

namespace glimmer::test {
namespace {

const std::string kSphere = std::string(GLIMMER_TEST_SOURCE_DIR) + "/examples/sphere.obj";

// A small equirectangular EXR (linear float RGB), generated per test.
std::string write_env(const std::string &name, bool constant) {
  const int w = 64, h = 32;
  std::vector<float> px(w * h * 3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      float v = 1.0f;
      if (!constant) {
        // Sky gradient plus a bright patch (tests the importance map and its pdf).
        v = 0.2f + 0.8f * (1.0f - static_cast<float>(y) / h);
        if (x >= 40 && x < 44 && y >= 8 && y < 11) v = 40.0f;
      }
      for (int c = 0; c < 3; ++c) px[(y * w + x) * 3 + c] = v * (constant || c == 2 ? 1.0f : 0.9f);
    }
  const std::string path = (temp_dir() / name).string();
  auto out = OIIO::ImageOutput::create(path);
  OIIO::ImageSpec spec(w, h, 3, OIIO::TypeDesc::FLOAT);
  EXPECT_TRUE(out->open(path, spec) && out->write_image(OIIO::TypeDesc::FLOAT, px.data()) && out->close());
  return path;
}

std::string camera_xml(int w, int h) {
  return "<camera width=\"" + std::to_string(w) + "\" height=\"" + std::to_string(h) +
         "\" fov=\"0.7\" />\n"
         "<transform translate=\"0 -6 1.2\" rotate=\"85 1 0 0\" scale=\"1 1 -1\"><camera /></transform>\n";
}

// White furnace: albedo-1 diffuse geometry under a uniform white environment
// renders exactly 1 in expectation everywhere (any number of bounces).
void furnace(const std::string &background_xml, bool with_floor, const std::string &name,
             const std::string &closure = "<diffuse_bsdf name=\"d\" color=\"1 1 1\" />") {
  std::string xml = "<cycles>\n" + camera_xml(48, 32) +
                    "<integrator max_bounce=\"1000\" max_diffuse_bounce=\"1000\" max_glossy_bounce=\"1000\" "
                    "max_transmission_bounce=\"1000\" sample_clamp_indirect=\"0\" />\n"
                    "<background>" + background_xml + "<connect from=\"bg background\" to=\"output surface\" /></background>\n"
                    "<shader name=\"white\">" + closure +
                    "<connect from=\"d bsdf\" to=\"output surface\" /></shader>\n"
                    "<state shader=\"white\">\n"
                    "<transform translate=\"0 0 1\"><mesh src=\"" + kSphere + "\" /></transform>\n";
  if (with_floor) xml += "<mesh P=\"-3 -3 0  3 -3 0  3 3 0  -3 3 0\" nverts=\"4\" verts=\"0 1 2 3\" />\n";
  xml += "</state>\n</cycles>\n";
  const std::string path = write_file(name + ".xml", xml);
  render::RenderOptions opt;
  opt.samples = 32;
  const auto r = render_scene(path, opt);
  EXPECT_EQ(r.nan_samples, 0u);
  for (int c = 0; c < 3; ++c) {
    const MeanAndError e = mean_and_standard_error(channel_values(r, c, 1.0));
    const double m = e.mean, se = e.standard_error;
    // 4.5 standard errors (Bonferroni over 3 channels x 4 furnace variants at ~1e-4 overall).
    EXPECT_LT(std::fabs(m), 4.5 * se + 1e-6) << name << " channel " << c << ": mean " << 1.0 + m << " se " << se;
    EXPECT_LT(std::fabs(m), 0.02) << name << " channel " << c;
  }
}

TEST(Integrator, FurnaceSphereConstantBackground) {
  furnace("<background name=\"bg\" color=\"1 1 1\" strength=\"1\" />", false, "furnace_sphere");
}

TEST(Integrator, FurnaceSphereAndFloorConstantBackground) {
  furnace("<background name=\"bg\" color=\"0.5 0.5 0.5\" strength=\"2\" />", true, "furnace_floor");
}

// Glass conserves energy: a smooth or rough (multi_ggx) glass sphere vanishes in the furnace.
// Exercises the front-face normal for transmissive closures (eta vs 1/eta on exit).
TEST(Integrator, FurnaceGlassSphere) {
  if (!plugin().find("microfacet_dielectric")) GTEST_SKIP() << "needs microfacet_dielectric";
  for (const char *roughness : {"0", "0.3"}) {
    SCOPED_TRACE(roughness);
    furnace("<background name=\"bg\" color=\"1 1 1\" strength=\"1\" />", false, std::string("furnace_glass_") + roughness,
            std::string("<glass_bsdf name=\"d\" IOR=\"1.5\" distribution=\"multi_ggx\" roughness=\"") + roughness +
                "\" color=\"1 1 1\" />");
  }
}

TEST(Integrator, FurnaceWithEnvironmentMap) {
  // A constant-1 equirectangular map goes through the importance-sampled environment path.
  const std::string env = write_env("furnace_env.exr", true);
  furnace("<environment_texture name=\"env\" filename=\"" + env +
              "\" /><background name=\"bg\" strength=\"1\" /><connect from=\"env color\" to=\"bg color\" />",
          true, "furnace_env");
}

// A floor and a ball lit by one light of the given kind (every kind BSDF
// sampling can hit): NEE-only, BSDF-only and MIS must estimate the same image.
std::string mis_scene(const std::string &light, const std::string &floor_shader, const std::string &name) {
  std::string background, lights;
  if (light == "env") {
    const std::string env = write_env(name + "_env.exr", false);
    background = "<background><environment_texture name=\"env\" filename=\"" + env +
                 "\" /><background name=\"bg\" strength=\"1\" /><connect from=\"env color\" to=\"bg color\" />"
                 "<connect from=\"bg background\" to=\"output surface\" /></background>\n";
  } else if (light == "area_quad") {
    lights = "<light light_type=\"area\" co=\"1 -1 2.5\" dir=\"-0.3 0 -1\" axisu=\"1 0 0\" axisv=\"0 1 0\" sizeu=\"1.5\" sizev=\"1\" strength=\"20 20 20\" />";
  } else if (light == "area_disk") {
    lights = "<light light_type=\"area\" round=\"true\" co=\"-1 0 2\" dir=\"0.3 0 -1\" axisu=\"1 0 0\" axisv=\"0 1 0\" sizeu=\"1.8\" sizev=\"1.4\" strength=\"20 15 10\" />";
  } else if (light == "area_spread") {
    lights = "<light light_type=\"area\" co=\"0.5 -0.5 2\" dir=\"-0.2 0.2 -1\" axisu=\"1 0 0\" axisv=\"0 1 0\" sizeu=\"1.2\" sizev=\"1\" spread=\"1.2\" strength=\"20 20 20\" />";
  } else if (light == "sphere") {
    lights = "<light light_type=\"point\" co=\"0.5 -0.5 1.9\" size=\"0.7\" strength=\"20 20 20\" />";
  } else if (light == "spot") {
    lights = "<light light_type=\"spot\" co=\"0 -1 2.5\" dir=\"0 0.3 -1\" size=\"0.6\" spot_angle=\"1.6\" spot_smooth=\"0.3\" strength=\"150 150 150\" />";
  } else if (light == "sun") {
    lights = "<light light_type=\"sun\" dir=\"-0.3 0.5 -1\" angle=\"0.8\" strength=\"1 0.9 0.8\" />";
  }
  std::string xml = "<cycles>\n<camera width=\"40\" height=\"30\" fov=\"0.9\" />\n"
                    "<transform translate=\"0 -3.5 3.5\" rotate=\"45 1 0 0\" scale=\"1 1 -1\"><camera /></transform>\n"
                    "<integrator max_bounce=\"2\" sample_clamp_indirect=\"0\" />\n" + background +
                    "<shader name=\"lamp\"><emission name=\"e\" color=\"1 1 1\" strength=\"1\" />"
                    "<connect from=\"e emission\" to=\"output surface\" /></shader>\n"
                    "<shader name=\"glow\"><emission name=\"e\" color=\"0.2 1 0.3\" strength=\"3\" />"
                    "<connect from=\"e emission\" to=\"output surface\" /></shader>\n"
                    "<shader name=\"floor\">" + floor_shader + "<connect from=\"f bsdf\" to=\"output surface\" /></shader>\n"
                    "<shader name=\"ball\"><diffuse_bsdf name=\"d\" color=\"0.7 0.5 0.3\" />"
                    "<connect from=\"d bsdf\" to=\"output surface\" /></shader>\n"
                    "<state shader=\"lamp\">" + lights + "</state>\n";
  if (light == "mesh")
    xml += "<state shader=\"glow\"><mesh P=\"-1.5 1 0.1  0 1.3 0.1  0 1.3 1.2  -1.5 1 1.2\" nverts=\"4\" verts=\"0 1 2 3\" /></state>\n";
  xml += "<state shader=\"floor\"><mesh P=\"-4 -4 0  4 -4 0  4 4 0  -4 4 0\" nverts=\"4\" verts=\"0 1 2 3\" /></state>\n"
         "<state shader=\"ball\"><transform translate=\"0.3 0.3 0.5\" scale=\"0.5 0.5 0.5\"><mesh src=\"" + kSphere +
         "\" /></transform></state>\n</cycles>\n";
  return write_file(name + ".xml", xml);
}

void check_mis_consistency(const std::string &path, int samples) {
  render::RenderOptions opt;
  opt.samples = samples;
  opt.aovs = false;
  opt.strategy = render::LightStrategy::MIS;
  opt.seed = 1;
  const auto mis = render_scene(path, opt);
  opt.strategy = render::LightStrategy::LightOnly;
  opt.seed = 2;
  const auto nee = render_scene(path, opt);
  opt.strategy = render::LightStrategy::BsdfOnly;
  opt.seed = 3;
  const auto bsdf = render_scene(path, opt);
  EXPECT_EQ(mis.nan_samples + nee.nan_samples + bsdf.nan_samples, 0u);
  // Whole image and 4 quadrants, 3 channels, 3 pairs: 45 z-scores; |z| < 4.5 keeps the
  // family-wise false-alarm rate below 3e-4 while a 2% bias in a quadrant is caught.
  const int w = mis.width, h = mis.height;
  const int rects[5][4] = {{0, 0, w, h}, {0, 0, w / 2, h / 2}, {w / 2, 0, w, h / 2}, {0, h / 2, w / 2, h}, {w / 2, h / 2, w, h}};
  for (const auto &rc : rects)
    for (int c = 0; c < 3; ++c) {
      EXPECT_LT(std::fabs(difference_z(mis, nee, c, rc[0], rc[1], rc[2], rc[3])), 4.5) << "MIS vs NEE, channel " << c;
      EXPECT_LT(std::fabs(difference_z(mis, bsdf, c, rc[0], rc[1], rc[2], rc[3])), 4.5) << "MIS vs BSDF, channel " << c;
      EXPECT_LT(std::fabs(difference_z(nee, bsdf, c, rc[0], rc[1], rc[2], rc[3])), 4.5) << "NEE vs BSDF, channel " << c;
    }
  if (std::getenv("GLIMMER_PRINT_Z"))
    for (int c = 0; c < 3; ++c)
      std::printf("channel %d z: mis-nee %.2f mis-bsdf %.2f nee-bsdf %.2f; means %.4f %.4f %.4f\n", c,
                  difference_z(mis, nee, c, 0, 0, w, h), difference_z(mis, bsdf, c, 0, 0, w, h),
                  difference_z(nee, bsdf, c, 0, 0, w, h), mean_channel(mis, c), mean_channel(nee, c), mean_channel(bsdf, c));
  // The estimators must not be trivially equal (e.g. all black).
  EXPECT_GT(mean_channel(mis, 1), 0.01);
}

const char *kLightKinds[] = {"area_quad", "area_disk", "area_spread", "sphere", "spot", "sun", "mesh", "env"};

TEST(Integrator, MisConsistencyDiffuse) {
  for (const char *light : kLightKinds) {
    SCOPED_TRACE(light);
    check_mis_consistency(mis_scene(light, "<diffuse_bsdf name=\"f\" color=\"0.8 0.8 0.8\" />", std::string("mis_") + light), 96);
  }
}

TEST(Integrator, MisConsistencyGlossy) {
  if (!plugin().find("microfacet_conductor")) GTEST_SKIP() << "microfacet_conductor not in the plugin yet";
  for (const char *light : kLightKinds) {
    SCOPED_TRACE(light);
    check_mis_consistency(
        mis_scene(light, "<glossy_bsdf name=\"f\" distribution=\"ggx\" roughness=\"0.35\" color=\"0.8 0.8 0.8\" />",
                  std::string("mis_glossy_") + light),
        64);
  }
}

// Same image, bit for bit, for any thread count and tile size.
TEST(Integrator, DeterministicAcrossThreadsAndTiles) {
  const std::string path = mis_scene("area_quad", "<diffuse_bsdf name=\"f\" color=\"0.8 0.8 0.8\" />", "determinism");
  render::RenderOptions opt;
  opt.samples = 4;
  const render::RenderResult a = render_scene_with(path, opt, 1, 7), b = render_scene_with(path, opt, 4, 16);
  ASSERT_EQ(a.combined.size(), b.combined.size());
  EXPECT_EQ(0, std::memcmp(a.combined.data(), b.combined.data(), a.combined.size() * sizeof(float)));
  EXPECT_EQ(0, std::memcmp(a.albedo.data(), b.albedo.data(), a.albedo.size() * sizeof(float)));
  // A different seed gives a different image.
  opt.seed = 77;
  const auto c = render_scene(path, opt);
  EXPECT_NE(0, std::memcmp(a.combined.data(), c.combined.data(), a.combined.size() * sizeof(float)));
}

}  // namespace
}  // namespace glimmer::test

namespace glimmer::test {
namespace {

// filter_glossy (Cycles): a shelf hides a small lamp from the floor, which is lit only
// through a vertical mirror. That caustic path (floor -> sharp mirror -> lamp) is found only
// by BSDF sampling and is very noisy; with filter_glossy = 1 the mirror seen after the diffuse
// bounce is blurred so light sampling reaches the lamp and the noise drops.
double floor_noise(float filter_glossy) {
  const std::string xml =
      "<cycles>\n<camera width=\"24\" height=\"16\" fov=\"0.8\" />\n"
      "<transform translate=\"0 -4 3\" rotate=\"55 1 0 0\" scale=\"1 1 -1\"><camera /></transform>\n"
      "<integrator max_bounce=\"3\" sample_clamp_indirect=\"0\" filter_glossy=\"" + std::to_string(filter_glossy) + "\" />\n"
      "<shader name=\"lamp\"><emission name=\"e\" color=\"1 1 1\" strength=\"1\" /><connect from=\"e emission\" to=\"output surface\" /></shader>\n"
      "<shader name=\"mirror\"><glossy_bsdf name=\"m\" distribution=\"sharp\" color=\"1 1 1\" /><connect from=\"m bsdf\" to=\"output surface\" /></shader>\n"
      "<state shader=\"lamp\"><light light_type=\"point\" co=\"0 1.6 2.6\" size=\"0.05\" strength=\"200 200 200\" /></state>\n"
      "<state shader=\"mirror\"><mesh P=\"-3 2 0  3 2 0  3 2 3  -3 2 3\" nverts=\"4\" verts=\"0 1 2 3\" /></state>\n"
      "<mesh P=\"-3 -3 0  3 -3 0  3 1.9 0  -3 1.9 0\" nverts=\"4\" verts=\"0 1 2 3\" />\n"
      "<mesh P=\"-3 1 2.3  3 1 2.3  3 1.7 2.3  -3 1.7 2.3\" nverts=\"4\" verts=\"0 1 2 3\" />\n</cycles>\n";
  const std::string path = write_file("filter_glossy.xml", xml);
  render::RenderOptions opt;
  // 64 spp: the caustic is a rare event (at 16 spp about half of all images of the sharp mirror miss it
  // entirely: 19 of 32 seeds with the sampler before issue 13's camera set, 24 of 32 with it), and the test
  // needs it found in both images; at 64 spp 2-3 of 16 seeds miss it.
  opt.samples = 64;
  opt.aovs = false;
  opt.seed = 1;
  const auto a = render_scene(path, opt);
  opt.seed = 2;
  const auto b = render_scene(path, opt);
  double var = 0.0;
  for (size_t i = 0; i < a.combined.size(); i += 4) var += std::pow(a.combined[i + 1] - b.combined[i + 1], 2.0);
  return var / (a.combined.size() / 4);
}

TEST(Integrator, FilterGlossyReducesCausticNoise) {
  if (!plugin().find("microfacet_conductor")) GTEST_SKIP() << "needs microfacet_conductor";
  const double sharp = floor_noise(0.0f), blurred = floor_noise(1.0f);
  EXPECT_GT(sharp, 0.0);
  EXPECT_LT(blurred * 4.0, sharp) << "noise variance " << sharp << " -> " << blurred;
  if (std::getenv("GLIMMER_PRINT_Z")) std::printf("filter_glossy noise variance %g -> %g\n", sharp, blurred);
}

}  // namespace
}  // namespace glimmer::test

namespace glimmer::test {
namespace {

std::string grey_world(const std::string &name, const std::string &integrator) {
  return write_file(name,
                    "<cycles>\n" + camera_xml(32, 24) + "<integrator " + integrator + " />\n"
                    "<background><background name=\"bg\" color=\"1 0.9 0.8\" strength=\"1\" />"
                    "<connect from=\"bg background\" to=\"output surface\" /></background>\n"
                    "<shader name=\"grey\"><diffuse_bsdf name=\"d\" color=\"0.6 0.6 0.6\" />"
                    "<connect from=\"d bsdf\" to=\"output surface\" /></shader>\n"
                    "<state shader=\"grey\">\n<transform translate=\"0 0 1\"><mesh src=\"" + kSphere + "\" /></transform>\n"
                    "<mesh P=\"-3 -3 0  3 -3 0  3 3 0  -3 3 0\" nverts=\"4\" verts=\"0 1 2 3\" />\n"
                    "<mesh P=\"-3 1.5 0  3 1.5 0  3 1.5 3  -3 1.5 3\" nverts=\"4\" verts=\"0 1 2 3\" />\n</state>\n</cycles>\n");
}

// Russian roulette is unbiased: with it (min_bounce 0) and without it (min_bounce 64) the
// interreflection-heavy grey scene agrees within noise; RR must actually terminate paths earlier.
TEST(Integrator, RussianRouletteIsUnbiased) {
  render::RenderOptions opt;
  opt.samples = 64;
  opt.aovs = false;
  opt.seed = 1;
  const auto with_rr = render_scene(grey_world("rr_on.xml", "max_bounce=\"64\" max_diffuse_bounce=\"64\" sample_clamp_indirect=\"0\" min_bounce=\"0\""), opt);
  opt.seed = 2;
  const auto without = render_scene(grey_world("rr_off.xml", "max_bounce=\"64\" max_diffuse_bounce=\"64\" sample_clamp_indirect=\"0\" min_bounce=\"64\""), opt);
  for (int c = 0; c < 3; ++c)
    EXPECT_LT(std::fabs(difference_z(with_rr, without, c, 0, 0, with_rr.width, with_rr.height)), 4.0) << c;
}

// Cycles' sample clamps bound the sum of a contribution's components (direct: camera and
// first-hit lighting; indirect: the rest).
TEST(Integrator, SampleClampsBoundContributions) {
  render::RenderOptions opt;
  opt.samples = 8;
  const auto r = render_scene(grey_world("clamped.xml", "sample_clamp_direct=\"0.3\" sample_clamp_indirect=\"0.05\" max_bounce=\"4\""), opt);
  // Every path adds at most 0.3 (direct) + 0.05 per later bounce contribution; the background
  // seen directly (sum 2.7) is clamped to 0.3.
  float max_sum = 0.0f;
  for (size_t i = 0; i < r.combined.size(); i += 4)
    max_sum = std::max(max_sum, r.combined[i] + r.combined[i + 1] + r.combined[i + 2]);
  EXPECT_LE(max_sum, 0.3f + 4 * 0.05f + 1e-4f);
  EXPECT_NEAR(r.combined[0] + r.combined[1] + r.combined[2], 0.3f, 1e-4f);  // top-left: background
}

// transparent_bsdf passes light straight through with its colour, for camera and shadow rays.
TEST(Integrator, TransparentPassThrough) {
  const std::string path = write_file(
      "transparent.xml",
      "<cycles>\n<camera width=\"16\" height=\"16\" fov=\"0.5\" />\n<camera />\n"
      "<shader name=\"glow\"><emission name=\"e\" color=\"1 1 1\" strength=\"2\" /><connect from=\"e emission\" to=\"output surface\" /></shader>\n"
      "<shader name=\"veil\"><transparent_bsdf name=\"t\" color=\"0.5 0.25 1\" /><connect from=\"t bsdf\" to=\"output surface\" /></shader>\n"
      "<state shader=\"veil\"><mesh P=\"-1 -1 2  1 -1 2  1 1 2  -1 1 2\" nverts=\"4\" verts=\"0 1 2 3\" /></state>\n"
      "<state shader=\"glow\"><mesh P=\"-3 -3 4  3 -3 4  3 3 4  -3 3 4\" nverts=\"4\" verts=\"0 1 2 3\" /></state>\n</cycles>\n");
  render::RenderOptions opt;
  opt.samples = 4;
  const auto r = render_scene(path, opt);
  const float *p = &r.combined[4 * (8 * 16 + 8)];
  EXPECT_NEAR(p[0], 1.0f, 1e-4f);
  EXPECT_NEAR(p[1], 0.5f, 1e-4f);
  EXPECT_NEAR(p[2], 2.0f, 1e-4f);
}

// A shader with only a volume output (Cycles' SD_HAS_ONLY_VOLUME: no surface at all) on a veil in front of an
// emitter: without volume rendering its objects let light through unscattered, with a warning that says so, instead
// of the black no-closure surface an empty surface output means (session 40; the corpus' scene_cube_volume.xml had
// rendered a black cube). Control: the same volume with a surface output as well (a black emission) keeps its
// surface: black.
TEST(Integrator, VolumeOnlyShaderLetsLightThrough) {
  const std::string glow =
      "<shader name=\"glow\"><emission name=\"e\" color=\"1 1 1\" strength=\"2\" />"
      "<connect from=\"e emission\" to=\"output surface\" /></shader>\n";
  const std::string geometry =
      "<state shader=\"veil\"><mesh P=\"-1 -1 2  1 -1 2  1 1 2  -1 1 2\" nverts=\"4\" verts=\"0 1 2 3\" /></state>\n"
      "<state shader=\"glow\"><mesh P=\"-3 -3 4  3 -3 4  3 3 4  -3 3 4\" nverts=\"4\" verts=\"0 1 2 3\" /></state>\n"
      "</cycles>\n";
  const std::string head = "<cycles>\n<camera width=\"16\" height=\"16\" fov=\"0.5\" />\n<camera />\n" + glow;
  const std::string volume =
      "<absorption_volume name=\"v\" color=\"0.5 0.5 0.5\" density=\"3\" />"
      "<connect from=\"v volume\" to=\"output volume\" />";
  std::vector<std::string> warnings;
  const auto only = render_with_warnings(
      write_file("volume_only.xml", head + "<shader name=\"veil\">" + volume + "</shader>\n" + geometry), 4, &warnings);
  const float *p = &only.combined[4 * (8 * 16 + 8)];
  EXPECT_NEAR(p[0], 2.0f, 1e-4f);
  EXPECT_NEAR(p[1], 2.0f, 1e-4f);
  EXPECT_NEAR(p[2], 2.0f, 1e-4f);
  const bool said = std::any_of(warnings.begin(), warnings.end(), [](const std::string &w) {
    return w.find("volume output is not supported") != std::string::npos &&
           w.find("let light pass") != std::string::npos;
  });
  EXPECT_TRUE(said) << warnings.size() << " warnings";
  // With a surface output as well, the surface is kept (black emission: black).
  const auto with_surface = render_with_warnings(
      write_file("volume_and_surface.xml", head + "<shader name=\"veil\">" + volume +
                                               "<emission name=\"black\" color=\"0 0 0\" strength=\"0\" />"
                                               "<connect from=\"black emission\" to=\"output surface\" /></shader>\n" +
                                               geometry),
      4);
  const float *q = &with_surface.combined[4 * (8 * 16 + 8)];
  EXPECT_NEAR(q[0] + q[1] + q[2], 0.0f, 1e-6f);
}

}  // namespace
}  // namespace glimmer::test
