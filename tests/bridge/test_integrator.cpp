// Integrator tests: white furnace, MIS consistency (light sampling vs BSDF
// sampling vs MIS agree within measured noise), determinism across thread
// counts and tile sizes, no non-finite pixels.
#include <OpenImageIO/imageio.h>
#include <tbb/global_control.h>

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
void furnace(const std::string &background_xml, bool with_floor, const std::string &name) {
  std::string xml = "<cycles>\n" + camera_xml(48, 32) +
                    "<integrator max_bounce=\"1000\" max_diffuse_bounce=\"1000\" sample_clamp_indirect=\"0\" />\n"
                    "<background>" + background_xml + "<connect from=\"bg background\" to=\"output surface\" /></background>\n"
                    "<shader name=\"white\"><diffuse_bsdf name=\"d\" color=\"1 1 1\" />"
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
    std::vector<double> d;
    for (size_t i = 0; i < static_cast<size_t>(r.width) * r.height; ++i) d.push_back(r.combined[4 * i + c] - 1.0);
    double m = 0, v = 0;
    for (double x : d) m += x;
    m /= d.size();
    for (double x : d) v += (x - m) * (x - m);
    const double se = std::sqrt(v / (d.size() - 1) / d.size());
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
  EXPECT_GT(mean_channel(mis, 1), 0.02);
}

const char *kLightKinds[] = {"area_quad", "area_disk", "sphere", "spot", "sun", "mesh", "env"};

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
  render::RenderResult a, b;
  {
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    opt.tile_size = 7;
    a = render_scene(path, opt);
  }
  {
    tbb::global_control many(tbb::global_control::max_allowed_parallelism, 4);
    opt.tile_size = 16;
    b = render_scene(path, opt);
  }
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
