// The Owen-scrambled Sobol sampler (bridge/render/sampler.h): the precomputed generator-matrix tables agree
// with the direction-number recurrence and with the bit-by-bit van der Corput / second-dimension
// constructions, and the sampler's pair tables give the points of the per-dimension definition (the float of
// each scrambled value by byte tables equals the reversal and conversion bit for bit); the first
// 2^m samples of every set are stratified (each dimension one point per 1/2^m interval, dimensions 0-1 a
// (0, m, 2)-net), which independent random numbers fail (negative control); values are a pure function of
// (seed, pixel, sample, set). And choose_and_rescale keeps a stratified sample stratified within each branch.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "glimmer/sampling.h"
#include "render/sampler.h"
#include "render/sampler_draw.h"

namespace glimmer::render {
namespace {

// The second Sobol dimension bit by bit (v_1 = 2^31, v_k = v_{k-1} ^ v_{k-1} >> 1).
uint32_t sobol_dim1_bitwise(uint32_t i) {
  uint32_t r = 0u;
  for (uint32_t v = 1u << 31; i != 0u; i >>= 1, v ^= v >> 1)
    if (i & 1u) r ^= v;
  return r;
}

TEST(Sampler, GeneratorTablesMatchTheRecurrence) {
  Pcg32 rng(3);
  for (int n = 0; n < 20000; ++n) {
    const uint32_t i = n < 1000 ? static_cast<uint32_t>(n) : rng.next_u32();
    EXPECT_EQ(sobol_by_matrix(0, i), reverse_bits(i));
    EXPECT_EQ(sobol_by_matrix(1, i), sobol_dim1_bitwise(i));
    for (int d = 0; d < kSobolDimensions; ++d) ASSERT_EQ(sobol_reversed(d, reverse_bits(i)), reverse_bits(sobol_by_matrix(d, i)));
  }
  // Known points (Joe & Kuo): index 1 -> all 1/2; index 2 -> (1/4, 3/4, 3/4, 3/4, 1/4, 1/4); index 3 ->
  // (3/4, 1/4, 1/4, 1/4, 3/4, 3/4) (dimensions 4 and 5 start with m_2 = 1).
  for (int d = 0; d < kSobolDimensions; ++d) {
    const bool quarter = d == 0 || d >= 4;
    EXPECT_EQ(sobol_by_matrix(d, 1), 0x80000000u);
    EXPECT_EQ(sobol_by_matrix(d, 2), quarter ? 0x40000000u : 0xc0000000u);
    EXPECT_EQ(sobol_by_matrix(d, 3), quarter ? 0xc0000000u : 0x40000000u);
  }
}

// The float of a scrambled reversed value from three byte tables equals the reversal and conversion, bit for
// bit, for every value of the 24 bits that reach the float (and random top bytes, which do not). Negative
// control: the tables applied to bytes 1-3 instead of 0-2 (a wrong shift) give other floats.
TEST(Sampler, ReversedByteFloatsEqualTheReversalAndConversion) {
  Pcg32 rng(5);
  int shifted_differs = 0;
  const auto &t = kReversedByteFloats.value;
  for (uint32_t low = 0; low < (1u << 24); ++low) {
    const uint32_t y = low | (rng.next_u32() & 0xff000000u);
    ASSERT_EQ(reversed_to_unit_float(y), uint_to_unit_float(reverse_bits(y))) << y;
    if ((low & 0xfffu) == 0u) {
      const float shifted = (t[0][(y >> 8) & 0xffu] + t[1][(y >> 16) & 0xffu]) + t[2][y >> 24];
      if (shifted != uint_to_unit_float(reverse_bits(y))) ++shifted_differs;
    }
  }
  EXPECT_GT(shifted_differs, 4096 * 9 / 10);
}

// Dimension d of set `set` by its definition, one dimension at a time: the sample index shuffled by a nested
// uniform scramble, the Sobol point by the generator matrix, then the dimension's nested uniform scramble
// (Burley 2020, sec. 3-4). `swap_pair` is a known bug for the negative control: the two words of a
// dimension pair exchanged.
float sampler_by_definition(uint32_t seed, uint32_t pixel, uint32_t sample, uint32_t set, int d, bool swap_pair = false) {
  const uint32_t set_seed = hash_combine(hash_u32x2(seed, pixel), set);
  const uint32_t index = reverse_bits(laine_karras_permutation(reverse_bits(sample), set_seed));
  const int column = swap_pair ? d ^ 1 : d;
  const uint32_t x = reverse_bits(laine_karras_permutation(reverse_bits(sobol_by_matrix(column, index)), dimension_seed(set_seed, d)));
  return uint_to_unit_float(x);
}

TEST(Sampler, PairTablesGiveThePointsOfTheDefinition) {
  Pcg32 rng(11);
  int swapped_differs = 0;
  const int n = 20000;
  for (int k = 0; k < n; ++k) {
    const uint32_t seed = rng.next_u32(), pixel = rng.next_u32() & 0xfffffu;
    const uint32_t sample = k < 1000 ? static_cast<uint32_t>(k) : rng.next_u32() & 0xffffu;
    const uint32_t set = k % 3 == 0 ? kSetLens : k % 5 == 0 ? kSetCamera : bounce_set(static_cast<int>(rng.next_u32() % 64u), k % 2);
    const PixelSampler sampler(seed, pixel, sample);
    float v1[1], v2[2], v3[3], v4[4], v6[6];
    sampler.get(set, v1);
    sampler.get(set, v2);
    sampler.get(set, v3);
    sampler.get(set, v4);
    sampler.get(set, v6);
    for (int d = 0; d < kSobolDimensions; ++d) {
      const float expected = sampler_by_definition(seed, pixel, sample, set, d);
      ASSERT_EQ(v6[d], expected) << "dimension " << d << " sample " << sample;
      if (sampler_by_definition(seed, pixel, sample, set, d, true) != v6[d]) ++swapped_differs;
      if (d >= 4) continue;
      ASSERT_EQ(v4[d], expected) << "dimension " << d << " sample " << sample;
      if (d < 3) {
        ASSERT_EQ(v3[d], expected);
      }
      if (d < 2) {
        ASSERT_EQ(v2[d], expected);
      }
      if (d < 1) {
        ASSERT_EQ(v1[d], expected);
      }
    }
  }
  // Negative control: exchanging the words of a pair (a wrong half of the 64-bit reversal) is caught.
  EXPECT_GT(swapped_differs, kSobolDimensions * n * 9 / 10);
}

// The camera set's pairs are dimensions 0-1 (film), 2-3 (BSDF x, y) and 4-5 (BSDF z, rr) of one set.
TEST(Sampler, CameraSetIsOneSixDimensionalSet) {
  for (uint32_t pixel : {0u, 17u, 4095u, 123456u})
    for (uint32_t s = 0; s < 300; ++s) {
      const PixelSampler sampler(99u, pixel, s);
      float film[2], bsdf[4], six[6];
      sampler.get_camera(film, bsdf);
      sampler.get(kSetCamera, six);
      ASSERT_EQ(film[0], six[2 * kCameraFilmPair]);
      ASSERT_EQ(film[1], six[2 * kCameraFilmPair + 1]);
      ASSERT_EQ(bsdf[0], six[2 * kCameraBsdfXyPair]);
      ASSERT_EQ(bsdf[1], six[2 * kCameraBsdfXyPair + 1]);
      ASSERT_EQ(bsdf[2], six[2 * kCameraBsdfZrrPair]);
      ASSERT_EQ(bsdf[3], six[2 * kCameraBsdfZrrPair + 1]);
    }
}

// Whether the points (in [0,1)^2) form a (0, m, 2)-net: every elementary box 2^-a x 2^-(m-a) holds one point.
bool is_0m2_net(const std::vector<float> &x, const std::vector<float> &y, int m) {
  const size_t n = size_t{1} << m;
  for (int a = 0; a <= m; ++a) {
    std::vector<int> count(n, 0);
    for (size_t k = 0; k < n; ++k) {
      const size_t bx = static_cast<size_t>(x[k] * (1u << a)), by = static_cast<size_t>(y[k] * (1u << (m - a)));
      if (++count[(bx << (m - a)) | by] > 1) return false;
    }
  }
  return true;
}
// Whether every interval [k, k + 1) / 2^m holds one of the 2^m values.
bool is_stratified_1d(const std::vector<float> &x, int m) {
  std::vector<int> count(size_t{1} << m, 0);
  for (float v : x)
    if (++count[static_cast<size_t>(v * (1u << m))] > 1) return false;
  return true;
}

TEST(Sampler, EverySetIsStratified) {
  const int m = 8;
  const size_t n = size_t{1} << m;
  for (uint32_t pixel : {0u, 17u, 4095u})
    for (uint32_t set : {kSetCamera, bounce_set(0, kSetLight), bounce_set(5, kSetBsdf), kSetLens}) {
      std::vector<std::vector<float>> dims(kSobolDimensions, std::vector<float>(n));
      for (uint32_t s = 0; s < n; ++s) {
        const PixelSampler sampler(12345u, pixel, s);
        float v[kSobolDimensions];
        sampler.get(set, v);
        for (int d = 0; d < kSobolDimensions; ++d) dims[d][s] = v[d];
      }
      for (int d = 0; d < kSobolDimensions; ++d)
        EXPECT_TRUE(is_stratified_1d(dims[d], m)) << "pixel " << pixel << " set " << set << " dim " << d;
      EXPECT_TRUE(is_0m2_net(dims[0], dims[1], m)) << "pixel " << pixel << " set " << set;
    }
  // Negative control: independent random numbers are not stratified.
  Pcg32 rng(9);
  std::vector<float> x(n), y(n);
  for (size_t k = 0; k < n; ++k) x[k] = rng.next_float(), y[k] = rng.next_float();
  EXPECT_FALSE(is_stratified_1d(x, m));
  EXPECT_FALSE(is_0m2_net(x, y, m));
}

// Whether the n = 2^m points form a (t, m, s)-net: every elementary box of volume 2^(t-m) (2^a_j intervals
// along dimension j, sum a_j = m - t) holds 2^t of them.
bool is_tms_net(const std::vector<std::vector<float>> &points, int t, int m) {
  const int s = static_cast<int>(points.size()), k = m - t;
  std::vector<int> a(static_cast<size_t>(s), 0);
  // Every split of k bits among the s dimensions (a_0 .. a_{s-2} enumerated, a_{s-1} the rest).
  for (;;) {
    int used = 0;
    for (int j = 0; j + 1 < s; ++j) used += a[static_cast<size_t>(j)];
    if (used <= k) {
      a[static_cast<size_t>(s - 1)] = k - used;
      std::vector<int> count(size_t{1} << k, 0);
      for (size_t i = 0; i < points[0].size(); ++i) {
        size_t box = 0;
        for (int j = 0; j < s; ++j)
          box = (box << a[static_cast<size_t>(j)]) |
                static_cast<size_t>(points[static_cast<size_t>(j)][i] * static_cast<float>(1u << a[static_cast<size_t>(j)]));
        ++count[box];
      }
      for (int c : count)
        if (c != 1 << t) return false;
    }
    int j = 0;
    while (j + 1 < s && ++a[static_cast<size_t>(j)] > k) a[static_cast<size_t>(j++)] = 0;
    if (j + 1 >= s) return true;
  }
}

// The point (film u, film v, BSDF x, BSDF y) of vertex 0 is a (3, 8, 4)-net in every pixel (Sobol dimensions
// 0-3: t = 3 at 256 samples); film and BSDF numbers from two sets (the padded layout before issue 13, session 6)
// are each stratified but not jointly: not even a (6, 8, 4)-net.
TEST(Sampler, CameraSetIsJointlyStratifiedInFourDimensions) {
  const int m = 8;
  const size_t n = size_t{1} << m;
  for (uint32_t pixel : {0u, 17u, 4095u}) {
    std::vector<std::vector<float>> joint(4, std::vector<float>(n)), padded(4, std::vector<float>(n));
    for (uint32_t s = 0; s < n; ++s) {
      const PixelSampler sampler(12345u, pixel, s);
      float film[2], bsdf[4], film_set[2], bsdf_set[2];
      sampler.get_camera(film, bsdf);
      sampler.get(0u, film_set);                       // a 2D set of its own (the old film set)
      sampler.get(bounce_set(0, kSetLight), bsdf_set);  // another one
      const float j[4] = {film[0], film[1], bsdf[0], bsdf[1]}, p[4] = {film_set[0], film_set[1], bsdf_set[0], bsdf_set[1]};
      for (int d = 0; d < 4; ++d) joint[static_cast<size_t>(d)][s] = j[d], padded[static_cast<size_t>(d)][s] = p[d];
    }
    EXPECT_TRUE(is_tms_net(joint, 3, m)) << "pixel " << pixel;
    EXPECT_FALSE(is_tms_net(padded, 6, m)) << "pixel " << pixel;
    EXPECT_TRUE(is_0m2_net(padded[0], padded[1], m));
    EXPECT_TRUE(is_0m2_net(padded[2], padded[3], m));
  }
}

// get_vertex draws a vertex's BSDF and light sets side by side; the values must be exactly those of the
// two sets drawn one after the other (get_bsdf, get_light), whose points the test above checks against the
// definition. Control: the sets of the neighbouring vertex differ, so a mixed-up vertex would be caught.
TEST(Sampler, VertexSetsTogetherEqualTheSetsApart) {
  int cases = 0, neighbour_differs = 0;
  for (uint32_t pixel : {0u, 17u, 4095u, 123456u})
    for (uint32_t s = 0; s < 300; ++s)
      for (int vertex = 0; vertex < 12; ++vertex) {
        const PixelSampler sampler(99u, pixel, s);
        float bsdf[4], light[2], bsdf_apart[4], lu, lv;
        sampler.get_vertex(vertex, bsdf, light);
        sampler.get_bsdf(vertex, bsdf_apart);
        sampler.get_light(vertex, lu, lv);
        for (int d = 0; d < 3; ++d) ASSERT_EQ(bsdf[d], bsdf_apart[d]) << pixel << " " << s << " " << vertex << " " << d;
        // Vertex 0's rr is never read (roulette needs bounce > min_bounce >= 1), so it is not drawn.
        ASSERT_EQ(bsdf[3], vertex == 0 ? kUndrawnRr : bsdf_apart[3]);
        ASSERT_EQ(light[0], lu);
        ASSERT_EQ(light[1], lv);
        float next_bsdf[4], next_u, next_v;
        sampler.get_bsdf(vertex + 1, next_bsdf);
        sampler.get_light(vertex + 1, next_u, next_v);
        ++cases;
        if (bsdf[0] != next_bsdf[0] && light[0] != next_u && light[1] != next_v) ++neighbour_differs;
      }
  EXPECT_GE(neighbour_differs, cases - 2);
}

// get_path_start: the camera set and vertex 0's light set, exactly as drawn apart.
TEST(Sampler, PathStartSetsEqualTheSetsApart) {
  for (uint32_t pixel : {0u, 17u, 4095u, 123456u})
    for (uint32_t s = 0; s < 300; ++s) {
      const PixelSampler sampler(99u, pixel, s);
      float film[2], bsdf[4], light[2], film0[2], bsdf0[4], lu, lv;
      sampler.get_path_start(film, bsdf, light);
      sampler.get_camera(film0, bsdf0);
      sampler.get_light(0, lu, lv);
      ASSERT_EQ(film[0], film0[0]);
      ASSERT_EQ(film[1], film0[1]);
      for (int d = 0; d < 3; ++d) ASSERT_EQ(bsdf[d], bsdf0[d]);
      ASSERT_EQ(bsdf[3], kUndrawnRr);  // never read at vertex 0, not drawn
      ASSERT_EQ(light[0], lu);
      ASSERT_EQ(light[1], lv);
      // Without a light sample the light set is not drawn; the other numbers stay the same.
      float film_n[2], bsdf_n[4], light_n[2];
      sampler.get_path_start(film_n, bsdf_n, light_n, false);
      ASSERT_EQ(film_n[0], film[0]);
      ASSERT_EQ(film_n[1], film[1]);
      for (int d = 0; d < 4; ++d) ASSERT_EQ(bsdf_n[d], bsdf[d]);
      ASSERT_EQ(light_n[0], kUndrawnLight);
      ASSERT_EQ(light_n[1], kUndrawnLight);
    }
}

// A vertex b >= 1 draws one 6D set: light (u, v) = Sobol dimensions 0-1, BSDF (x, y) = 2-3, (z, rr) = 4-5.
// The numbers it skips (light without a light sample, rr where roulette cannot fire) read the undrawn
// constants, and the numbers it draws do not depend on which are skipped. Control: the neighbouring vertex's
// set differs, so a set id mixed up between vertices would be caught.
TEST(Sampler, VertexSetIsOneSixDimensionalSetAndSkipsUnreadNumbers) {
  int cases = 0, neighbour_differs = 0;
  for (uint32_t pixel : {0u, 17u, 4095u, 123456u})
    for (uint32_t s = 0; s < 300; ++s)
      for (int vertex = 1; vertex < 12; ++vertex) {
        const PixelSampler sampler(99u, pixel, s);
        float six[6], next[6];
        sampler.get(bounce_set(vertex, kSetBsdf), six);
        sampler.get(bounce_set(vertex + 1, kSetBsdf), next);
        for (int need = 0; need < 4; ++need) {
          const bool need_light = (need & 1) != 0, need_rr = (need & 2) != 0;
          float bsdf[4], light[2];
          sampler.get_vertex(vertex, bsdf, light, need_light, need_rr);
          ASSERT_EQ(bsdf[0], six[2 * kVertexBsdfXyPair]);
          ASSERT_EQ(bsdf[1], six[2 * kVertexBsdfXyPair + 1]);
          ASSERT_EQ(bsdf[2], six[2 * kVertexBsdfZrrPair]);
          ASSERT_EQ(bsdf[3], need_rr ? six[2 * kVertexBsdfZrrPair + 1] : kUndrawnRr);
          ASSERT_EQ(light[0], need_light ? six[2 * kVertexLightPair] : kUndrawnLight);
          ASSERT_EQ(light[1], need_light ? six[2 * kVertexLightPair + 1] : kUndrawnLight);
        }
        ++cases;
        if (six[0] != next[0] && six[2] != next[2] && six[4] != next[4]) ++neighbour_differs;
      }
  EXPECT_GE(neighbour_differs, cases - 2);
}

// The light numbers and the BSDF (x, y) of a vertex >= 1 are Sobol dimensions 0-3 of one index: a (3, 8, 4)-net
// at 256 samples, like the camera set's film and BSDF numbers. Control: light numbers from vertex 0's own 2D set
// with the BSDF numbers of another vertex's set (two independently shuffled sets) are not a (6, 8, 4)-net.
TEST(Sampler, VertexSetIsJointlyStratifiedInFourDimensions) {
  const int m = 8;
  const size_t n = size_t{1} << m;
  for (uint32_t pixel : {0u, 17u, 4095u}) {
    std::vector<std::vector<float>> joint(4, std::vector<float>(n)), apart(4, std::vector<float>(n));
    for (uint32_t s = 0; s < n; ++s) {
      const PixelSampler sampler(12345u, pixel, s);
      float bsdf[4], light[2], other_light[2];
      sampler.get_vertex(3, bsdf, light);
      sampler.get(bounce_set(0, kSetLight), other_light);
      // In Sobol dimension order: light (u, v) in pair kVertexLightPair, BSDF (x, y) in pair kVertexBsdfXyPair.
      const size_t l = 2 * kVertexLightPair, b = 2 * kVertexBsdfXyPair;
      joint[l][s] = light[0], joint[l + 1][s] = light[1], joint[b][s] = bsdf[0], joint[b + 1][s] = bsdf[1];
      apart[l][s] = other_light[0], apart[l + 1][s] = other_light[1], apart[b][s] = bsdf[0], apart[b + 1][s] = bsdf[1];
    }
    EXPECT_TRUE(is_tms_net(joint, 3, m)) << "pixel " << pixel;
    EXPECT_TRUE(is_0m2_net(joint[0], joint[1], m)) << "pixel " << pixel;  // Sobol dimensions 0-1
    EXPECT_FALSE(is_tms_net(apart, 6, m)) << "pixel " << pixel;
  }
}

TEST(Sampler, PureFunctionOfItsArguments) {
  float a[4], b[4], c[4], d[4];
  PixelSampler(7u, 100u, 33u).get(bounce_set(2, kSetBsdf), a);
  PixelSampler(7u, 100u, 33u).get(bounce_set(2, kSetBsdf), b);
  PixelSampler(7u, 100u, 33u).get(bounce_set(3, kSetBsdf), c);
  PixelSampler(8u, 100u, 33u).get(bounce_set(2, kSetBsdf), d);
  for (int k = 0; k < 4; ++k) {
    EXPECT_EQ(a[k], b[k]);
    EXPECT_NE(a[k], c[k]);
    EXPECT_NE(a[k], d[k]);
    EXPECT_GE(a[k], 0.0f);
    EXPECT_LT(a[k], 1.0f);
  }
}

// The vector draws (sampler_draw.cpp) against the scalar code, bit for bit, for every variant this CPU can
// run: get_vertex and get_path_start with the variant made active, against get_vertex_scalar and
// get_path_start_scalar, over seeds, pixels, samples and vertices including the extremes (sample 0 and
// 2^32 - 1, pixel 0 and 2^32 - 1, seed 0 and 2^32 - 1, vertices up to 1000) and every combination of the
// numbers needed. Control: the same comparison against the neighbouring vertex's scalar values fails.
bool same_bits(const float *a, const float *b, int n) { return std::memcmp(a, b, sizeof(float) * static_cast<size_t>(n)) == 0; }

TEST(Sampler, VectorDrawEqualsScalarDraw) {
  using sampler_draw::Variant;
  Pcg32 rng(13);
  std::vector<uint32_t> seeds = {0u, 1u, 99u, 0xffffffffu}, pixels = {0u, 1u, 4095u, 0xfffffffeu, 0xffffffffu},
                        samples = {0u, 1u, 2u, 255u, 256u, 0x7fffffffu, 0x80000000u, 0xfffffffeu, 0xffffffffu};
  for (int k = 0; k < 6; ++k) seeds.push_back(rng.next_u32()), pixels.push_back(rng.next_u32()), samples.push_back(rng.next_u32());
  for (uint32_t s = 0; s < 64; ++s) samples.push_back(s * 977u);
  int variants_run = 0;
  for (Variant variant : {Variant::kScalar, Variant::kAvx2}) {
    if (!sampler_draw::supported(variant)) continue;
    ++variants_run;
    const Variant before = sampler_draw::set_active(variant);
    long cases = 0, neighbour_differs = 0;
    for (uint32_t seed : seeds)
      for (uint32_t pixel : pixels)
        for (uint32_t sample : samples) {
          const PixelSampler sampler(seed, pixel, sample);
          for (int need = 0; need < 4; ++need) {
            const bool need_light = (need & 1) != 0, need_rr = (need & 2) != 0;
            float film[2], bsdf[4], light[2], film_s[2], bsdf_s[4], light_s[2];
            sampler.get_path_start(film, bsdf, light, need_light);
            sampler.get_path_start_scalar(film_s, bsdf_s, light_s, need_light);
            ASSERT_TRUE(same_bits(film, film_s, 2) && same_bits(bsdf, bsdf_s, 4) && same_bits(light, light_s, 2))
                << sampler_draw::name(variant) << " path start " << seed << " " << pixel << " " << sample << " " << need;
            for (int vertex : {1, 2, 3, 7, 16, 63, 1000}) {
              sampler.get_vertex(vertex, bsdf, light, need_light, need_rr);
              sampler.get_vertex_scalar(vertex, bsdf_s, light_s, need_light, need_rr);
              ASSERT_TRUE(same_bits(bsdf, bsdf_s, 4) && same_bits(light, light_s, 2))
                  << sampler_draw::name(variant) << " vertex " << vertex << " " << seed << " " << pixel << " " << sample << " " << need;
              sampler.get_vertex_scalar(vertex + 1, bsdf_s, light_s, need_light, need_rr);
              ++cases;
              if (!same_bits(bsdf, bsdf_s, 3)) ++neighbour_differs;
            }
          }
        }
    sampler_draw::set_active(before);
    EXPECT_GE(neighbour_differs, cases - 2) << sampler_draw::name(variant);
    std::printf("[          ] %s: %ld vertex draws and %ld path starts equal the scalar code\n", sampler_draw::name(variant),
                cases, cases / 7);
  }
  EXPECT_GE(variants_run, 1);
  // The start-up choice is the vector draw wherever the CPU has it (unless GLIMMER_SAMPLER_DRAW=scalar).
  const char *forced = std::getenv("GLIMMER_SAMPLER_DRAW");
  const bool scalar_forced = forced != nullptr && std::strcmp(forced, "scalar") == 0;
  EXPECT_EQ(sampler_draw::startup_choice(),
            sampler_draw::supported(Variant::kAvx2) && !scalar_forced ? Variant::kAvx2 : Variant::kScalar);
}

// draw_path_starts (the render loop's batched path starts) against the scalar code path by path, bit for bit,
// for every variant this CPU can run: batches of 1-8 paths mixing pixels and samples (extremes and random, a
// pixel's consecutive samples as the render loop passes them), with and without the light set: the path start
// (get_path_start_scalar), the sampler's members, the path seed and vertex 1's set start; the rows past n are not
// written. Control: each row compared with the next path's scalar values (a batch whose lanes are shifted by
// one, a bug the comparison must catch) differs in almost every case.
TEST(Sampler, BatchedPathStartsEqualPathByPath) {
  using sampler_draw::Variant;
  Pcg32 rng(29);
  const uint32_t extremes[6] = {0u, 1u, 255u, 0x80000000u, 0xfffffffeu, 0xffffffffu};
  int variants_run = 0;
  for (Variant variant : {Variant::kScalar, Variant::kAvx2}) {
    if (!sampler_draw::supported(variant)) continue;
    ++variants_run;
    const Variant before = sampler_draw::set_active(variant);
    long paths = 0, compared = 0, shifted_differs = 0;
    for (int batch = 0; batch < 3000; ++batch) {
      const int n = 1 + batch % kPathStartBatch;
      const bool need_light = (batch / kPathStartBatch) % 2 == 0;
      const uint32_t seed = batch % 5 == 0 ? extremes[batch % 6] : rng.next_u32();
      uint32_t pixels[kPathStartBatch + 1], samples[kPathStartBatch + 1];
      const uint32_t first_pixel = batch % 3 == 0 ? extremes[(batch / 3) % 6] : rng.next_u32() % 65536u;
      const uint32_t first_sample = batch % 7 == 0 ? extremes[(batch / 7) % 6] : rng.next_u32() % 4096u;
      const int per_pixel = 1 + batch % 4;  // consecutive samples of a pixel, then the next pixel
      for (int i = 0; i <= n; ++i) {
        pixels[i] = batch % 11 == 0 ? rng.next_u32() : first_pixel + static_cast<uint32_t>(i / per_pixel);
        samples[i] = first_sample + static_cast<uint32_t>(i % per_pixel);
      }
      PathStart out[kPathStartBatch];
      for (PathStart &p : out) std::fill(std::begin(p.value), std::end(p.value), -7.0f);
      draw_path_starts(seed, pixels, samples, n, need_light, out);
      float expected[kPathStartBatch + 1][8];
      for (int i = 0; i <= n; ++i) {
        float film[2], bsdf[4], light[2];
        PixelSampler(seed, pixels[i], samples[i]).get_path_start_scalar(film, bsdf, light, need_light);
        const float row[8] = {film[0], film[1], bsdf[0], bsdf[1], bsdf[2], bsdf[3], light[0], light[1]};
        std::copy(std::begin(row), std::end(row), expected[i]);
      }
      for (int i = 0; i < n; ++i) {
        ASSERT_TRUE(same_bits(out[i].value, expected[i], 8))
            << sampler_draw::name(variant) << " batch " << batch << " path " << i << " of " << n;
        const PixelSampler sampler(seed, pixels[i], samples[i]);
        ASSERT_EQ(out[i].pixel_seed, sampler.pixel_seed);
        ASSERT_EQ(out[i].sample_reversed, sampler.sample_reversed);
        ASSERT_EQ(out[i].path_seed, hash_u32x3(seed, pixels[i], samples[i]));
        const PixelSampler::Set vertex1 = sampler.start_set(bounce_set(1, kSetBsdf));
        ASSERT_EQ(out[i].vertex1.vertex, 1);
        ASSERT_EQ(out[i].vertex1.set.seed, vertex1.seed);
        ASSERT_EQ(out[i].vertex1.set.index_reversed, vertex1.index_reversed);
        for (int d = 0; d < 8; ++d)
          ASSERT_EQ(out[i].vertex1.words[d], d < kSobolDimensions ? sobol_reversed(d, vertex1.index_reversed) : 0u);
        ++paths;
        if (pixels[i + 1] != pixels[i] || samples[i + 1] != samples[i]) {
          ++compared;
          if (!same_bits(out[i].value, expected[i + 1], 5)) ++shifted_differs;
        }
      }
      for (int i = n; i < kPathStartBatch; ++i) EXPECT_EQ(out[i].value[0], -7.0f) << "row " << i << " past n " << n;
    }
    sampler_draw::set_active(before);
    EXPECT_GE(shifted_differs, compared - 2) << sampler_draw::name(variant);
    EXPECT_GT(compared, paths / 2);
    std::printf("[          ] %s: %ld batched path starts equal the scalar code; shifted by one: %ld of %ld differ\n",
                sampler_draw::name(variant), paths, shifted_differs, compared);
  }
  EXPECT_GE(variants_run, 1);
}

// get_vertex along a path with the set start drawn ahead (`next`, from the path start for vertex 1) equals
// get_vertex_scalar bit for bit, for every variant: vertices 1..40 in order, and with vertices skipped (a
// `next` for another vertex must not be used), every combination of the flags. Control (AVX2, the variant that
// uses `next`): a `next` naming the right vertex with another vertex's set gives other numbers, so the draw
// does read it.
TEST(Sampler, VertexDrawnAheadEqualsScalarDraw) {
  using sampler_draw::Variant;
  Pcg32 rng(31);
  int variants_run = 0;
  for (Variant variant : {Variant::kScalar, Variant::kAvx2}) {
    if (!sampler_draw::supported(variant)) continue;
    ++variants_run;
    const Variant before = sampler_draw::set_active(variant);
    long draws = 0, wrong_set_differs = 0, wrong_set_draws = 0;
    for (int path = 0; path < 400; ++path) {
      const uint32_t seed = path < 4 ? 0xffffffffu * (path & 1) : rng.next_u32();
      const uint32_t pixel = path < 4 ? 0xffffffffu * (path >> 1) : rng.next_u32(), sample = rng.next_u32() >> (path % 32);
      PathStart start;
      draw_path_starts(seed, &pixel, &sample, 1, true, &start);
      const PixelSampler sampler(start);
      const int step = 1 + path % 3;  // 1: every vertex in order; 2, 3: vertices skipped
      const int need = path % 4;
      sampler_draw::NextVertex next = start.vertex1;
      for (int vertex = 1; vertex <= 40; vertex += step) {
        float bsdf[4], light[2], bsdf_s[4], light_s[2];
        sampler.get_vertex(vertex, next, bsdf, light, (need & 1) != 0, (need & 2) != 0);
        sampler.get_vertex_scalar(vertex, bsdf_s, light_s, (need & 1) != 0, (need & 2) != 0);
        ASSERT_TRUE(same_bits(bsdf, bsdf_s, 4) && same_bits(light, light_s, 2))
            << sampler_draw::name(variant) << " path " << path << " vertex " << vertex;
        ++draws;
      }
      if (variant == Variant::kAvx2) {
        sampler_draw::NextVertex wrong;  // vertex 6's set start and words, labelled as vertex 5's
        const PixelSampler::Set six = sampler.start_set(bounce_set(6, kSetBsdf));
        wrong.set = six;
        for (int d = 0; d < kSobolDimensions; ++d) wrong.words[d] = sobol_reversed(d, six.index_reversed);
        wrong.vertex = 5;
        float bsdf[4], light[2], bsdf_s[4], light_s[2];
        sampler.get_vertex(5, wrong, bsdf, light, true, true);
        sampler.get_vertex_scalar(5, bsdf_s, light_s, true, true);
        ++wrong_set_draws;
        if (!same_bits(bsdf, bsdf_s, 3)) ++wrong_set_differs;
      }
    }
    sampler_draw::set_active(before);
    EXPECT_GE(wrong_set_differs, wrong_set_draws - 2) << sampler_draw::name(variant);
    std::printf("[          ] %s: %ld vertex draws with the start drawn ahead equal the scalar code; wrong set: %ld of %ld differ\n",
                sampler_draw::name(variant), draws, wrong_set_differs, wrong_set_draws);
  }
  EXPECT_GE(variants_run, 1);
}

// The vector kernel alone: eight lanes of (word, seed) scrambled and converted equal the scalar
// reversed_to_unit_float(laine_karras_permutation(word, seed)) bit for bit, over random and extreme lanes.
// Negative control (a test-only copy of the kernel with one wrong round constant, a bug the test must
// catch): each of the four constants changed by one bit gives other floats in almost every lane.
TEST(Sampler, VectorScrambleEqualsScalarAndCatchesAWrongRoundConstant) {
  if (!sampler_draw::supported(sampler_draw::Variant::kAvx2)) GTEST_SKIP() << "no AVX2 on this CPU";
  Pcg32 rng(17);
  const uint32_t extremes[8] = {0u, 1u, 0x80000000u, 0xffffffffu, 0x00ffffffu, 0xff000000u, 0x7fffffffu, 0xfffffffeu};
  const uint32_t(&rounds)[4] = kLaineKarrasRounds;
  int wrong_differs[4] = {0, 0, 0, 0}, lanes = 0;
  for (int n = 0; n < 20000; ++n) {
    uint32_t words[8], seeds[8];
    for (int k = 0; k < 8; ++k) {
      words[k] = n < 8 ? extremes[(k + n) % 8] : rng.next_u32();
      seeds[k] = n < 16 ? extremes[(3 * k + n) % 8] : rng.next_u32();
    }
    float out[8];
    sampler_draw::scramble_to_floats_avx2(words, seeds, rounds, out);
    for (int k = 0; k < 8; ++k) {
      const float scalar = reversed_to_unit_float(laine_karras_permutation(words[k], seeds[k]));
      ASSERT_EQ(std::memcmp(&out[k], &scalar, sizeof(float)), 0) << words[k] << " " << seeds[k];
    }
    for (int r = 0; r < 4; ++r) {
      uint32_t wrong[4] = {rounds[0], rounds[1], rounds[2], rounds[3]};
      wrong[r] ^= 1u << (3 + 5 * r);
      sampler_draw::scramble_to_floats_avx2(words, seeds, wrong, out);
      for (int k = 0; k < 8; ++k)
        if (out[k] != reversed_to_unit_float(laine_karras_permutation(words[k], seeds[k]))) ++wrong_differs[r];
    }
    lanes += 8;
  }
  for (int r = 0; r < 4; ++r) EXPECT_GT(wrong_differs[r], lanes * 9 / 10) << "round " << r;
}

// The in-vector float (byte order by vpshufb, nibble reversal by two table vpshufb, exact conversion and
// scale) equals the scalar reversal and conversion for every value of the 24 bits that reach the float, with
// random top bytes: the kernel with zero seeds and zero round constants is the identity scramble. Control:
// the bytes 0 and 2 of the input exchanged (a wrong byte order) give other floats.
TEST(Sampler, VectorFloatEqualsTheReversalAndConversion) {
  if (!sampler_draw::supported(sampler_draw::Variant::kAvx2)) GTEST_SKIP() << "no AVX2 on this CPU";
  Pcg32 rng(19);
  const uint32_t zero_rounds[4] = {0u, 0u, 0u, 0u}, zero_seeds[8] = {0u, 0u, 0u, 0u, 0u, 0u, 0u, 0u};
  int swapped_differs = 0, swapped_checked = 0;
  for (uint32_t low = 0; low < (1u << 24); low += 8) {
    uint32_t words[8];
    for (uint32_t k = 0; k < 8; ++k) words[k] = (low + k) | (rng.next_u32() & 0xff000000u);
    float out[8];
    sampler_draw::scramble_to_floats_avx2(words, zero_seeds, zero_rounds, out);
    for (int k = 0; k < 8; ++k) {
      const float scalar = uint_to_unit_float(reverse_bits(words[k]));
      ASSERT_EQ(std::memcmp(&out[k], &scalar, sizeof(float)), 0) << words[k];
    }
    if ((low & 0xff8u) == 0u) {
      uint32_t swapped[8];
      for (int k = 0; k < 8; ++k)
        swapped[k] = (words[k] & 0xff00ff00u) | ((words[k] & 0xffu) << 16) | ((words[k] >> 16) & 0xffu);
      sampler_draw::scramble_to_floats_avx2(swapped, zero_seeds, zero_rounds, out);
      for (int k = 0; k < 8; ++k, ++swapped_checked)
        if (out[k] != uint_to_unit_float(reverse_bits(words[k]))) ++swapped_differs;
    }
  }
  EXPECT_GT(swapped_differs, swapped_checked * 9 / 10);
}

TEST(Sampler, ChooseAndRescaleKeepsEachBranchStratified) {
  const int n = 1000;
  for (float p : {0.0f, 0.13f, 0.5f, 0.9f, 1.0f}) {
    std::vector<float> first, second;
    for (int i = 0; i < n; ++i) {
      float u = (i + 0.5f) / n;
      (choose_and_rescale(p, u) ? first : second).push_back(u);
    }
    EXPECT_NEAR(static_cast<double>(first.size()) / n, p, 1.0 / n);
    // Within a branch the rescaled values are evenly spaced over [0, 1): sorted, the k-th of m is near (k + 1/2) / m.
    for (auto *branch : {&first, &second}) {
      std::sort(branch->begin(), branch->end());
      const double m = static_cast<double>(branch->size());
      for (size_t k = 0; k < branch->size(); ++k) {
        ASSERT_LT((*branch)[k], 1.0f);
        ASSERT_NEAR((*branch)[k], (k + 0.5) / m, 1.0 / m) << "p " << p;
      }
    }
  }
}

}  // namespace
}  // namespace glimmer::render
