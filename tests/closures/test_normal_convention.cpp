// The normal convention of the closure ABI 2.3 (closure_abi.h, GlimmerShadingContext
// .N and .backfacing), checked on every closure of the plugin:
//  - the host hands N (and Ng) turned toward wi; a closure's result depends only
//    on wi, wo, the frame (N, T) and `backfacing`: the whole setup rotated
//    (N, Ng, T, wi, wo turned 180 degrees about T, `backfacing` kept) gives the
//    same eval, pdf and samples;
//  - `backfacing` decides the medium wi is in: a TRANSMISSIVE closure at ior = 2
//    with backfacing set equals ior = 0.5 without it (same N, wi, wo), and
//    differs from ior = 2 without it (a closure of the ABI <= 2.2 convention,
//    which took the side from dot(wi, N) and so ignores backfacing here, fails
//    both); a reflection closure ignores backfacing;
//  - a TRANSMISSIVE closure with wi below N (a bent shading normal) scatters nothing.
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

GlimmerShadingContext turned(const GlimmerShadingContext &c) {
  GlimmerShadingContext t = c;
  t.wi = turn(Vec3(c.wi));
  t.P = turn(Vec3(c.P));
  t.N = turn(Vec3(c.N));
  t.Ng = turn(Vec3(c.Ng));
  t.T = turn(Vec3(c.T));
  t.dPdu = turn(Vec3(c.dPdu));
  t.dPdv = turn(Vec3(c.dPdv));
  return t;
}

