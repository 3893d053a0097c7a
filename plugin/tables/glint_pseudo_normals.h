// Per-particle pseudo-normals for lobes narrower than the glint cone (issue
// 10, fifteenth session; docs/glints.md "Pseudo-normals for lobes narrower than the cone").
//
// The exact discrete model (Jakob 2014) gives every particle its own normal
// m ~ D(m) cos(theta_m) and lights it for (wi, wo) iff its mirror direction
// r = 2 (wi.m) m - wi lies within gamma of wo. The direction cells of
// glint_particles.h light a particle when its threshold is below P: within a
// cell the lit sets of all directions are nested, which where the lobe is
// narrower than the cone keeps the lit sets of cones 2 gamma apart
// correlated (they are disjoint in the exact model) and cones gamma apart too
// little correlated (docs/glints.md, "The albedo CV estimator, and the lit
// correlation at gamma for narrow lobes"). Here the exact model is reproduced locally:
//
// - the normals' chart is the stereographic chart of m (p = 2 m.xy / (1 +
//   m.z), independent of wi and wo), cut into square tiles of side T;
// - node n (the particle level of density N, glint_particles.h) x tile t
//   holds K ~ Poisson(N s^2 g_t T^2) candidate particles, g_t the largest
//   normal density in the chart over the tile (D cos / (1 + |p|^2/4)^2,
//   decreasing in |p| for the lobes this runs on), each with its own
//   position in the node and its own chart point in the tile (hashes of the
//   node's hash in the tile), kept with probability g(p) / g_t (thinning:
//   the kept particles are a Poisson process of density N D cos exactly);
// - a query visits the tiles that can hold a normal whose mirror direction
//   is in the cone (a box around the lit region's ellipse in the chart,
//   semi-axes gamma / 2 and gamma / (2 wi.h) in m, with a margin) and counts
//   the kept particles inside the footprint whose r is in the cone: E[K] =
//   N a P with P the exact lobe mass in the cone, and the lit sets of two
//   directions overlap as the exact model's do.
//
// Everything is a pure function of (uv, wi, wo) and the material's seed.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>

#include "glimmer/math.h"
#include "glimmer/microfacet.h"
#include "glimmer/rng.h"
#include "tables/glint_particles.h"

namespace glimmer::plugin::glint {

// The pseudo-normal counting runs when the lobe (alpha, radians) is at most
// kPseudoNormalLobeRatio times the cone (gamma, radians) wide: GGX
// roughness <= 0.229 at gamma 2 degrees (0.2 is the statistics grid's narrow
// row; 0.3 keeps the direction cells).
inline constexpr float kPseudoNormalLobeRatio = 1.5f;
inline bool uses_pseudo_normals(float alpha, float gamma_rad) { return alpha <= kPseudoNormalLobeRatio * gamma_rad; }

struct PseudoNormalField {
  static constexpr float kTileInGamma = 1.0f;  // tile side T in the chart, in units of gamma
  static constexpr float kMargin = 1.1f;       // on the lit region's first-order semi-axes
  static constexpr int kMaxTiles = 192;        // beyond (wi.h below ~0.02, grazing): not used, the caller uses the cells
  microfacet::Distribution dist = microfacet::Distribution::GGX;
  float alpha = 0.04f;
  float gamma_rad = 0.0349f;
  float cos_gamma = 0.99939f;
  float tile = 0.01745f;  // T
  uint32_t key = 0;
  PseudoNormalField() = default;
  PseudoNormalField(microfacet::Distribution d, float a, float g, uint32_t seed)
      : dist(d), alpha(a), gamma_rad(g), cos_gamma(std::cos(g)), tile(kTileInGamma * g),
        key(hash_u32x2(seed, 0x6e6f726du)) {}

