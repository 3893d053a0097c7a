// frosted_glass method=sg under the host's bounce limits (issue 12, session 26, frostedfloor26; closure ABI 2.9
// GlimmerShadingContext.max_bounce / max_glossy_bounce / max_transmission_bounce, frosted::reflections_allowed;
// docs/history/frosted_glass_sessions.md "Session 26 (frostedfloor26)").
//
// method=path's walk through a solid is one host scatter per event (the entry, every internal reflection, the exit),
// and the host ends a path at the next surface once a count reaches its limit, so the light that needs more internal
// reflections than max_glossy_bounce (or max_bounce) allows never leaves. sg's walk is one scatter for the host: it
// applies the same limits from the context itself. The check, in the renderer: a rough frosted sphere (roughness 0.5,
// IOR 1.5, the caustic bench's) under a uniform white world (every direction sees 1: only the energy that leaves
// counts, not its directions), rendered by method=path (the brute-force reference, the same limits) and by sg, per
// limit case the mean over the sphere's centre pixels. sg with the limits in the context must be within 1.5 % and 5
// standard errors of path (measured: -0.20 / -0.88 / -0.73 %, z -0.75 / -0.89 / -1.01); negative control: sg with the
// host's limits left out of the context (RenderOptions::bounce_limits_in_context = false, the estimator before) must
// fail that bound in every case where a limit binds (measured: +2.5 / +12.4 / +8.8 %); where none binds the two
// images must be the same.
#include <algorithm>
#include <cmath>
#include <cstdio>

#include "render_test_util.h"

namespace glimmer::test {
namespace {

const std::string kSphere = std::string(GLIMMER_TEST_SOURCE_DIR) + "/examples/sphere.obj";

struct Limits {
  int bounce, glossy, transmission;
};

std::string scene(const std::string &method, const Limits &l) {
  const std::string xml =
      "<cycles>\n<camera width=\"24\" height=\"24\" fov=\"0.5\" />\n"
      "<transform translate=\"0 -6 1\" rotate=\"90 1 0 0\" scale=\"1 1 -1\"><camera /></transform>\n"
      "<integrator max_bounce=\"" + std::to_string(l.bounce) + "\" max_glossy_bounce=\"" + std::to_string(l.glossy) +
      "\" max_transmission_bounce=\"" + std::to_string(l.transmission) +
      "\" sample_clamp_direct=\"0\" sample_clamp_indirect=\"0\" />\n"
      "<background><background name=\"bg\" color=\"1 1 1\" strength=\"1\" />"
      "<connect from=\"bg background\" to=\"output surface\" /></background>\n"
      "<shader name=\"glass\"><frosted_glass_bsdf name=\"g\" roughness=\"0.5\" ior=\"1.5\" method=\"" + method +
      "\" /><connect from=\"g bsdf\" to=\"output surface\" /></shader>\n"
      "<state shader=\"glass\"><transform translate=\"0 0 1\"><mesh src=\"" + kSphere + "\" /></transform></state>\n"
      "</cycles>\n";
  return write_file("frosted_bounce_limits_" + method + "_" + std::to_string(l.bounce) + "_" +
                        std::to_string(l.glossy) + "_" + std::to_string(l.transmission) + ".xml",
                    xml);
}

// The mean over the sphere's centre pixels (12 x 12) and its standard error (the pixels' spread over sqrt(n): each
// pixel is an independent estimate of its own value, so this over-states the error of the mean, a safe side).
struct Mean {
  double mean = 0.0, se = 0.0;
};
Mean centre_mean(const render::RenderResult &r) {
  double s = 0.0, s2 = 0.0;
  int n = 0;
  for (int y = 6; y < 18; ++y)
    for (int x = 6; x < 18; ++x) {
      double v = 0.0;
      for (int c = 0; c < 3; ++c) v += r.combined[4 * (static_cast<size_t>(y) * r.width + x) + c];
      v /= 3.0;
      s += v, s2 += v * v, ++n;
    }
  Mean m;
  m.mean = s / n;
  m.se = std::sqrt(std::max(0.0, s2 / n - m.mean * m.mean) / n);
  return m;
}

// sg's mean against path's: relative difference and z (both standard errors combined).
struct Compare {
  double rel = 0.0, z = 0.0;
};
Compare compare(const Mean &est, const Mean &ref) {
  return {est.mean / ref.mean - 1.0, (est.mean - ref.mean) / std::max(std::hypot(est.se, ref.se), 1e-30)};
}
constexpr double kRelativeBound = 0.015, kZBound = 5.0;
bool within(const Compare &c) { return std::fabs(c.rel) < kRelativeBound && std::fabs(c.z) < kZBound; }

render::RenderResult render_with(const std::string &path, int samples, int seed, bool limits_in_context) {
  render::RenderOptions opt;
  opt.samples = samples;
  opt.seed = seed;
  opt.bounce_limits_in_context = limits_in_context;
  return render_scene(path, opt);
}

TEST(FrostedSgBounceLimits, SphereUnderAUniformWorldLosesWhatThePathLoses) {
  // The caustic bench's limits (glossy binds at 8 reflections), glossy alone, the total alone, and no binding limit.
  const Limits cases[] = {{12, 7, 7}, {64, 2, 64}, {4, 64, 64}, {64, 64, 64}};
  constexpr int kPathSpp = 512, kSgSpp = 128;
  int control_failed = 0, binding = 0;
  for (const Limits &l : cases) {
    const std::string path = scene("path", l), sg = scene("sg", l);
    const auto ref = render_with(path, kPathSpp, 3, true);
    const auto with = render_with(sg, kSgSpp, 4, true), without = render_with(sg, kSgSpp, 4, false);
    for (const auto *r : {&ref, &with, &without}) EXPECT_EQ(r->nan_samples, 0u);
    const Mean p = centre_mean(ref), w = centre_mean(with), o = centre_mean(without);
    const Compare c = compare(w, p), control = compare(o, p);
    std::printf("[frosted bounce limits] max_bounce %d glossy %d transmission %d: path %.4f (se %.4f), sg %+.4f "
                "(z %+.2f), sg without the limits %+.4f (z %+.2f)\n",
                l.bounce, l.glossy, l.transmission, p.mean, p.se, c.rel, c.z, control.rel, control.z);
    EXPECT_TRUE(within(c)) << "limits " << l.bounce << " " << l.glossy << " " << l.transmission << ": " << c.rel
                           << " (z " << c.z << ")";
    if (l.glossy >= 64 && l.bounce >= 64) {  // nothing binds: the two must agree (the limits change nothing)
      EXPECT_EQ(with.combined, without.combined);
      continue;
    }
    ++binding;
    control_failed += within(control) ? 0 : 1;
  }
  std::printf("[frosted bounce limits] negative control: sg without the limits fails the bound in %d of %d cases\n",
              control_failed, binding);
  EXPECT_EQ(control_failed, binding) << "the negative control must fail every binding case";
}

}  // namespace
}  // namespace glimmer::test
