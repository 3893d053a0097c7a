// Spatial part of the separable glint model (Wang et al. 2018, sec. 4.3,
// Algorithm 1): particles scattered over the uv plane, counted inside a
// footprint, each particle reflecting when its random threshold lambda is
// below the directional probability P(wi, wo).
//
// Particle field. The (scaled) uv plane is cut into square nodes of side
// s = 2^-l. The query level l is the one whose node side is the smallest power
// of two >= the footprint's uv bounding box, so the box touches at most 2 x 2
// nodes. Node (l, i, j) holds n = floor(N s^2) + [u0 < frac(N s^2)] particles
// (mean exactly N s^2). The count and the smallest threshold come from an
// integer hash of the node id; every later random number (positions, further
// thresholds) from the node's TEA seed (8 rounds over (i, j) and (seed, l)),
// started only for nodes that hold a reflecting particle. Glint randomness
// depends on the surface position and the node only, never on directions.
//
// Thresholds as order statistics. The n thresholds lambda_k are i.i.d.
// uniform; instead of drawing all n of them we walk their order statistics
// from the smallest, 1 - lambda_(j+1) = (1 - lambda_(j)) V^(1/(n-j)) with V
// uniform (Renyi's representation), and stop at the first lambda_(j) >= P.
// This costs O(n P) steps instead of O(n), and the set of reflecting
// particles {k : lambda_k < P} is NESTED in P: when the view or light moves,
// P changes continuously (trilinear table lookups) and particles switch on or
// off one at a time; no bin boundary re-randomises anything (temporal
// coherence, unlike the public code that seeds by the direction bin).
// Each visited particle gets a uniform position inside its node and counts
// when it lies inside the footprint parallelogram (exact membership instead
// of Algorithm 1's fractional overlap).
#pragma once

#include <cmath>
#include <cstdint>

#include "glimmer/rng.h"

