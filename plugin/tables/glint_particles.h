// Spatial and directional randomness of the separable glint model (after
// Wang et al. 2018, sec. 4.3, Algorithm 1): particles scattered over the uv
// plane, counted inside a footprint, each particle reflecting when its random
// threshold lambda is below the directional probability P(wi, wo).
//
// Direction cells (twinkle). In the exact discrete model (Jakob 2014) a
// particle is lit while its mirror direction lies within gamma of wo: the lit
// set decorrelates when wo (or wi) moves by about gamma. Here the half-vector
// plane is cut into cells of the size of a particle's lit region, and every
// cell carries its own independent particle field: a particle of cell c is
// lit when its threshold for that cell is below P. The lit region of a
// particle in the half-vector domain is an ellipse, semi-axes gamma / 2 in the
// plane of incidence and gamma / (2 wi.h) across it (the half-vector map
// r -> normalize(wi + r) has derivative (I - h h^T) / |wi + r|, foreshortened
// by wo.h = wi.h in the plane of incidence), so the cell coordinates are the
// stereographic chart of h (p = 2 (h.x, h.y) / (1 + h.z), conformal, ~ the
// polar angle near the normal) compressed by wi.h across the plane of
// incidence and divided by kCellSize gamma / 2; the compression vanishes at
// wi.h = 1, so it is continuous where the plane of incidence is undefined.
// kDirectionGroups groups of particles (density N / G each) use grids
// shifted by a fraction of a cell, so crossing a cell border renews 1/G of
// the glints, not all of them. Everything is a pure function of (uv, wi, wo):
// no temporal noise.
//
// Particle field. The (scaled) uv plane is cut into square nodes of side
// s = 2^-l. Node (l, i, j) holds n = floor(N s^2) + [u0 < frac(N s^2)]
// particles (mean exactly N s^2). The particles live at ONE level per
// material, the particle level l* whose nodes hold kNodeParticles / 4 ..
// kNodeParticles particles per group, so a footprint counts the same particles
// whatever its size (zoom and resolution keep the glints; counts grow
// monotonically with nested footprints). A footprint is counted over the
// nodes of that level it overlaps, found by rasterising the parallelogram row
// by row (a long thin footprint touches O(length) nodes, not its bounding
// box). Footprints overlapping more than kMaxNodes nodes fall back to a
// coarser level whose node side is >= the footprint's bounding box (at most
// 2 x 2 nodes, an independent field per level: Wang's Algorithm 1); with the
// default filter_threshold these footprints hold thousands of particles and
// are filtered anyway. The count and the smallest threshold of a node come from
// an integer hash of the node id and the cell seed; every later random number
// (positions, further thresholds) from the node's TEA seed (8 rounds), started
// only for nodes that hold a reflecting particle.
//
// Thresholds as order statistics. The n thresholds lambda_k are i.i.d.
// uniform; instead of drawing all n of them we walk their order statistics
// from the smallest, 1 - lambda_(j+1) = (1 - lambda_(j)) V^(1/(n-j)) with V
// uniform (Renyi's representation), and stop at the first lambda_(j) >= P.
// This costs O(n P) steps instead of O(n); inside one direction cell the set
// of reflecting particles is nested in P (no flicker from the trilinear table
// lookups). Each visited particle gets a uniform position inside its node and
// counts when it lies inside the footprint parallelogram (exact membership
// instead of Algorithm 1's fractional overlap).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>

#include "glimmer/math.h"
#include "glimmer/rng.h"