  // Normal density per unit chart area at chart point p: D(m) m.z times
  // the area element of the stereographic chart, 1 / (1 + t2)^2 with t2 =
  // |p|^2 / 4 = tan^2(theta_m / 2), in closed form in t2 (cos = (1 - t2) /
  // (1 + t2), tan^2 = 4 t2 / (1 - t2)^2): GGX alpha^2 (1 - t2^2) / (pi Q^2),
  // Q = alpha^2 (1 - t2)^2 + 4 t2; Beckmann exp(-4 t2 / (alpha^2 (1 -
  // t2)^2)) (1 + t2) / (pi alpha^2 (1 - t2)^3). 0 below the horizon (t2 >= 1).
  float chart_density_t2(float t2) const {
    if (!(t2 < 1.0f)) return 0.0f;
    const float a2 = alpha * alpha, c = 1.0f - t2;
    if (dist == microfacet::Distribution::GGX) {
      const float q = a2 * c * c + 4.0f * t2;
      return a2 * c * (1.0f + t2) * (1.0f / 3.14159265f) / (q * q);
    }
    return std::exp(-4.0f * t2 / (a2 * c * c)) * (1.0f + t2) * (1.0f / 3.14159265f) / (a2 * c * c * c);
  }
  float chart_density(float px, float py) const { return chart_density_t2(0.25f * (px * px + py * py)); }
  // The normal at chart point p (inverse stereographic chart).
  static Vec3 chart_normal(float px, float py) {
    const float t2 = 0.25f * (px * px + py * py);
    const float inv = 1.0f / (1.0f + t2);
    return Vec3(px * inv, py * inv, (1.0f - t2) * inv);
  }
  // One hash per tile (the seed of its particles; key + tx W + ty W').
  uint32_t tile_seed(int32_t tx, int32_t ty) const {
    return mix_u32(key + static_cast<uint32_t>(tx) * kNodeKeyStep + static_cast<uint32_t>(ty) * 0x85ebca6bu);
  }
};

// Chart point of lit particle k's normal in its tile, from the node x tile
// hash h0 (16-bit uniforms in x, y) and the thinning uniform.
inline constexpr uint32_t kNormalKey = 0x165667b1u;
struct PseudoNormalDraw {
  float ux, uy, w;
};
// The uniforms one at a time (the reflection-first order draws the thinning
// uniform only for candidates that reflect into the cone).
inline uint32_t pseudo_normal_key(uint32_t h0, uint32_t k) { return (h0 ^ kNormalKey) + (2u * k + 1u) * kNodeKeyStep; }
inline std::array<float, 2> pseudo_normal_chart_uniforms(uint32_t key) {
  const uint32_t a = mix_u32(key);
  return {(static_cast<float>(a & 0xffffu) + 0.5f) * (1.0f / 65536.0f), (static_cast<float>(a >> 16) + 0.5f) * (1.0f / 65536.0f)};
}
inline float pseudo_normal_thinning_uniform(uint32_t key) { return uint_to_unit_float(mix_u32(key + kNodeKeyStep)); }
inline PseudoNormalDraw pseudo_normal_draw(uint32_t h0, uint32_t k) {
  const uint32_t key = pseudo_normal_key(h0, k);
  const auto [ux, uy] = pseudo_normal_chart_uniforms(key);
  return {ux, uy, pseudo_normal_thinning_uniform(key)};
}
// Whether the pseudo-normal at chart point (mx, my) reflects wi into the cone
// of half-angle gamma around wo.
[[gnu::always_inline]] inline bool pseudo_normal_reflects_into_cone(float mx, float my, const Vec3 &wi, const Vec3 &wo, float cos_gamma) {
  const Vec3 m = PseudoNormalField::chart_normal(mx, my);
  const float wim = dot(wi, m);
  const Vec3 r = (2.0f * wim) * m - wi;
  return wim > 0.0f && dot(r, wo) >= cos_gamma;
}

// The tiles a query visits: rows ty0..ty1 of the chart, row r holding tiles
// tx0[r]..tx1[r] (the lit region's ellipse rasterised row by row, each row's
// span widened to the ellipse's widest chord in the row: conservative);
// false when there are more than kMaxTiles tiles or no half vector.
struct PseudoNormalTiles {
  static constexpr int kMaxRows = 64;
  int32_t ty0 = 0, ty1 = -1;
  std::array<int32_t, kMaxRows> tx0{}, tx1{};
  int tiles = 0;
  bool holds(int32_t tx, int32_t ty) const {
    return ty >= ty0 && ty <= ty1 && tx >= tx0[static_cast<size_t>(ty - ty0)] && tx <= tx1[static_cast<size_t>(ty - ty0)];
  }
};
[[gnu::noinline]] inline bool pseudo_normal_tiles(const PseudoNormalField &field, const Vec3 &wi, const Vec3 &wo, float margin,
                                PseudoNormalTiles &tiles) {
  const Vec3 s = wi + wo;
  const float len2 = dot(s, s);
  if (!(len2 > 1e-12f) || !(s.z > 0.0f)) return false;
  const float len = std::sqrt(len2);
  const Vec3 h = s * (1.0f / len);
  const float wih = 0.5f * len;  // wi.h for unit wi, wo
  const float hz1 = 1.0f + h.z;
  const float px = 2.0f * h.x / hz1, py = 2.0f * h.y / hz1;
  const float scale = 2.0f / hz1;  // the chart's (conformal) scale at h
  const float a = margin * scale * 0.5f * field.gamma_rad;                          // in the plane of incidence
  const float b = margin * scale * 0.5f * field.gamma_rad / std::max(wih, 1e-6f);  // across it
  // Across direction: c = wi x h (tangent at h), its chart image (dp = 2 (dm.xy (1 + h.z) - h.xy dm.z) / (1 + h.z)^2).
  const Vec3 c = cross(wi, h);
  float ex = c.x * hz1 - h.x * c.z, ey = c.y * hz1 - h.y * c.z;
  const float e2 = ex * ex + ey * ey;
  if (e2 > 1e-20f) {
    const float inv = 1.0f / std::sqrt(e2);
    ex *= inv, ey *= inv;
  } else {
    ex = 1.0f, ey = 0.0f;
  }
  // The ellipse d^T S^-1 d <= 1, S = b^2 e e^T + a^2 e' e'^T (e' = e rotated by 90 degrees).
  const float sxx = b * b * ex * ex + a * a * ey * ey, syy = b * b * ey * ey + a * a * ex * ex;
  const float sxy = (b * b - a * a) * ex * ey;
  const float hy = std::sqrt(syy);
  const float inv_t = 1.0f / field.tile;
  if (!(hy * inv_t < 0.5f * PseudoNormalTiles::kMaxRows - 1.0f) || !(sxx * inv_t * inv_t < 4096.0f)) return false;
  tiles.ty0 = floor_to_int32((py - hy) * inv_t), tiles.ty1 = floor_to_int32((py + hy) * inv_t);
  if (tiles.ty1 - tiles.ty0 >= PseudoNormalTiles::kMaxRows) return false;
  const float k = sxy / syy;                  // chord centre: x = px + k dy
  const float w0 = a * b / hy;                // chord half-width at dy = 0: sqrt(det S / syy)
  tiles.tiles = 0;
  for (int32_t ty = tiles.ty0; ty <= tiles.ty1; ++ty) {
    const float lo = std::max(static_cast<float>(ty) * field.tile - py, -hy);
    const float hi = std::min(static_cast<float>(ty + 1) * field.tile - py, hy);
    const float nearest = lo > 0.0f ? lo : (hi < 0.0f ? hi : 0.0f);
    const float w = w0 * std::sqrt(std::max(1.0f - nearest * nearest / syy, 0.0f));  // widest chord in the row
    const float c0 = px + k * lo, c1 = px + k * hi;
    const auto row = static_cast<size_t>(ty - tiles.ty0);
    tiles.tx0[row] = floor_to_int32((std::min(c0, c1) - w) * inv_t);
    tiles.tx1[row] = floor_to_int32((std::max(c0, c1) + w) * inv_t);
    tiles.tiles += tiles.tx1[row] - tiles.tx0[row] + 1;
  }
  return tiles.tiles <= PseudoNormalField::kMaxTiles;
}

// Largest chart density over tile (tx, ty): at its point nearest the chart
// origin (the density decreases with |p|).
inline float pseudo_normal_tile_bound(const PseudoNormalField &field, int32_t tx, int32_t ty) {
  const float t = field.tile;
  const float x0 = static_cast<float>(tx) * t, y0 = static_cast<float>(ty) * t;
  const float nx = std::min(std::max(0.0f, x0), x0 + t), ny = std::min(std::max(0.0f, y0), y0 + t);
  return field.chart_density(nx, ny);
}

// count_pseudo_normal_glints (below) with the candidates' tests in one order.
template <bool kPositionFirst, typename Visitor>
[[gnu::always_inline]] inline GlintCount count_pseudo_normal_glints_in_order(const Footprint &f, const NodeList &nodes, double density,
                                                      const PseudoNormalField &field, const PseudoNormalTiles &tiles,
                                                      const Vec3 &wi, const Vec3 &wo, int max_steps, Visitor &&visit) {
  GlintCount result;
  const FootprintFrame frame(f, nodes.size);
  std::array<FootprintFrame::NodeOrigin, kMaxNodes> origin;
  std::array<bool, kMaxNodes> inside;
  for (int n = 0; n < nodes.count; ++n) {
    origin[static_cast<size_t>(n)] =
        frame.origin(static_cast<double>(nodes.i[n]) * nodes.size, static_cast<double>(nodes.j[n]) * nodes.size);
    inside[static_cast<size_t>(n)] = frame.node_inside(origin[static_cast<size_t>(n)]);
  }
  const double per_node = std::min(density * nodes.size * nodes.size, 4.0e18);
  const double tile_area = static_cast<double>(field.tile) * field.tile;
  for (int32_t ty = tiles.ty0; ty <= tiles.ty1; ++ty)
    for (int32_t tx = tiles.tx0[static_cast<size_t>(ty - tiles.ty0)]; tx <= tiles.tx1[static_cast<size_t>(ty - tiles.ty0)];
         ++tx) {
      const float g_max = pseudo_normal_tile_bound(field, tx, ty);
      if (!(g_max > 0.0f)) continue;
      const double lambda = per_node * g_max * tile_area;
      const uint64_t below = static_cast<uint64_t>(std::min(lambda, 1.0) * 4294967296.0) + 1u;
      const uint32_t seed = field.tile_seed(tx, ty);
      std::optional<LitCountBounds> bounds;  // at the first node passing the quick reject (most tiles have none)
      std::optional<LitCountModel> model;
      const float x0 = static_cast<float>(tx) * field.tile, y0 = static_cast<float>(ty) * field.tile;
      for (int n = 0; n < nodes.count; ++n) {
        const uint32_t h0 = node_seed_hash(nodes.id_hash[n], seed);
        if (h0 >= below) continue;
        const double u = lit_count_uniform(h0);
        if (!bounds) bounds.emplace(lambda);
        const int64_t K = lit_count_at_uniform(u, *bounds, model, lambda);
        if (K == 0) continue;
        if (K < 0 || result.steps + K > max_steps) {
          result.complete = false;
          return result;
        }
        result.steps += static_cast<int>(K);
        const auto &o = origin[static_cast<size_t>(n)];
        const bool in = inside[static_cast<size_t>(n)];
        for (int64_t k = 0; k < K; ++k) {
          const auto kk = static_cast<uint32_t>(k);
          if constexpr (kPositionFirst) {
            if (!in) {
              const auto [ux, uy] = particle_position(h0, kk);
              if (!frame.particle_inside(o, ux, uy)) continue;
            }
            const PseudoNormalDraw d = pseudo_normal_draw(h0, kk);
            const float mx = x0 + d.ux * field.tile, my = y0 + d.uy * field.tile;
            if (!(d.w * g_max < field.chart_density(mx, my))) continue;  // thinned
            if (!pseudo_normal_reflects_into_cone(mx, my, wi, wo, field.cos_gamma)) continue;
          } else {  // the reflection first (one hash), then the position and the thinning
            const uint32_t key = pseudo_normal_key(h0, kk);
            const auto [cu, cv] = pseudo_normal_chart_uniforms(key);
            const float mx = x0 + cu * field.tile, my = y0 + cv * field.tile;
            if (!pseudo_normal_reflects_into_cone(mx, my, wi, wo, field.cos_gamma)) continue;
            if (!in) {
              const auto [ux, uy] = particle_position(h0, kk);
              if (!frame.particle_inside(o, ux, uy)) continue;
            }
            if (!(pseudo_normal_thinning_uniform(key) * g_max < field.chart_density(mx, my))) continue;  // thinned
          }
          ++result.count;
          if constexpr (std::decay_t<Visitor>::kVisitsParticles) visit(h0, kk);
        }
      }
    }
  return result;
}

// Counts the particles of the footprint whose pseudo-normal reflects wi into
// the cone around wo (nodes: the particle level of density N, footprint_nodes
// with the full density). `complete` false when more than max_steps candidates
// would be visited (the caller returns the mean). A candidate counts when it
// lies in the footprint, reflects wi into the cone and survives the
// thinning; the three tests read the same uniforms in either order, so the
// order changes the cost, not the count. Where the footprint covers less
// than kPositionFirstCover of its nodes' area (most candidates lie outside
// it) the position is tested first, else the reflection (one hash and no
// density; 18..22 % of the candidates pass it). Session 16.
inline constexpr double kPositionFirstCover = 0.15;
template <typename Visitor = NoParticleVisitor>
inline GlintCount count_pseudo_normal_glints(const Footprint &f, const NodeList &nodes, double density,
                                             const PseudoNormalField &field, const PseudoNormalTiles &tiles,
                                             const Vec3 &wi, const Vec3 &wo, int max_steps,
                                             Visitor &&visit = Visitor{}) {
  if (f.area() < kPositionFirstCover * static_cast<double>(nodes.count) * nodes.size * nodes.size)
    return count_pseudo_normal_glints_in_order<true>(f, nodes, density, field, tiles, wi, wo, max_steps,
                                                     std::forward<Visitor>(visit));
  return count_pseudo_normal_glints_in_order<false>(f, nodes, density, field, tiles, wi, wo, max_steps,
                                                    std::forward<Visitor>(visit));
}

}  // namespace glimmer::plugin::glint
