// DielectricLobe::sample_reflection (session 38, frostedwalk38): the sampled internal reflections of frosted_glass's
// solid walk (frosted_glass_sg.cpp sample_reflection) draw with it instead of sample(). It must accept exactly the
// draws that sample() turns into a reflection, with the same direction bit for bit, on both sides of the interface
// (the walk reflects from inside: wi.z < 0), at grazing incidence (TIR inside) and for the sharp lobe (sample itself).
// Control: a reflection drawn with the outside IOR on both sides (a known way to get the inside wrong) must differ.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>

#include "closures/microfacet_test_util.h"
#include "core/dielectric_lobe.h"
#include "glimmer/rng.h"

namespace {

using namespace glimmer;
using namespace glimmer::plugin;

bool same_bits(const Vec3 &a, const Vec3 &b) { return std::memcmp(&a, &b, sizeof(Vec3)) == 0; }

// The control: sample_reflection's steps with eta = ior on both sides (the inside's 1 / ior forgotten).
bool reflection_outside_eta(const DielectricLobe &lobe, const Vec3 &wi_in, const Vec3 &rand, Vec3 &wo_out) {
  if (wi_in.z == 0.0f) return false;
  const bool outside = wi_in.z > 0.0f;
  const Vec3 wi = outside ? wi_in : mf::flip_z_local(wi_in);
  Vec3 m;
  const float F = lobe.visible_facet(wi, lobe.ior, rand.x, rand.y, m);
  if (!(rand.z < F)) return false;
  const Vec3 wo = normalize(mf::reflect_about(wi, m));
  if (!(wo.z > 0.0f)) return false;
  wo_out = outside ? wo : mf::flip_z_local(wo);
  return true;
}

struct Counts {
  int64_t draws = 0, reflections = 0, mismatches = 0, control_mismatches = 0;
};

Counts compare(float roughness, float ior, MicrofacetMode mode, uint32_t seed) {
  DielectricLobe lobe;
  lobe.build(MicrofacetLobeParams::make(mode, roughness, 0.0f), ior, false, false);
  Counts c;
  uint32_t state = seed;
  auto next = [&state] { return float(hash_u32(state++) >> 8) * 0x1p-24f; };
  // Incidences from normal to grazing on both sides (cos 1 .. 0.02), each with 400 draws.
  for (int k = 0; k < 100; ++k) {
    const float cos_theta = 1.0f - 0.98f * float(k) / 99.0f;
    for (float side : {1.0f, -1.0f}) {
      Vec3 wi = mftest::direction_from(cos_theta, 6.2831853f * next());
      wi.z *= side;
      for (int d = 0; d < 400; ++d) {
        const Vec3 rand(next(), next(), next());
        LocalSample s;
        const bool by_sample = lobe.sample(wi, rand, s) && (s.label & GLIMMER_LABEL_REFLECT);
        Vec3 wo(0.0f), wo_control(0.0f);
        const bool by_reflection = lobe.sample_reflection(wi, rand, wo);
        const bool by_control = reflection_outside_eta(lobe, wi, rand, wo_control);
        ++c.draws;
        c.reflections += by_sample;
        c.mismatches += by_sample != by_reflection || (by_sample && !same_bits(s.wo, wo));
        c.control_mismatches += by_sample != by_control || (by_sample && !same_bits(s.wo, wo_control));
      }
    }
  }
  return c;
}

TEST(DielectricLobeReflection, SameReflectionsAsSampleBitForBit) {
  int row = 0;
  for (float ior : {1.5f, 1.33f, 2.4f})
    for (float roughness : {0.05f, 0.3f, 0.5f, 0.8f, 1.0f}) {
      const Counts c = compare(roughness, ior, kMultiGgx, 0x5eed0000u + uint32_t(row++));
      SCOPED_TRACE(testing::Message() << "ior " << ior << " roughness " << roughness);
      EXPECT_GT(c.reflections, c.draws / 100);  // the comparison sees reflections on both sides
      EXPECT_EQ(c.mismatches, 0) << "of " << c.draws << " draws, " << c.reflections << " reflections";
      EXPECT_GT(c.control_mismatches, 0) << "the control (outside IOR inside) should differ";
    }
}

TEST(DielectricLobeReflection, SharpLobeIsSampleItself) {
  const Counts c = compare(0.0f, 1.5f, kSharp, 0x5eed1000u);
  EXPECT_GT(c.reflections, 0);
  EXPECT_EQ(c.mismatches, 0) << "of " << c.draws << " draws";
}

}  // namespace
