// microfacet::fused_multiply_add (shared/include/glimmer/microfacet.h; session 33) against libm's fmaf, bit for bit:
// the GGX visible-normal sampler's one multiply-add, inline where the CPU has FMA3. Every case of the IEEE operation
// is reached: special operands, exact and cancelling sums, results halfway between floats (where a product and sum
// in double, then rounded to float, would round twice), subnormal and overflowing results.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <vector>

#include "glimmer/microfacet.h"
#include "glimmer/rng.h"

namespace {

using Rng = glimmer::Pcg32;

float from_bits(uint32_t b) {
  float x;
  std::memcpy(&x, &b, sizeof x);
  return x;
}
uint32_t to_bits(float x) {
  uint32_t b;
  std::memcpy(&b, &x, sizeof b);
  return b;
}
bool same_bits(float x, float y) { return (std::isnan(x) && std::isnan(y)) || to_bits(x) == to_bits(y); }

// A float of random sign, mantissa and exponent in [lo, hi] (unbiased exponent).
float random_float(Rng &rng, int lo, int hi) {
  const uint32_t span = static_cast<uint32_t>(hi - lo + 1);
  const uint32_t e = static_cast<uint32_t>(127 + lo + static_cast<int>(rng.next_u32() % span));
  return from_bits((rng.next_u32() & 0x807fffffu) | (e << 23));
}

// The k-th of n inputs, four families in turn: raw bit patterns (NaN, infinities, subnormals, everything);
// c = -(a b) rounded, perturbed by a few ulps (cancellation: the result is the product's rounding error, exact);
// products exactly halfway between two floats and a small c (the double-rounding cases); products and sums around
// the subnormal and overflow ranges.
struct Input {
  float a, b, c;
};
Input make_input(Rng &rng, uint64_t k) {
  switch (k % 4) {
    case 0:
      return {from_bits(rng.next_u32()), from_bits(rng.next_u32()), from_bits(rng.next_u32())};
    case 1: {
      const float a = random_float(rng, -20, 20), b = random_float(rng, -20, 20);
      const int32_t ulps = static_cast<int32_t>(rng.next_u32() % 9u) - 4;
      return {a, b, from_bits(to_bits(-(a * b)) + static_cast<uint32_t>(ulps))};
    }
    case 2: {
      // Odd 13-bit times odd 12-bit integers: a product of 25 significant bits (or 24) ends in the half-ulp bit, so
      // it lies exactly halfway between two floats; c, 2^-26 .. 2^-56 of it or 0, decides the rounding (a product
      // rounded first, or a double sum rounded to float, loses c and rounds the tie to even).
      const float sa = (k & 4) ? -1.0f : 1.0f, sc = (k & 8) ? -1.0f : 1.0f;
      const int ea = static_cast<int>(rng.next_u32() % 21u) - 10, eb = static_cast<int>(rng.next_u32() % 21u) - 10;
      const float a = sa * std::ldexp(static_cast<float>(4096u + 2u * (rng.next_u32() % 2048u) + 1u), ea);
      const float b = std::ldexp(static_cast<float>(2048u + 2u * (rng.next_u32() % 1024u) + 1u), eb);
      const int ec = ea + eb + 24 - 26 - static_cast<int>(rng.next_u32() % 31u);
      const float c = (k & 16) ? 0.0f : sc * std::ldexp(1.0f + static_cast<float>(rng.next_u32() % 16u) / 16.0f, ec);
      return {a, b, c};
    }
    default: {
      const bool tiny = (k & 4) != 0;
      const float a = tiny ? random_float(rng, -75, -60) : random_float(rng, 60, 70);
      const float b = tiny ? random_float(rng, -75, -60) : random_float(rng, 57, 64);
      const float c = tiny ? random_float(rng, -149 + 23, -120) : random_float(rng, 120, 127);
      return {a, b, tiny && (k & 8) ? from_bits(to_bits(c) & 0x807fffffu) : c};  // sometimes a subnormal c
    }
  }
}

// Special and boundary operands: every triple of them.
std::vector<float> edge_values() {
  const float inf = std::numeric_limits<float>::infinity();
  const std::vector<float> v = {0.0f, 1.0f, 2.0f, 0.5f, 3.0f, std::nextafter(1.0f, 2.0f), std::nextafter(1.0f, 0.0f),
                                std::numeric_limits<float>::max(), std::numeric_limits<float>::min(),
                                std::numeric_limits<float>::denorm_min(), from_bits(0x007fffffu), 1e-20f, 1e20f,
                                0x1.000002p-12f, inf, std::numeric_limits<float>::quiet_NaN()};
  std::vector<float> both;
  for (float x : v) {
    both.push_back(x);
    both.push_back(-x);
  }
  return both;
}

// Inputs (edge triples, then n generated ones) where f differs from libm's fmaf; the first few printed.
template <typename F>
uint64_t count_mismatches(F &&f, uint64_t n, const char *name) {
  uint64_t bad = 0;
  const auto check = [&](float a, float b, float c) {
    const float want = std::fma(a, b, c), got = f(a, b, c);
    if (same_bits(want, got)) return;
    if (++bad <= 3)
      std::printf("%s: fma(%a, %a, %a) = %a, got %a\n", name, static_cast<double>(a), static_cast<double>(b),
                  static_cast<double>(c), static_cast<double>(want), static_cast<double>(got));
  };
  const std::vector<float> edges = edge_values();
  for (float a : edges)
    for (float b : edges)
      for (float c : edges) check(a, b, c);
  Rng rng(20261206u);
  for (uint64_t k = 0; k < n; ++k) {
    const Input in = make_input(rng, k);
    check(in.a, in.b, in.c);
  }
  return bad;
}

// a b + c rounded twice (the product, then the sum; volatile so that no build contracts it into an FMA).
float unfused(float a, float b, float c) {
  volatile float product = a * b;
  return product + c;
}
// The exact product plus c rounded to double, then to float: right but for the double rounding of family 2.
float double_rounded(float a, float b, float c) {
  return static_cast<float>(static_cast<double>(a) * static_cast<double>(b) + static_cast<double>(c));
}

// Inputs of one family (make_input's k % 4) where f differs from fmaf, out of 100 000.
template <typename F>
uint64_t family_mismatches(F &&f, uint64_t family) {
  uint64_t bad = 0;
  Rng rng(7u + family);
  for (uint64_t k = family; k < 400'000; k += 4) {
    const Input in = make_input(rng, k);
    bad += same_bits(std::fma(in.a, in.b, in.c), f(in.a, in.b, in.c)) ? 0 : 1;
  }
  return bad;
}

TEST(MicrofacetFma, FusedMultiplyAddMatchesLibmFmaf) {
#if GLIMMER_FMA_DISPATCH
  // Without FMA3 fused_multiply_add is std::fma itself: the comparison would test nothing.
  if (!glimmer::microfacet::detail::kCpuHasFma) GTEST_SKIP() << "no FMA3: fused_multiply_add is std::fma";
  std::printf("inline VFMADD213SS\n");
#else
  std::printf("no dispatch in this build: std::fma\n");
#endif
  const uint64_t n = 100'000'000;
  EXPECT_EQ(count_mismatches(glimmer::microfacet::fused_multiply_add, n, "fused_multiply_add"), 0u);
  // Negative controls: the same check rejects a b + c rounded twice, in each family of inputs but the raw bits', and
  // a double sum rounded to float (the halfway family); the whole check rejects both.
  for (uint64_t family = 1; family < 4; ++family) EXPECT_GT(family_mismatches(unfused, family), 0u) << family;
  EXPECT_GT(family_mismatches(double_rounded, 2), 0u);
  EXPECT_GT(count_mismatches(unfused, 1'000'000, "unfused"), 0u);
  EXPECT_GT(count_mismatches(double_rounded, 1'000'000, "double_rounded"), 0u);
}

}  // namespace