namespace glimmer::plugin::glint {

// Parallelogram c + s a + t b, |s|, |t| <= 1/2, in scaled uv units.
struct Footprint {
  double cx = 0, cy = 0;
  double ax = 0, ay = 0, bx = 0, by = 0;
  double area() const { return std::fabs(ax * by - ay * bx); }
};

// The nodes a footprint is counted over (at most kMaxNodes).
inline constexpr int kMaxNodes = 64;
struct NodeList {
  int level = 0;
  double size = 1.0;  // node side s = 2^-level
  int count = 0;
  std::array<int64_t, kMaxNodes> i{}, j{};
  bool add(int64_t ni, int64_t nj) {
    if (count == kMaxNodes) return false;
    i[count] = ni;
    j[count] = nj;
    ++count;
    return true;
  }
};

// Nodes of the particle level hold kNodeParticles / 4 .. kNodeParticles
// particles per group on average.
inline constexpr double kNodeParticles = 128.0;

// The particle level l* for density N (per unit area): the largest node side
// 2^-l* with N s^2 <= kNodeParticles.
inline int particle_level(double density) {
  int e = 0;
  std::frexp(std::sqrt(kNodeParticles / std::fmax(density, 1e-30)), &e);  // value = mant 2^e, mant in [0.5, 1)
  return 1 - e;  // 2^(e-1) <= value
}

// x extent of the footprint parallelogram inside the band y0 <= y <= y1
// (its four corners clipped to the band, Sutherland-Hodgman); false when the
// band misses it.
inline bool footprint_x_range_in_band(const Footprint &f, double y0, double y1, double &x_min, double &x_max) {
  const double cx[4] = {f.cx - 0.5 * f.ax - 0.5 * f.bx, f.cx + 0.5 * f.ax - 0.5 * f.bx, f.cx + 0.5 * f.ax + 0.5 * f.bx,
                        f.cx - 0.5 * f.ax + 0.5 * f.bx};
  const double cy[4] = {f.cy - 0.5 * f.ay - 0.5 * f.by, f.cy + 0.5 * f.ay - 0.5 * f.by, f.cy + 0.5 * f.ay + 0.5 * f.by,
                        f.cy - 0.5 * f.ay + 0.5 * f.by};
  x_min = 1e300, x_max = -1e300;
  for (int k = 0; k < 4; ++k) {
    const double ax = cx[k], ay = cy[k], bx = cx[(k + 1) % 4], by = cy[(k + 1) % 4];
    if (ay >= y0 && ay <= y1) x_min = std::fmin(x_min, ax), x_max = std::fmax(x_max, ax);
    for (const double yc : {y0, y1})  // edge crossings of the band's borders
      if ((ay - yc) * (by - yc) < 0.0) {
        const double x = ax + (bx - ax) * (yc - ay) / (by - ay);
        x_min = std::fmin(x_min, x), x_max = std::fmax(x_max, x);
      }
  }
  return x_min <= x_max;
}

// The nodes of `level` the footprint overlaps, row by row (the parallelogram
// rasterised, not its bounding box); false when there are more than kMaxNodes.
inline bool nodes_at_level(const Footprint &f, int level, NodeList &list) {
  list = NodeList{};
  list.level = level;
  list.size = std::ldexp(1.0, -level);
  const double inv = 1.0 / list.size;
  const double ey = 0.5 * (std::fabs(f.ay) + std::fabs(f.by));
  const auto j0 = static_cast<int64_t>(std::floor((f.cy - ey) * inv));
  const auto j1 = static_cast<int64_t>(std::floor((f.cy + ey) * inv));
  if (j1 - j0 >= kMaxNodes) return false;
  for (int64_t j = j0; j <= j1; ++j) {
    double x_min, x_max;
    const double y0 = static_cast<double>(j) * list.size;
    if (!footprint_x_range_in_band(f, y0, y0 + list.size, x_min, x_max)) continue;
    const auto i0 = static_cast<int64_t>(std::floor(x_min * inv));
    const auto i1 = static_cast<int64_t>(std::floor(x_max * inv));
    if (i1 - i0 >= kMaxNodes) return false;
    for (int64_t i = i0; i <= i1; ++i)
      if (!list.add(i, j)) return false;
  }
  return true;
}

// The nodes a footprint is counted over: those of the particle level it
// overlaps, or, when there are more than kMaxNodes of them, the (at most
// 2 x 2) nodes of the level whose node side is >= the footprint's bounding box.
inline NodeList footprint_nodes(const Footprint &f, double density) {
  NodeList list;
  if (nodes_at_level(f, particle_level(density), list)) return list;
  const double ex = 0.5 * (std::fabs(f.ax) + std::fabs(f.bx));
  const double ey = 0.5 * (std::fabs(f.ay) + std::fabs(f.by));
  int e = 0;
  std::frexp(std::fmax(2.0 * std::fmax(ex, ey), 1e-30), &e);  // extent <= 2^e
  nodes_at_level(f, -e, list);
  return list;
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

// ---- Direction cells (see the header comment) ------------------------------
inline constexpr int kDirectionGroups = 4;
// Cell side in units of gamma / 2 (the lit region's in-plane semi-axis).
// Chosen by measurement (docs/glints.md): the correlation of the lit counts
// between directions gamma apart matches the exact model's (~0.4), and one
// cell covers about one cone of reflected directions (c^2 / pi ~ 1), so the
// per-footprint albedo varies like the exact model's.
inline constexpr float kCellSize = 1.75f;
// Grid shifts of the groups, in cells (a 4-point lattice).
inline constexpr std::array<std::array<float, 2>, kDirectionGroups> kGroupShift = {
    {{0.0f, 0.0f}, {0.5f, 0.25f}, {0.25f, 0.75f}, {0.75f, 0.5f}}};

// Seed of the particle field of each group's direction cell at (wi, wo);
// false when there is no half vector above the surface.
inline bool direction_cell_seeds(uint32_t seed, const Vec3 &wi, const Vec3 &wo, float gamma_rad,
                                 std::array<uint32_t, kDirectionGroups> &seeds) {
  const Vec3 sum = wi + wo;
  const float len = length(sum);
  if (!(len > 1e-6f)) return false;
  const Vec3 h = sum / len;
  if (!(h.z > 0.0f)) return false;
  // Stereographic chart of h.
  const float k = 2.0f / (1.0f + h.z);
  float px = k * h.x, py = k * h.y;
  // Compress by wi.h across the plane of incidence: n = wi x h (tangent at h),
  // its chart direction e = k (n.xy - n.z / (1 + h.z) h.xy).
  const float wi_h = dot(wi, h);
  const Vec3 n = cross(wi, h);
  float ex = n.x - n.z / (1.0f + h.z) * h.x, ey = n.y - n.z / (1.0f + h.z) * h.y;
  const float e_len = std::sqrt(ex * ex + ey * ey);
  if (e_len > 1e-12f) {
    ex /= e_len, ey /= e_len;
    const float along = (wi_h - 1.0f) * (px * ex + py * ey);
    px += along * ex;
    py += along * ey;
  }
  const float inv_cell = 2.0f / (kCellSize * gamma_rad);
  for (int g = 0; g < kDirectionGroups; ++g) {
    const auto cx = static_cast<int32_t>(std::floor(px * inv_cell + kGroupShift[g][0]));
    const auto cy = static_cast<int32_t>(std::floor(py * inv_cell + kGroupShift[g][1]));
    seeds[g] = hash_u32x4(seed, static_cast<uint32_t>(g), static_cast<uint32_t>(cx), static_cast<uint32_t>(cy));
  }
  return true;
}

struct GlintCount {
  int count = 0;         // particles in the footprint with lambda < P
  int steps = 0;         // particles visited
  bool complete = true;  // false when max_steps was reached (caller falls back to the mean)
};

// Counts the reflecting particles of a footprint (see the header comment).
// Each node first draws its count n and its smallest threshold lambda_(1)
// from a cheap integer hash of the node id; only when lambda_(1) < P (the node
// holds at least one reflecting particle) is the node's TEA stream started for
// the positions and the following thresholds. Most nodes stop at one hash and
// one log.
inline GlintCount count_reflecting_particles(const Footprint &f, const NodeList &nodes, double density,
                                             uint32_t seed, double P, int max_steps) {
  GlintCount result;
  if (!(P > 0.0)) return result;
  const double det = f.ax * f.by - f.ay * f.bx;
  const double inv_det = 1.0 / det;
  const double log_one_minus_P = std::log1p(-std::fmin(P, 1.0 - 1e-16));
  const double mean = std::fmin(density * nodes.size * nodes.size, 4.0e18);
  const double whole = std::floor(mean);
  // A node of n particles holds a reflecting one when lambda_(1) = 1 - V^(1/n)
  // < P, i.e. V > (1 - P)^n: one hash and one compare per node (n is whole
  // or whole + 1).
  const double v_min_whole = std::exp(whole * log_one_minus_P);
  const double v_min_plus = std::exp((whole + 1.0) * log_one_minus_P);
  int &steps = result.steps;
  for (int node = 0; node < nodes.count; ++node) {
      const int64_t i = nodes.i[node], j = nodes.j[node];
      const uint32_t h0 = hash_u32x4(static_cast<uint32_t>(i), static_cast<uint32_t>(j),
                                     static_cast<uint32_t>(nodes.level), seed ^ 0x3c6ef372u);
      const uint64_t n = static_cast<uint64_t>(whole) + (uint_to_unit_float(h0) < static_cast<float>(mean - whole) ? 1u : 0u);
      if (n == 0) continue;
      const double v1 = 1.0 - static_cast<double>(uint_to_unit_float(hash_u32(h0 ^ 0x85ebca6bu)));  // (0, 1]
      if (!(v1 > (static_cast<double>(n) > whole ? v_min_plus : v_min_whole))) continue;
      const double log_v1 = std::log(v1);
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

// Reflecting particles of a footprint over the kDirectionGroups groups
// (density N / G each), each group counted in its own direction cell at
// (wi, wo); the caller falls back to the mean when `complete` is false.
inline GlintCount count_glints(const Footprint &f, double density, uint32_t seed, const Vec3 &wi, const Vec3 &wo,
                               float gamma_rad, double P, int max_steps) {
  GlintCount total;
  std::array<uint32_t, kDirectionGroups> cell_seeds;
  if (!direction_cell_seeds(seed, wi, wo, gamma_rad, cell_seeds)) return total;
  const double group_density = density / kDirectionGroups;
  const NodeList nodes = footprint_nodes(f, group_density);
  for (uint32_t cell_seed : cell_seeds) {
    const GlintCount k = count_reflecting_particles(f, nodes, group_density, cell_seed, P, max_steps - total.steps);
    total.count += k.count;
    total.steps += k.steps;
    if (!k.complete) {
      total.complete = false;
      break;
    }
  }
  return total;
}

}  // namespace glimmer::plugin::glint
