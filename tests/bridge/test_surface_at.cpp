// Mesh::surface_at is the one place a triangle point is computed (shading, the
// host's trace_ray, emissive triangles). Its shading normal must stay a unit
// vector where smooth vertex normals cancel (the zero-length guard host_trace
// lacked before), and its interpolation must match the barycentric formula.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>

#include "scene/scene.h"

namespace glimmer::test {
namespace {

scene::Mesh one_triangle(bool smooth) {
  scene::Mesh m;
  m.P = {Vec3(0, 0, 0), Vec3(2, 0, 0), Vec3(0, 1, 0)};
  m.generated = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
  m.triangles = {{0u, 1u, 2u}};
  m.uv = {{0.0f, 0.0f}, {1.0f, 0.0f}, {0.0f, 1.0f}};
  m.smooth = smooth;
  // Opposite normals at vertices 0 and 1: their average (b0 = b1 = 0.5) has zero length.
  m.N = {Vec3(0, 0, 1), Vec3(0, 0, -1), Vec3(0, 0, 1)};
  return m;
}

TEST(SurfaceAt, CancellingSmoothNormalsFallBackToTheGeometricNormal) {
  const scene::Mesh m = one_triangle(true);
  const scene::SurfacePoint s = m.surface_at(0, 0.5f, 0.0f);
  // Negative control: the unguarded interpolation has zero length here.
  const Vec3 raw = m.N[0] * 0.5f + m.N[1] * 0.5f;
  EXPECT_EQ(length(raw), 0.0f);
  EXPECT_NEAR(length(s.N), 1.0f, 1e-6f);
  EXPECT_EQ(s.N.z, s.Ng.z);
  EXPECT_EQ(s.Ng.z, 1.0f);
  EXPECT_EQ(length(s.dn1), 0.0f);  // no normal derivatives for the fallback
}

TEST(SurfaceAt, InterpolatesPositionUvNormalAndTangents) {
  const scene::Mesh m = one_triangle(true);
  const float b1 = 0.25f, b2 = 0.5f;
  const scene::SurfacePoint s = m.surface_at(0, b1, b2);
  EXPECT_FLOAT_EQ(s.P.x, 2.0f * b1);
  EXPECT_FLOAT_EQ(s.P.y, b2);
  EXPECT_FLOAT_EQ(s.uv[0], b1);
  EXPECT_FLOAT_EQ(s.uv[1], b2);
  EXPECT_FLOAT_EQ(s.generated.x, b1);
  // N interpolated: 0.25 (+z) + 0.25 (-z) + 0.5 (+z) = 0.5 z -> +z.
  EXPECT_FLOAT_EQ(s.N.z, 1.0f);
  // dP/du = e1 / du1 = (2, 0, 0), dP/dv = (0, 1, 0).
  EXPECT_FLOAT_EQ(s.dPdu.x, 2.0f);
  EXPECT_FLOAT_EQ(s.dPdv.y, 1.0f);
  const scene::SurfacePoint flat = one_triangle(false).surface_at(0, b1, b2);
  EXPECT_EQ(flat.N.z, flat.Ng.z);
}

// The services' hit records (renderer.cpp fill_ray_hit) read Mesh::hit_geometry, not surface_at: its P, Ng, N
// and uv must be surface_at's bit for bit (smooth and flat, with and without a uv map, cancelling normals).
bool same_bits(float a, float b) { return std::memcmp(&a, &b, sizeof(float)) == 0; }
bool same_bits(const Vec3 &a, const Vec3 &b) { return same_bits(a.x, b.x) && same_bits(a.y, b.y) && same_bits(a.z, b.z); }
bool same_geometry(const scene::HitGeometry &g, const scene::SurfacePoint &s) {
  return same_bits(g.P, s.P) && same_bits(g.Ng, s.Ng) && same_bits(g.N, s.N) && same_bits(g.uv[0], s.uv[0]) &&
         same_bits(g.uv[1], s.uv[1]);
}

TEST(SurfaceAt, HitGeometryIsSurfaceAtsPositionNormalsAndUvBitForBit) {
  std::mt19937 rng(12);
  std::uniform_real_distribution<float> coord(-3.0f, 3.0f), unit(0.0f, 1.0f);
  int compared = 0, smooth_normals = 0, perturbed_caught = 0;
  for (int mesh = 0; mesh < 400; ++mesh) {
    scene::Mesh m;
    for (int v = 0; v < 6; ++v) {
      m.P.push_back(Vec3(coord(rng), coord(rng), coord(rng)));
      m.N.push_back(normalize(Vec3(coord(rng), coord(rng), coord(rng))));
      m.generated.push_back(Vec3(unit(rng), unit(rng), unit(rng)));
    }
    m.triangles = {{0u, 1u, 2u}, {3u, 4u, 5u}, {1u, 3u, 5u}};
    m.smooth = mesh % 2 == 0;
    if (mesh % 4 < 2)
      for (int c = 0; c < 9; ++c) m.uv.push_back({coord(rng), coord(rng)});
    if (mesh % 8 == 0) m.N[1] = -m.N[0];  // cancelling normals on the edge 0-1 of the first triangle
    for (size_t prim = 0; prim < m.triangles.size(); ++prim)
      for (int k = 0; k < 8; ++k) {
        float b1 = unit(rng), b2 = unit(rng) * (1.0f - b1);
        if (k == 0) b1 = 0.5f, b2 = 0.0f;  // the cancelling point when N[1] = -N[0]
        const scene::SurfacePoint s = m.surface_at(prim, b1, b2);
        const scene::HitGeometry g = m.hit_geometry(prim, b1, b2);
        EXPECT_TRUE(same_geometry(g, s)) << "mesh " << mesh << " prim " << prim << " b " << b1 << " " << b2;
        ++compared;
        smooth_normals += m.smooth && !same_bits(s.N, s.Ng);
        // Control: the comparison sees a one-ulp change of any one component.
        scene::HitGeometry off = g;
        (&off.P.x)[k % 3] = std::nextafter((&off.P.x)[k % 3], 1e30f);
        perturbed_caught += !same_geometry(off, s);
      }
  }
  EXPECT_EQ(compared, 400 * 3 * 8);
  EXPECT_GT(smooth_normals, 1000);  // the smooth branch was exercised
  EXPECT_EQ(perturbed_caught, compared);
}

}  // namespace
}  // namespace glimmer::test