// N = Ng = +z toward wi (wi above), T = +x, `backfacing` as given.
GlimmerShadingContext context_at(const Vec3 &wi, bool backfacing) {
  GlimmerShadingContext ctx = footprint_context(wi, 0.3, 0.7, 1e-3, 0.0, 0.0, 1e-3);
  ctx.N = ctx.Ng = Vec3(0.0f, 0.0f, 1.0f);
  ctx.backfacing = backfacing ? 1u : 0u;
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
const Vec3 kWis[] = {normalize(Vec3(0.3f, 0.2f, 0.93f)), normalize(Vec3(-0.7f, 0.1f, 0.2f))};

bool transmissive(const GlimmerClosureType &type) { return (type.flags & GLIMMER_CLOSURE_TRANSMISSIVE) != 0; }

TEST(NormalConvention, EveryClosureDependsOnTheFrameAndBackfacingNotOnWorldAxes) {
  ASSERT_TRUE(kCacheInBuild);
  for (const GlimmerClosureType *type : plugin().closures()) {
    const auto closure = make_closure(*type);
    for (const Vec3 &wi : kWis)
      for (const bool backfacing : {false, true}) {
        const GlimmerShadingContext ctx = context_at(wi, backfacing), rotated = turned(ctx);
        Pcg32 rng(7);
        for (int i = 0; i < 64; ++i) {
          const Vec3 wo = spherical_dir(180.0 * rng.next_float(), 360.0 * rng.next_float());
          EXPECT_TRUE(same_eval(*closure, ctx, wo, *closure, rotated, turn(wo)))
              << type->name << " wi " << format_vec(wi) << " backfacing " << backfacing;
        }
        for (int i = 0; i < 64; ++i) {
          const float u[3] = {rng.next_float(), rng.next_float(), rng.next_float()};
          GlimmerSample a{}, b{};
          const uint32_t la = closure->sample(ctx, u, a), lb = closure->sample(rotated, u, b);
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

// Negative control: the rotated setup really is another world geometry.
TEST(NormalConvention, TheTurnedSetupIsNotTheSameWorldGeometry) {
  const GlimmerShadingContext ctx = context_at(kWis[0], false);
  const GlimmerShadingContext rotated = turned(ctx);
  EXPECT_LT(rotated.N.z, 0.0f);
  EXPECT_LT(rotated.wi.z, 0.0f);
  // A world-space "closure" f = max(wo.z, 0) differs between the two setups.
  const Vec3 wo(0.0f, 0.0f, 1.0f);
  EXPECT_NE(std::max(wo.z, 0.0f), std::max(turn(wo).z, 0.0f));
}

TEST(NormalConvention, BackfacingDecidesEtaOfTransmissiveClosures) {
  int checked = 0;
  for (const GlimmerClosureType *type : plugin().closures()) {
    if (!transmissive(*type) || (type->flags & GLIMMER_CLOSURE_STOCHASTIC_EVAL)) continue;
    if (host::find_param(*type, "ior") == nullptr) continue;
    const auto dense = make_closure(*type, {{"ior", "2"}});
    const auto sparse = make_closure(*type, {{"ior", "0.5"}});
    const Vec3 wi = normalize(Vec3(0.3f, 0.2f, 0.8f));
    const GlimmerShadingContext inside = context_at(wi, true), outside = context_at(wi, false);
    Pcg32 rng(11);
    int differing = 0;
    for (int i = 0; i < 128; ++i) {
      const Vec3 wo = spherical_dir(180.0 * rng.next_float(), 360.0 * rng.next_float());
      // From inside (backfacing) at ior 2 = from outside at 1 / 2 ...
      EXPECT_TRUE(same_eval(*dense, inside, wo, *sparse, outside, wo)) << type->name;
      // ... and not the outside at ior 2, which a closure ignoring backfacing would give.
      differing += same_eval(*dense, inside, wo, *dense, outside, wo) ? 0 : 1;
    }
    EXPECT_GT(differing, 16) << type->name;
    ++checked;
  }
  EXPECT_GE(checked, 2);  // microfacet_dielectric and frosted_glass
}

TEST(NormalConvention, ReflectionClosuresIgnoreBackfacing) {
  int checked = 0;
  for (const GlimmerClosureType *type : plugin().closures()) {
    if (transmissive(*type)) continue;
    const auto closure = make_closure(*type);
    for (const Vec3 &wi : kWis) {
      Pcg32 rng(5);
      for (int i = 0; i < 64; ++i) {
        const Vec3 wo = spherical_dir(180.0 * rng.next_float(), 360.0 * rng.next_float());
        EXPECT_TRUE(same_eval(*closure, context_at(wi, false), wo, *closure, context_at(wi, true), wo)) << type->name;
      }
    }
    ++checked;
  }
  EXPECT_GE(checked, 4);
}

TEST(NormalConvention, TransmissiveClosuresScatterNothingWithWiBelowN) {
  int checked = 0;
  for (const GlimmerClosureType *type : plugin().closures()) {
    if (!transmissive(*type)) continue;
    const auto closure = make_closure(*type);
    for (const bool backfacing : {false, true}) {
      // A bent shading normal: wi above Ng (+z) but below N.
      GlimmerShadingContext ctx = context_at(normalize(Vec3(0.9f, 0.0f, 0.1f)), backfacing);
      ctx.N = normalize(Vec3(-0.5f, 0.0f, 0.8f));
      ctx.T = normalize(Vec3(0.8f, 0.0f, 0.5f));
      ASSERT_LT(dot(Vec3(ctx.wi), Vec3(ctx.N)), 0.0f);
      Pcg32 rng(3);
      for (int i = 0; i < 32; ++i) {
        Spectrum f;
        float pdf = 1.0f;
        closure->eval(ctx, spherical_dir(180.0 * rng.next_float(), 360.0 * rng.next_float()), f, pdf);
        EXPECT_TRUE(is_zero(f) && pdf == 0.0f) << type->name;
        const float u[3] = {rng.next_float(), rng.next_float(), rng.next_float()};
        GlimmerSample s{};
        EXPECT_EQ(closure->sample(ctx, u, s), 0u) << type->name;
      }
      if (type->albedo != nullptr) {
        EXPECT_TRUE(is_zero(closure->albedo(ctx))) << type->name;
      }
    }
    // Control: the same wi above N scatters.
    GlimmerSample s{};
    const float u[3] = {0.3f, 0.6f, 0.5f};
    EXPECT_NE(closure->sample(context_at(normalize(Vec3(0.9f, 0.0f, 0.1f)), false), u, s), 0u) << type->name;
    ++checked;
  }
  EXPECT_GE(checked, 3);  // microfacet_dielectric, frosted_glass, microfacet_random_walk
}

}  // namespace
}  // namespace glimmer::test
