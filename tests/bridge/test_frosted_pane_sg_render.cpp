// frosted_glass method=sg through a thin pane (thin = 1) in the renderer
// (issue 12): the closure's exit sample is moved to the exit face of the same
// point (ABI 2.3) and carries its exit lobe (ABI 2.4, light sampling there).
//  - white furnace: a lossless sg pane under a uniform white world renders 1
//    (mean within 4.5 se and 2 %), no NaN;
//  - against method=path: the pane (roughness 0.2, IOR 1.5, one quad) in
//    front of an emissive quad and of a small area light (dark world): the
//    mean over each quarter of the pane's pixels, sg (256 spp, MIS) vs path
//    (1024 spp, BSDF sampling only: see render_at). Negative control: the
//    same scene seen through a pane of roughness 0.7 (path) differs by more
//    than the bound;
//    A small light behind the pane: against a reference whose own error is checked (two seeds), the 5 % goal
//    (met since the pane's exit lobe has GGX-like tails, eleventh session; 0.069 before);
//  - a rough pane (roughness 0.7, the exact walk between the faces with the leaving table's SG, twelfth session) in
//    front of the emissive quad: sg 0.0121 off path (the single SG before: 0.0804); control: the 0.2 pane;
//  - determinism: 1 thread / tile 5 and 4 threads / tile 16 give the same image;
//  - method=path through the pane: MIS agrees with BSDF sampling alone and light sampling alone; under a checker
//    world alone MIS has the same mean as BSDF sampling and at most 1.5x its per-pixel noise; determinism.
#include "render_test_util.h"

