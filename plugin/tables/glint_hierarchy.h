// The 4D particle hierarchy of Jakob, Hasan, Yan, Lawrence, Ramamoorthi,
// Marschner 2014, "Discrete Stochastic Microfacet Models" (sec. 4-5): the
// exact discrete model behind the reference closure glint_jakob14, shared
// with the tests that enumerate every particle by brute force.
//
// Particles live in a 4D domain: position x in the (scaled) uv plane and a
// direction code (u, v) in [0,1]^2 that the sampling warp of D(m) cos(theta_m)
// maps to the particle normal (GGX: tan^2 theta = alpha^2 u / (1 - u);
// Beckmann: tan^2 theta = -alpha^2 log(1 - u); phi = 2 pi v), so uniform codes
// give normals distributed exactly as D cos (Jakob 2014 sec. 4).
//
// The particle set (a pure function of the seed): every unit uv cell holds
// floor(N) + [u < frac(N)] particles (TEA-seeded by the cell); a node is split
// in half along x, y, u, v in turn, the left child receiving
// Binomial(n, 1/2) particles: exact (popcount of n random bits) for n <= 512,
// Gaussian N(n/2, n/4) rounded above, seeded by the node id (TEA of the
// parent's id and the child index). Nodes with <= 8 particles (or at depth
// 200) are leaves whose particles are drawn explicitly, position and code
// uniform in the node. `root`, `split`, `is_leaf` and `leaf_particle` define
// the set; `count` is the pruned query (Jakob 2014 sec. 5).
//
// Query: count K of particles inside the footprint parallelogram A whose
// mirror reflection of wi lies in the cone of half-angle gamma around wo.
// Nodes are pruned by exact box/parallelogram tests in uv and by the exact
// angular distance from h = normalize(wi + wo) to the node's (theta, phi)
// rectangle against R_out = gamma / (2 wi.h - gamma) (the half-vector map
// r -> normalize(wi + r) is 1 / |wi + r|-Lipschitz); a node inside A whose
// normals all lie within gamma / 2 of h (reflection is 2-Lipschitz) counts
// all its particles without descending. Leaves test each particle exactly.
// All query geometry is in double precision so the pruning margins (1e-4
// relative) dominate rounding.
#pragma once

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>

#include "glimmer/math.h"
#include "glimmer/microfacet.h"
#include "glimmer/rng.h"
#include "tables/glint_particles.h"

