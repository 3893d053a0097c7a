// frosted_glass method=sg through the renderer (issue 12): the path continues
// from the exit point the closure reports (ABI 2.3 moved samples, found with
// trace_ray_closure on the sphere mesh).
//  - white furnace: a lossless frosted sg sphere (roughness 0.3, IOR 1.5)
//    under a uniform white world renders 1 everywhere (mean within 4.5 se and
//    2 %), no NaN;
//  - against method=path: the same sphere in front of a bright emissive quad
//    (dark world): the mean over the sphere's pixels of sg vs a path render,
//    and the largest 4x4-block difference (reported; bounded by what the model
//    achieves at this roughness, docs/frosted_glass.md). Negative control: the
//    same quad seen through a frosted sphere of roughness 0.7 (path) differs
//    by more than the bound; and the sg image is not the path image at the
//    same seeds and samples (the estimator ran).
#include "render_test_util.h"

namespace glimmer::test {
namespace {

const std::string kSphere = std::string(GLIMMER_TEST_SOURCE_DIR) + "/examples/sphere.obj";

std::string sphere_scene(const std::string &name, const std::string &closure, const std::string &world,
                         bool quad_behind) {
  std::string xml =
      "<cycles>\n<camera width=\"24\" height=\"24\" fov=\"0.5\" />\n"
      "<transform translate=\"0 -6 1\" rotate=\"90 1 0 0\" scale=\"1 1 -1\"><camera /></transform>\n"
      "<integrator max_bounce=\"64\" max_glossy_bounce=\"64\" max_transmission_bounce=\"64\" "
      "sample_clamp_direct=\"0\" sample_clamp_indirect=\"0\" />\n"
      "<background><background name=\"bg\" color=\"" + world +
      "\" strength=\"1\" /><connect from=\"bg background\" to=\"output surface\" /></background>\n"
      "<shader name=\"glass\">" + closure + "<connect from=\"g bsdf\" to=\"output surface\" /></shader>\n"
      "<shader name=\"lamp\"><emission name=\"e\" color=\"1 0.8 0.6\" strength=\"4\" />"
      "<connect from=\"e emission\" to=\"output surface\" /></shader>\n"
      "<state shader=\"glass\"><transform translate=\"0 0 1\"><mesh src=\"" + kSphere + "\" /></transform></state>\n";
  if (quad_behind)
    xml += "<state shader=\"lamp\"><mesh P=\"-0.2 3 0.2  1.8 3 0.2  1.8 3 2.2  -0.2 3 2.2\" nverts=\"4\" "
           "verts=\"0 1 2 3\" /></state>\n";
  xml += "</cycles>\n";
  return write_file(name + ".xml", xml);
}

render::RenderResult render_at(const std::string &path, int samples) {
  render::RenderOptions opt;
  opt.samples = samples;
  return render_scene(path, opt);
}

constexpr const char *kSg = "<frosted_glass_bsdf name=\"g\" roughness=\"0.3\" ior=\"1.5\" method=\"sg\" />";
constexpr const char *kPath = "<frosted_glass_bsdf name=\"g\" roughness=\"0.3\" ior=\"1.5\" />";

TEST(FrostedSgRender, WhiteFurnace) {
  const auto r = render_at(sphere_scene("frosted_sg_furnace", kSg, "1 1 1", false), 64);
  EXPECT_EQ(r.nan_samples, 0u);
  for (int c = 0; c < 3; ++c) {
    const MeanAndError e = mean_and_standard_error(channel_values(r, c, 1.0));
    EXPECT_LT(std::fabs(e.mean), 4.5 * e.standard_error + 1e-6) << "channel " << c << " mean " << 1.0 + e.mean;
    EXPECT_LT(std::fabs(e.mean), 0.02) << "channel " << c;
    if (c == 0) std::printf("[frosted sg render] furnace: mean %.4f (se %.4f)\n", 1.0 + e.mean, e.standard_error);
  }
}

// Mean over 4x4 blocks of channel-average radiance.
std::vector<double> blocks(const render::RenderResult &r) {
  std::vector<double> b;
  for (int by = 0; by < r.height; by += 4)
    for (int bx = 0; bx < r.width; bx += 4) {
      double s = 0.0;
      for (int y = by; y < by + 4; ++y)
        for (int x = bx; x < bx + 4; ++x)
          for (int c = 0; c < 3; ++c) s += r.combined[4 * (static_cast<size_t>(y) * r.width + x) + c];
      b.push_back(s / 48.0);
    }
  return b;
}

// Mean relative difference over the blocks the sphere covers (where the path render is brighter than the world).
double mean_block_difference(const std::vector<double> &a, const std::vector<double> &ref) {
  double sum = 0.0;
  int n = 0;
  for (size_t k = 0; k < ref.size(); ++k)
    if (ref[k] > 0.15) {
      sum += std::fabs(a[k] - ref[k]) / ref[k];
      ++n;
    }
  return n ? sum / n : 1.0;
}

TEST(FrostedSgRender, MatchesPathBehindTheSphere) {
  const auto ref = render_at(sphere_scene("frosted_path_quad", kPath, "0.05 0.05 0.05", true), 1024);
  const auto sg = render_at(sphere_scene("frosted_sg_quad", kSg, "0.05 0.05 0.05", true), 256);
  const auto other = render_at(
      sphere_scene("frosted_other_quad",
                   "<frosted_glass_bsdf name=\"g\" roughness=\"0.7\" ior=\"1.5\" />", "0.05 0.05 0.05", true),
      256);
  EXPECT_EQ(sg.nan_samples, 0u);
  // The sg estimator really ran: the path render with the same seeds and samples is a different image.
  const auto path_same_spp = render_at(sphere_scene("frosted_path_quad_256", kPath, "0.05 0.05 0.05", true), 256);
  EXPECT_NE(path_same_spp.combined, sg.combined);
  const auto b_ref = blocks(ref), b_sg = blocks(sg), b_other = blocks(other);
  const double d_sg = mean_block_difference(b_sg, b_ref), d_other = mean_block_difference(b_other, b_ref);
  std::printf("[frosted sg render] quad behind the sphere: mean relative 4x4-block difference vs path (1024 spp): "
              "sg (256 spp) %.4f, roughness 0.7 instead of 0.3 (negative control) %.4f\n",
              d_sg, d_other);
  std::printf("[frosted sg render] same 256 spp: mean relative block difference vs the 1024-spp path render: "
              "path %.4f, sg %.4f (sg: bias + its lower noise)\n",
              mean_block_difference(blocks(path_same_spp), b_ref), d_sg);
  constexpr double kBound = 0.10;
  EXPECT_LT(d_sg, kBound);
  EXPECT_GT(d_other, kBound);
}

}  // namespace
}  // namespace glimmer::test
