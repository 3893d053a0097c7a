// The adapter's sanitize (plugin/core/closure.h; session 43: compare masks instead of branches where the target has
// SSE2) against its definition, (isfinite(v) && v > 0) ? v : 0, bit for bit: every special float (NaN of both signs,
// both infinities and zeros, the denormal and normal extremes, negatives) and random bit patterns, as a float and in
// each lane of a Spectrum. Negative controls: masks that test v > 0 alone let +inf through; an unordered compare
// lets NaN through.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "core/closure.h"
#include "glimmer/rng.h"

namespace {

using glimmer::Spectrum;
using glimmer::plugin::sanitize;

float reference(float v) { return (std::isfinite(v) && v > 0.0f) ? v : 0.0f; }
bool same_bits(float a, float b) { return std::bit_cast<uint32_t>(a) == std::bit_cast<uint32_t>(b); }

std::vector<float> special_and_random_floats() {
  using L = std::numeric_limits<float>;
  std::vector<float> v = {0.0f,
                          -0.0f,
                          1.0f,
                          -1.0f,
                          L::infinity(),
                          -L::infinity(),
                          L::quiet_NaN(),
                          -L::quiet_NaN(),
                          L::signaling_NaN(),
                          L::denorm_min(),
                          -L::denorm_min(),
                          L::min(),
                          -L::min(),
                          L::max(),
                          -L::max(),
                          L::epsilon(),
                          1e-30f,
                          1e30f};
  glimmer::Pcg32 rng(43);
  for (int i = 0; i < 100000; ++i) v.push_back(std::bit_cast<float>(rng.next_u32()));
  return v;
}

TEST(ClosureSanitize, EqualsItsDefinitionBitForBit) {
  const std::vector<float> values = special_and_random_floats();
  for (size_t i = 0; i < values.size(); ++i) {
    const float x = values[i];
    ASSERT_TRUE(same_bits(sanitize(x), reference(x))) << "v bits " << std::bit_cast<uint32_t>(x);
    // Each lane of a Spectrum, beside two other values.
    const float a = values[(i + 1) % values.size()], b = values[(i + 2) % values.size()];
    for (const Spectrum &s : {Spectrum(x, a, b), Spectrum(a, x, b), Spectrum(a, b, x)}) {
      const Spectrum r = sanitize(s);
      ASSERT_TRUE(same_bits(r.x, reference(s.x)) && same_bits(r.y, reference(s.y)) && same_bits(r.z, reference(s.z)))
          << "v bits " << std::bit_cast<uint32_t>(x);
    }
  }
}

#if defined(__SSE2__)
// The lanes form without its upper compare (v > 0 only) passes +inf: the test above sees that bug.
TEST(ClosureSanitize, NegativeControlWithoutTheInfinityTestFails) {
  const auto without_upper = [](float v) {
    const __m128 x = _mm_set_ss(v);
    return _mm_cvtss_f32(_mm_and_ps(_mm_cmpgt_ps(x, _mm_setzero_ps()), x));
  };
  int differ = 0;
  for (const float x : special_and_random_floats()) differ += !same_bits(without_upper(x), reference(x));
  EXPECT_GT(differ, 0);
  const float inf = std::numeric_limits<float>::infinity();
  EXPECT_FALSE(same_bits(without_upper(inf), reference(inf)));
}

// The lanes form with an unordered "not <= 0" compare instead of "> 0" passes NaN: the NaN inputs matter too.
TEST(ClosureSanitize, NegativeControlThatPassesNaNFails) {
  const auto passes_nan = [](float v) {
    const __m128 x = _mm_set_ss(v);
    const __m128 ok = _mm_and_ps(_mm_cmpnle_ps(x, _mm_setzero_ps()),
                                 _mm_cmpneq_ps(x, _mm_set1_ps(std::numeric_limits<float>::infinity())));
    return _mm_cvtss_f32(_mm_and_ps(ok, x));
  };
  int differ = 0;
  for (const float x : special_and_random_floats()) differ += !same_bits(passes_nan(x), reference(x));
  EXPECT_GT(differ, 0);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  EXPECT_FALSE(same_bits(passes_nan(nan), reference(nan)));
}
#endif

}  // namespace