namespace glimmer::plugin::glint {

// Parallelogram c + s a + t b, |s|, |t| <= 1/2, in scaled uv units.
struct Footprint {
  double cx = 0, cy = 0;
  double ax = 0, ay = 0, bx = 0, by = 0;
  double area() const { return std::fabs(ax * by - ay * bx); }
};

// Nodes of the query level touched by the footprint's bounding box.
struct NodeRange {
  int level = 0;
  double size = 1.0;   // node side s = 2^-level
  int64_t i0 = 0, j0 = 0;
  int ni = 1, nj = 1;  // 1 or 2 each
  double covered_area() const { return ni * nj * size * size; }
};

inline NodeRange footprint_nodes(const Footprint &f) {
  const double ex = 0.5 * (std::fabs(f.ax) + std::fabs(f.bx));
  const double ey = 0.5 * (std::fabs(f.ay) + std::fabs(f.by));
  const double extent = std::fmax(2.0 * std::fmax(ex, ey), 1e-30);
  int e = 0;
  const double mant = std::frexp(extent, &e);  // extent = mant 2^e, mant in [0.5, 1)
  (void)mant;
  NodeRange r;
  r.level = -e;
  r.size = std::ldexp(1.0, e);  // >= extent
  const double inv = 1.0 / r.size;
  r.i0 = static_cast<int64_t>(std::floor((f.cx - ex) * inv));
  r.j0 = static_cast<int64_t>(std::floor((f.cy - ey) * inv));
  r.ni = static_cast<int>(static_cast<int64_t>(std::floor((f.cx + ex) * inv)) - r.i0) + 1;
  r.nj = static_cast<int>(static_cast<int64_t>(std::floor((f.cy + ey) * inv)) - r.j0) + 1;
  r.ni = r.ni < 1 ? 1 : (r.ni > 2 ? 2 : r.ni);
  r.nj = r.nj < 1 ? 1 : (r.nj > 2 ? 2 : r.nj);
  return r;
}

// Per-node random stream: the node seed comes from 8 TEA rounds, the values
// along the stream from a cheap integer hash of (seed, index).
struct NodeStream {
  uint32_t a, b;
  float operator()(uint32_t index) const { return uint_to_unit_float(hash_u32(a ^ hash_u32(b + index * 0x9e3779b9u))); }
};

inline NodeStream node_stream(uint32_t seed, int level, int64_t i, int64_t j) {
  uint32_t v0 = static_cast<uint32_t>(i) ^ static_cast<uint32_t>(static_cast<uint64_t>(i) >> 32);
  uint32_t v1 = static_cast<uint32_t>(j) ^ hash_u32(seed ^ hash_u32(static_cast<uint32_t>(level) + 0x632be5abu));
  tea<8>(v0, v1);
  return {v0, v1};
}

// Number of particles in node (level, i, j) for density N (per unit area).
inline uint64_t node_particle_count(const NodeStream &stream, double density, double size) {
  const double mean = std::fmin(density * size * size, 4.0e18);
  const double whole = std::floor(mean);
  return static_cast<uint64_t>(whole) + (stream(0) < static_cast<float>(mean - whole) ? 1u : 0u);
}

struct GlintCount {
  int count = 0;         // particles in the footprint with lambda < P
  bool complete = true;  // false when max_steps was reached (caller falls back to the mean)
};

// Counts the reflecting particles of a footprint (see the header comment).
// Each node first draws its count n and its smallest threshold lambda_(1)
// from a cheap integer hash of the node id; only when lambda_(1) < P (the node
// holds at least one reflecting particle) is the node's TEA stream started for
// the positions and the following thresholds. Most nodes stop at one hash and
// one log.
inline GlintCount count_reflecting_particles(const Footprint &f, const NodeRange &nodes, double density,
                                             uint32_t seed, double P, int max_steps) {
  GlintCount result;
  if (!(P > 0.0)) return result;
  const double det = f.ax * f.by - f.ay * f.bx;
  const double inv_det = 1.0 / det;
  const double log_one_minus_P = std::log1p(-std::fmin(P, 1.0 - 1e-16));
  const double mean = std::fmin(density * nodes.size * nodes.size, 4.0e18);
  const double whole = std::floor(mean);
  int steps = 0;
  for (int dj = 0; dj < nodes.nj; ++dj)
    for (int di = 0; di < nodes.ni; ++di) {
      const int64_t i = nodes.i0 + di, j = nodes.j0 + dj;
      const uint32_t h0 = hash_u32x4(static_cast<uint32_t>(i), static_cast<uint32_t>(j),
                                     static_cast<uint32_t>(nodes.level), seed ^ 0x3c6ef372u);
      const uint64_t n = static_cast<uint64_t>(whole) + (uint_to_unit_float(h0) < static_cast<float>(mean - whole) ? 1u : 0u);
      if (n == 0) continue;
      // lambda_(1) = 1 - V^(1/n) < P  <=>  log V > n log(1 - P).
      const double log_v1 = std::log(1.0 - static_cast<double>(uint_to_unit_float(hash_u32(h0 ^ 0x85ebca6bu))));
      if (!(log_v1 > static_cast<double>(n) * log_one_minus_P)) continue;
      const NodeStream stream = node_stream(seed, nodes.level, i, j);
      const double x0 = static_cast<double>(i) * nodes.size, y0 = static_cast<double>(j) * nodes.size;
      double one_minus_lambda = std::exp(log_v1 / static_cast<double>(n));
      for (uint64_t k = 0; k < n; ++k) {
        const uint32_t idx = static_cast<uint32_t>(3u * k + 1u);
        if (k > 0) {
          const double v = 1.0 - static_cast<double>(stream(idx));  // in (0, 1]
          // V^(1/m) = exp(-E/m), E = -log V exponential; for m > 1000 the
          // 2nd-order Taylor form has a relative error below (E/m)^3/6 < 1e-8.
          const double m = static_cast<double>(n - k);
          const double e = -std::log(v) / m;
          one_minus_lambda *= m > 1000.0 ? 1.0 - e + 0.5 * e * e : std::exp(-e);
          if (1.0 - one_minus_lambda >= P) break;
        }
        if (++steps > max_steps) {
          result.complete = false;
          return result;
        }
        const double px = x0 + nodes.size * stream(idx + 1u) - f.cx;
        const double py = y0 + nodes.size * stream(idx + 2u) - f.cy;
        const double s = (px * f.by - py * f.bx) * inv_det;
        const double t = (f.ax * py - f.ay * px) * inv_det;
        if (std::fabs(s) <= 0.5 && std::fabs(t) <= 0.5) ++result.count;
      }
    }
  return result;
}

}  // namespace glimmer::plugin::glint