namespace glimmer::test {
namespace {

// A 2.4 x 2.4 pane at y = 0 facing the camera (at y = -6), an emissive quad or a small area light behind it.
std::string pane_scene(const std::string &name, const std::string &closure, const std::string &world, int behind) {
  std::string xml =
      "<cycles>\n<camera width=\"24\" height=\"24\" fov=\"0.35\" />\n"
      "<transform translate=\"0 -6 1\" rotate=\"90 1 0 0\" scale=\"1 1 -1\"><camera /></transform>\n"
      "<integrator max_bounce=\"64\" max_glossy_bounce=\"64\" max_transmission_bounce=\"64\" "
      "sample_clamp_direct=\"0\" sample_clamp_indirect=\"0\" />\n"
      "<background><background name=\"bg\" color=\"" + world +
      "\" strength=\"1\" /><connect from=\"bg background\" to=\"output surface\" /></background>\n"
      "<shader name=\"glass\">" + closure + "<connect from=\"g bsdf\" to=\"output surface\" /></shader>\n"
      "<shader name=\"lamp\"><emission name=\"e\" color=\"1 0.8 0.6\" strength=\"4\" />"
      "<connect from=\"e emission\" to=\"output surface\" /></shader>\n"
      "<state shader=\"glass\"><mesh P=\"-1.2 0 -0.2  1.2 0 -0.2  1.2 0 2.2  -1.2 0 2.2\" nverts=\"4\" "
      "verts=\"0 1 2 3\" /></state>\n";
  if (behind == 1)  // an emissive quad covering the upper right of the view, 2 behind the pane
    xml += "<state shader=\"lamp\"><mesh P=\"-0.1 2 0.9  1.9 2 0.9  1.9 2 2.9  -0.1 2 2.9\" nverts=\"4\" "
           "verts=\"0 1 2 3\" /></state>\n";
  if (behind == 2)  // a small area light 0.6 behind the pane, facing it
    xml += "<state shader=\"lamp\"><light light_type=\"area\" co=\"0.3 0.6 1.2\" dir=\"0 -1 0\" axisu=\"1 0 0\" "
           "axisv=\"0 0 1\" sizeu=\"0.15\" sizev=\"0.15\" strength=\"20 20 20\" /></state>\n";
  xml += "</cycles>\n";
  return write_file(name + ".xml", xml);
}

// The reference (method=path) is rendered with BSDF sampling only (the cheapest unbiased estimator of this
// scene). Path with MIS agrees with it (FrostedPanePathRender below): since the thirteenth session the walk through
// the pane is a singular sample that is not light-sampled (before: a stochastic eval whose f and pdf came from
// independent walks; with one shared walk MIS had rendered 0.942 where BSDF sampling alone gave 1.093).
render::RenderResult render_at(const std::string &path, int samples,
                               render::LightStrategy strategy = render::LightStrategy::MIS) {
  render::RenderOptions opt;
  opt.samples = samples;
  opt.strategy = strategy;
  return render_scene(path, opt);
}

std::string pane(float roughness, const char *method) {
  return "<frosted_glass_bsdf name=\"g\" roughness=\"" + std::to_string(roughness) +
         "\" ior=\"1.5\" thin=\"1\" thickness=\"0.02\" method=\"" + method + "\" />";
}

TEST(FrostedSgPaneRender, WhiteFurnace) {
  const auto r = render_at(pane_scene("frosted_sg_pane_furnace", pane(0.2f, "sg"), "1 1 1", 0), 64);
  EXPECT_EQ(r.nan_samples, 0u);
  for (int c = 0; c < 3; ++c) {
    const MeanAndError e = mean_and_standard_error(channel_values(r, c, 1.0));
    EXPECT_LT(std::fabs(e.mean), 4.5 * e.standard_error + 1e-6) << "channel " << c << " mean " << 1.0 + e.mean;
    EXPECT_LT(std::fabs(e.mean), 0.02) << "channel " << c;
    if (c == 0) std::printf("[frosted sg pane render] furnace: mean %.4f (se %.4f)\n", 1.0 + e.mean, e.standard_error);
  }
}

// Mean relative difference of the channel-average radiance over the 4 quarters of the image (the pane fills it).
double quarter_difference(const render::RenderResult &a, const render::RenderResult &ref) {
  double sum = 0.0;
  const int hw = ref.width / 2, hh = ref.height / 2;
  for (int q = 0; q < 4; ++q) {
    const int x0 = (q % 2) * hw, y0 = (q / 2) * hh;
    double va = 0.0, vr = 0.0;
    for (int c = 0; c < 3; ++c) {
      va += mean_channel(a, c, x0, y0, x0 + hw, y0 + hh);
      vr += mean_channel(ref, c, x0, y0, x0 + hw, y0 + hh);
    }
    sum += std::fabs(va - vr) / std::max(vr, 1e-9);
  }
  return sum / 4.0;
}

// `roughness`: the pane's; `control`: the negative control's pane roughness (path), which must differ by > bound.
void check_behind(int behind, const char *what, double bound, int reference_spp = 1024, int sg_spp = 256,
                  float roughness = 0.2f, float control = 0.7f) {
  const std::string world = "0.05 0.05 0.05";
  const auto ref = render_at(pane_scene(std::string("frosted_pane_path_") + what, pane(roughness, "path"), world,
                                        behind),
                             reference_spp, render::LightStrategy::BsdfOnly);
  const auto sg = render_at(pane_scene(std::string("frosted_pane_sg_") + what, pane(roughness, "sg"), world, behind),
                            sg_spp);
  const auto path = render_at(pane_scene(std::string("frosted_pane_path256_") + what, pane(roughness, "path"), world,
                                         behind), 256, render::LightStrategy::BsdfOnly);
  const auto other = render_at(pane_scene(std::string("frosted_pane_other_") + what, pane(control, "path"), world,
                                          behind), 256, render::LightStrategy::BsdfOnly);
  EXPECT_EQ(sg.nan_samples, 0u);
  EXPECT_NE(path.combined, sg.combined);  // the sg estimator ran
  const double d_sg = quarter_difference(sg, ref), d_path = quarter_difference(path, ref),
               d_other = quarter_difference(other, ref);
  std::printf("[frosted sg pane render] %s: mean relative difference of the image quarters vs path at %d spp: sg "
              "(%d spp) %.4f, path (256 spp) %.4f, roughness %.1f instead of %.1f (negative control) %.4f\n",
              what, reference_spp, sg_spp, d_sg, d_path, double(control), double(roughness), d_other);
  EXPECT_LT(d_sg, bound);
  EXPECT_GT(d_other, bound);
}

TEST(FrostedSgPaneRender, MatchesPathInFrontOfAnEmissiveQuad) { check_behind(1, "quad", 0.05); }
// A rough pane (roughness 0.7: the exact walk between the faces with the leaving table's SG, kPaneWalk, twelfth
// session) in front of the emissive quad; the control is the roughness-0.2 pane.
TEST(FrostedSgPaneRender, RoughPaneMatchesPathInFrontOfAnEmissiveQuad) {
  check_behind(1, "rough_quad", 0.05, 1024, 256, 0.7f, 0.2f);
}

// The small area light 0.6 behind the pane (issue 12, tenth session). Its reference is method=path with BSDF
// sampling only on two seeds, averaged; its own error is checked: the two seeds' images differ by `ref_noise` (the
// same quarter measure), so the average is off by about ref_noise / 2. Light sampling is the noisier estimator
// here (the pane's walk estimate of f toward a lamp point: 4 seeds at 2048 spp spread 9.7..11.6 over the lamp's
// quarter, BSDF sampling 10.74..10.97, MIS 10.27..11.07; same means), so BSDF sampling is the reference.
// What the small light needs of sg is the lobe's tails: in the quarters away from the lamp path gets 10-25 % of
// their light from the lamp through the rough interfaces' wide GGX tails. The tenth session's exit lobe (a vMF
// mixture whose widest lobes were kappa / 4) got almost none of it (0.069 / 0.084 off); the pane's exit mixture
// now has GGX-like tails down to kappa / 256 (frosted_glass_sg.h, PaneTail; docs/frosted_glass.md "The small
// light behind a pane").
struct SmallLightRenders {
  render::RenderResult sg, other;
  double ref_noise = 0.0, d_sg = 0.0, d_other = 0.0;
  int reference_spp = 0;
};
const SmallLightRenders &small_light_renders() {
  static const SmallLightRenders r = [] {
    SmallLightRenders out;
    out.reference_spp = stress_scale() > 1 ? 16384 : 8192;
    const std::string world = "0.05 0.05 0.05";
    const std::string path_scene = pane_scene("frosted_pane_path_small_light", pane(0.2f, "path"), world, 2);
    render::RenderOptions opt;
    opt.samples = out.reference_spp;
    opt.strategy = render::LightStrategy::BsdfOnly;
    opt.seed = 1;
    const auto ref_a = render_scene(path_scene, opt);
    opt.seed = 2;
    const auto ref_b = render_scene(path_scene, opt);
    render::RenderResult ref = ref_a;
    for (size_t i = 0; i < ref.combined.size(); ++i) ref.combined[i] = 0.5f * (ref_a.combined[i] + ref_b.combined[i]);
    out.ref_noise = quarter_difference(ref_a, ref_b);
    opt = render::RenderOptions{};
    opt.samples = 1024;
    opt.seed = 3;
    out.sg = render_scene(pane_scene("frosted_pane_sg_small_light", pane(0.2f, "sg"), world, 2), opt);
    opt.samples = 256;
    opt.strategy = render::LightStrategy::BsdfOnly;
    out.other = render_scene(pane_scene("frosted_pane_other_small_light", pane(0.7f, "path"), world, 2), opt);
    out.d_sg = quarter_difference(out.sg, ref);
    out.d_other = quarter_difference(out.other, ref);
    std::printf("[frosted sg pane render] small light: reference path %d spp x 2 seeds (BSDF sampling), the seeds "
                "differ by %.4f (its own error ~%.4f); sg (1024 spp, MIS) %.4f off it; roughness 0.7 instead of 0.2 "
                "(negative control) %.4f\n",
                out.reference_spp, out.ref_noise, 0.5 * out.ref_noise, out.d_sg, out.d_other);
    return out;
  }();
  return r;
}

// Checked reference and sg's measured figure: the reference's own error well under the 5 % goal (seed difference
// < 0.025: measured 0.011 / 0.012 at 16384 spp on two seed pairs, 0.0166 at 8192), sg within the tenth session's
// bound (0.069 / 0.084 then + ~30 %; 0.0097 / 0.0086 since the pane's heavy tail: the goal test below is the
// tighter one), the negative control far outside that (6.7).
TEST(FrostedSgPaneRender, SmallLightAgainstACheckedReference) {
  const SmallLightRenders &r = small_light_renders();
  EXPECT_EQ(r.sg.nan_samples, 0u);
  EXPECT_LT(r.ref_noise, 0.025);
  EXPECT_LT(r.d_sg, 0.11);
  EXPECT_GT(r.d_other, 0.11);
}

// The 5 % goal (issue 12) behind the small light, threshold unchanged. Enabled in the eleventh session: with the
// pane's heavy tail (frosted_glass_sg.h, PaneTail) sg is 0.0097 / 0.0086 off the checked reference (8192 spp x 2
// seeds, its own error ~0.008; seeds 3 / 4 of sg), 0.069 / 0.084 before (the exit lobe's missing tails).
TEST(FrostedSgPaneRender, MatchesPathInFrontOfASmallLight) {
  const SmallLightRenders &r = small_light_renders();
  EXPECT_LT(r.ref_noise, 0.025);
  EXPECT_LT(r.d_sg, 0.05);
  EXPECT_GT(r.d_other, 0.05);
}

// method=path through a pane, in front of the emissive quad: MIS, BSDF sampling alone and light sampling alone are
// three unbiased estimators of the same image. Per-pixel differences (image structure cancels): mean within 4.5
// standard errors of 0. A stochastic eval whose pdf estimate is correlated with its f estimate (one shared walk)
// failed this by ~14 % of the mean. Since the thirteenth session the walk through the pane is singular (not
// light-sampled): MIS and BSDF sampling alone differ only at the front reflection, and light sampling alone still
// sees the quad through the pane (emission after a singular scatter counts whole).
TEST(FrostedPanePathRender, MisAgreesWithEitherStrategyAlone) {
  const std::string scene = pane_scene("frosted_pane_path_mis", pane(0.2f, "path"), "0.05 0.05 0.05", 1);
  const auto mis = render_at(scene, 256), bsdf = render_at(scene, 256, render::LightStrategy::BsdfOnly),
             light = render_at(scene, 256, render::LightStrategy::LightOnly);
  EXPECT_EQ(mis.nan_samples + bsdf.nan_samples + light.nan_samples, 0u);
  for (const auto *other : {&bsdf, &light}) {
    std::vector<double> d(channel_values(mis, 0).size(), 0.0);  // per pixel, the channel average
    double mean_mis = 0.0;
    for (int c = 0; c < 3; ++c) {
      const std::vector<double> a = channel_values(mis, c), b = channel_values(*other, c);
      for (size_t i = 0; i < a.size(); ++i) {
        d[i] += (a[i] - b[i]) / 3.0;
        mean_mis += a[i] / 3.0;
      }
    }
    mean_mis /= static_cast<double>(d.size());
    const MeanAndError e = mean_and_standard_error(d);
    std::printf("[frosted path pane render] MIS - %s: %.5f (se %.5f) on a mean of %.4f\n",
                other == &bsdf ? "BSDF only" : "light only", e.mean, e.standard_error, mean_mis);
    EXPECT_LT(std::fabs(e.mean), 4.5 * e.standard_error) << (other == &bsdf ? "BSDF only" : "light only");
  }
}

// method=path's pane under the world alone (issue 12, thirteenth session): a pane (roughness 0.2, IOR 1.5, 2 cm,
// tilted 15 degrees) filling the view in front of a high-contrast checker world (cells 3.0 / 0.05, as
// benchmarks/scenes/frosted_fair.xml without its lamp). MIS and BSDF sampling alone, 256 spp, two seeds each:
// the same mean (per-pixel differences of the seed averages within 4.5 standard errors of 0) and MIS's per-pixel
// noise (rms of (seed 1 - seed 2) / sqrt 2) at most 1.5x BSDF sampling's. Before the thirteenth session the pane's
// eval() was a one-walk estimate (the walk's weight x the exit interface's density at the walk's own internal
// direction, ~600 / sr at its peak) that NEE used for every world sample: MIS was ~27x noisier than BSDF sampling
// alone on the fair scene (docs/frosted_glass.md "Light sampling through a pane"); the previous plugin fails this.
std::string world_pane_scene(const std::string &name) {
  const std::string xml =
      "<cycles>\n<camera width=\"24\" height=\"24\" fov=\"0.3\" />\n"
      "<transform translate=\"0 -6 1\" rotate=\"90 1 0 0\" scale=\"1 1 -1\"><camera /></transform>\n"
      "<integrator max_bounce=\"64\" max_glossy_bounce=\"64\" max_transmission_bounce=\"64\" "
      "sample_clamp_direct=\"0\" sample_clamp_indirect=\"0\" />\n"
      "<background><checker_texture name=\"c\" scale=\"3\" color1=\"3.0 2.7 2.4\" color2=\"0.05 0.05 0.1\" />"
      "<background name=\"bg\" strength=\"1\" /><connect from=\"c color\" to=\"bg color\" />"
      "<connect from=\"bg background\" to=\"output surface\" /></background>\n"
      "<shader name=\"glass\">" + pane(0.2f, "path") + "<connect from=\"g bsdf\" to=\"output surface\" /></shader>\n"
      "<transform translate=\"0 0 1\" rotate=\"15 0 0 1\"><state shader=\"glass\"><mesh "
      "P=\"-1.5 0 -1.5  1.5 0 -1.5  1.5 0 1.5  -1.5 0 1.5\" nverts=\"4\" verts=\"0 1 2 3\" /></state></transform>\n"
      "</cycles>\n";
  return write_file(name + ".xml", xml);
}

// Per-pixel noise of a render from two seeds: rms over the pixels and channels of (a - b) / sqrt 2.
double seed_noise(const render::RenderResult &a, const render::RenderResult &b) {
  double sum = 0.0;
  size_t n = 0;
  for (int c = 0; c < 3; ++c) {
    const std::vector<double> x = channel_values(a, c), y = channel_values(b, c);
    for (size_t i = 0; i < x.size(); ++i, ++n) sum += 0.5 * (x[i] - y[i]) * (x[i] - y[i]);
  }
  return std::sqrt(sum / double(n));
}

// MIS against BSDF sampling alone on one scene, two seeds each at `samples` spp: the per-pixel noise of each
// strategy (seed_noise), the mean of the per-pixel MIS - BSDF difference (channel average) with its standard
// error, and the BSDF image's mean.
struct MisVersusBsdf {
  double noise_mis = 0.0, noise_bsdf = 0.0, mean_bsdf = 0.0;
  MeanAndError difference;
  uint64_t nan_samples = 0;
};
MisVersusBsdf mis_versus_bsdf(const std::string &scene, int samples) {
  const auto render_seed = [&](render::LightStrategy strategy, int seed) {
    render::RenderOptions opt;
    opt.samples = samples;
    opt.strategy = strategy;
    opt.seed = seed;
    return render_scene(scene, opt);
  };
  const auto mis_a = render_seed(render::LightStrategy::MIS, 1), mis_b = render_seed(render::LightStrategy::MIS, 2);
  const auto bsdf_a = render_seed(render::LightStrategy::BsdfOnly, 3),
             bsdf_b = render_seed(render::LightStrategy::BsdfOnly, 4);
  MisVersusBsdf r;
  r.nan_samples = mis_a.nan_samples + mis_b.nan_samples + bsdf_a.nan_samples + bsdf_b.nan_samples;
  r.noise_mis = seed_noise(mis_a, mis_b);
  r.noise_bsdf = seed_noise(bsdf_a, bsdf_b);
  std::vector<double> d;  // per pixel, the channel average of the seed averages' difference
  for (size_t i = 0; i < size_t(mis_a.width) * mis_a.height; ++i) {
    double v = 0.0;
    for (int c = 0; c < 3; ++c) {
      v += (mis_a.combined[4 * i + c] + mis_b.combined[4 * i + c] - bsdf_a.combined[4 * i + c] -
            bsdf_b.combined[4 * i + c]) / 6.0;
      r.mean_bsdf += (bsdf_a.combined[4 * i + c] + bsdf_b.combined[4 * i + c]) / 6.0;
    }
    d.push_back(v);
  }
  r.mean_bsdf /= double(d.size());
  r.difference = mean_and_standard_error(d);
  return r;
}

TEST(FrostedPanePathRender, MisUnderTheWorldNoNoisierThanBsdfSampling) {
  const MisVersusBsdf m = mis_versus_bsdf(world_pane_scene("frosted_pane_path_world"), 256);
  EXPECT_EQ(m.nan_samples, 0u);
  const MeanAndError &e = m.difference;
  std::printf("[frosted path pane render] world only, 256 spp: per-pixel noise MIS %.4f, BSDF only %.4f (ratio "
              "%.2f); mean MIS - BSDF %.5f (se %.5f) on %.4f\n",
              m.noise_mis, m.noise_bsdf, m.noise_mis / m.noise_bsdf, e.mean, e.standard_error, m.mean_bsdf);
  EXPECT_LT(std::fabs(e.mean), 4.5 * e.standard_error);
  EXPECT_LE(m.noise_mis, 1.5 * m.noise_bsdf);
}

// method=path's pane (its walk seeded by the path seed and the sample's numbers): the same image for any thread
// count and tile size, MIS under the checker world.
TEST(FrostedPanePathRender, SameImageForAnyThreadCountAndTileSize) {
  const std::string path = world_pane_scene("frosted_path_pane_determinism");
  render::RenderOptions opt;
  opt.samples = 16;
  const auto a = render_scene_with(path, opt, 1, 5), b = render_scene_with(path, opt, 4, 16);
  EXPECT_EQ(a.combined, b.combined);
}

TEST(FrostedSgPaneRender, SameImageForAnyThreadCountAndTileSize) {
  const std::string path = pane_scene("frosted_sg_pane_determinism", pane(0.2f, "sg"), "0.05 0.05 0.05", 2);
  render::RenderOptions opt;
  opt.samples = 16;
  const auto a = render_scene_with(path, opt, 1, 5), b = render_scene_with(path, opt, 4, 16);
  EXPECT_EQ(a.combined, b.combined);
}

}  // namespace
}  // namespace glimmer::test

