// The per-shading-point lobe set-up of the one-lobe microfacet closures
// (OneLobeClosure + PointLobeCache in plugin/core/closure.h): with a varying
// (textured) roughness the lobe is built once per point and reused by the
// following calls with the same values. Reuse must never change a result: every
// call equals the constant-parameter closure of the same value, whatever was
// evaluated before (another point, another instance with the same values).
#include <gtest/gtest.h>

#include <bit>
#include <thread>
#include <vector>

#include "closures/closure_checks.h"
#include "glimmer/rng.h"
#include "tables/microfacet_energy.h"

namespace glimmer::test {
namespace {

struct Result {
  Spectrum f, a;
  float pdf = 0.0f;
  GlimmerSample s{};
  bool operator==(const Result &o) const {
    return f.x == o.f.x && f.y == o.f.y && f.z == o.f.z && a.x == o.a.x && a.y == o.a.y && a.z == o.a.z &&
           pdf == o.pdf && s.pdf == o.s.pdf && s.eval[0] == o.s.eval[0] && s.wo.x == o.s.wo.x && s.wo.z == o.s.wo.z;
  }
};

// albedo, eval and sample at one point, as the renderer calls them.
Result shade(const host::ClosureInstance &c, const GlimmerShadingContext &ctx, int i) {
  Pcg32 rng(static_cast<uint64_t>(i));
  Result r;
  r.a = c.albedo(ctx);
  c.eval(ctx, normalize(Vec3(rng.next_float() - 0.5f, rng.next_float() - 0.5f, 0.7f)), r.f, r.pdf);
  const float u[3] = {rng.next_float(), rng.next_float(), rng.next_float()};
  c.sample(ctx, u, r.s);
  return r;
}

GlimmerShadingContext varying_context(const GlimmerClosureType &type, GlimmerVaryingValue &roughness, float value) {
  GlimmerShadingContext ctx = host::make_local_context(normalize(Vec3(0.3f, 0.1f, 0.9f)));
  roughness = {host::param_index(type, *host::find_param(type, "roughness")), {value, 0.0f, 0.0f}};
  ctx.varying_count = 1;
  ctx.varying = &roughness;
  return ctx;
}

TEST(LobeAtPoint, ReusedSetUpEqualsTheConstantClosureOfThatValue) {
  ASSERT_TRUE(cache_tables_in_build_folder());
  const float values[] = {0.2f, 0.55f, 0.2f, 0.8f, 0.8f, 0.2f};
  for (const char *name : {"microfacet_conductor", "microfacet_dielectric"}) {
    const GlimmerClosureType &type = closure_type(name);
    // Two instances differing only in a constant (f0 / ior): same varying values, different lobes.
    const char *other = std::string(name) == "microfacet_conductor" ? "f0" : "ior";
    const auto first = make_closure(type, {{"distribution", "multi_ggx"}});
    const auto second = make_closure(type, {{"distribution", "multi_ggx"}, {other, "0.6"}});
    int differing = 0;
    for (int i = 0; i < 6; ++i) {
      const float v = values[i];
      char text[16];
      std::snprintf(text, sizeof(text), "%g", v);
      const auto first_constant = make_closure(type, {{"distribution", "multi_ggx"}, {"roughness", text}});
      const auto second_constant =
          make_closure(type, {{"distribution", "multi_ggx"}, {other, "0.6"}, {"roughness", text}});
      GlimmerVaryingValue roughness;
      const GlimmerShadingContext ctx = varying_context(type, roughness, v);
      const GlimmerShadingContext plain = host::make_local_context(Vec3(ctx.wi));
      // Interleaved: each call follows a call of the other instance with the same values.
      const Result a = shade(*first, ctx, i), b = shade(*second, ctx, i), a_again = shade(*first, ctx, i);
      EXPECT_TRUE(a == shade(*first_constant, plain, i)) << name << " roughness " << v;
      EXPECT_TRUE(b == shade(*second_constant, plain, i)) << name << " roughness " << v;
      EXPECT_TRUE(a == a_again) << name;
      differing += !(a == b);  // the control: the two instances really differ
    }
    EXPECT_EQ(differing, 6) << name;
  }
}

// A shading point's dielectric row fills its mu nodes as lookups need them (tables::GlassRow::set); every
// lookup, in any order, must equal the instance's whole row (build) bit for bit. Control: a row of a
// slightly different alpha differs.
TEST(LobeAtPoint, LazilyFilledGlassRowEqualsTheBuiltRow) {
  Pcg32 rng(7);
  int control_differs = 0, lookups = 0;
  for (const float alpha : {0.01f, 0.09f, 0.3f, 0.64f, 1.0f})
    for (const float eta : {1.0001f, 1.1f, 1.45f, 2.4f, 1.0f / 1.45f, 1.0f / 1.1f}) {
      tables::GlassRow whole, lazy, other;
      whole.build(alpha, eta);
      lazy.set(alpha, eta);
      other.build(alpha * 0.95f, eta);
      for (int i = 0; i < 200; ++i) {
        const float mu = i < 2 ? float(i) : rng.next_float();  // both ends, then random order
        const float e = lazy(mu);
        ASSERT_EQ(std::bit_cast<uint32_t>(e), std::bit_cast<uint32_t>(whole(mu))) << alpha << " " << eta << " " << mu;
        ASSERT_TRUE(e > 0.0f && e < 1.01f) << alpha << " " << eta << " " << mu;  // an albedo
        control_differs += other(mu) != e;
        ++lookups;
      }
    }
  EXPECT_GT(control_differs, lookups * 9 / 10);
}

TEST(LobeAtPoint, ResultsDoNotDependOnThreads) {
  const GlimmerClosureType &type = closure_type("microfacet_conductor");
  const auto closure = make_closure(type, {{"distribution", "multi_ggx"}});
  auto run = [&](int threads) {
    std::vector<Result> out(4000);
    std::vector<std::thread> pool;
    for (int t = 0; t < threads; ++t)
      pool.emplace_back([&, t] {
        for (int i = t; i < 4000; i += threads) {
          GlimmerVaryingValue roughness;
          const GlimmerShadingContext ctx = varying_context(type, roughness, 0.1f + 0.8f * float(i % 7) / 7.0f);
          out[i] = shade(*closure, ctx, i);
        }
      });
    for (auto &th : pool) th.join();
    return out;
  };
  const std::vector<Result> one = run(1), three = run(3);
  for (size_t i = 0; i < one.size(); ++i) ASSERT_TRUE(one[i] == three[i]) << i;
}

}  // namespace
}  // namespace glimmer::test
