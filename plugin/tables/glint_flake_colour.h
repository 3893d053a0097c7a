// Per-flake colour variation of the glint closure (car paint; issue 10).
//
// Each lit particle ("flake") has its own Schlick F0, drawn from the
// material's flake-colour distribution: the base `color` converted to HSV,
// its hue shifted by a uniform offset in [-H, H] degrees and its value scaled
// by a uniform factor in [1 - V, 1 + V] (clamped to 1), H =
// flake_hue_variation and V = flake_value_variation. The distribution is
// represented by a palette of kSize colours on a 2D lattice of (hue, value)
// offsets (entry m: hue at the midpoint (m + 1/2) / kSize, value at the
// rank-1 lattice point (89 m mod kSize + 1/2) / kSize); a flake's entry is
// the top bits of a hash of its identity, so every entry has probability
// exactly 1 / kSize and the mean flake colour is the palette's mean, exactly.
//
// Identity. In the particle field (glint_particles.h) the lit particles of
// a node in a direction cell are the first K of that node's particle stream
// (node hash h0 of the cell seed), so flake k of h0 is one particle: its
// colour is a pure function of (h0, k). It keeps its colour while it stays
// lit (the lit set of a cell is nested in P) and across footprint sizes
// (one particle level per material).
//
// BRDF. Schlick's F(c) = c + (1 - c) (1 - wi.h)^5 is affine in the F0 c, so
// the sum of the K lit flakes' F is K F(c_mean_lit) with c_mean_lit the
// mean F0 of the lit flakes: the unfiltered BRDF (glint.cpp eq. 2) is W
// evaluated at c_mean_lit times K / (N a sigma). Its expectation over
// positions is W(c_mean) P / sigma with c_mean the palette mean (the flake
// colours are independent of the count), which is what the filtered mode
// (eq. 3) returns: the switch stays continuous in the mean.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>

#include "glimmer/math.h"
#include "glimmer/rng.h"

namespace glimmer::plugin::glint {

// HSV (hue in [0, 1) turns, saturation, value) of a linear RGB colour and back.
struct Hsv {
  float h = 0.0f, s = 0.0f, v = 0.0f;
};

inline Hsv rgb_to_hsv(const Spectrum &c) {
  const float mx = std::max({c.x, c.y, c.z}), mn = std::min({c.x, c.y, c.z});
  Hsv out;
  out.v = mx;
  const float range = mx - mn;
  if (!(mx > 0.0f) || !(range > 0.0f)) return out;  // grey: hue undefined (0)
  out.s = range / mx;
  float h;
  if (mx == c.x)
    h = (c.y - c.z) / range;
  else if (mx == c.y)
    h = 2.0f + (c.z - c.x) / range;
  else
    h = 4.0f + (c.x - c.y) / range;
  h /= 6.0f;
  out.h = h - std::floor(h);
  return out;
}

inline Spectrum hsv_to_rgb(const Hsv &c) {
  // Each channel: v (1 - s clamp(|6 h - k| - 1 ... )) written with the
  // standard distance-to-sector form: f(n) = v - v s max(0, min(k, 4 - k, 1)),
  // k = (n + 6 h) mod 6, n = 5, 3, 1 for R, G, B.
  auto channel = [&c](float n) {
    float k = n + 6.0f * c.h;
    k -= 6.0f * std::floor(k / 6.0f);
    const float t = std::max(0.0f, std::min({k, 4.0f - k, 1.0f}));
    return c.v - c.v * c.s * t;
  };
  return Spectrum(channel(5.0f), channel(3.0f), channel(1.0f));
}

// One flake's F0 for hue offset `hue_offset` (turns) and value factor.
inline Spectrum flake_colour(const Hsv &base, float hue_offset, float value_factor) {
  Hsv c = base;
  c.h = base.h + hue_offset;
  c.h -= std::floor(c.h);
  c.v = std::min(base.v * value_factor, 1.0f);
  return hsv_to_rgb(c);
}

class FlakePalette {
 public:
  static constexpr int kSize = 256;
  static constexpr uint32_t kLatticeStep = 89;  // rank-1 lattice generator (odd: a permutation of 0..255)

  // No variation (both spreads 0): every flake has the base colour and
  // mean() is `base` exactly, so the closure's results are unchanged.
  FlakePalette(const Spectrum &base, float hue_variation_deg, float value_variation)
      : mean_(base), varies_(hue_variation_deg > 0.0f || value_variation > 0.0f) {
    white_ = mean_.x == 1.0f && mean_.y == 1.0f && mean_.z == 1.0f;
    if (!varies_) return;
    const Hsv hsv = rgb_to_hsv(base);
    const float hue_half_width = hue_variation_deg / 360.0f;  // turns
    double sum[3] = {0.0, 0.0, 0.0};
    for (uint32_t m = 0; m < kSize; ++m) {
      const float xi_hue = (static_cast<float>(m) + 0.5f) / kSize;
      const float xi_value = (static_cast<float>((kLatticeStep * m) % kSize) + 0.5f) / kSize;
      colours_[m] = flake_colour(hsv, hue_half_width * (2.0f * xi_hue - 1.0f),
                                 1.0f + value_variation * (2.0f * xi_value - 1.0f));
      sum[0] += colours_[m].x, sum[1] += colours_[m].y, sum[2] += colours_[m].z;
    }
    mean_ = Spectrum(static_cast<float>(sum[0] / kSize), static_cast<float>(sum[1] / kSize),
                     static_cast<float>(sum[2] / kSize));
    white_ = mean_.x == 1.0f && mean_.y == 1.0f && mean_.z == 1.0f;
  }

  bool varies() const { return varies_; }
  // The mean flake colour: the filtered lobe's F0.
  const Spectrum &mean() const { return mean_; }
  // mean() is (1, 1, 1) exactly: Schlick's F at that F0 is 1 exactly (1 + 0 x), so W skips it (session 25).
  bool mean_is_white() const { return white_; }
  // Flake k of the lit particles whose node hash (in their direction cell) is node_hash.
  const Spectrum &colour(uint32_t node_hash, uint32_t k) const {
    return colours_[hash_combine(node_hash ^ 0x85ebca6bu, k) >> 24];
  }

 private:
  std::array<Spectrum, kSize> colours_{};
  Spectrum mean_;
  bool varies_ = false;
  bool white_ = false;  // mean_ == (1, 1, 1)
};

// Visitor of count_glints that sums the F0 of the counted flakes.
struct FlakeColourSum {
  static constexpr bool kVisitsParticles = true;
  const FlakePalette &palette;
  Spectrum sum{0.0f};
  void operator()(uint32_t node_hash, uint32_t k) { sum += palette.colour(node_hash, k); }
};

}  // namespace glimmer::plugin::glint
