// Varying closure parameters (ABI 2): a texture linked into a closure parameter
// is evaluated at every shading point. A quad carries a 2x2 checker (uv, scale 2)
// linked into one parameter with the two checker values A and B; it must render,
// region by region, like the same quad with the constant parameter A or B.
//
// The regions come from a mask render of the same checker as emission (pixel =
// mean checker fac over its samples): pixels with mask exactly 1 (or 0) saw only
// region A (or B) in every sample. Renders share the camera and the sampler, so
// a pixel of the textured render traces the same paths as the constant render
// of its region: the test asks for equality (to float rounding), which is
// stricter than "within noise", and also reports the z-score of the mean
// difference. Negative control: the constant A and B renders differ in most
// pixels (the test can tell the two values apart), and the pre-ABI-2 behaviour
// (the constant used everywhere) fails it.
//
// Unsupported links (a socket the closure does not declare varying, or a socket
// the host does not map) render with their constant and warn with file:line.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <regex>

#include "render_test_util.h"

namespace glimmer::test {
namespace {

constexpr int kSize = 32;

// A 2.2 x 2.2 quad facing the camera at z = 3 under a point light 40 degrees
// off the mirror direction (so roughness and IOR change what the pixel sees),
// black background. `nodes` must define the closure "g" and may use the
// checker "c" (uv coordinates, 2x2 cells); `output` is g's output socket. `behind`: more scene elements (e.g. an
// emitter behind the quad, for closures that transmit).
std::string quad_scene(const std::string &name, const std::string &nodes, const std::string &checker_colors,
                       const std::string &output = "bsdf", const std::string &behind = "") {
  return write_file(
      name,
      "<cycles>\n<camera width=\"32\" height=\"32\" fov=\"0.7\" />\n<camera />\n"
      "<integrator sample_clamp_direct=\"0\" sample_clamp_indirect=\"0\" />\n"
      "<state><light light_type=\"point\" co=\"2 0 0.5\" strength=\"300 300 300\" /></state>\n"
      "<shader name=\"s\">\n<texture_coordinate name=\"tc\" />\n<checker_texture name=\"c\" scale=\"2\" " +
          checker_colors + " />\n<connect from=\"tc uv\" to=\"c vector\" />\n" + nodes + "\n<connect from=\"g " +
          output +
          "\" to=\"output surface\" />\n</shader>\n"
          "<state shader=\"s\"><mesh P=\"-1.1 -1.1 3  1.1 -1.1 3  1.1 1.1 3  -1.1 1.1 3\" nverts=\"4\" "
          "verts=\"0 1 2 3\" UV=\"0 0 1 0 1 1 0 1\" /></state>\n" +
          behind + "</cycles>\n");
}

render::RenderResult render(const std::string &path, std::vector<std::string> *warnings = nullptr) {
  return render_with_warnings(path, 4, warnings);
}

// Which checker cell every sample of a pixel saw: 1 = all color1 (A), 0 = all color2 (B), else mixed.
std::vector<float> region_mask() {
  const auto r = render(quad_scene("mask.xml",
                                   "<emission name=\"g\" strength=\"1\" />\n<connect from=\"c fac\" to=\"g color\" />",
                                   "", "emission"));
  std::vector<float> mask;
  for (int i = 0; i < kSize * kSize; ++i) mask.push_back(r.combined[4 * i]);
  return mask;
}

struct RegionComparison {
  int pixels = 0;      // pixels of the region
  int mismatched = 0;  // pixels whose value differs beyond rounding
  double z = 0.0;      // z-score of the mean difference (all channels)
};

RegionComparison compare_region(const render::RenderResult &a, const render::RenderResult &b,
                                const std::vector<float> &mask, float region) {
  RegionComparison out;
  std::vector<double> d;
  for (int i = 0; i < kSize * kSize; ++i) {
    if (mask[i] != region) continue;
    ++out.pixels;
    bool same = true;
    for (int c = 0; c < 3; ++c) {
      const double x = a.combined[4 * i + c], y = b.combined[4 * i + c];
      d.push_back(x - y);
      same = same && std::fabs(x - y) <= 1e-5 * std::max(1.0, std::fabs(y));
    }
    if (!same) ++out.mismatched;
  }
  const MeanAndError e = mean_and_standard_error(d);
  out.z = e.standard_error > 0.0 ? e.mean / e.standard_error : (e.mean == 0.0 ? 0.0 : 1e9);
  return out;
}

// `closure` is the closure node with `{}` where the parameter's attribute goes,
// `socket` the linked input, `a` and `b` the two values (as XML numbers).
void expect_textured_equals_constants(const std::string &label, const std::string &closure, const std::string &socket,
                                      const std::string &a, const std::string &b, const std::string &behind = "") {
  auto with = [&](const std::string &attribute) {
    std::string node = closure;
    node.replace(node.find("{}"), 2, attribute);
    return node;
  };
  const std::string colors = "color1=\"" + a + " " + a + " " + a + "\" color2=\"" + b + " " + b + " " + b + "\"";
  std::vector<std::string> warnings;
  const auto textured =
      render(quad_scene(label + "_textured.xml", with("") + "\n<connect from=\"c color\" to=\"g " + socket + "\" />",
                        colors, "bsdf", behind),
             &warnings);
  for (const auto &w : warnings) ADD_FAILURE() << label << ": unexpected warning: " << w;
  const auto const_a = render(quad_scene(label + "_a.xml", with(socket + "=\"" + a + "\""), colors, "bsdf", behind));
  const auto const_b = render(quad_scene(label + "_b.xml", with(socket + "=\"" + b + "\""), colors, "bsdf", behind));
  const std::vector<float> mask = region_mask();

  const RegionComparison in_a = compare_region(textured, const_a, mask, 1.0f);
  const RegionComparison in_b = compare_region(textured, const_b, mask, 0.0f);
  const RegionComparison control = compare_region(const_a, const_b, mask, 1.0f);
  std::printf("[varying %s] region A: %d px, %d differ, z %.2f; region B: %d px, %d differ, z %.2f; "
              "control A vs B: %d of %d px differ, z %.1f\n",
              label.c_str(), in_a.pixels, in_a.mismatched, in_a.z, in_b.pixels, in_b.mismatched, in_b.z,
              control.mismatched, control.pixels, control.z);
  // Both regions are large (the 2x2 checker covers the frame; borders excluded).
  EXPECT_GT(in_a.pixels, kSize * kSize / 8) << label;
  EXPECT_GT(in_b.pixels, kSize * kSize / 8) << label;
  EXPECT_EQ(in_a.mismatched, 0) << label;
  EXPECT_EQ(in_b.mismatched, 0) << label;
  EXPECT_LT(std::fabs(in_a.z), 4.0) << label;
  EXPECT_LT(std::fabs(in_b.z), 4.0) << label;
  // Negative control: the two constants render differently in most pixels.
  EXPECT_GT(control.mismatched, control.pixels / 2) << label;
}

TEST(VaryingParams, CheckerRoughnessOnGlossyMatchesConstantRenders) {
  expect_textured_equals_constants("roughness", "<glossy_bsdf name=\"g\" distribution=\"ggx\" {} />", "roughness",
                                   "0.35", "0.7");
}

TEST(VaryingParams, CheckerAnisotropyOnAnisotropicMatchesConstantRenders) {
  expect_textured_equals_constants("anisotropy", "<anisotropic_bsdf name=\"g\" roughness=\"0.6\" {} />", "anisotropy",
                                   "0.8", "0");
}

TEST(VaryingParams, CheckerColourOnDiffuseMatchesConstantRenders) {
  expect_textured_equals_constants("colour", "<diffuse_bsdf name=\"g\" {} />", "color", "0.9", "0.2");
}

// Session 40: frosted_glass's colour is a tint per interface crossing and varying; a linked colour had become the
// closure's weight (a multiplier of reflection and transmission, once), so the textured render matched neither
// constant. A thin pane in front of an emitter (the tint is on transmission only).
TEST(VaryingParams, CheckerColourOnFrostedGlassMatchesConstantRenders) {
  const std::string emitter =
      "<shader name=\"lamp\"><emission name=\"e\" strength=\"2\" color=\"1 1 1\" />\n"
      "<connect from=\"e emission\" to=\"output surface\" /></shader>\n"
      "<state shader=\"lamp\"><mesh P=\"-9 -9 6  9 -9 6  9 9 6  -9 9 6\" nverts=\"4\" verts=\"0 1 2 3\" /></state>\n";
  expect_textured_equals_constants("frosted_colour",
                                   "<frosted_glass_bsdf name=\"g\" roughness=\"0.4\" thin=\"1\" {} />", "color", "0.9",
                                   "0.3", emitter);
}

TEST(VaryingParams, CheckerIorOnGlassMatchesConstantRenders) {
  expect_textured_equals_constants("ior", "<glass_bsdf name=\"g\" distribution=\"ggx\" roughness=\"0.5\" {} />",
                                   "IOR", "1.2", "2.2");
}

TEST(VaryingParams, CheckerDensityOnGlintMatchesConstantRenders) {
  expect_textured_equals_constants(
      "density", "<glint_bsdf name=\"g\" roughness=\"0.5\" gamma=\"4\" filter_threshold=\"1e9\" seed=\"3\" {} />",
      "density", "30000", "3000000");
}

// A textured value outside the parameter's range is clamped by the closure at each shading point (core/closure.h);
// the render reports how many shading points, the extreme value and the range at the <connect>'s file:line
// (session 41: a noise in [0, 1] into a glint density, range [1, 1e12], rendered as density 1 without a word).
// Below the minimum (glint density 0.2 / 0.7), above the maximum (glossy roughness 1.5 / 0.5: only the 1.5 cells), a
// colour (frosted glass colour 1.5 / 0.5 per channel: counted once per shading point, not per channel), and a
// Principled BSDF's roughness (one link into its diffuse and specular parts: one line naming the artist's node).
// The line is the same for 1 and 2 threads and for a second render of the same Renderer (counts reset per render).
// Negative controls: the same checkers with values in the range report nothing.
TEST(VaryingParams, TexturedValuesOutsideTheRangeAreReported) {
  struct Case {
    const char *closure, *socket, *colors, *expected;  // expected: a regex of the report, "" for none
  };
  const char *const below = " shading points had a textured value below the minimum, down to ";
  const char *const above = " shading points had a textured value above the maximum, up to ";
  const std::string cases_expected[] = {
      std::string(".*:11: warning: <glint_bsdf> 'g' parameter 'density': [0-9]+") + below +
          "0.2, clamped to 1 \\(its range is \\[1, 1e\\+12\\]\\)",
      std::string(".*:11: warning: <glossy_bsdf> 'g' parameter 'roughness': [0-9]+") + above +
          "1.5, clamped to 1 \\(its range is \\[0, 1\\]\\)",
      std::string(".*:11: warning: <frosted_glass_bsdf> 'g' parameter 'color': [0-9]+") + above +
          "1.5, clamped to 1 \\(its range is \\[0, 1\\]\\)",
      std::string(".*:11: warning: <principled_bsdf> 'g' parameter 'roughness': [0-9]+") + above +
          "1.5, clamped to 1 \\(its range is \\[0, 1\\]\\)",
  };
  const Case cases[] = {
      {"<glint_bsdf name=\"g\" roughness=\"0.5\" />", "density", "color1=\"0.2 0.2 0.2\" color2=\"0.7 0.7 0.7\"",
       cases_expected[0].c_str()},
      {"<glint_bsdf name=\"g\" roughness=\"0.5\" />", "density",
       "color1=\"30000 30000 30000\" color2=\"3000000 3000000 3000000\"", ""},
      {"<glossy_bsdf name=\"g\" distribution=\"ggx\" />", "roughness", "color1=\"1.5 1.5 1.5\" color2=\"0.5 0.5 0.5\"",
       cases_expected[1].c_str()},
      {"<glossy_bsdf name=\"g\" distribution=\"ggx\" />", "roughness", "color1=\"0.9 0.9 0.9\" color2=\"0.1 0.1 0.1\"",
       ""},
      {"<frosted_glass_bsdf name=\"g\" roughness=\"0.4\" thin=\"1\" />", "color",
       "color1=\"1.5 1.5 1.5\" color2=\"0.5 0.5 0.5\"", cases_expected[2].c_str()},
      {"<principled_bsdf name=\"g\" />", "roughness", "color1=\"1.5 1.5 1.5\" color2=\"0.5 0.5 0.5\"",
       cases_expected[3].c_str()},
  };
  int index = 0;
  for (const Case &c : cases) {
    const std::string name = "clamped_" + std::to_string(index++) + ".xml";
    const std::string path =
        quad_scene(name, std::string(c.closure) + "\n<connect from=\"c color\" to=\"g " + c.socket + "\" />", c.colors);
    const scene::Scene scene = scene::load_scene(path);
    render::RenderOptions opt;
    opt.samples = 4;
    render::Renderer renderer(scene, plugin(), opt);
    std::vector<std::string> lines[3];
    for (int run = 0; run < 3; ++run) {  // 1 thread, 2 threads, 1 thread again
      tbb::global_control limit(tbb::global_control::max_allowed_parallelism, run == 1 ? 2 : 1);
      lines[run] = renderer.render().warnings;
    }
    for (const auto &w : lines[0]) std::printf("[clamped] %s\n", w.c_str());
    if (*c.expected == '\0') {
      EXPECT_TRUE(lines[0].empty()) << name << ": " << lines[0].front();
      continue;
    }
    ASSERT_EQ(lines[0].size(), 1u) << name;
    EXPECT_TRUE(std::regex_match(lines[0][0], std::regex(c.expected))) << lines[0][0];
    EXPECT_EQ(lines[1], lines[0]) << "2 threads";
    EXPECT_EQ(lines[2], lines[0]) << "a second render";
    const long count = std::stol(std::regex_replace(lines[0][0], std::regex(".*': ([0-9]+) shading points.*"), "$1"));
    EXPECT_GT(count, 0);
    EXPECT_LE(count, 4L * kSize * kSize * 8) << "at most a few shading points per sample";
  }
}

// The records behind those lines travel in EXR metadata (render/clamped_parameters.h): the encoding reads back
// exactly (floats bit for bit, counts past 2^53, texts with tabs, newlines and backslashes, no extreme: +-inf), a
// malformed text or another version is refused, and records of the same parameter add up (counts add, lowest min,
// highest max) while another parameter (or another range) stays apart.
TEST(VaryingParams, ClampedRecordsRoundTripAndAddUp) {
  using render::ClampedParameterRecord;
  const float inf = std::numeric_limits<float>::infinity();
  const render::ClampedParameterRecords records = {
      {"scene.xml:20", "<glint_bsdf> 'Glint' parameter 'density'", 1.0f, 1e12f, 323, 0, 0.215369f, -inf},
      {"odd\tname\\with\nbreaks.xml:3", "<glossy_bsdf> 'a\tb' parameter 'roughness'", 0.0f, 1.0f,
       (uint64_t(1) << 60) + 1, 7, std::nextafter(0.0f, -1.0f), 1.0f + std::numeric_limits<float>::epsilon()},
  };
  const std::string text = render::encode_clamped_records(records);
  EXPECT_EQ(text.rfind("glimmer-clamped-parameters 1\n", 0), 0u) << text;
  EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 2) << "one line per record: " << text;
  const render::ClampedParameterRecords back = render::decode_clamped_records(text);
  ASSERT_EQ(back.size(), records.size());
  for (size_t k = 0; k < records.size(); ++k) {
    const ClampedParameterRecord &a = records[k], &b = back[k];
    EXPECT_EQ(b.where, a.where);
    EXPECT_EQ(b.what, a.what);
    EXPECT_EQ(b.below, a.below);
    EXPECT_EQ(b.above, a.above);
    for (auto field : {&ClampedParameterRecord::min_value, &ClampedParameterRecord::max_value,
                       &ClampedParameterRecord::lowest, &ClampedParameterRecord::highest})
      EXPECT_EQ(std::memcmp(&(a.*field), &(b.*field), sizeof(float)), 0) << k << ": " << text;
  }
  EXPECT_TRUE(render::encode_clamped_records({}).empty());
  EXPECT_TRUE(render::decode_clamped_records("").empty());
  // Refused: another version, a missing field, a number that is not one.
  const std::string line = text.substr(text.find('\n') + 1, text.find('\n', text.find('\n') + 1) - text.find('\n') - 1);
  EXPECT_THROW(render::decode_clamped_records("glimmer-clamped-parameters 2\n" + line), std::runtime_error);
  EXPECT_THROW(render::decode_clamped_records("glimmer-clamped-parameters 1\na\tb\t0\t1\t2\t3\t0.5"),
               std::runtime_error);
  EXPECT_THROW(render::decode_clamped_records("glimmer-clamped-parameters 1\na\tb\t0\t1\t2x\t3\t0.5\t-inf"),
               std::runtime_error);
  EXPECT_NO_THROW(render::decode_clamped_records("glimmer-clamped-parameters 1\na\tb\t0\t1\t2\t3\t0.5\t-inf"));
  // Adding up: the first record twice, the second once, and the first with another range.
  render::ClampedParameterRecords sum = records;
  ClampedParameterRecord more = records[0];
  more.below = 10;
  more.lowest = 0.5f;  // not lower: the minimum stays
  more.above = 2;
  more.highest = 3e12f;
  ClampedParameterRecord other_range = records[0];
  other_range.max_value = 1e9f;
  render::add_clamped_records(sum, {more, other_range});
  ASSERT_EQ(sum.size(), 3u);
  EXPECT_EQ(sum[0].below, 333u);
  EXPECT_EQ(sum[0].above, 2u);
  EXPECT_EQ(sum[0].lowest, 0.215369f);
  EXPECT_EQ(sum[0].highest, 3e12f);
  EXPECT_EQ(sum[1].below, records[1].below);
  EXPECT_EQ(sum[2].below, 323u);
  // The warning lines are the render's (TexturedValuesOutsideTheRangeAreReported): one per direction with a count.
  const std::vector<std::string> lines = render::clamped_parameter_warnings(sum);
  ASSERT_EQ(lines.size(), 5u);  // both directions of the first two records, below of the third
  EXPECT_EQ(lines[0],
            "scene.xml:20: warning: <glint_bsdf> 'Glint' parameter 'density': 333 shading points had a textured value "
            "below the minimum, down to 0.215369, clamped to 1 (its range is [1, 1e+12])");
  EXPECT_EQ(lines[1],
            "scene.xml:20: warning: <glint_bsdf> 'Glint' parameter 'density': 2 shading points had a textured value "
            "above the maximum, up to 3e+12, clamped to 1e+12 (its range is [1, 1e+12])");
}

// Every linked socket the host cannot honour renders with its constant and
// warns at the <connect> line.
TEST(VaryingParams, UnsupportedLinksWarnWithFileAndLine) {
  struct Case {
    const char *closure;
    const char *socket;
  };
  const Case cases[] = {
      {"<glossy_bsdf name=\"g\" roughness=\"0.3\" />", "surface_mix_weight"},  // ignored by the host
      {"<diffuse_bsdf name=\"g\" />", "roughness"},                   // Oren-Nayar is not supported
      {"<glint_bsdf name=\"g\" />", "seed"},                          // not varying in the closure's schema
      {"<glint_bsdf name=\"g\" />", "gamma"},
  };
  int index = 0;
  for (const Case &c : cases) {
    const std::string name = "unsupported_" + std::to_string(index++) + ".xml";
    const std::string path = quad_scene(
        name, std::string(c.closure) + "\n<connect from=\"c fac\" to=\"g " + c.socket + "\" />", "");
    std::vector<std::string> warnings;
    render(path, &warnings);
    // The <connect> into the socket is line 11 of the generated file.
    const std::regex expected(".*" + name + ":11: warning: .*'" + c.socket + "'.*not supported.*constant.*");
    const bool found = std::any_of(warnings.begin(), warnings.end(),
                                   [&](const std::string &w) { return std::regex_match(w, expected); });
    EXPECT_TRUE(found) << c.closure << " <- " << c.socket << ": no file:line warning; got " << warnings.size()
                       << " warnings" << (warnings.empty() ? "" : ": " + warnings.front());
  }
}

}  // namespace
}  // namespace glimmer::test
