// Render-level acceptance of issue 10 (glints), through the renderer:
//  - resolution: a render at double resolution, 2x2-downsampled, against the
//    single-resolution render of the same camera (Pearson correlation of the
//    per-pixel values) >= 0.9 for glint and for the reference glint_jakob14;
//  - twinkle: the Jaccard overlap of the lit pixels when the light moves by
//    3.8 degrees, glint within 0.1 of glint_jakob14.
// The scene: a glint plane seen at 45 degrees under a sun (angle 0) in the
// mirror direction, black world, direct light only (max_bounce 0), so the
// only Monte Carlo noise is the pixel sample position (which particles a
// footprint covers). docs/glints.md, "Render-level acceptance", explains the
// figures and the controls.
#include <algorithm>
#include <cstdio>

#include "render_test_util.h"
#include "sample_statistics.h"

namespace glimmer::test {
namespace {

// A glint closure node named "g" with the material of this test: GGX roughness 0.5, gamma 2 degrees, about
// 1e6 particles per unit uv (the 2 x 2 plane has uv [0,1]^2: ~100 particles and ~0.3 glints in the
// footprint of a 32-pixel-wide image's pixel in the highlight). `kind` is glint_bsdf or glint_jakob14_bsdf.
// `gamma` and `density` change the cone and the particle density (the glints per footprint grow as
// density * gamma^2).
std::string glint_node(const std::string &kind, int seed, const std::string &extra = "", double gamma = 2.0,
                       double density = 1e6) {
  return "<" + kind + " name=\"g\" distribution=\"ggx\" roughness=\"0.5\" gamma=\"" + std::to_string(gamma) +
         "\" density=\"" + std::to_string(density) + "\" uv_scale=\"1\" seed=\"" + std::to_string(seed) + "\" " +
         extra + " />";
}
const std::string kGlint = "glint_bsdf", kJakob = "glint_jakob14_bsdf";
// glint_bsdf always counting glints (never the filtered mean), and always the filtered mean.
const std::string kCounted = "filter_threshold=\"1e9\"", kFiltered = "filter_threshold=\"0\"";

// The plane z = 0 (2 x 2, uv [0,1]^2) seen from (0, -3, 3) at 45 degrees; the sun shines from elevation
// `light_elevation` degrees in the plane of incidence (45: the mirror direction of the camera's axis).
std::string plane_scene(const std::string &name, const std::string &closure, double light_elevation) {
  const double e = light_elevation * M_PI / 180.0;
  char dir[96];
  std::snprintf(dir, sizeof(dir), "0 %.9f %.9f", -std::cos(e), -std::sin(e));
  return write_file(
      name + ".xml",
      "<cycles>\n<camera width=\"32\" height=\"32\" fov=\"0.3\" />\n"
      "<transform translate=\"0 -3 3\" rotate=\"45 1 0 0\" scale=\"1 1 -1\"><camera /></transform>\n"
      "<integrator max_bounce=\"0\" sample_clamp_direct=\"0\" sample_clamp_indirect=\"0\" />\n"
      "<film filter_type=\"box\" />\n"
      "<background><background name=\"bg\" color=\"0 0 0\" strength=\"0\" />"
      "<connect from=\"bg background\" to=\"output surface\" /></background>\n"
      "<shader name=\"sun\"><emission name=\"e\" color=\"1 1 1\" strength=\"1\" />"
      "<connect from=\"e emission\" to=\"output surface\" /></shader>\n"
      "<state shader=\"sun\"><light light_type=\"sun\" dir=\"" + std::string(dir) + "\" angle=\"0\" strength=\"3 3 3\" /></state>\n"
      "<shader name=\"flakes\">" + closure + "<connect from=\"g bsdf\" to=\"output surface\" /></shader>\n"
      "<state shader=\"flakes\"><mesh P=\"-1 -1 0  1 -1 0  1 1 0  -1 1 0\" nverts=\"4\" verts=\"0 1 2 3\" "
      "UV=\"0 0  1 0  1 1  0 1\" /></state>\n</cycles>\n");
}

// Per-pixel value: the mean of R, G, B of the combined pass (row-major).
std::vector<double> pixel_values(const std::string &scene, int width, int samples, int seed = -1) {
  render::RenderOptions opt;
  opt.samples = samples;
  opt.width = opt.height = width;
  opt.seed = seed;
  opt.aovs = false;
  const render::RenderResult r = render_scene(scene, opt);
  EXPECT_EQ(r.nan_samples, 0u);
  std::vector<double> v(static_cast<size_t>(r.width) * r.height);
  for (size_t i = 0; i < v.size(); ++i) v[i] = (r.combined[4 * i] + r.combined[4 * i + 1] + r.combined[4 * i + 2]) / 3.0;
  return v;
}

// The mean of each 2 x 2 block of a square image `width` wide.
std::vector<double> downsample_2x2(const std::vector<double> &image, int width) {
  const int half = width / 2;
  std::vector<double> out(static_cast<size_t>(half) * half);
  for (int y = 0; y < half; ++y)
    for (int x = 0; x < half; ++x) {
      const auto at = [&](int dx, int dy) { return image[static_cast<size_t>(2 * y + dy) * width + 2 * x + dx]; };
      out[static_cast<size_t>(y) * half + x] = 0.25 * (at(0, 0) + at(1, 0) + at(0, 1) + at(1, 1));
    }
  return out;
}

constexpr int kWidth = 32;             // single resolution; the double one is 64 x 64
constexpr int kSingleSamples = 32;   // per pixel; the double-resolution pixels get a quarter, so both
constexpr int kDoubleSamples = 8;    // images spend 32 samples per single-resolution pixel

// Correlation of the single-resolution render with the 2x2-downsampled double-resolution render of the
// same camera. With footprints centred on the pixel samples and a box filter the two images are the
// particle field smoothed by kernels of 2 and 1.5 pixels (box * box), so an additive field (counts of
// nested footprints add up) correlates at (0.978)^2 = 0.957 without noise, an independent field per
// resolution at 0.
double resolution_correlation(const std::string &name, const std::string &closure_single,
                              const std::string &closure_double) {
  const auto single = pixel_values(plane_scene(name + "_1x", closure_single, 45.0), kWidth, kSingleSamples);
  const auto twice = pixel_values(plane_scene(name + "_2x", closure_double, 45.0), 2 * kWidth, kDoubleSamples);
  return correlation(single, downsample_2x2(twice, 2 * kWidth));
}

TEST(GlintRender, DownsampledDoubleResolutionCorrelatesWithSingleResolution) {
  const std::string glint = glint_node(kGlint, 7, kCounted), jakob = glint_node(kJakob, 7);
  // The harness: the noise ceiling (the same render with another sampling seed: what the pixel sample
  // positions alone leave of a perfect correlation) and the reference.
  const auto a = pixel_values(plane_scene("res_noise", glint, 45.0), kWidth, kSingleSamples, 1);
  const auto b = pixel_values(plane_scene("res_noise", glint, 45.0), kWidth, kSingleSamples, 2);
  const double noise_ceiling = correlation(a, b);
  const double reference = resolution_correlation("res_jakob", jakob, jakob);
  const double model = resolution_correlation("res_glint", glint, glint);
  const double model_default = resolution_correlation("res_glint_default", glint_node(kGlint, 7), glint_node(kGlint, 7));
  // Negative control: an independent particle field at the double resolution (another seed), what a
  // model with an independent field per node level does when the footprint halves.
  const double independent = resolution_correlation("res_independent", glint, glint_node(kGlint, 8, kCounted));
  std::printf("[glint render] resolution correlation: glint %.3f (default filter_threshold %.3f), glint_jakob14 "
              "%.3f, independent fields %.3f; noise ceiling %.3f\n",
              model, model_default, reference, independent, noise_ceiling);
  EXPECT_GE(noise_ceiling, 0.97) << "too few samples: the noise, not the glints, would be measured";
  EXPECT_NEAR(reference, 0.957, 0.03) << "the closed form for an additive field";
  EXPECT_GE(reference, 0.9);
  EXPECT_GE(model, 0.9);
  EXPECT_GE(model_default, 0.9);
  EXPECT_LT(independent, 0.3);
}

// Lit pixels: value above twice the filtered mean of the same pixel (glint_bsdf with filter_threshold 0
// at the same light, the expectation both closures converge to), among the pixels whose filtered mean is
// at least 5 % of the image's largest (the lobe).
std::vector<bool> lit_pixels(const std::vector<double> &image, const std::vector<double> &filtered) {
  const double peak = *std::max_element(filtered.begin(), filtered.end());
  std::vector<bool> lit(image.size());
  for (size_t i = 0; i < image.size(); ++i) lit[i] = filtered[i] > 0.05 * peak && image[i] > 2.0 * filtered[i];
  return lit;
}

double jaccard(const std::vector<bool> &a, const std::vector<bool> &b) {
  size_t both = 0, either = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    both += a[i] && b[i];
    either += a[i] || b[i];
  }
  return either ? static_cast<double>(both) / either : 1.0;
}

constexpr int kLitWidth = 48, kLitSamples = 64;
// The sun's elevations: the mirror direction of the camera's axis, then 1 degree (half the cone: about
// half of the glints stay) and the 3.8 degrees higher (the lit set renews).
constexpr double kElevations[] = {45.0, 46.0, 48.8};

// The lit pixels of `closure` at each of kElevations; `filtered` is the same glint material with
// filter_threshold 0 (the expectation).
std::vector<std::vector<bool>> lit_sets(const std::string &name, const std::string &closure,
                                        const std::string &filtered, int seed = -1) {
  std::vector<std::vector<bool>> sets;
  for (const double elevation : kElevations) {
    const std::string at = name + "_" + std::to_string(sets.size());
    const auto mean = pixel_values(plane_scene(at + "_mean", filtered, elevation), kLitWidth, kLitSamples);
    sets.push_back(lit_pixels(pixel_values(plane_scene(at, closure, elevation), kLitWidth, kLitSamples, seed), mean));
  }
  return sets;
}

size_t count_lit(const std::vector<bool> &lit) { return static_cast<size_t>(std::count(lit.begin(), lit.end(), true)); }

TEST(GlintRender, LitPixelsUnderALightMoveChangeLikeTheReference) {
  const std::string filtered = glint_node(kGlint, 7, kFiltered);
  const auto model = lit_sets("lit_glint", glint_node(kGlint, 7, kCounted), filtered);
  const auto reference = lit_sets("lit_jakob", glint_node(kJakob, 7), filtered);
  // The harness: the model's lit sets rendered with another sampling seed (what the pixel sample
  // positions alone change).
  const auto reseeded = lit_sets("lit_glint_seed", glint_node(kGlint, 7, kCounted), filtered, 12345);
  const double noise_ceiling = jaccard(model[0], reseeded[0]);
  std::printf("[glint render] lit-pixel Jaccard, same light, two sampling seeds: %.3f\n", noise_ceiling);
  EXPECT_GE(noise_ceiling, 0.8);
  for (const auto *sets : {&model, &reference})
    for (const auto &lit : *sets) EXPECT_GE(count_lit(lit), 50u) << "too few lit pixels for an overlap";
  for (size_t k = 1; k < std::size(kElevations); ++k) {
    const double move = kElevations[k] - kElevations[0];
    const double m = jaccard(model[0], model[k]), r = jaccard(reference[0], reference[k]);
    std::printf("[glint render] lit-pixel Jaccard under a %.1f-degree light move: glint %.3f (%zu / %zu lit), "
                "glint_jakob14 %.3f (%zu / %zu lit)\n",
                move, m, count_lit(model[0]), count_lit(model[k]), r, count_lit(reference[0]), count_lit(reference[k]));
    EXPECT_LE(std::fabs(m - r), 0.1) << move << " degrees";
  }
  // Negative control: glints whose lit set outlasts the move, as every glint's did when the randomness
  // depended on position only: a 10-degree cone (each particle stays lit over a move of 3.8 degrees) at
  // 1/25 of the density (about the same glints per footprint), lit relative to its own filtered mean.
  const auto wide = lit_sets("lit_wide", glint_node(kGlint, 7, kCounted, 10.0, 4e4),
                             glint_node(kGlint, 7, kFiltered, 10.0, 4e4));
  const double persistent = jaccard(wide[0], wide[2]);
  std::printf("[glint render] negative control, persistent lit sets (gamma 10): Jaccard %.3f (%zu / %zu lit) "
              "under the 3.8-degree move\n",
              persistent, count_lit(wide[0]), count_lit(wide[2]));
  EXPECT_GE(std::min(count_lit(wide[0]), count_lit(wide[2])), 50u);
  EXPECT_GT(std::fabs(persistent - jaccard(reference[0], reference[2])), 0.1);
}

}  // namespace
}  // namespace glimmer::test