namespace glimmer::test {
namespace {

// ABI 2.8 (issue 12, sixteenth session): method=path's pane hands the host its walk's last interface, and the host
// light-samples through it at the shading point (MIS with the continued path). The small area light behind the
// pane (as pane_scene's, the pane and lamp turned together about the pane's horizontal axis so the camera sees the
// pane at 0 or 60 degrees), roughness 0.1 / 0.3 / 0.6, IOR 1.5, dark world: MIS (exit light sampling on) and BSDF
// sampling alone, 256 spp each: the same mean (per-pixel differences within 3 standard errors of 0), and at
// roughness 0.6, where the exit lobe is wider than the lamp, MIS's per-pixel noise (two seeds) at most 0.6x BSDF
// sampling's (measured 0.24-0.41x at 1024 spp). The walk's weight without the 1 / P_T factor fails
// FrostedGlassThin.EvalExitIsTheWalksLastInterfaceWithItsLeavingProbability (tests/closures/test_frosted_pane.cpp).
std::string tilted_small_light_scene(const std::string &name, float roughness, float degrees,
                                     const char *method = "path") {
  const float a = degrees * float(M_PI) / 180.0f, c = std::cos(a), s = std::sin(a);
  const auto turn = [&](Vec3 p, bool point) {  // about the x axis through (0, 0, 1)
    if (point) p.z -= 1.0f;
    Vec3 q(p.x, c * p.y - s * p.z, s * p.y + c * p.z);
    if (point) q.z += 1.0f;
    return q;
  };
  const auto str = [](const Vec3 &v) {
    char b[96];
    std::snprintf(b, sizeof b, "%.6f %.6f %.6f", double(v.x), double(v.y), double(v.z));
    return std::string(b);
  };
  std::string quad;
  for (const Vec3 &q : {Vec3(-1.2f, 0, -0.2f), Vec3(1.2f, 0, -0.2f), Vec3(1.2f, 0, 2.2f), Vec3(-1.2f, 0, 2.2f)})
    quad += str(turn(q, true)) + "  ";
  const std::string xml =
      "<cycles>\n<camera width=\"24\" height=\"24\" fov=\"0.35\" />\n"
      "<transform translate=\"0 -6 1\" rotate=\"90 1 0 0\" scale=\"1 1 -1\"><camera /></transform>\n"
      "<integrator max_bounce=\"64\" max_glossy_bounce=\"64\" max_transmission_bounce=\"64\" "
      "sample_clamp_direct=\"0\" sample_clamp_indirect=\"0\" />\n"
      "<background><background name=\"bg\" color=\"0.05 0.05 0.05\" strength=\"1\" /><connect from=\"bg "
      "background\" to=\"output surface\" /></background>\n"
      "<shader name=\"glass\">" + pane(roughness, method) +
      "<connect from=\"g bsdf\" to=\"output surface\" /></shader>\n"
      "<shader name=\"lamp\"><emission name=\"e\" color=\"1 0.8 0.6\" strength=\"4\" />"
      "<connect from=\"e emission\" to=\"output surface\" /></shader>\n"
      "<state shader=\"glass\"><mesh P=\"" + quad + "\" nverts=\"4\" verts=\"0 1 2 3\" /></state>\n"
      "<state shader=\"lamp\"><light light_type=\"area\" co=\"" + str(turn(Vec3(0.3f, 0.6f, 1.2f), true)) + "\" dir=\"" +
      str(turn(Vec3(0, -1, 0), false)) + "\" axisu=\"" + str(turn(Vec3(1, 0, 0), false)) + "\" axisv=\"" +
      str(turn(Vec3(0, 0, 1), false)) + "\" sizeu=\"0.15\" sizev=\"0.15\" strength=\"20 20 20\" /></state>\n"
      "</cycles>\n";
  return write_file(name + ".xml", xml);
}

TEST(FrostedPanePathRender, ExitLightSamplingAgreesWithBsdfSamplingBehindAPane) {
  double worst_z = 0.0;
  for (float roughness : {0.1f, 0.3f, 0.6f}) {
    for (float degrees : {0.0f, 60.0f}) {
      const std::string scene = tilted_small_light_scene(
          "frosted_pane_exit_nee_" + std::to_string(int(roughness * 10)) + "_" + std::to_string(int(degrees)),
          roughness, degrees);
      const MisVersusBsdf m = mis_versus_bsdf(scene, 256);
      EXPECT_EQ(m.nan_samples, 0u);
      const MeanAndError &e = m.difference;
      std::printf("[frosted path pane exit NEE] roughness %.1f, %2.0f deg, 256 spp: mean MIS - BSDF %+.5f (se %.5f, "
                  "z %+.2f) on %.4f; per-pixel noise MIS %.4f, BSDF only %.4f (ratio %.2f)\n",
                  roughness, degrees, e.mean, e.standard_error, e.mean / e.standard_error, m.mean_bsdf, m.noise_mis,
                  m.noise_bsdf, m.noise_mis / m.noise_bsdf);
      worst_z = std::max(worst_z, std::fabs(e.mean / e.standard_error));
      EXPECT_LT(std::fabs(e.mean), 3.0 * e.standard_error) << roughness << " " << degrees;
      if (roughness > 0.5f) {
        EXPECT_LE(m.noise_mis, 0.6 * m.noise_bsdf) << degrees;
      }
    }
  }
  std::printf("[frosted path pane exit NEE] worst |z| %.2f\n", worst_z);
}

// Session 24 (frostedpane24): method=sg's rough pane values the lamps seen through its exit by the exact exit
// (frosted::PaneSgExitState: the walks' own exit BTDF f_k / E_k instead of the leaving table's SG at d_k). The
// tilted small-light scene above at roughness 0.5 (kPaneWalk, the caustic bench's pane) and 0 / 60 degrees: sg at
// 2048 spp (MIS) against method=path at 16384 spp (MIS: its exit light sampling, checked above): the mean relative
// difference of the image quarters below 0.03 (measured 0.0182 / 0.0105; the reference's own noise is ~0.01: path
// at 2048 spp is 0.025 / 0.039 off it). Negative control: the same sg render with the host's exit states off
// (RenderOptions::exit_state_nee = false: the closure hands no state, the lamps are integrated against the SG
// mixture, the estimator before) must be further off (measured 0.044 / 0.040). The per-quarter z-scores are
// printed: path's per-pixel noise keeps the mixture's at ~3, so the unbiasedness check per direction is the
// closure's (FrostedGlassSgPane.RoughPaneExactExitAgainstThePathsExitState).
// `make test` renders 0 degrees, the twin (`make stress`) both tilts. At ae64861: 0 degrees sg 0.0124, control 0.0421;
// 60 degrees sg 0.0180, control 0.0516: 0 degrees is where the control is nearest the bound (margin 0.012, as sg's
// at 60 degrees).
void expect_exact_exit_matches_path(const std::vector<float> &tilts) {
  for (float degrees : tilts) {
    const std::string name = "frosted_pane_exact_exit_" + std::to_string(int(degrees));
    const std::string path_scene = tilted_small_light_scene(name + "_path", 0.5f, degrees);
    const std::string sg_scene = tilted_small_light_scene(name + "_sg", 0.5f, degrees, "sg");
    render::RenderOptions opt;
    opt.samples = 16384;
    opt.seed = 1;
    const auto ref = render_scene(path_scene, opt);
    opt.samples = 2048;
    opt.seed = 2;
    const auto ref_small = render_scene(path_scene, opt);  // the reference's own noise at sg's spp
    const auto exact = render_scene(sg_scene, opt);
    opt.exit_state_nee = false;
    const auto mixture = render_scene(sg_scene, opt);
    EXPECT_EQ(exact.nan_samples + mixture.nan_samples, 0u);
    EXPECT_NE(exact.combined, mixture.combined);  // the exact exit ran
    const double d_exact = quarter_difference(exact, ref), d_mixture = quarter_difference(mixture, ref),
                 d_path = quarter_difference(ref_small, ref);
    // Per quarter and channel, the z-score of the mean per-pixel difference (difference_z: both noises).
    const auto worst_z = [&](const render::RenderResult &a) {
      double worst = 0.0;
      const int hw = ref.width / 2, hh = ref.height / 2;
      for (int q = 0; q < 4; ++q)
        for (int c = 0; c < 3; ++c) {
          const int x0 = (q % 2) * hw, y0 = (q / 2) * hh;
          worst = std::max(worst, std::fabs(difference_z(a, ref, c, x0, y0, x0 + hw, y0 + hh)));
        }
      return worst;
    };
    const double z_exact = worst_z(exact), z_mixture = worst_z(mixture), z_path = worst_z(ref_small);
    std::printf("[frosted sg pane exact exit] roughness 0.5, %2.0f deg: mean relative difference of the quarters vs "
                "path (16384 spp): sg exact exit %.4f (worst |z| %.2f), sg SG mixture (negative control) %.4f "
                "(worst |z| %.2f), path at 2048 spp %.4f (worst |z| %.2f)\n",
                double(degrees), d_exact, z_exact, d_mixture, z_mixture, d_path, z_path);
    EXPECT_LT(d_exact, 0.03) << degrees;
    EXPECT_GT(d_mixture, 0.03) << degrees;
  }
}

TEST(FrostedSgPaneRender, RoughPaneExactExitMatchesPathBehindASmallLight) { expect_exact_exit_matches_path({0.0f}); }

TEST(FrostedSgPaneRender, RoughPaneExactExitMatchesPathBehindASmallLightStress) {
  if (stress_scale() == 1) GTEST_SKIP() << "make stress only";
  expect_exact_exit_matches_path({0.0f, 60.0f});
}

// Session 34 (frostedbudget34): a small lamp on the camera's side of a rough pane (roughness 0.5, IOR 1.5: the split
// with both faces' ends in the exit state, frosted::pane_both_faces_level). Its light reaches the camera by the front
// face's reflection and, through the pane, only by the far face's internal reflection (out through the front face):
// the ends the state carries for the face the pick did not take. 16 x 16 pixels (the pane fills them), dark world; sg
// (MIS, default level 1) against method=path (MIS, more samples, independent numbers): per image quarter and channel
// the mean per-pixel difference within 4 standard errors (difference_z: both noises) and the 12 pooled within 4.
// Negative control: the same sg render with GLIMMER_FROSTED_PANE_BOTH_FACES=9 (kPaneBothFacesControl: c_k without the
// face's probability, the lamps through both faces counted over p_F) in a copy of the DSO loaded with that knob (the
// knob is read once per DSO), which must be off by a pooled |z| > 8. The route ran: a level-0 copy (one face, main's
// state before session 33) must give a different image from the default's (review 34, finding 6). Detectable bias:
// the pooled bound 4 passes a bias below 4 pooled standard errors, printed as a fraction of the image mean (measured
// 5.8 %; the control's +40 % gives z +19.0), so this test catches a gross route error, not a few-percent bias. The
// level-0 render's own pooled z is printed (measured -1.16).
// `absorption`: extra attributes of the pane (session 35's coloured Beer; empty: session 34's scene).
std::string camera_side_lamp_scene(const std::string &name, const char *method, const std::string &absorption = "") {
  std::string glass = pane(0.5f, method);
  if (!absorption.empty()) glass.insert(glass.find("method="), absorption + " ");
  const std::string xml =
      "<cycles>\n<camera width=\"16\" height=\"16\" fov=\"0.35\" />\n"
      "<transform translate=\"0 -6 1\" rotate=\"90 1 0 0\" scale=\"1 1 -1\"><camera /></transform>\n"
      "<integrator max_bounce=\"64\" max_glossy_bounce=\"64\" max_transmission_bounce=\"64\" "
      "sample_clamp_direct=\"0\" sample_clamp_indirect=\"0\" />\n"
      "<background><background name=\"bg\" color=\"0.02 0.02 0.02\" strength=\"1\" /><connect from=\"bg "
      "background\" to=\"output surface\" /></background>\n"
      "<shader name=\"glass\">" +
      glass +
      "<connect from=\"g bsdf\" to=\"output surface\" /></shader>\n"
      "<shader name=\"lamp\"><emission name=\"e\" color=\"1 0.8 0.6\" strength=\"4\" />"
      "<connect from=\"e emission\" to=\"output surface\" /></shader>\n"
      "<state shader=\"glass\"><mesh P=\"-1.2 0 -0.2  1.2 0 -0.2  1.2 0 2.2  -1.2 0 2.2\" nverts=\"4\" "
      "verts=\"0 1 2 3\" /></state>\n"
      // above the view, 1.6 in front of the pane, facing it and down
      "<state shader=\"lamp\"><light light_type=\"area\" co=\"0.2 -1.6 2.7\" dir=\"0 0.6 -0.8\" axisu=\"1 0 0\" "
      "axisv=\"0 0.8 0.6\" sizeu=\"0.4\" sizev=\"0.4\" strength=\"40 40 40\" /></state>\n"
      "</cycles>\n";
  return write_file(name + ".xml", xml);
}

// Per quarter and channel z of the mean per-pixel difference a - ref (the worst |z| of 12), and the 4 quarters'
// differences of the channels' average pooled (the quarters' pixels are independent; the channels are not).
struct QuarterZ {
  double worst = 0.0, pooled = 0.0;
  double detectable = 0.0;  // 4 pooled standard errors over the reference's mean (channels' average)
};
QuarterZ quarter_z(const render::RenderResult &a, const render::RenderResult &ref) {
  QuarterZ out;
  const int hw = ref.width / 2, hh = ref.height / 2;
  double sum = 0.0, var = 0.0;
  for (int q = 0; q < 4; ++q) {
    const int x0 = (q % 2) * hw, y0 = (q / 2) * hh;
    for (int c = 0; c < 3; ++c)
      out.worst = std::max(out.worst, std::fabs(difference_z(a, ref, c, x0, y0, x0 + hw, y0 + hh)));
    std::vector<double> d;
    for (int y = y0; y < y0 + hh; ++y)
      for (int x = x0; x < x0 + hw; ++x) {
        const size_t i = 4 * (static_cast<size_t>(y) * a.width + x);
        d.push_back((double(a.combined[i]) + a.combined[i + 1] + a.combined[i + 2] - ref.combined[i] -
                     ref.combined[i + 1] - ref.combined[i + 2]) / 3.0);
      }
    const MeanAndError e = mean_and_standard_error(d);
    sum += e.mean;
    var += e.standard_error * e.standard_error;
  }
  out.pooled = var > 0.0 ? sum / std::sqrt(var) : 0.0;
  const double mean = (mean_channel(ref, 0) + mean_channel(ref, 1) + mean_channel(ref, 2)) / 3.0;
  out.detectable = mean > 0.0 ? 4.0 * std::sqrt(var) / (4.0 * mean) : 0.0;  // the sum is over 4 equal quarters
  return out;
}

// Sets an environment variable for its lifetime and restores the previous value (or unsets it) on destruction, also
// when a render throws.
class ScopedEnv {
 public:
  ScopedEnv(const char *name, const char *value) : name_(name) {
    const char *before = std::getenv(name);
    had_ = before != nullptr;
    if (had_) saved_ = before;
    ::setenv(name, value, 1);
  }
  ~ScopedEnv() {
    if (had_) {
      ::setenv(name_, saved_.c_str(), 1);
    } else {
      ::unsetenv(name_);
    }
  }
  ScopedEnv(const ScopedEnv &) = delete;
  ScopedEnv &operator=(const ScopedEnv &) = delete;

