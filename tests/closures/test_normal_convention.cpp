// The normal convention of the closure ABI (closure_abi.h, GlimmerShadingContext
// .N and .backfacing), checked on every closure of the plugin:
//  - a closure's result depends only on wi, wo and the frame (N, T) it is
//    given: the whole setup turned over (N, Ng, T frame, wi, wo rotated 180
//    degrees about T, so N points the other way in world space, and
//    `backfacing` toggled) gives the same eval, pdf and sample. `backfacing`
//    is information; N decides the side;
//  - TRANSMISSIVE closures read the side from dot(wi, N): wi below N means the
//    path arrives from inside, so relative IOR 1/ior applies (the host hands
//    them the front-face normal; bridge/render/renderer.cpp, ctx_front): at
//    ior = 2 from inside they equal the mirror image (z -> -z) at ior = 0.5
//    from outside, and differ from the mirror image at ior = 2.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "closures/closure_checks.h"
#include "glimmer/rng.h"

namespace glimmer::test {
namespace {

// Rotation by 180 degrees about the x axis (= T of host::make_local_context):
// a proper rotation, so local coordinates in the turned frame are unchanged.
Vec3 turn(const Vec3 &v) { return Vec3(v.x, -v.y, -v.z); }
// Reflection in the tangent plane z = 0 (same frame): the other side of N.
Vec3 mirror(const Vec3 &v) { return Vec3(v.x, v.y, -v.z); }

GlimmerShadingContext turned(const GlimmerShadingContext &c) {
  GlimmerShadingContext t = c;
  t.wi = turn(Vec3(c.wi));
  t.P = turn(Vec3(c.P));
  t.N = turn(Vec3(c.N));
  t.Ng = turn(Vec3(c.Ng));
  t.T = turn(Vec3(c.T));
  t.dPdu = turn(Vec3(c.dPdu));
  t.dPdv = turn(Vec3(c.dPdv));
  t.backfacing = c.backfacing ? 0u : 1u;
  return t;
}

GlimmerShadingContext context_at(const Vec3 &wi) {
  GlimmerShadingContext ctx = footprint_context(wi, 0.3, 0.7, 1e-3, 0.0, 0.0, 1e-3);
  ctx.path_seed = 12345u;
  return ctx;
}

bool close(float a, float b) { return std::fabs(a - b) <= 1e-5f * std::max({1.0f, std::fabs(a), std::fabs(b)}); }

::testing::AssertionResult same_eval(const host::ClosureInstance &a, const GlimmerShadingContext &ca, const Vec3 &wo_a,
                                     const host::ClosureInstance &b, const GlimmerShadingContext &cb,
                                     const Vec3 &wo_b) {
  Spectrum fa, fb;
  float pa = 0.0f, pb = 0.0f;
  a.eval(ca, wo_a, fa, pa);
  b.eval(cb, wo_b, fb, pb);
  if (close(fa.x, fb.x) && close(fa.y, fb.y) && close(fa.z, fb.z) && close(pa, pb))
    return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "eval " << format_vec(fa) << " pdf " << pa << " vs " << format_vec(fb)
                                       << " pdf " << pb << " at wo " << format_vec(wo_a);
}

const bool kCacheInBuild = cache_tables_in_build_folder();

TEST(NormalConvention, EveryClosureDependsOnNAndWiNotOnBackfacing) {
  ASSERT_TRUE(kCacheInBuild);
  const Vec3 wis[] = {normalize(Vec3(0.3f, 0.2f, 0.93f)), normalize(Vec3(-0.7f, 0.1f, 0.2f)),
                      normalize(Vec3(0.2f, -0.3f, -0.9f))};
  for (const GlimmerClosureType *type : plugin().closures()) {
    const auto closure = make_closure(*type);
    for (const Vec3 &wi : wis) {
      const GlimmerShadingContext ctx = context_at(wi), flipped = turned(ctx);
      Pcg32 rng(7);
      for (int i = 0; i < 64; ++i) {
        const Vec3 wo = spherical_dir(180.0 * rng.next_float(), 360.0 * rng.next_float());
        EXPECT_TRUE(same_eval(*closure, ctx, wo, *closure, flipped, turn(wo))) << type->name << " wi " << format_vec(wi);
      }
      for (int i = 0; i < 64; ++i) {
        const float u[3] = {rng.next_float(), rng.next_float(), rng.next_float()};
        GlimmerSample a{}, b{};
        const uint32_t la = closure->sample(ctx, u, a), lb = closure->sample(flipped, u, b);
        EXPECT_EQ(la, lb) << type->name;
        if (la == GLIMMER_LABEL_NONE || la != lb) continue;
        const Vec3 expected = turn(Vec3(a.wo));
        EXPECT_TRUE(close(expected.x, b.wo.x) && close(expected.y, b.wo.y) && close(expected.z, b.wo.z))
            << type->name << ": sampled " << format_vec(Vec3(b.wo)) << ", expected " << format_vec(expected);
        EXPECT_TRUE(close(a.pdf, b.pdf) && close(a.eval[0], b.eval[0]) && close(a.eta, b.eta)) << type->name;
      }
    }
  }
}

// Negative control: the check sees a closure that reads N's world direction.
TEST(NormalConvention, TheTurnedSetupIsNotTheSameWorldGeometry) {
  const GlimmerShadingContext ctx = context_at(normalize(Vec3(0.3f, 0.2f, 0.93f)));
  const GlimmerShadingContext flipped = turned(ctx);
  EXPECT_LT(flipped.N.z, 0.0f);
  EXPECT_LT(flipped.wi.z, 0.0f);
  EXPECT_NE(flipped.backfacing, ctx.backfacing);
  // A world-space "closure" f = max(wo.z, 0) differs between the two setups.
  const Vec3 wo(0.0f, 0.0f, 1.0f);
  EXPECT_NE(std::max(wo.z, 0.0f), std::max(turn(wo).z, 0.0f));
}

TEST(NormalConvention, TransmissiveClosuresUseInverseIorWhenWiIsBelowN) {
  int checked = 0;
  for (const GlimmerClosureType *type : plugin().closures()) {
    if (!(type->flags & GLIMMER_CLOSURE_TRANSMISSIVE) || (type->flags & GLIMMER_CLOSURE_STOCHASTIC_EVAL)) continue;
    if (host::find_param(*type, "ior") == nullptr) continue;
    const auto dense = make_closure(*type, {{"ior", "2"}});
    const auto sparse = make_closure(*type, {{"ior", "0.5"}});
    const Vec3 wi_inside = normalize(Vec3(0.3f, 0.2f, -0.8f));
    const GlimmerShadingContext inside = context_at(wi_inside);           // N = +z, wi below: from inside
    const GlimmerShadingContext outside = context_at(mirror(wi_inside));  // the mirror image: wi above N
    Pcg32 rng(11);
    for (int i = 0; i < 128; ++i) {
      const Vec3 wo = spherical_dir(180.0 * rng.next_float(), 360.0 * rng.next_float());
      // From inside at ior 2 = the mirror image from outside at 1 / 2.
      EXPECT_TRUE(same_eval(*dense, inside, wo, *sparse, outside, mirror(wo))) << type->name;
    }
    // And not the outside behaviour of ior 2 (the check can fail).
    int differing = 0;
    for (int i = 0; i < 128; ++i) {
      const Vec3 wo = spherical_dir(180.0 * rng.next_float(), 360.0 * rng.next_float());
      differing += same_eval(*dense, inside, wo, *dense, outside, mirror(wo)) ? 0 : 1;
    }
    EXPECT_GT(differing, 16) << type->name;
    ++checked;
  }
  EXPECT_GE(checked, 2);  // microfacet_dielectric and frosted_glass
}

}  // namespace
}  // namespace glimmer::test
