// Bump, Normal Map and Tangent nodes (bridge/render/nodes/normal_nodes.cpp) and the closures' own
// shading frames, against closed forms:
//  - Bump of a linear height h(P) = g . P on a plane with normal N: the finite differences over any
//    footprint in the plane give the exact surface gradient, so N' = normalize(N - distance g_t)
//    (g_t: g's part in the plane), blended with N by strength; invert negates distance. Negative
//    controls: the result misses the formula with the distance's sign flipped, and with no footprint
//    (no ray differentials) the normal is unperturbed.
//  - Normal Map of a constant tangent-space colour on a rotated, UV-mapped quad: R normalize(2c - 1)
//    in the frame (u direction, v direction, normal) rotated by R; negative control: the same quad with
//    its UV map turned 90 degrees (the tangent frame matters).
//  - Tangent node (uv_map) on an affinely parametrized quad equals normalize(dP/du); on a cylinder
//    mesh, the analytic dP/du within the chord error; negative control: dP/dv (u and v swapped).
//  - ensure_valid_reflection: reflections above the threshold, unit normals in the plane of N and Ng;
//    negative control: the unmodified normals reflect below the surface.
//  - Rendered: a diffuse quad under a sun, with a linear-height bump (or a normal map): the pixel ratio
//    to the flat quad is cos(N', L) / cos(N, L) (noise-free: a delta light, one constant normal), times
//    Cycles' bump shadowing term where it is below 1 (negative control: the cosines alone miss).
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <iterator>
#include <map>
#include <set>
#include <string>

#include "render/nodes/node_program.h"
#include "render/nodes/shading_normal.h"
#include "render_test_util.h"
#include "scene/scene.h"
#include "scene/uv_tangents.h"