namespace glimmer::plugin::glint {

// How angular_range measures a node's azimuth interval [p0, p1] (p0 >= 0)
// against phi_h in (-pi, pi]. Periodic is the model. SignedLegacy is the
// former wrap to (-pi, pi], which pruned every half vector with azimuth in
// (-pi, 0) from nodes not yet split in azimuth; it exists only so the
// brute-force test can show that it fails (negative control).
enum class AzimuthWrap { Periodic, SignedLegacy };

struct HierarchyNode {
  double x0, x1, y0, y1;  // uv box (scaled uv)
  double u0, u1, v0, v1;  // direction-code box
  uint64_t count;
  uint32_t id_a, id_b;    // TEA-derived node id
  int depth;
};

// One particle: position (x, y) in scaled uv, direction code (u, v).
struct HierarchyParticle {
  double x, y, u, v;
};

struct Vec3d {
  double x, y, z;
};
inline double dot3(const Vec3d &a, const Vec3d &b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

// One count query: footprint, directions and the derived pruning radii.
struct ParticleQuery {
  Footprint fp;
  double inv_det = 0.0;
  Vec3d wi{}, wo{}, h{};
  double theta_h = 0.0, phi_h = 0.0;
  double cos_gamma = 1.0;
  double r_out = M_PI, r_in = 0.0;
  double theta_ih = 0.0;  // angle between wi and h
  bool valid = false;     // false when wi + wo vanishes (no half vector)

  static ParticleQuery make(const Footprint &fp, const Vec3 &wi_f, const Vec3 &wo_f, double gamma) {
    ParticleQuery q;
    q.fp = fp;
    q.inv_det = 1.0 / (fp.ax * fp.by - fp.ay * fp.bx);
    q.wi = {wi_f.x, wi_f.y, wi_f.z};
    q.wo = {wo_f.x, wo_f.y, wo_f.z};
    const Vec3d s{q.wi.x + q.wo.x, q.wi.y + q.wo.y, q.wi.z + q.wo.z};
    const double len = std::sqrt(dot3(s, s));
    if (!(len > 1e-12)) return q;
    q.h = {s.x / len, s.y / len, s.z / len};
    q.theta_h = std::acos(std::clamp(q.h.z, -1.0, 1.0));
    q.phi_h = std::atan2(q.h.y, q.h.x);
    q.cos_gamma = std::cos(gamma);
    const double wi_h = dot3(q.wi, q.h);
    const double denom = 2.0 * wi_h - gamma;
    q.r_out = denom > 0.0 ? std::min(M_PI, 1.0001 * gamma / denom + 1e-9) : M_PI;
    q.r_in = 0.4999 * gamma;
    q.theta_ih = std::acos(std::clamp(wi_h, -1.0, 1.0));
    q.valid = true;
    return q;
  }

  bool inside_footprint(double x, double y) const {
    const double px = x - fp.cx, py = y - fp.cy;
    const double s = (px * fp.by - py * fp.bx) * inv_det;
    const double t = (fp.ax * py - fp.ay * px) * inv_det;
    return std::fabs(s) <= 0.5 && std::fabs(t) <= 0.5;
  }
};

// What a count did (for tests: every pruning branch must be exercised).
struct HierarchyCount {
  uint64_t count = 0;
  uint64_t nodes_visited = 0;
  uint64_t angular_prunes = 0;  // nodes discarded by d_min > R_out
  uint64_t whole_nodes = 0;     // nodes counted whole (inside A, all normals within gamma / 2)
  uint64_t leaves = 0;          // leaves whose particles were tested one by one
  bool budget_reached = false;  // the remainder was counted by its expectation
};

class ParticleHierarchy {
 public:
  static constexpr uint64_t kLeafSize = 8;
  static constexpr int kMaxDepth = 200;
  // Cost bound: after this many visited nodes the remaining ones are counted
  // by their expectation (only reached for absurd particle counts, e.g.
  // 1e12 per unit area under footprints of many units; never in tests).
  static constexpr uint64_t kNodeBudget = 20000;
  // Footprints whose bounding box covers more unit cells are not counted (0).
  static constexpr int64_t kMaxCells = 4096;

  ParticleHierarchy() = default;
  ParticleHierarchy(microfacet::Distribution distribution, double alpha, double density, uint32_t seed)
      : distribution_(distribution), alpha_(alpha), density_(density), seed_(seed) {}

  // ---- The particle set ---------------------------------------------------
  HierarchyNode root(int64_t i, int64_t j) const {
    const NodeStream s = node_stream(seed_ ^ 0x5bd1e995u, 0, i, j);
    return {static_cast<double>(i), static_cast<double>(i + 1), static_cast<double>(j), static_cast<double>(j + 1),
            0.0, 1.0, 0.0, 1.0, node_particle_count(s, density_, 1.0), s.a, s.b, 0};
  }

  static bool is_leaf(const HierarchyNode &n) { return n.count <= kLeafSize || n.depth >= kMaxDepth; }

  // Children of a non-leaf node: halves along x, y, u, v in turn.
  static void split(const HierarchyNode &n, HierarchyNode &a, HierarchyNode &b) {
    const uint64_t left = split_count(n.count, n.id_a, n.id_b);
    a = n;
    b = n;
    a.count = left;
    b.count = n.count - left;
    a.depth = b.depth = n.depth + 1;
    uint32_t a0 = n.id_a, a1 = n.id_b ^ 1u, b0 = n.id_a, b1 = n.id_b ^ 2u;
    tea<8>(a0, a1);
    tea<8>(b0, b1);
    a.id_a = a0, a.id_b = a1, b.id_a = b0, b.id_b = b1;
    switch (n.depth % 4) {
      case 0: a.x1 = b.x0 = 0.5 * (n.x0 + n.x1); break;
      case 1: a.y1 = b.y0 = 0.5 * (n.y0 + n.y1); break;
      case 2: a.u1 = b.u0 = 0.5 * (n.u0 + n.u1); break;
      default: a.v1 = b.v0 = 0.5 * (n.v0 + n.v1); break;
    }
  }

  // Particle p < n.count of a leaf.
  static HierarchyParticle leaf_particle(const HierarchyNode &n, uint32_t p) {
    const NodeStream ps{n.id_a, n.id_b};
    return {n.x0 + (n.x1 - n.x0) * ps(4 * p + 1), n.y0 + (n.y1 - n.y0) * ps(4 * p + 2),
            n.u0 + (n.u1 - n.u0) * ps(4 * p + 3), n.v0 + (n.v1 - n.v0) * ps(4 * p + 4)};
  }

  // Unit cells touched by the footprint's bounding box; false when there are
  // more than kMaxCells of them.
  static bool unit_cells(const Footprint &f, int64_t &i0, int64_t &i1, int64_t &j0, int64_t &j1) {
    const double ex = 0.5 * (std::fabs(f.ax) + std::fabs(f.bx)), ey = 0.5 * (std::fabs(f.ay) + std::fabs(f.by));
    i0 = static_cast<int64_t>(std::floor(f.cx - ex)), i1 = static_cast<int64_t>(std::floor(f.cx + ex));
    j0 = static_cast<int64_t>(std::floor(f.cy - ey)), j1 = static_cast<int64_t>(std::floor(f.cy + ey));
    return (i1 - i0 + 1) * (j1 - j0 + 1) <= kMaxCells;
  }

  // Polar angle of the normal for direction code u (monotone in u).
  double code_theta(double u) const {
    u = std::clamp(u, 0.0, 1.0);
    if (u >= 1.0) return 0.5 * M_PI;
    const double a2 = alpha_ * alpha_;
    const double tan2 = distribution_ == microfacet::Distribution::GGX ? a2 * u / (1.0 - u) : -a2 * std::log1p(-u);
    return std::atan(std::sqrt(std::max(tan2, 0.0)));
  }

  // Does a particle with direction code (u, v) reflect wi into the cone?
  bool reflects(const ParticleQuery &q, double u, double v) const {
    const double theta = code_theta(u), phi = 2.0 * M_PI * v;
    const Vec3d m{std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
    const double wi_m = dot3(q.wi, m);
    if (!(wi_m > 0.0)) return false;
    const Vec3d r{2.0 * wi_m * m.x - q.wi.x, 2.0 * wi_m * m.y - q.wi.y, 2.0 * wi_m * m.z - q.wi.z};
    return dot3(r, q.wo) > q.cos_gamma;
  }

  // ---- The pruned query ----------------------------------------------------
  // Exact min / max angular distance from h to the (theta, phi) rectangle of a node.
  void angular_range(const ParticleQuery &q, const HierarchyNode &n, AzimuthWrap wrap_mode, double &d_min,
                     double &d_max) const {
    const double t0 = code_theta(n.u0), t1 = code_theta(n.u1);
    const double p0 = 2.0 * M_PI * n.v0, width = 2.0 * M_PI * (n.v1 - n.v0);
    // Offset of an azimuth a from the interval start, in [0, 2 pi).
    auto offset = [p0](double a) {
      double d = std::fmod(a - p0, 2.0 * M_PI);
      return d < 0.0 ? d + 2.0 * M_PI : d;
    };
    // Angular distance |a| folded to [0, pi].
    auto fold = [](double a) {
      a = std::fmod(std::fabs(a), 2.0 * M_PI);
      return a > M_PI ? 2.0 * M_PI - a : a;
    };
    const double d0 = fold(q.phi_h - p0), d1 = fold(q.phi_h - (p0 + width));
    bool inside_phi, anti_inside;
    if (wrap_mode == AzimuthWrap::Periodic) {
      inside_phi = offset(q.phi_h) <= width;
      anti_inside = offset(q.phi_h + M_PI) <= width;
    } else {  // legacy: signed offsets in (-pi, pi], negative ones never inside
      auto wrap = [](double a) {
        a = std::fmod(a + M_PI, 2.0 * M_PI);
        if (a < 0) a += 2.0 * M_PI;
        return a - M_PI;
      };
      const double w = wrap(q.phi_h - p0), anti = wrap(q.phi_h + M_PI - p0);
      inside_phi = w >= 0.0 && w <= width;
      anti_inside = anti >= 0.0 && anti <= width;
    }
    const double near_dphi = inside_phi ? 0.0 : std::min(d0, d1);
    // Farthest azimuth: the point of the interval farthest from phi_h (the antipode if inside).
    const double far_dphi = anti_inside ? M_PI : std::max(d0, d1);
    const double st = std::sin(q.theta_h), ct = std::cos(q.theta_h);
    auto cos_dist = [&](double theta, double dphi) {
      return std::sin(theta) * st * std::cos(dphi) + std::cos(theta) * ct;
    };
    // Max of cos over theta at the nearest azimuth: theta* clamped to [t0, t1].
    const double theta_star = std::atan2(st * std::cos(near_dphi), ct);
    const double tc = std::clamp(theta_star, t0, t1);
    d_min = std::acos(std::clamp(cos_dist(tc, near_dphi), -1.0, 1.0));
    const double c_far = std::min(cos_dist(t0, far_dphi), cos_dist(t1, far_dphi));
    d_max = std::acos(std::clamp(c_far, -1.0, 1.0));
  }

  // Separating-axis test of a uv box against the footprint parallelogram.
  static bool box_overlaps(const ParticleQuery &q, const HierarchyNode &n) {
    const Footprint &f = q.fp;
    const double ex = 0.5 * (std::fabs(f.ax) + std::fabs(f.bx)), ey = 0.5 * (std::fabs(f.ay) + std::fabs(f.by));
    if (n.x1 < f.cx - ex || n.x0 > f.cx + ex || n.y1 < f.cy - ey || n.y0 > f.cy + ey) return false;
    const double axes[2][2] = {{-f.ay, f.ax}, {-f.by, f.bx}};  // normals of the parallelogram edges
    const double cx = 0.5 * (n.x0 + n.x1) - f.cx, cy = 0.5 * (n.y0 + n.y1) - f.cy;
    const double hx = 0.5 * (n.x1 - n.x0), hy = 0.5 * (n.y1 - n.y0);
    for (const auto &a : axes) {
      const double box_r = hx * std::fabs(a[0]) + hy * std::fabs(a[1]);
      const double par_r = 0.5 * (std::fabs(a[0] * f.ax + a[1] * f.ay) + std::fabs(a[0] * f.bx + a[1] * f.by));
      if (std::fabs(cx * a[0] + cy * a[1]) > box_r + par_r) return false;
    }
    return true;
  }

  static bool box_inside(const ParticleQuery &q, const HierarchyNode &n) {
    return q.inside_footprint(n.x0, n.y0) && q.inside_footprint(n.x1, n.y0) && q.inside_footprint(n.x0, n.y1) &&
           q.inside_footprint(n.x1, n.y1);
  }

  HierarchyCount count(const ParticleQuery &q, AzimuthWrap wrap_mode = AzimuthWrap::Periodic) const {
    HierarchyCount result;
    int64_t i0, i1, j0, j1;
    if (!q.valid || !unit_cells(q.fp, i0, i1, j0, j1)) return result;
    // Depth-first: the stack never holds more than kMaxDepth + 2 nodes.
    std::array<HierarchyNode, kMaxDepth + 2> stack;
    for (int64_t j = j0; j <= j1; ++j)
      for (int64_t i = i0; i <= i1; ++i) {
        size_t top = 0;
        stack[top++] = root(i, j);
        while (top > 0) {
          const HierarchyNode n = stack[--top];
          if (n.count == 0 || !box_overlaps(q, n)) continue;
          if (++result.nodes_visited > kNodeBudget) {
            result.budget_reached = true;
            result.count += expected_count(q, n);
            continue;
          }
          double d_min, d_max;
          angular_range(q, n, wrap_mode, d_min, d_max);
          if (d_min > q.r_out) {
            ++result.angular_prunes;
            continue;
          }
          if (box_inside(q, n) && d_max < q.r_in && q.theta_ih + d_max < 0.5 * M_PI) {
            ++result.whole_nodes;
            result.count += n.count;
            continue;
          }
          if (is_leaf(n)) {
            ++result.leaves;
            for (uint32_t p = 0; p < n.count; ++p) {
              const HierarchyParticle particle = leaf_particle(n, p);
              if (q.inside_footprint(particle.x, particle.y) && reflects(q, particle.u, particle.v)) ++result.count;
            }
            continue;
          }
          split(n, stack[top], stack[top + 1]);
          top += 2;
        }
      }
    return result;
  }

 private:
  // Binomial(n, 1/2) from the node's random stream.
  static uint64_t split_count(uint64_t n, uint32_t a, uint32_t b) {
    if (n <= 512) {
      uint64_t c = 0;
      for (uint64_t w = 0; w * 32 < n; ++w) {
        uint32_t bits = hash_u32(a ^ hash_u32(b + static_cast<uint32_t>(w) * 0x9e3779b9u));
        const uint64_t left = n - w * 32;
        if (left < 32) bits &= (1u << left) - 1u;
        c += static_cast<uint64_t>(std::popcount(bits));
      }
      return c;
    }
    // Gaussian approximation (Box-Muller), rounded and clamped.
    const double u1 = (uint_to_unit_float(hash_u32(a + 0x68bc21ebu)) + 0.5 / 16777216.0);
    const double u2 = uint_to_unit_float(hash_u32(b ^ 0x02e5be93u));
    const double z = std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
    const double c = std::floor(0.5 * static_cast<double>(n) + 0.5 * std::sqrt(static_cast<double>(n)) * z + 0.5);
    return static_cast<uint64_t>(std::clamp(c, 0.0, static_cast<double>(n)));
  }

  // Expectation of a node's count (8 x 8 stratified points in uv and in the
  // direction code), rounded: the bounded-cost fallback.
  uint64_t expected_count(const ParticleQuery &q, const HierarchyNode &n) const {
    int in_uv = 0, in_dir = 0;
    for (int a = 0; a < 8; ++a)
      for (int b = 0; b < 8; ++b) {
        const double fa = (a + 0.5) / 8.0, fb = (b + 0.5) / 8.0;
        in_uv += q.inside_footprint(n.x0 + (n.x1 - n.x0) * fa, n.y0 + (n.y1 - n.y0) * fb);
        in_dir += reflects(q, n.u0 + (n.u1 - n.u0) * fa, n.v0 + (n.v1 - n.v0) * fb);
      }
    return static_cast<uint64_t>(std::floor(static_cast<double>(n.count) * in_uv * in_dir / 4096.0 + 0.5));
  }

  microfacet::Distribution distribution_ = microfacet::Distribution::GGX;
  double alpha_ = 0.16;
  double density_ = 1e6;
  uint32_t seed_ = 0;
};

}  // namespace glimmer::plugin::glint