 private:
  const char *name_;
  std::string saved_;
  bool had_ = false;
};

// A render of `scene` with the DSO under test loaded afresh from a copy while GLIMMER_FROSTED_PANE_BOTH_FACES is
// `level` (the DSO reads the knob once, at its first pane sample).
render::RenderResult render_with_both_faces_level(const std::string &scene_path, const render::RenderOptions &opt,
                                                  const char *level) {
  const auto copy = temp_dir() / (std::string("glimmer_closures_both_faces_") + level + ".so");
  std::filesystem::copy_file(GLIMMER_TEST_PLUGIN_PATH, copy, std::filesystem::copy_options::overwrite_existing);
  const ScopedEnv knob("GLIMMER_FROSTED_PANE_BOTH_FACES", level);
  const auto library = host::PluginLibrary::load(copy.string());
  const scene::Scene scene = scene::load_scene(scene_path);
  render::Renderer renderer(scene, *library, opt);
  return renderer.render();
}

// The pane render tests' two budgets: method=path's reference (4096 spp, seed 1) and the sg renders' options (1024
// spp, seed 2: numbers independent of the reference's).
render::RenderResult render_path_reference(const std::string &path_scene) {
  render::RenderOptions opt;
  opt.samples = 4096;
  opt.seed = 1;
  return render_scene(path_scene, opt);
}
render::RenderOptions sg_render_options() {
  render::RenderOptions opt;
  opt.samples = 1024;
  opt.seed = 2;
  return opt;
}

TEST(FrostedSgPaneRender, RoughPaneLampOnTheCameraSideMatchesPath) {
  const std::string sg_scene = camera_side_lamp_scene("frosted_pane_camera_lamp_sg", "sg");
  const auto ref = render_path_reference(camera_side_lamp_scene("frosted_pane_camera_lamp_path", "path"));
  const render::RenderOptions opt = sg_render_options();
  const auto sg = render_scene(sg_scene, opt);
  const auto control = render_with_both_faces_level(sg_scene, opt, "9");
  const auto one_face = render_with_both_faces_level(sg_scene, opt, "0");
  EXPECT_EQ(sg.nan_samples + control.nan_samples + one_face.nan_samples, 0u);
  EXPECT_NE(sg.combined, control.combined);   // the control's knob was read
  EXPECT_NE(sg.combined, one_face.combined);  // the default is not level 0: the both-faces route ran
  const QuarterZ z = quarter_z(sg, ref), z_control = quarter_z(control, ref), z_one = quarter_z(one_face, ref);
  std::printf("[frosted sg pane camera-side lamp] roughness 0.5, 16x16: path 4096 spp mean %.5f; sg 1024 spp mean "
              "%.5f, worst |z| %.2f over 12 (quarters x channels), pooled z %+.2f (detectable bias %.1f %% of the "
              "mean); level 0 (one face) mean %.5f, pooled z %+.2f; control (c_k without p_F) mean %.5f, worst |z| "
              "%.2f, pooled z %+.2f\n",
              mean_channel(ref, 1), mean_channel(sg, 1), z.worst, z.pooled, 100.0 * z.detectable,
              mean_channel(one_face, 1), z_one.pooled, mean_channel(control, 1), z_control.worst, z_control.pooled);
  EXPECT_LT(z.worst, 4.0);
  EXPECT_LT(std::fabs(z.pooled), 4.0);
  EXPECT_GT(std::fabs(z_control.pooled), 8.0) << "negative control passed";
}

// Session 35 (frostedbeer35): the camera-side lamp scene with a coloured-Beer pane (absorption colour 0.95 / 0.5 / 0.1
// over 0.02, the pane's thickness; roughness 0.5): sg with GLIMMER_FROSTED_PANE_BEER_SPLIT=1 (the split with one end
// per sample: frosted::kPaneOneColourState's comment) against method=path (MIS, 4096 spp, independent numbers), per
// quarter and channel within 4 se (worst of 12) and each channel's 4 quarters pooled within 4. Printed: the default
// (knob 0, the single walk with the SG at its last direction, 65a01b6's images) against path: measured -0.29 / -0.56 /
// -1.14. Negative control: GLIMMER_FROSTED_PANE_BOTH_FACES=8 (both faces without the colour guard,
// kPaneBothFacesNoColourGuard) must be > 8 se off in some channel (measured -6.99 / +13.14 / +26.48); the split
// measured -0.95 / -1.08 / -1.24, worst |z| 2.23. The old one-colour state (BOTH_FACES=7 with the split; not rendered
// here, the closure tests catch it at 5-15 se) measured -0.91 / -1.73 / -1.80: below this render's resolution.
// ~13 s (3 sg renders of 1024 spp, path 4096).
std::string coloured_beer_scene(const std::string &name, const char *method) {
  return camera_side_lamp_scene(name, method, "absorption_color=\"0.95 0.5 0.1\" absorption_distance=\"0.02\"");
}
render::RenderResult render_with_knobs(const std::string &scene_path, const render::RenderOptions &opt,
                                       const char *beer_split, const char *both_faces) {
  const auto copy = temp_dir() / (std::string("glimmer_closures_beer_") + beer_split + "_" + both_faces + ".so");
  std::filesystem::copy_file(GLIMMER_TEST_PLUGIN_PATH, copy, std::filesystem::copy_options::overwrite_existing);
  const ScopedEnv split("GLIMMER_FROSTED_PANE_BEER_SPLIT", beer_split);
  const ScopedEnv faces("GLIMMER_FROSTED_PANE_BOTH_FACES", both_faces);
  const auto library = host::PluginLibrary::load(copy.string());
  const scene::Scene scene = scene::load_scene(scene_path);
  render::Renderer renderer(scene, *library, opt);
  return renderer.render();
}
// Per channel: the 4 quarters' mean differences pooled (z), and the worst quarter's |z|.
void channel_z(const render::RenderResult &a, const render::RenderResult &ref, double z[3], double &worst) {
  const int hw = ref.width / 2, hh = ref.height / 2;
  worst = 0.0;
  for (int c = 0; c < 3; ++c) {
    double sum = 0.0, var = 0.0;
    for (int q = 0; q < 4; ++q) {
      const int x0 = (q % 2) * hw, y0 = (q / 2) * hh;
      worst = std::max(worst, std::fabs(difference_z(a, ref, c, x0, y0, x0 + hw, y0 + hh)));
      std::vector<double> d;
      for (int y = y0; y < y0 + hh; ++y)
        for (int x = x0; x < x0 + hw; ++x) {
          const size_t i = 4 * (static_cast<size_t>(y) * a.width + x) + c;
          d.push_back(double(a.combined[i]) - ref.combined[i]);
        }
      const MeanAndError e = mean_and_standard_error(d);
      sum += e.mean, var += e.standard_error * e.standard_error;
    }
    z[c] = var > 0.0 ? sum / std::sqrt(var) : 0.0;
  }
}

TEST(FrostedSgPaneRender, ColouredBeerPaneSplitMatchesPathPerChannel) {
  const std::string sg_scene = coloured_beer_scene("frosted_pane_beer_sg", "sg");
  const auto ref = render_path_reference(coloured_beer_scene("frosted_pane_beer_path", "path"));
  const render::RenderOptions opt = sg_render_options();
  const auto split = render_with_knobs(sg_scene, opt, "1", "1");
  const auto walk = render_with_knobs(sg_scene, opt, "0", "1");
  const auto control = render_with_knobs(sg_scene, opt, "1", "8");
  EXPECT_EQ(split.nan_samples + walk.nan_samples + control.nan_samples, 0u);
  EXPECT_NE(split.combined, walk.combined);  // the knob was read: the split ran
  const render::RenderResult *renders[] = {&split, &walk, &control};
  const char *names[] = {"split, one end (knob 1)", "single walk (default)",
                         "split, both faces without the colour guard (control)"};
  for (int r = 0; r < 3; ++r) {
    double z[3], worst;
    channel_z(*renders[r], ref, z, worst);
    std::printf(
        "[frosted sg pane coloured Beer render] %s: means %.5f / %.5f / %.5f (path %.5f / %.5f / %.5f), per "
        "channel pooled z %+.2f / %+.2f / %+.2f, worst |z| %.2f over 12\n",
        names[r], mean_channel(*renders[r], 0), mean_channel(*renders[r], 1), mean_channel(*renders[r], 2),
        mean_channel(ref, 0), mean_channel(ref, 1), mean_channel(ref, 2), z[0], z[1], z[2], worst);
    if (r == 0) {
      EXPECT_LT(worst, 4.0);
      for (int c = 0; c < 3; ++c) EXPECT_LT(std::fabs(z[c]), 4.0) << "channel " << c;
    }
    if (r == 2) {
      EXPECT_GT(std::max({std::fabs(z[0]), std::fabs(z[1]), std::fabs(z[2])}), 8.0) << "negative control passed";
    }
  }
}

}  // namespace
}  // namespace glimmer::test
