// principled_bsdf in the host (bridge/render/principled.cpp): the node is expanded into
// Cycles closure nodes, so a Principled material must render like the same mix of
// closures written by hand in XML. Each case renders a smooth sphere under a point
// light in front of a coloured (emissive) background, once with principled_bsdf and
// once with a hand-built reference graph written independently below from the
// documented recipe (docs/scene-format.md, "principled_bsdf"); the per-channel
// z-score of the mean per-pixel difference must be below 4 (the renders are equal
// within noise; identical trees give identical images). Negative control per case:
// a reference with a known bug (the former base model: Lambert + a constant-f0 GGX and a glossy metal of the base
// colour; the metal mix reversed, specular_tint dropped, transmission or clearcoat dropped, the clearcoat as the
// former GGX lobe, alpha reversed, the metallic link dropped) must differ (z > 4). The base closures themselves
// (principled_diffuse, principled_specular) are checked against Cycles 3.4's formulas in tests/closures.
#include <algorithm>
#include <regex>

#include "render_test_util.h"

namespace glimmer::test {
namespace {

// A coloured background, a point light up-left, a unit sphere 4 units away seen
// whole (grazing angles included) with background around it.
std::string sphere_scene(const std::string &name, const std::string &shader_nodes) {
  return write_file(
      name, "<cycles>\n<camera width=\"32\" height=\"32\" fov=\"0.6\" />\n<camera />\n"
            "<integrator sample_clamp_direct=\"0\" sample_clamp_indirect=\"0\" filter_glossy=\"0\" />\n"
            "<background><background name=\"bg\" color=\"0.2 0.35 0.6\" strength=\"1\" />"
            "<connect from=\"bg background\" to=\"output surface\" /></background>\n"
            "<state><light light_type=\"point\" co=\"-2 2 1\" strength=\"200 200 200\" /></state>\n"
            "<shader name=\"s\">\n" + shader_nodes + "\n</shader>\n"
            "<state shader=\"s\" interpolation=\"smooth\">" + uv_sphere_mesh(24, 48, 4.0) + "</state>\n</cycles>\n");
}

render::RenderResult render(const std::string &path, std::vector<std::string> *warnings = nullptr) {
  return render_with_warnings(path, 16, warnings);
}

// The largest |z| over the three channels of the mean per-pixel difference.
double max_z(const render::RenderResult &a, const render::RenderResult &b) {
  double z = 0.0;
  for (int c = 0; c < 3; ++c) z = std::max(z, std::fabs(difference_z(a, b, c, 0, 0, a.width, a.height)));
  return z;
}

double mean_rgb(const render::RenderResult &r) {
  return (mean_channel(r, 0) + mean_channel(r, 1) + mean_channel(r, 2)) / 3.0;
}

const char *kBase = "0.8 0.3 0.1";

// The hand-built pieces of the reference graphs (Cycles nodes; `out` is the root's name and socket).
// Cycles 3.4's specular lobe (its Fresnel colour carries metallic, specular and specular_tint).
std::string specular_lobe(const std::string &attributes) {
  return std::string("<principled_specular_bsdf name=\"sp\" roughness=\"0.3\" base_color=\"") + kBase + "\" " +
         attributes + " />";
}
// diel = principled_diffuse(base colour, roughness) + the specular lobe `sp`.
std::string dielectric(const std::string &specular_attributes) {
  return std::string("<principled_diffuse_bsdf name=\"d\" roughness=\"0.3\" color=\"") + kBase + "\" />" +
         specular_lobe(specular_attributes) +
         "<add_closure name=\"diel\" /><connect from=\"d bsdf\" to=\"diel closure1\" />"
         "<connect from=\"sp bsdf\" to=\"diel closure2\" />";
}
const std::string kDielectric = dielectric("metallic=\"0\" specular=\"0.5\" specular_tint=\"0\"");
// The former base (negative control): Lambert + GGX of the constant reflectance 0.08 * specular.
const std::string kFormerDielectric =
    std::string("<diffuse_bsdf name=\"d\" color=\"") + kBase + "\" />"
    "<glossy_bsdf name=\"sp\" distribution=\"ggx\" roughness=\"0.3\" color=\"0.04 0.04 0.04\" />"
    "<add_closure name=\"diel\" /><connect from=\"d bsdf\" to=\"diel closure1\" />"
    "<connect from=\"sp bsdf\" to=\"diel closure2\" />";
std::string to_output(const std::string &from) { return "<connect from=\"" + from + "\" to=\"output surface\" />"; }
std::string principled(const std::string &attributes) {
  return "<principled_bsdf name=\"p\" base_color=\"" + std::string(kBase) + "\" roughness=\"0.3\" " + attributes +
         " />" + to_output("p bsdf");
}
// The coat on top of the base: Cycles 3.4's clearcoat lobe (clearcoat_bsdf) of weight 0.25 * clearcoat.
std::string clearcoat_over(const std::string &base_nodes, const std::string &base_out) {
  return base_nodes + "<clearcoat_bsdf name=\"coat\" roughness=\"0.1\" color=\"0.25 0.25 0.25\" />"
         "<add_closure name=\"layer\" />"
         "<connect from=\"" + base_out + "\" to=\"layer closure1\" /><connect from=\"coat bsdf\" to=\"layer closure2\" />" +
         to_output("layer closure");
}
// The coat principled_bsdf had before the clearcoat closure (a negative control): GGX of the same alpha weighted
// 0.25 * Fresnel(1.5, N.I).
std::string ggx_clearcoat_over(const std::string &base_nodes, const std::string &base_out) {
  return base_nodes +
         "<fresnel name=\"cf\" ior=\"1.5\" /><math name=\"cw\" math_type=\"multiply\" value1=\"0.25\" />"
         "<connect from=\"cf fac\" to=\"cw value2\" />"
         "<glossy_bsdf name=\"coat\" distribution=\"ggx\" roughness=\"0.1\" />"
         "<connect from=\"cw value\" to=\"coat color\" />"
         "<add_closure name=\"layer\" />"
         "<connect from=\"" + base_out + "\" to=\"layer closure1\" /><connect from=\"coat bsdf\" to=\"layer closure2\" />" +
         to_output("layer closure");
}
std::string alpha_over(const std::string &base_nodes, const std::string &base_out, const char *fac) {
  return base_nodes + "<transparent_bsdf name=\"t\" color=\"1 1 1\" /><mix_closure name=\"am\" fac=\"" +
         std::string(fac) + "\" /><connect from=\"t bsdf\" to=\"am closure1\" /><connect from=\"" + base_out +
         "\" to=\"am closure2\" />" + to_output("am closure");
}

struct Case {
  const char *label;
  std::string principled, reference, buggy;
};

void expect_principled_equals_reference(const Case &c) {
  std::vector<std::string> warnings;
  const auto p = render(sphere_scene(std::string(c.label) + "_principled.xml", c.principled), &warnings);
  for (const auto &w : warnings) ADD_FAILURE() << c.label << ": unexpected warning: " << w;
  const auto ref = render(sphere_scene(std::string(c.label) + "_reference.xml", c.reference));
  const auto bug = render(sphere_scene(std::string(c.label) + "_buggy.xml", c.buggy));
  const double z = max_z(p, ref), z_bug = max_z(p, bug);
  std::printf("[principled %s] mean %.5f vs reference %.5f: max |z| %.2f; buggy reference %.5f: max |z| %.1f\n",
              c.label, mean_rgb(p), mean_rgb(ref), z, mean_rgb(bug), z_bug);
  EXPECT_LT(z, 4.0) << c.label;
  EXPECT_GT(z_bug, 4.0) << c.label << ": the negative control is not detected";
}

TEST(Principled, Metallic0IsPrincipledDiffusePlusSpecular) {
  expect_principled_equals_reference({"metallic0", principled("metallic=\"0\" specular=\"0.5\""),
                                      kDielectric + to_output("diel closure"),
                                      kFormerDielectric + to_output("diel closure")});
}

TEST(Principled, Metallic1IsTheSpecularWithBaseColourCspec0) {
  const std::string metal_glossy =
      std::string("<glossy_bsdf name=\"m\" distribution=\"ggx\" roughness=\"0.3\" color=\"") + kBase + "\" />";
  expect_principled_equals_reference({"metallic1", principled("metallic=\"1\""),
                                      specular_lobe("metallic=\"1\"") + to_output("sp bsdf"),
                                      metal_glossy + to_output("m bsdf")});
}

TEST(Principled, HalfMetallicMixesDielectricAndSpecular) {
  // Cycles 3.4: diffuse (1 - metallic), specular 1 with cspec0 = mix(0.08 specular, base, metallic).
  auto mixed = [&](const char *fac) {
    return dielectric("metallic=\"0.3\"") + "<mix_closure name=\"mm\" fac=\"" + fac +
           "\" /><connect from=\"diel closure\" to=\"mm closure1\" /><connect from=\"sp bsdf\" to=\"mm closure2\" />" +
           to_output("mm closure");
  };
  expect_principled_equals_reference({"metallic03", principled("metallic=\"0.3\""), mixed("0.3"), mixed("0.7")});
}

TEST(Principled, SpecularTintTintsTheSpecular) {
  expect_principled_equals_reference({"tint1", principled("specular=\"1\" specular_tint=\"1\""),
                                      dielectric("specular=\"1\" specular_tint=\"1\"") + to_output("diel closure"),
                                      dielectric("specular=\"1\" specular_tint=\"0\"") + to_output("diel closure")});
}

TEST(Principled, Transmission1IsGlass) {
  expect_principled_equals_reference(
      {"transmission1", principled("transmission=\"1\" ior=\"1.45\""),
       std::string("<glass_bsdf name=\"gl\" distribution=\"ggx\" roughness=\"0.3\" IOR=\"1.45\" color=\"") + kBase +
           "\" />" + to_output("gl bsdf"),
       kDielectric + to_output("diel closure")});
}

TEST(Principled, Clearcoat1AddsAQuarterWeightedClearcoatLobe) {
  expect_principled_equals_reference({"clearcoat1", principled("clearcoat=\"1\" clearcoat_roughness=\"0.1\""),
                                      clearcoat_over(kDielectric, "diel closure"),
                                      kDielectric + to_output("diel closure")});
}

TEST(Principled, ClearcoatIsNotThePreviousGgxCoat) {
  expect_principled_equals_reference({"clearcoat1_ggx", principled("clearcoat=\"1\" clearcoat_roughness=\"0.1\""),
                                      clearcoat_over(kDielectric, "diel closure"),
                                      ggx_clearcoat_over(kDielectric, "diel closure")});
}

// Sheen (Cycles 3.4): the principled sheen lobe beside the diffuse, weight (1 - metallic)(1 - transmission).
std::string sheen_over(const std::string &base_nodes, const std::string &base_out, const char *tint) {
  return base_nodes + "<principled_sheen_bsdf name=\"sh\" sheen=\"1\" sheen_tint=\"" + tint + "\" base_color=\"" +
         kBase + "\" /><add_closure name=\"shl\" /><connect from=\"" + base_out + "\" to=\"shl closure1\" />"
         "<connect from=\"sh bsdf\" to=\"shl closure2\" />" + to_output("shl closure");
}

TEST(Principled, SheenAddsThePrincipledSheenLobe) {
  expect_principled_equals_reference({"sheen1", principled("sheen=\"1\" sheen_tint=\"1\""),
                                      sheen_over(kDielectric, "diel closure", "1"),
                                      kDielectric + to_output("diel closure")});
}

TEST(Principled, SheenTintTintsTheSheen) {
  expect_principled_equals_reference({"sheen_tint1", principled("sheen=\"1\" sheen_tint=\"1\""),
                                      sheen_over(kDielectric, "diel closure", "1"),
                                      sheen_over(kDielectric, "diel closure", "0")});
}

TEST(Principled, SheenIsWeightedOneMinusMetallic) {
  // Cycles 3.4: the sheen's weight is (1 - metallic)(1 - transmission), as the diffuse's (inside the metallic mix).
  const std::string sheen = std::string("<principled_sheen_bsdf name=\"sh\" sheen=\"1\" sheen_tint=\"0.5\" base_color=\"") +
                            kBase + "\" />";
  auto mixed = [&](bool sheen_inside) {
    const std::string base = sheen_inside ? "shl closure" : "diel closure";
    std::string nodes = dielectric("metallic=\"0.3\"") + sheen;
    if (sheen_inside)
      nodes += "<add_closure name=\"shl\" /><connect from=\"diel closure\" to=\"shl closure1\" />"
               "<connect from=\"sh bsdf\" to=\"shl closure2\" />";
    nodes += "<mix_closure name=\"mm\" fac=\"0.3\" /><connect from=\"" + base + "\" to=\"mm closure1\" />"
             "<connect from=\"sp bsdf\" to=\"mm closure2\" />";
    if (sheen_inside) return nodes + to_output("mm closure");
    return nodes + "<add_closure name=\"top\" /><connect from=\"mm closure\" to=\"top closure1\" />"
                   "<connect from=\"sh bsdf\" to=\"top closure2\" />" + to_output("top closure");
  };
  expect_principled_equals_reference(
      {"sheen_metallic03", principled("metallic=\"0.3\" sheen=\"1\""), mixed(true), mixed(false)});
}

TEST(Principled, AlphaMixesWithTransparent) {
  expect_principled_equals_reference({"alpha03", principled("alpha=\"0.3\""), alpha_over(kDielectric, "diel closure", "0.3"),
                                      alpha_over(kDielectric, "diel closure", "0.7")});
}

// Linked sockets are evaluated per shading point: a checker into base_color, roughness and metallic.
TEST(Principled, LinkedSocketsVaryPerShadingPoint) {
  const std::string checker =
      "<checker_texture name=\"c\" scale=\"3\" color1=\"0.9 0.9 0.9\" color2=\"0.1 0.1 0.1\" />";
  const std::string principled_nodes =
      checker + "<principled_bsdf name=\"p\" />" + "<connect from=\"c color\" to=\"p base_color\" />"
      "<connect from=\"c fac\" to=\"p roughness\" /><connect from=\"c fac\" to=\"p metallic\" />" + to_output("p bsdf");
  auto reference = [&](const char *mix_from) {
    return checker +
           "<principled_diffuse_bsdf name=\"d\" /><connect from=\"c color\" to=\"d color\" />"
           "<connect from=\"c fac\" to=\"d roughness\" />"
           "<principled_specular_bsdf name=\"sp\" /><connect from=\"c color\" to=\"sp base_color\" />"
           "<connect from=\"c fac\" to=\"sp roughness\" /><connect from=\"c fac\" to=\"sp metallic\" />"
           "<add_closure name=\"diel\" /><connect from=\"d bsdf\" to=\"diel closure1\" />"
           "<connect from=\"sp bsdf\" to=\"diel closure2\" />"
           "<mix_closure name=\"mm\" /><connect from=\"" + std::string(mix_from) + "\" to=\"mm fac\" />"
           "<connect from=\"diel closure\" to=\"mm closure1\" /><connect from=\"sp bsdf\" to=\"mm closure2\" />" +
           to_output("mm closure");
  };
  // Buggy: the metallic link dropped (a constant mix of 0.5 instead of the checker).
  std::string buggy = reference("c fac");
  auto replace = [&](const std::string &from, const std::string &to) {
    ASSERT_NE(buggy.find(from), std::string::npos) << from;
    buggy.replace(buggy.find(from), from.size(), to);
  };
  replace("<mix_closure name=\"mm\" />", "<mix_closure name=\"mm\" fac=\"0.5\" />");
  replace("<connect from=\"c fac\" to=\"mm fac\" />", "");
  expect_principled_equals_reference({"linked", principled_nodes, reference("c fac"), buggy});
}

// A link into a socket the Principled BSDF does not have is a scene error, as on the other closure nodes.
TEST(Principled, UnknownSocketIsAnError) {
  const std::string path = sphere_scene("typo.xml", "<checker_texture name=\"c\" /><principled_bsdf name=\"p\" />"
                                                    "<connect from=\"c fac\" to=\"p metalic\" />" + to_output("p bsdf"));
  try {
    scene::load_scene(path);
    ADD_FAILURE() << "no error for the unknown socket 'metalic'";
  } catch (const scene::SceneError &e) {
    EXPECT_NE(std::string(e.what()).find("unknown socket 'metalic'"), std::string::npos) << e.what();
  }
}

TEST(Principled, SubsurfaceWarnsOnceAtTheNodeAndNothingFallsBack) {
  const std::string path = sphere_scene(
      "subsurface.xml",
      "<principled_bsdf name=\"p\" subsurface=\"0.5\" sheen=\"0.5\" clearcoat=\"0.5\" alpha=\"0.8\" />" +
          to_output("p bsdf"));
  std::vector<std::string> warnings;
  render(path, &warnings);
  const std::regex subsurface(".*subsurface\\.xml:8: warning: principled_bsdf: subsurface scattering is not supported.*");
  EXPECT_EQ(std::count_if(warnings.begin(), warnings.end(),
                          [&](const std::string &w) { return std::regex_match(w, subsurface); }),
            1);
  for (const auto &w : warnings)
    EXPECT_EQ(w.find("falls back"), std::string::npos) << w;
  EXPECT_EQ(warnings.size(), 1u);
}

}  // namespace
}  // namespace glimmer::test
