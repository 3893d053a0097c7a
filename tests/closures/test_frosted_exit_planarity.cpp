// frosted::exit_planarity (session 38, frostedwalk38): the solid walk's planar-exit tests decided from bounds on acos
// (2 t <= acos x <= pi t, t = sqrt((1 - x) / 2)) where they settle the comparison, else by the exact form. The
// decisions must be exit_planarity_exact's for every input: random rays whose mean turn lies around the threshold
// (both sides, facing and not), the ends (x = +-1, zero angles), NaN and no rays. Control: a wrong bound (pi -> 2:
// acos x ~ 2 t, which under-estimates wide angles) must change some decisions.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>

#include "closures/frosted_glass_sg.h"
#include "glimmer/rng.h"

namespace {

using namespace glimmer;
using namespace glimmer::plugin;

struct Tally {
  int64_t cases = 0, mismatches = 0, control_mismatches = 0, planar = 0, facing = 0;
};

void check(const float *c, const float *d, int n, float threshold, Tally &t) {
  const frosted::ExitPlanarity exact = frosted::exit_planarity_exact(c, d, n, threshold);
  const frosted::ExitPlanarity by_bounds = frosted::exit_planarity(c, d, n, threshold);
  const frosted::ExitPlanarity control = frosted::exit_planarity(c, d, n, threshold, 2.0f);
  ++t.cases;
  t.planar += exact.planar;
  t.facing += exact.planar_facing;
  t.mismatches += exact.planar != by_bounds.planar || exact.planar_facing != by_bounds.planar_facing;
  t.control_mismatches += exact.planar != control.planar || exact.planar_facing != control.planar_facing;
}

TEST(FrostedExitPlanarity, BoundsDecideAsTheExactFormEverywhere) {
  uint32_t state = 0x9a11u;
  auto next = [&state] { return float(hash_u32(state++) >> 8) * 0x1p-24f; };
  Tally t;
  for (float threshold : {0.1f, 0.5f})
    for (int k = 0; k < 200000; ++k) {
      const int n = 1 + int(next() * 4.0f) % 4;
      float c[4], d[4];
      for (int i = 0; i < n; ++i) {
        // The direction's angle b anywhere in (0, pi); the normal's a = b x turn, turns spread over 0 .. 3 thresholds.
        const float b = 3.14159f * next() * (next() < 0.3f ? 0.02f : 1.0f);
        const float a = std::fmin(b * threshold * 3.0f * next(), 3.14159f);
        c[i] = std::cos(a), d[i] = std::cos(b);
      }
      check(c, d, n, threshold, t);
    }
  EXPECT_EQ(t.mismatches, 0) << "of " << t.cases;
  EXPECT_GT(t.planar, t.cases / 10);  // both outcomes are exercised
  EXPECT_LT(t.planar, t.cases * 9 / 10);
  EXPECT_GT(t.control_mismatches, 0) << "the control (acos bounded above by 2 t) should change decisions";
}

TEST(FrostedExitPlanarity, EndsNanAndNoRays) {
  constexpr float kNan = std::numeric_limits<float>::quiet_NaN();
  const float xs[] = {1.0f, -1.0f, 0.0f, 0.99999994f, -0.99999994f, 1.5f, -1.5f, 0.995f, kNan};
  Tally t;
  for (float x : xs)
    for (float y : xs) {
      const float c[2] = {x, 1.0f}, d[2] = {y, y};
      check(c, d, 1, 0.1f, t);
      check(c, d, 2, 0.1f, t);
    }
  check(nullptr, nullptr, 0, 0.1f, t);
  const frosted::ExitPlanarity none = frosted::exit_planarity(nullptr, nullptr, 0, 0.1f);
  EXPECT_FALSE(none.planar);
  EXPECT_FALSE(none.planar_facing);
  EXPECT_EQ(t.mismatches, 0) << "of " << t.cases;
}

}  // namespace