namespace glimmer::test {
namespace {

using render::nodes::ShadingPoint;
using Attributes = std::map<std::string, std::string>;

struct Program {
  scene::ShaderGraph graph;
  render::nodes::NodeProgram program;
  std::vector<std::string> warnings;
};

// Compiles the graph's link into output "e color" (emission e), as the shader system does.
std::unique_ptr<Program> compile(std::vector<scene::ShaderNode> nodes, std::vector<scene::ShaderLink> links,
                                 const std::string &from) {
  auto p = std::make_unique<Program>();
  p->graph.name = "test";
  p->graph.nodes = std::move(nodes);
  p->graph.nodes.push_back({"emission", "e", {}, {"test.xml", 9}});
  p->graph.links = std::move(links);
  const auto dot = from.find(' ');
  const scene::ShaderLink out{from.substr(0, dot), from.substr(dot + 1), "e", "color", {"test.xml", 10}};
  p->graph.links.push_back(out);
  render::nodes::BuildHooks hooks;
  hooks.external = [](const scene::ShaderLink &, render::nodes::SocketType &) { return -1; };
  hooks.warn = [w = &p->warnings](const scene::SourceLocation &where, const std::string &m) {
    w->push_back(where.str() + ": " + m);
  };
  p->program = render::nodes::compile_program(p->graph, out, hooks);
  return p;
}

Vec3 run(const Program &p, const ShadingPoint &sp) {
  return p.program.eval(sp, [](int, const ShadingPoint &) { return Vec3(0.0f); });
}

std::string vec_text(const Vec3 &v) {
  return std::to_string(v.x) + " " + std::to_string(v.y) + " " + std::to_string(v.z);
}

// Bump whose height is g . P (texture_coordinate object -> vector_math dot_product).
std::unique_ptr<Program> linear_bump(const Vec3 &g, const Attributes &bump) {
  const scene::SourceLocation at{"test.xml", 2};
  return compile({{"texture_coordinate", "tc", {}, at},
                  {"vector_math", "h", {{"math_type", "dot_product"}, {"vector2", vec_text(g)}}, at},
                  {"bump", "b", bump, at}},
                 {{"tc", "object", "h", "vector1", at}, {"h", "value", "b", "height", at}}, "b normal");
}

// A point on the plane through P0 with unit normal N, footprint (fx, fy) in the plane, seen from `view`
// (toward the viewer; default head-on).
ShadingPoint plane_point(const Vec3 &N, const Vec3 &fx, const Vec3 &fy, Vec3 view = Vec3(0.0f)) {
  ShadingPoint sp;
  sp.P = Vec3(0.3f, -0.2f, 0.1f);
  sp.N = sp.Ng = N;
  sp.direction = is_zero(view) ? -N : -normalize(view);
  sp.bump_dPdx = fx;
  sp.bump_dPdy = fy;
  return sp;
}

Vec3 expected_bump(const Vec3 &N, const Vec3 &g, float distance, float strength) {
  const Vec3 g_t = g - N * dot(N, g);
  const Vec3 bumped = normalize(N - distance * g_t);
  return normalize(strength * bumped + (1.0f - strength) * N);
}

float angle_between(const Vec3 &a, const Vec3 &b) {
  return std::acos(std::clamp(dot(normalize(a), normalize(b)), -1.0f, 1.0f));
}

TEST(Bump, LinearHeightGivesTheAnalyticNormal) {
  const Frame plane = Frame::from_normal(normalize(Vec3(0.3f, -0.5f, 0.8f)));
  const Vec3 N = plane.n;
  // A skewed footprint in the plane (ray differentials are not orthogonal in general).
  const Vec3 fx = plane.s * 0.01f + plane.t * 0.004f, fy = plane.s * -0.003f + plane.t * 0.012f;
  const Vec3 g(0.7f, 0.2f, -0.4f);
  struct Case {
    float distance, strength;
    bool invert;
  };
  for (const Case c : {Case{1.0f, 1.0f, false}, Case{0.25f, 1.0f, false}, Case{2.0f, 0.5f, false},
                       Case{1.0f, 1.0f, true}, Case{0.5f, 0.3f, true}, Case{1.0f, 0.0f, false}}) {
    const auto p = linear_bump(g, {{"distance", std::to_string(c.distance)},
                                   {"strength", std::to_string(c.strength)},
                                   {"invert", c.invert ? "true" : "false"}});
    // The Object output's caveat (world-space position), once per copy of the height graph (the shader
    // system prints each line once).
    EXPECT_EQ(std::set<std::string>(p->warnings.begin(), p->warnings.end()).size(), 1u);
    const Vec3 want = expected_bump(N, g, c.invert ? -c.distance : c.distance, c.strength);
    // Seen along the bumped normal, so that the terminator fix (tested below) leaves it alone.
    const Vec3 got = run(*p, plane_point(N, fx, fy, want));
    EXPECT_LT(angle_between(got, want), 2e-3f)
        << "distance " << c.distance << " strength " << c.strength << " invert " << c.invert;
    EXPECT_NEAR(length(got), 1.0f, 1e-5f);
    // Negative control: the distance's sign flipped (invert ignored or applied twice) misses clearly.
    if (c.strength > 0.0f) {
      EXPECT_GT(angle_between(got, expected_bump(N, g, c.invert ? c.distance : -c.distance, c.strength)), 0.05f);
    }
  }
}

TEST(Bump, HeightAEqualsAxGivesNormalizeMinusAOne) {
  // The closed form: plane z = 0, h = a x: N' = normalize(-a distance, 0, 1).
  const Vec3 N(0, 0, 1), fx(0.02f, 0, 0), fy(0, 0.02f, 0);
  for (float a : {0.1f, 0.5f, 2.0f}) {
    const auto p = linear_bump(Vec3(a, 0.0f, 0.0f), {});
    const Vec3 want = normalize(Vec3(-a, 0.0f, 1.0f));
    EXPECT_LT(angle_between(run(*p, plane_point(N, fx, fy, want)), want), 1e-4f) << a;
    // Seen head-on, the steep normal (a = 2: 63 degrees) would mirror the view ray below the surface:
    // the terminator fix tilts it back toward Ng, exactly as ensure_valid_reflection does to the closed form.
    const Vec3 head_on = run(*p, plane_point(N, fx, fy));
    const Vec3 fixed = render::nodes::ensure_valid_reflection(N, N, want);
    EXPECT_LT(angle_between(head_on, fixed), 1e-4f) << a;
    if (a == 2.0f) {
      EXPECT_GT(angle_between(fixed, want), 0.1f);
    } else {
      EXPECT_EQ(angle_between(fixed, want), 0.0f);
    }
  }
}

TEST(Bump, WithoutFootprintTheNormalIsUnperturbed) {
  // Cycles needs ray differentials for the finite difference; without them (shadow rays here) the
  // bump is flat rather than NaN.
  const auto p = linear_bump(Vec3(1.0f, 0.0f, 0.0f), {});
  const Vec3 got = run(*p, plane_point(Vec3(0, 0, 1), Vec3(0.0f), Vec3(0.0f)));
  EXPECT_LT(angle_between(got, Vec3(0, 0, 1)), 1e-6f);
}

TEST(Bump, TextureHeightIsReadAtTheOffsetPoints) {
  // A noise height: the program evaluates it at P, P + dPdx and P + dPdy (three copies of its steps).
  const scene::SourceLocation at{"test.xml", 2};
  const auto p = compile({{"noise_texture", "n", {{"scale", "3"}}, at}, {"bump", "b", {}, at}},
                         {{"n", "fac", "b", "height", at}}, "b normal");
  EXPECT_EQ(p->program.step_count(), 4);  // noise at the point, at +dPdx, at +dPdy; bump
  ShadingPoint sp = plane_point(Vec3(0, 0, 1), Vec3(0.01f, 0, 0), Vec3(0, 0.01f, 0));
  sp.generated = Vec3(0.31f, 0.42f, 0.5f);  // the noise reads generated coordinates: they move with the footprint
  sp.bump_dgenerated_dx = Vec3(0.01f, 0, 0);
  sp.bump_dgenerated_dy = Vec3(0, 0.01f, 0);
  const Vec3 got = run(*p, sp);
  EXPECT_GT(angle_between(got, Vec3(0, 0, 1)), 1e-3f);
  sp.bump_dgenerated_dx = sp.bump_dgenerated_dy = Vec3(0.0f);  // negative control: heights read at one point only
  EXPECT_EQ(angle_between(run(*p, sp), Vec3(0, 0, 1)), 0.0f);
}

// ---- ensure_valid_reflection --------------------------------------------------------------------------------

TEST(ShadingNormal, EnsureValidReflectionLiftsReflectionsToTheThreshold) {
  const Vec3 Ng(0, 0, 1);
  int fixed = 0;
  for (int i = 0; i < 200; ++i) {
    const float a = 0.05f + 1.4f * (i % 20) / 20.0f, b = 6.2831853f * (i / 20) / 10.0f;
    const Vec3 I = normalize(Vec3(std::sin(a) * std::cos(b), std::sin(a) * std::sin(b), std::cos(a)));
    const Vec3 N = normalize(Vec3(0.9f * std::cos(b + 0.3f), 0.9f * std::sin(b + 0.3f), 0.35f));
    const Vec3 out = render::nodes::ensure_valid_reflection(Ng, I, N);
    const float t = std::fmin(0.9f * dot(Ng, I), 0.01f);
    const Vec3 R = 2.0f * dot(out, I) * out - I;
    EXPECT_NEAR(length(out), 1.0f, 1e-5f);
    EXPECT_GE(dot(R, Ng), t - 1e-4f) << i;
    EXPECT_NEAR(dot(out, cross(N, Ng)), 0.0f, 1e-5f);  // in the plane of N and Ng
    const Vec3 R0 = 2.0f * dot(N, I) * N - I;
    if (dot(R0, Ng) >= t) {
      EXPECT_EQ(out.x, N.x);  // a valid normal is kept as it is
      EXPECT_EQ(out.z, N.z);
    } else {
      ++fixed;  // negative control: these normals did reflect below the threshold
      EXPECT_NEAR(dot(R, Ng), t, 1e-3f) << i;  // tilted just enough
    }
  }
  EXPECT_GT(fixed, 20);
}

// ---- Normal Map and Tangent on UV-mapped meshes -------------------------------------------------------------

// A quad in the plane z = 0 (u along x, v along y, uv from `uv`), rotated by R (columns), as a mesh.
scene::Mesh quad_mesh(const Frame &R, const std::array<std::array<float, 2>, 4> &uv, Vec3 scale = Vec3(1.0f)) {
  scene::Mesh m;
  const Vec3 corners[4] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  for (const Vec3 &c : corners) {
    m.P.push_back(R.to_world(Vec3(c.x * scale.x, c.y * scale.y, 0.0f)));
    m.generated.push_back(c);
  }
  m.triangles = {{0, 1, 2}, {0, 2, 3}};
  for (int k : {0, 1, 2, 0, 2, 3}) m.uv.push_back(uv[k]);
  scene::compute_uv_tangents(m);
  return m;
}

// The shading point of the mesh at barycentrics (b1, b2) of triangle 0, seen along -N.
ShadingPoint mesh_point(const scene::Mesh &m, float b1, float b2) {
  const scene::SurfacePoint s = m.surface_at(0, b1, b2);
  ShadingPoint sp;
  sp.P = s.P;
  sp.N = sp.Ng = s.N;
  sp.dPdu = s.dPdu;
  sp.dPdv = s.dPdv;
  sp.tangent = s.tangent;
  sp.tangent_sign = s.tangent_sign;
  sp.generated = s.generated;
  sp.direction = -s.N;
  return sp;
}

std::unique_ptr<Program> normal_map(const Vec3 &color, const Attributes &extra = {}) {
  Attributes a = extra;
  a["color"] = vec_text(color);
  return compile({{"normal_map", "m", a, {"test.xml", 2}}}, {}, "m normal");
}

// Every closure's normal, not only a Bump / Normal Map output, keeps wi's mirror direction above Ng (Cycles 3.4,
// svm_node_closure_bsdf): on a coarse smooth-shaded sphere seen whole, the interpolated normal near the silhouette
// leans away from wi, and before the renderer bent it the equal-error scene (a) lost energy at the silhouette.
// Negative control: without the bend some silhouette pixels reflect below Ng (counted below, must exist).
TEST(ShadingNormal, EveryClosureNormalKeepsTheMirrorDirectionAboveNg) {
  const std::string path = write_file(
      "coarse_sphere.xml", "<cycles>\n<camera width=\"64\" height=\"64\" fov=\"0.7\" />\n<camera />\n"
                           "<shader name=\"s\"><glossy_bsdf name=\"b\" roughness=\"0.5\" />"
                           "<connect from=\"b bsdf\" to=\"output surface\" /></shader>\n"
                           "<state shader=\"s\" interpolation=\"smooth\">" + uv_sphere_mesh(6, 12, 4.0) +
                               "</state>\n</cycles>\n");
  const scene::Scene scene = scene::load_scene(path);
  render::RenderOptions opt;
  opt.samples = 1;
  const render::Renderer r(scene, plugin(), opt);
  int hits = 0, bent = 0;
  for (int y = 0; y < 64; ++y)
    for (int x = 0; x < 64; ++x) {
      GlimmerShadingContext ctx;
      if (!r.probe(x + 0.5f, y + 0.5f, ctx)) continue;
      ++hits;
      const Vec3 wi(ctx.wi), N(ctx.N), Ng(ctx.Ng);
      const Vec3 R = 2.0f * dot(N, wi) * N - wi;
      EXPECT_GE(dot(R, Ng), std::fmin(0.9f * dot(wi, Ng), 0.01f) - 1e-4f) << "pixel " << x << "," << y;
      // The sphere's own smooth normal here is close to the direction from its centre (0, 0, 4).
      const Vec3 radial = normalize(Vec3(ctx.P) - Vec3(0.0f, 0.0f, 4.0f));
      const Vec3 R_radial = 2.0f * dot(radial, wi) * radial - wi;
      if (dot(R_radial, Ng) < std::fmin(0.9f * dot(wi, Ng), 0.01f) - 1e-4f) ++bent;
    }
  EXPECT_GT(hits, 500);
  EXPECT_GT(bent, 0);  // the unbent normal does fail at the silhouette
  std::printf("  coarse sphere: %d pixels, %d where the unbent normal reflects below Ng\n", hits, bent);
}

TEST(NormalMap, ConstantTangentSpaceColourOnARotatedQuad) {
  const Frame R = Frame::from_normal_tangent(normalize(Vec3(-0.4f, 0.6f, 0.7f)), Vec3(1, 0.2f, 0));
  const std::array<std::array<float, 2>, 4> uv = {{{0, 0}, {1, 0}, {1, 1}, {0, 1}}};
  const std::array<std::array<float, 2>, 4> uv_turned = {{{0, 0}, {0, 1}, {-1, 1}, {-1, 0}}};  // u along y
  const scene::Mesh quad = quad_mesh(R, uv, Vec3(2.0f, 0.5f, 1.0f));  // anisotropic scale: dP/du not unit
  const scene::Mesh turned = quad_mesh(R, uv_turned);
  for (const Vec3 c : {Vec3(0.7f, 0.5f, 0.9f), Vec3(0.4f, 0.65f, 0.85f), Vec3(0.5f, 0.5f, 1.0f)}) {
    const auto p = normal_map(c);
    EXPECT_TRUE(p->warnings.empty());
    const Vec3 want = R.to_world(normalize(2.0f * (c - Vec3(0.5f))));
    const Vec3 got = run(*p, mesh_point(quad, 0.3f, 0.2f));
    EXPECT_LT(angle_between(got, want), 1e-4f) << c.x << " " << c.y;
    if (c.x == 0.5f && c.y == 0.5f) continue;
    // Negative control: with the UV map turned 90 degrees the tangent frame turns, and so does the normal.
    const Vec3 got_turned = run(*p, mesh_point(turned, 0.3f, 0.2f));
    EXPECT_GT(angle_between(got_turned, want), 0.05f);
    const Vec3 c2 = 2.0f * (c - Vec3(0.5f));
    // Turned: dP/du = -y, dP/dv = +x of the quad's frame, so the normal is (c.y, -c.x, c.z) there.
    EXPECT_LT(angle_between(got_turned, R.to_world(normalize(Vec3(c2.y, -c2.x, c2.z)))), 1e-4f);
  }
}

TEST(NormalMap, StrengthAndWorldSpace) {
  const Vec3 N(0, 0, 1);
  ShadingPoint sp = plane_point(N, Vec3(0.0f), Vec3(0.0f));
  const Vec3 c(0.8f, 0.5f, 0.9f);
  const Vec3 full = normalize(2.0f * (c - Vec3(0.5f)));
  EXPECT_LT(angle_between(run(*normal_map(c, {{"space", "world"}}), sp), full), 1e-5f);
  // Blender's world space negates y and z.
  const Vec3 c2(0.6f, 0.2f, 0.1f);
  const Vec3 blender = normalize(2.0f * (c2 - Vec3(0.5f)) * Vec3(1, -1, -1));
  EXPECT_LT(angle_between(run(*normal_map(c2, {{"space", "blender_world"}}), sp), blender), 1e-5f);
  // strength s: normalize(N + (N' - N) s).
  const Vec3 half = run(*normal_map(c, {{"space", "world"}, {"strength", "0.5"}}), sp);
  EXPECT_LT(angle_between(half, normalize(N + (full - N) * 0.5f)), 1e-5f);
  EXPECT_LT(angle_between(run(*normal_map(c, {{"space", "world"}, {"strength", "0"}}), sp), N), 1e-6f);
}

TEST(TangentNode, UvTangentEqualsNormalizedDPdu) {
  // Affine parametrization P(u, v) = R (2 u + 0.5 v, 0.8 v, 0): dP/du = R (2, 0, 0).
  const Frame R = Frame::from_normal(normalize(Vec3(0.2f, 0.9f, -0.3f)));
  scene::Mesh m = quad_mesh(R, {{{0, 0}, {1, 0}, {1, 1}, {0, 1}}});
  for (size_t i = 0; i < 4; ++i) {
    const float u = m.uv[i == 3 ? 5 : i][0], v = m.uv[i == 3 ? 5 : i][1];
    m.P[i] = R.to_world(Vec3(2.0f * u + 0.5f * v, 0.8f * v, 0.0f));
  }
  scene::compute_uv_tangents(m);
  const auto uvmap = compile({{"tangent", "t", {{"direction_type", "uv_map"}}, {"test.xml", 2}}}, {}, "t tangent");
  const Vec3 got = run(*uvmap, mesh_point(m, 0.25f, 0.5f));
  EXPECT_LT(angle_between(got, R.s), 1e-5f);
  EXPECT_GT(angle_between(got, R.to_world(normalize(Vec3(0.5f, 0.8f, 0.0f)))), 0.3f);  // negative control: dP/dv
}

TEST(TangentNode, UvTangentOnACylinderFollowsTheParametrization) {
  // Smooth cylinder P(u, v) = (cos 2 pi u, sin 2 pi u, v), 32 segments: the per-vertex tangents (averaged
  // over the corners sharing a vertex and UV) follow the analytic dP/du (-sin, cos, 0) to O(h^2) inside;
  // the seam's columns (u = 0 and 1 are different UVs) and the flat mesh's per-triangle chords only to
  // within h / 2 = pi / 32 (the contrast shows the averaging is there).
  scene::Mesh m;
  const int n = 32;
  for (int i = 0; i <= n; ++i)
    for (int j = 0; j <= 1; ++j) {
      const float u = static_cast<float>(i) / n;
      m.P.push_back(Vec3(std::cos(2 * kPi * u), std::sin(2 * kPi * u), static_cast<float>(j)));
      m.N.push_back(Vec3(std::cos(2 * kPi * u), std::sin(2 * kPi * u), 0.0f));
      m.generated.push_back(Vec3(u, static_cast<float>(j), 0.0f));
    }
  m.smooth = true;
  for (int i = 0; i < n; ++i) {
    const uint32_t a = 2 * i, b = 2 * i + 2, c = 2 * i + 3, d = 2 * i + 1;
    const float u0 = static_cast<float>(i) / n, u1 = static_cast<float>(i + 1) / n;
    m.triangles.push_back({a, b, c});
    m.uv.insert(m.uv.end(), {{u0, 0}, {u1, 0}, {u1, 1}});
    m.triangles.push_back({a, c, d});
    m.uv.insert(m.uv.end(), {{u0, 0}, {u1, 1}, {u0, 1}});
  }
  const auto uvmap = compile({{"tangent", "t", {{"direction_type", "uv_map"}}, {"test.xml", 2}}}, {}, "t tangent");
  auto worst_error = [&](const scene::Mesh &mesh, bool inside_only, bool swapped) {
    float worst = 0.0f;
    for (size_t f = 0; f < mesh.triangles.size(); ++f) {
      if (inside_only && (f < 2 || f >= mesh.triangles.size() - 2)) continue;
      const scene::SurfacePoint s = mesh.surface_at(f, 0.3f, 0.3f);
      ShadingPoint sp;
      sp.P = s.P;
      sp.N = sp.Ng = s.N;
      sp.dPdu = swapped ? s.dPdv : s.dPdu;
      sp.tangent = swapped ? s.dPdv : s.tangent;  // negative control: v's tangent
      const float phi = std::atan2(s.P.y, s.P.x);
      worst = std::max(worst, angle_between(run(*uvmap, sp), Vec3(-std::sin(phi), std::cos(phi), 0.0f)));
    }
    return worst;
  };
  scene::compute_uv_tangents(m);
  scene::Mesh flat = m;
  flat.smooth = false;
  scene::compute_uv_tangents(flat);
  const float smooth_inside = worst_error(m, true, false), flat_inside = worst_error(flat, true, false);
  EXPECT_LT(smooth_inside, 1e-3f);  // exact up to rounding: interpolated vertex tangents turn with P
  EXPECT_LT(worst_error(m, false, false), kPi / n + 1e-4f);
  EXPECT_GT(flat_inside, 0.02f);  // the chord misses by 0.2 h at these barycentrics
  EXPECT_LT(flat_inside, kPi / n + 1e-4f);
  EXPECT_GT(worst_error(m, false, true), 1.0f);
}

TEST(TangentNode, RadialZ) {
  ShadingPoint sp;
  sp.N = Vec3(1, 0, 0);
  sp.generated = Vec3(1.0f, 0.5f, 0.3f);  // on the +x side of the bounding box: radial Z tangent is +y
  const auto radial = compile({{"tangent", "t", {}, {"test.xml", 2}}}, {}, "t tangent");
  EXPECT_LT(angle_between(run(*radial, sp), Vec3(0, 1, 0)), 1e-6f);
}

// ---- Rendered: the closure sees the perturbed normal ---------------------------------------------------------

// A diffuse quad at z = 3 (filling the view) under a sun from direction L (no world): every pixel is
// albedo E cos(N', L) / pi, so the ratio of two renders is the ratio of the cosines.
std::string sun_quad(const std::string &name, const Vec3 &to_light, const std::string &normal_nodes) {
  const Vec3 dir = -to_light;
  return write_file(
      name,
      "<cycles>\n<camera width=\"8\" height=\"8\" fov=\"0.3\" />\n"
      "<integrator sample_clamp_direct=\"0\" sample_clamp_indirect=\"0\" />\n"
      "<state><light light_type=\"sun\" angle=\"0\" dir=\"" + vec_text(dir) + "\" strength=\"3 3 3\" /></state>\n"
      "<shader name=\"s\">\n<diffuse_bsdf name=\"d\" color=\"0.8 0.8 0.8\" />\n" + normal_nodes +
      "\n<connect from=\"d bsdf\" to=\"output surface\" />\n</shader>\n"
      "<state shader=\"s\"><mesh P=\"-2 -2 3  2 -2 3  2 2 3  -2 2 3\" nverts=\"4\" "
      "verts=\"0 3 2 1\" UV=\"0 0 0 1 1 1 1 0\" /></state>\n</cycles>\n");
}

double mean_red(const std::string &path, std::vector<std::string> *warnings = nullptr) {
  const scene::Scene scene = scene::load_scene(path);
  render::RenderOptions opt;
  opt.samples = 2;
  render::Renderer renderer(scene, plugin(), opt);
  const render::RenderResult r = renderer.render();
  if (warnings) *warnings = renderer.warnings();
  EXPECT_EQ(r.nan_samples, 0u);
  return mean_channel(r, 0);
}

// Cycles' bump shadowing term (Chiang et al. 2019) on a diffuse closure with a perturbed normal.
double shadowing_term(const Vec3 &Ng, const Vec3 &N, const Vec3 &L) {
  const double g = dot(Ng, L) / (dot(N, L) * dot(Ng, N));
  return g >= 1.0 ? 1.0 : g < 0.0 ? 0.0 : -g * g * g + g * g + g;
}

// The nodes of a height h = 4 a generated.x (node "h", output "value"): the quad spans x in [-2, 2], so
// generated.x = (x + 2) / 4 and dh/dx = a (the offset points move generated coordinates with the footprint).
std::string linear_height_nodes(float a) {
  return "<texture_coordinate name=\"tc\" />\n<separate_xyz name=\"sx\" />\n"
         "<math name=\"h\" math_type=\"multiply\" value2=\"" + std::to_string(4.0f * a) + "\" />\n"
         "<connect from=\"tc generated\" to=\"sx vector\" />\n<connect from=\"sx x\" to=\"h value1\" />\n";
}

struct BumpedRatio {
  double measured, cosines, shadowing;
  double want() const { return cosines * shadowing; }
};

// The pixel ratio of the quad (normal -z) with `normal_nodes` to the flat quad under a sun toward L, and what
// a bump whose height has the gradient (g, 0, 0) in the plane z = 3 predicts.
BumpedRatio bumped_quad_ratio(const Vec3 &L, float g, const std::string &normal_nodes, const std::string &name) {
  const Vec3 N(0, 0, -1);
  std::vector<std::string> warnings;
  const double flat = mean_red(sun_quad("flat.xml", L, ""));
  const double bumped = mean_red(sun_quad(name, L, normal_nodes), &warnings);
  for (const auto &w : warnings) ADD_FAILURE() << w;
  const Vec3 bent = normalize(N - g * Vec3(1, 0, 0));
  return {bumped / flat, dot(bent, L) / dot(N, L), shadowing_term(N, bent, L)};
}

// A bump of h = a x on the quad under a sun toward L: the pixel ratio to the flat quad.
void check_bumped_quad(const Vec3 &L, float a, bool expect_shadowing) {
  const std::string bump = linear_height_nodes(a) +
                           "<bump name=\"b\" />\n<connect from=\"h value\" to=\"b height\" />\n"
                           "<connect from=\"b normal\" to=\"d normal\" />";
  const BumpedRatio r = bumped_quad_ratio(L, a, bump, "bumped.xml");
  EXPECT_NEAR(r.measured, r.want(), 1e-3);
  EXPECT_GT(std::fabs(r.want() - 1.0), 0.2);  // negative control: the unperturbed normal (ratio 1) fails
  if (expect_shadowing) {  // negative control: without the shadowing term the ratio is the cosines' alone
    EXPECT_LT(r.shadowing, 0.95);
    EXPECT_GT(std::fabs(r.cosines - r.measured), 0.05);
  } else {
    EXPECT_EQ(r.shadowing, 1.0);
  }
}

TEST(ShadingNormalRender, BumpedQuadShadesWithThePerturbedNormal) {
  check_bumped_quad(normalize(Vec3(0.6f, 0.0f, -0.8f)), 0.5f, false);  // tilted away from the sun
}

TEST(ShadingNormalRender, BumpTowardAGrazingSunIsSoftenedByTheShadowingTerm) {
  check_bumped_quad(normalize(Vec3(0.8f, 0.0f, -0.6f)), -0.5f, true);  // g = 0.75: term 0.89
}

TEST(ShadingNormalRender, NormalMappedQuadShadesWithTheMappedNormal) {
  const Vec3 L = normalize(Vec3(0.0f, 0.5f, -0.8f));
  const std::string nm = "<normal_map name=\"m\" color=\"0.5 0.8 0.9\" />\n<connect from=\"m normal\" to=\"d normal\" />";
  std::vector<std::string> warnings;
  const double flat = mean_red(sun_quad("flat_nm.xml", L, ""));
  const double mapped = mean_red(sun_quad("mapped.xml", L, nm), &warnings);
  for (const auto &w : warnings) ADD_FAILURE() << w;
  // The quad faces the camera (winding normal -z); its UV map has u along +x and v along +y, so the
  // tangent-space colour (0, 0.6, 0.8) is the normal 0.6 dP/dv + 0.8 N.
  const scene::Scene scene = scene::load_scene(sun_quad("probe.xml", L, nm));
  const scene::SurfacePoint s = scene.meshes[0].surface_at(0, 0.2f, 0.2f);
  EXPECT_LT(angle_between(s.tangent, Vec3(1, 0, 0)), 1e-6f);
  const Vec3 c(0.0f, 0.6f, 0.8f);  // 2 (color - 0.5)
  const Vec3 mapped_n = normalize(c.y * Vec3(0, 1, 0) + c.z * Vec3(0, 0, -1));
  const double want = std::max(0.0f, dot(mapped_n, L)) / dot(Vec3(0, 0, -1), L);
  EXPECT_NEAR(mapped / flat, want, 1e-3) << "flat " << flat << " mapped " << mapped;
  EXPECT_GT(std::fabs(want - 1.0), 0.1);  // negative control: the unperturbed normal fails
}

// The shader's displacement output renders as bump (Cycles' default displacement method): a float f linked to
// it is the vector (f, f, f), whose height along the quad's normal (0, 0, -1) is -f, so h = 4 a generated.x
// bumps as the gradient (-a, 0, 0); a displacement along x, perpendicular to the normal, leaves it flat.
TEST(ShadingNormalRender, DisplacementOutputShadesAsABumpOfItsHeightAlongTheNormal) {
  const Vec3 L = normalize(Vec3(0.6f, 0.0f, -0.8f));
  const float a = 0.5f;
  const BumpedRatio r = bumped_quad_ratio(
      L, -a, linear_height_nodes(a) + "<connect from=\"h value\" to=\"output displacement\" />", "displaced.xml");
  EXPECT_NEAR(r.measured, r.cosines, 1e-3);
  EXPECT_GT(std::fabs(r.cosines - 1.0), 0.2);  // negative control: the unperturbed normal fails
  const Vec3 unsigned_bent = normalize(Vec3(0, 0, -1) - a * Vec3(1, 0, 0));  // the height f, without N's sign
  EXPECT_GT(std::fabs(dot(unsigned_bent, L) / dot(Vec3(0, 0, -1), L) - r.measured), 0.2);  // negative control
  const BumpedRatio sideways = bumped_quad_ratio(
      L, 0.0f,
      linear_height_nodes(a) + "<combine_xyz name=\"v\" />\n<connect from=\"h value\" to=\"v x\" />\n"
                               "<connect from=\"v vector\" to=\"output displacement\" />",
      "sideways.xml");
  EXPECT_NEAR(sideways.measured, 1.0, 1e-3);
  // The bumped normal replaces the shading normal itself (Cycles' set_normal), so a diffuse closure is not
  // "perturbed": no bump shadowing term, unlike the same bump linked into its normal socket (above).
  const Vec3 grazing = normalize(Vec3(0.8f, 0.0f, -0.6f));
  const BumpedRatio g = bumped_quad_ratio(
      grazing, -a, linear_height_nodes(a) + "<connect from=\"h value\" to=\"output displacement\" />",
      "displaced_grazing.xml");
  EXPECT_LT(g.shadowing, 0.95);
  EXPECT_NEAR(g.measured, g.cosines, 1e-3);
  EXPECT_GT(std::fabs(g.want() - g.measured), 0.05);  // negative control: the shadowing term applied
  // Blender's Displacement node: (height - midlevel) scale N, so its height along N is +h: the gradient (a, 0, 0).
  const BumpedRatio node = bumped_quad_ratio(
      L, a,
      linear_height_nodes(a) + "<displacement name=\"disp\" midlevel=\"0\" />\n"
                               "<connect from=\"h value\" to=\"disp height\" />\n"
                               "<connect from=\"disp displacement\" to=\"output displacement\" />",
      "displacement_node.xml");
  EXPECT_NEAR(node.measured, node.cosines, 1e-3);
  EXPECT_GT(std::fabs(node.cosines - r.cosines), 0.2);  // the two signs are told apart
}

TEST(ShadingNormalRender, TrueDisplacementIsReportedAndRendersAsBump) {
  const Vec3 L = normalize(Vec3(0.6f, 0.0f, -0.8f));
  std::ifstream in(sun_quad(
      "displaced_true.xml", L, linear_height_nodes(0.5f) + "<connect from=\"h value\" to=\"output displacement\" />"));
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string shader = "<shader name=\"s\">";
  text.replace(text.find(shader), shader.size(), "<shader name=\"s\" displacement_method=\"true\">");
  const std::string path = write_file("displaced_true.xml", text);
  std::vector<std::string> warnings;
  mean_red(path, &warnings);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("displacement_method 'true'"), std::string::npos) << warnings[0];
  const std::string method = "displacement_method=\"true\"";
  text.replace(text.find(method), method.size(), "displacement_method=\"fake\"");
  EXPECT_THROW(scene::load_scene(write_file("displaced_fake.xml", text)), scene::SceneError);
}

// Geometry node (Cycles svm_node_geometry) on a shading point: position, normal, true normal, incoming and
// backfacing read the point; the tangent is radial about z and perpendicular to N.
TEST(GeometryNode, ReadsTheShadingPoint) {
  ShadingPoint sp;
  sp.P = Vec3(1, 2, 3);
  sp.N = normalize(Vec3(0.1f, 0.2f, 1.0f));
  sp.Ng = Vec3(0, 0, 1);
  sp.direction = normalize(Vec3(0.3f, 0.0f, -1.0f));
  sp.backfacing = true;
  sp.generated = Vec3(0.9f, 0.5f, 0.2f);
  const auto out = [&](const char *socket) {
    return run(*compile({{"geometry", "g", {}, {"test.xml", 2}}}, {}, std::string("g ") + socket), sp);
  };
  const auto same = [](const Vec3 &a, const Vec3 &b) { return a.x == b.x && a.y == b.y && a.z == b.z; };
  EXPECT_TRUE(same(out("position"), sp.P));
  EXPECT_TRUE(same(out("normal"), sp.N));
  EXPECT_TRUE(same(out("true_normal"), sp.Ng));
  EXPECT_TRUE(same(out("incoming"), -sp.direction));
  EXPECT_EQ(out("backfacing").x, 1.0f);
  const Vec3 t = out("tangent");  // radial about z at generated (0.9, 0.5): (0, 0.4, 0), made perpendicular to N
  const Vec3 y(0, 1, 0), want = normalize(y - dot(y, sp.N) * sp.N);  // y's part in N's plane
  EXPECT_LT(length(t - want), 1e-6f);
  EXPECT_FALSE(same(out("normal"), out("true_normal")));  // negative control: the two normals are told apart
}

}  // namespace
}  // namespace glimmer::test
