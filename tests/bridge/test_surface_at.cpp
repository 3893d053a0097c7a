// Mesh::surface_at is the one place a triangle point is computed (shading, the
// host's trace_ray, emissive triangles). Its shading normal must stay a unit
// vector where smooth vertex normals cancel (the zero-length guard host_trace
// lacked before), and its interpolation must match the barycentric formula.
#include <gtest/gtest.h>

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

}  // namespace
}  // namespace glimmer::test
