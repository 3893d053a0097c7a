// Shared helpers of the closure laboratory's .cpp files (not a public API).
#pragma once

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cmath>
#include <cstdint>
#include <vector>

#include "glimmer/math.h"
#include "lab/closure_lab.h"

namespace glimmer::lab::detail {

// Fixed block size: the partition of the index range, and therefore every
// floating-point reduction, is independent of the thread count.
inline constexpr uint64_t kBlockSize = 4096;

// Runs body(block_begin, block_end, Accumulator &) for every fixed block of
// [0, count) in parallel and returns the per-block accumulators in order.
template <typename Accumulator, typename Body>
std::vector<Accumulator> for_each_block(uint64_t count, Body body) {
  const uint64_t blocks = (count + kBlockSize - 1) / kBlockSize;
  std::vector<Accumulator> partial(blocks);
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, blocks, 1), [&](const tbb::blocked_range<uint64_t> &r) {
    for (uint64_t b = r.begin(); b != r.end(); ++b) {
      const uint64_t begin = b * kBlockSize;
      const uint64_t end = std::min(count, begin + kBlockSize);
      body(begin, end, partial[b]);
    }
  });
  return partial;
}

// sample() for sample `index` of a run seeded with `seed` (random numbers
// from sample_random3): returns the label and fills `s`.
inline uint32_t sample_at(const host::ClosureInstance &instance, const GlimmerShadingContext &ctx, uint64_t seed,
                          uint64_t index, GlimmerSample &s) {
  float rand3[3];
  sample_random3(seed, index, rand3);
  s = GlimmerSample{};
  return instance.sample(ctx, rand3, s);
}

// The context's shading frame (z = N, x = T projected): the lab's frame for binning and sweeps.
inline Frame shading_frame(const GlimmerShadingContext &ctx) {
  return Frame::from_normal_tangent(Vec3(ctx.N), Vec3(ctx.T));
}

inline bool is_unit_direction(const Vec3 &w) {
  return is_finite(w) && std::fabs(length_squared(w) - 1.0f) < 2e-3f;
}

inline bool spectrum_invalid(const float v[3]) {
  return is_invalid_value(v[0]) || is_invalid_value(v[1]) || is_invalid_value(v[2]);
}

// Unit direction for spherical coordinates in the local frame.
inline Vec3 spherical_direction(double theta, double phi) {
  const double s = std::sin(theta);
  return Vec3(static_cast<float>(s * std::cos(phi)), static_cast<float>(s * std::sin(phi)),
              static_cast<float>(std::cos(theta)));
}

}  // namespace glimmer::lab::detail
