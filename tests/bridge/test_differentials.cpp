// Ray differentials and the uv footprint handed to closures (Igehy 1999),
// checked against the analytic pixel footprint; camera orientation; PLY meshes.
#include "render_test_util.h"

namespace glimmer::test {
namespace {

constexpr int kW = 64, kH = 48;
constexpr float kFov = 0.6f;

// World size of one pixel at distance `d` along the optical axis (fov across the shorter side).
float pixel_size(float d) { return d * 2.0f * std::tan(0.5f * kFov) / kH; }

std::unique_ptr<render::Renderer> make_renderer(const std::string &name, const std::string &body, scene::Scene &scene) {
  const std::string path = write_file(name, "<cycles>\n<camera width=\"" + std::to_string(kW) + "\" height=\"" +
                                                std::to_string(kH) + "\" fov=\"" + std::to_string(kFov) +
                                                "\" />\n<camera />\n" + body + "</cycles>\n");
  scene = scene::load_scene(path);
  render::RenderOptions opt;
  return std::make_unique<render::Renderer>(scene, plugin(), opt);
}

TEST(Differentials, PlaneFacingTheCamera) {
  // Plane z = 3, 4 x 4 units, u = (x + 2) / 4, v = (y + 2) / 4.
  scene::Scene scene;
  auto r = make_renderer("diff_plane.xml",
                         "<mesh P=\"-2 -2 3  2 -2 3  2 2 3  -2 2 3\" nverts=\"4\" verts=\"0 1 2 3\" UV=\"0 0 1 0 1 1 0 1\" />\n",
                         scene);
  GlimmerShadingContext ctx{};
  ASSERT_TRUE(r->probe(kW * 0.5f, kH * 0.5f, ctx));
  const float expected = pixel_size(3.0f) / 4.0f;  // uv per pixel
  EXPECT_NEAR(ctx.duv_dx[0], expected, 1e-3f * expected + 1e-7f);
  EXPECT_NEAR(ctx.duv_dx[1], 0.0f, 1e-6f);
  EXPECT_NEAR(ctx.duv_dy[0], 0.0f, 1e-6f);
  EXPECT_NEAR(ctx.duv_dy[1], -expected, 1e-3f * expected + 1e-7f);  // image y runs down, v up
  EXPECT_EQ(ctx.spread_angle, 0.0f);
  // Tangent frame from the UVs: dPdu = (4, 0, 0), T = +x.
  EXPECT_NEAR(ctx.dPdu.x, 4.0f, 1e-4f);
  EXPECT_NEAR(ctx.dPdv.y, 4.0f, 1e-4f);
  EXPECT_NEAR(ctx.T.x, 1.0f, 1e-5f);
  EXPECT_NEAR(std::fabs(ctx.uv[0] - 0.5f) + std::fabs(ctx.uv[1] - 0.5f), 0.0f, 0.02f);
  // A grazing plane stretches the footprint along the slope: plane tilted 60 degrees about x.
  scene::Scene tilted_scene;
  const float c = std::cos(1.0471976f), s = std::sin(1.0471976f);
  char p[512];
  std::snprintf(p, sizeof(p), "<mesh P=\"-2 %f %f  2 %f %f  2 %f %f  -2 %f %f\" nverts=\"4\" verts=\"0 1 2 3\" UV=\"0 0 1 0 1 1 0 1\" />\n",
                -2 * c, 3 - 2 * s, -2 * c, 3 - 2 * s, 2 * c, 3 + 2 * s, 2 * c, 3 + 2 * s);
  auto tilted = make_renderer("diff_tilted.xml", p, tilted_scene);
  ASSERT_TRUE(tilted->probe(kW * 0.5f, kH * 0.5f, ctx));
  // Along y the footprint grows by 1 / cos(60 deg) = 2 (the plane is tilted away by 60 degrees).
  EXPECT_NEAR(std::fabs(ctx.duv_dy[1]), 2.0f * expected, 0.02f * expected);
  EXPECT_NEAR(ctx.duv_dx[0], expected, 0.01f * expected);
}

TEST(Differentials, ThroughAPlanarMirror) {
  if (!plugin().find("microfacet_conductor")) GTEST_SKIP() << "needs microfacet_conductor (sharp mirror)";
  // Mirror through (0,0,2) with normal (0,1,-1)/sqrt2 turns +z into +y; target plane y = 3 faces -y.
  // Total path 2 + 3 = 5: a planar mirror keeps the footprint of a plane at distance 5.
  scene::Scene scene;
  auto r = make_renderer(
      "diff_mirror.xml",
      "<shader name=\"mirror\"><glossy_bsdf name=\"m\" distribution=\"sharp\" color=\"1 1 1\" />"
      "<connect from=\"m bsdf\" to=\"output surface\" /></shader>\n"
      "<state shader=\"mirror\"><mesh P=\"-1 -0.7 1.3  1 -0.7 1.3  1 0.7 2.7  -1 0.7 2.7\" nverts=\"4\" verts=\"0 1 2 3\" /></state>\n"
      "<mesh P=\"-2 3 0  2 3 0  2 3 4  -2 3 4\" nverts=\"4\" verts=\"0 1 2 3\" UV=\"0 0 1 0 1 1 0 1\" />\n",
      scene);
  GlimmerShadingContext ctx{};
  ASSERT_TRUE(r->probe(kW * 0.5f, kH * 0.5f, ctx));
  EXPECT_NEAR(ctx.P.y, 3.0f, 1e-3f);
  const float expected = pixel_size(5.0f) / 4.0f;
  const float fx = std::hypot(ctx.duv_dx[0], ctx.duv_dx[1]), fy = std::hypot(ctx.duv_dy[0], ctx.duv_dy[1]);
  EXPECT_NEAR(fx, expected, 0.01f * expected);
  EXPECT_NEAR(fy, expected, 0.01f * expected);
  // Without differential propagation the footprint would stay that of distance 2 or 3, not 5.
  EXPECT_GT(fx, 1.5f * pixel_size(3.0f) / 4.0f);
}

// A thin frosted pane (method=path) returns its walk between the faces as one singular sample: the path behind it
// must still widen by the pane's roughness (beta = 2 alpha, alpha = roughness^2), as a rough closure's does; a
// sharp mirror (roughness 0, ThroughAPlanarMirror) keeps spread 0.
TEST(Differentials, ARoughPaneWidensThePathBehindIt) {
  if (!plugin().find("frosted_glass")) GTEST_SKIP() << "needs frosted_glass";
  for (const float roughness : {0.1f, 0.3f, 0.6f}) {
    scene::Scene scene;
    char body[1024];
    std::snprintf(body, sizeof(body),
                  "<shader name=\"pane\"><frosted_glass_bsdf name=\"g\" roughness=\"%g\" ior=\"1.5\" thin=\"1\" "
                  "thickness=\"0.02\" method=\"path\" /><connect from=\"g bsdf\" to=\"output surface\" /></shader>\n"
                  "<state shader=\"pane\"><mesh P=\"-2 -2 2  2 -2 2  2 2 2  -2 2 2\" nverts=\"4\" verts=\"0 1 2 3\" />"
                  "</state>\n<mesh P=\"-4 -4 5  4 -4 5  4 4 5  -4 4 5\" nverts=\"4\" verts=\"0 1 2 3\" "
                  "UV=\"0 0 1 0 1 1 0 1\" />\n",
                  double(roughness));
    auto r = make_renderer("diff_pane.xml", body, scene);
    GlimmerShadingContext ctx{};
    ASSERT_TRUE(r->probe(kW * 0.5f, kH * 0.5f, ctx)) << roughness;
    EXPECT_NEAR(ctx.P.z, 5.0f, 1e-3f) << "the probe stops at the plane behind the pane";
    EXPECT_NEAR(ctx.spread_angle, 2.0f * roughness * roughness, 1e-5f) << roughness;
  }
}

// Depth of field: seen through lens points at radius A that all focus at depth f, a point at depth d
// spreads over the circle of confusion of radius A |1 - d / f| (P(d) = (d / f) focus + (1 - d / f) lens).
// The footprint at the first hit adds it to the pixel's: on the 4-unit plane facing the camera,
// duv = (pixel_size(d) + A |1 - d / f|) / 4 before, on and behind the focal plane. (Aperture 0 keeps the
// pinhole footprint: images without depth of field are bit-identical, see docs/architecture.md.)
TEST(Differentials, DepthOfFieldWidensTheFootprintByTheCircleOfConfusion) {
  const float A = 0.1f, f = 6.0f;
  auto probe_plane = [&](float aperture, float d, GlimmerShadingContext &ctx) {
    const std::string z = std::to_string(d);
    const std::string path = write_file(
        "dof_plane.xml", "<cycles>\n<camera width=\"" + std::to_string(kW) + "\" height=\"" + std::to_string(kH) +
                             "\" fov=\"" + std::to_string(kFov) + "\" aperturesize=\"" + std::to_string(aperture) +
                             "\" focaldistance=\"" + std::to_string(f) + "\" />\n<camera />\n<mesh P=\"-2 -2 " + z +
                             "  2 -2 " + z + "  2 2 " + z + "  -2 2 " + z +
                             "\" nverts=\"4\" verts=\"0 1 2 3\" UV=\"0 0 1 0 1 1 0 1\" />\n</cycles>\n");
    const scene::Scene scene = scene::load_scene(path);
    render::RenderOptions opt;
    const render::Renderer r(scene, plugin(), opt);
    return r.probe(kW * 0.5f, kH * 0.5f, ctx);
  };
  for (const float d : {3.0f, 6.0f, 9.0f}) {
    GlimmerShadingContext lens{}, pinhole{};
    ASSERT_TRUE(probe_plane(A, d, lens));
    ASSERT_TRUE(probe_plane(0.0f, d, pinhole));
    const float coc = A * std::fabs(1.0f - d / f);
    const float expected = (pixel_size(d) + coc) / 4.0f;
    EXPECT_NEAR(lens.duv_dx[0], expected, 1e-3f * expected) << "depth " << d;
    EXPECT_NEAR(-lens.duv_dy[1], expected, 1e-3f * expected) << "depth " << d;
    EXPECT_NEAR(lens.duv_dx[1], 0.0f, 1e-6f);
    // The pinhole footprint (what the camera gave before): the circle of confusion is missing, a
    // difference the tolerance above catches except on the focal plane.
    EXPECT_NEAR(pinhole.duv_dx[0], pixel_size(d) / 4.0f, 1e-3f * expected);
    if (d != f) {
      EXPECT_GT(std::fabs(pinhole.duv_dx[0] - expected), 0.1f * expected);
    }
  }
}

// A ray through a tilted glass slab leaves parallel to its entry direction, shifted sideways:
// the exit refraction must use 1/ior (the host hands transmissive closures the front-face
// normal; the closure picks eta from the side of wi).
TEST(Transmission, SlabShiftsButKeepsTheDirection) {
  if (!plugin().find("microfacet_dielectric")) GTEST_SKIP() << "needs microfacet_dielectric";
  const float s = 0.70710678f;
  // Quads with outward normals (as a closed glass object has): front = n, back = -n.
  auto quad = [&](Vec3 c, bool front) {
    const Vec3 e1(2 * s, 0, 2 * s), e2(0, front ? -2.0f : 2.0f, 0);
    const Vec3 p[4] = {c - e1 - e2, c + e1 - e2, c + e1 + e2, c - e1 + e2};
    std::string out = "<mesh P=\"";
    for (const auto &v : p) out += std::to_string(v.x) + " " + std::to_string(v.y) + " " + std::to_string(v.z) + "  ";
    return out + "\" nverts=\"4\" verts=\"0 1 2 3\" />";
  };
  const Vec3 n(s, 0, -s);  // slab normal toward the camera
  scene::Scene scene;
  auto r = make_renderer("slab.xml",
                         "<shader name=\"glass\"><refraction_bsdf name=\"g\" IOR=\"1.5\" roughness=\"0\" />"
                         "<connect from=\"g bsdf\" to=\"output surface\" /></shader>\n"
                         "<state shader=\"glass\">" + quad(Vec3(0, 0, 2), true) + quad(Vec3(0, 0, 2) - n * 0.5f, false) + "</state>\n"
                         "<mesh P=\"-5 -5 5  5 -5 5  5 5 5  -5 5 5\" nverts=\"4\" verts=\"0 1 2 3\" />\n",
                         scene);
  GlimmerShadingContext ctx{};
  ASSERT_TRUE(r->probe(kW * 0.5f, kH * 0.5f, ctx));
  // Snell at 45 degrees into n = 1.5: theta_t = 28.13 deg; path 0.567 inside; exit point x = -0.1646.
  EXPECT_NEAR(ctx.P.z, 5.0f, 1e-3f);
  EXPECT_NEAR(ctx.P.x, -0.1646f, 0.003f);
  EXPECT_NEAR(ctx.P.y, 0.0f, 1e-3f);
}

TEST(Camera, LooksAlongPlusZWithYUp) {
  // A bright patch at +x (right) and one at +y (top), in front of the default camera.
  const std::string path = write_file(
      "orientation.xml",
      "<cycles>\n<camera width=\"40\" height=\"40\" fov=\"1.0\" />\n<camera />\n"
      "<shader name=\"glow\"><emission name=\"e\" color=\"1 1 1\" strength=\"1\" />"
      "<connect from=\"e emission\" to=\"output surface\" /></shader>\n"
      "<state shader=\"glow\">\n"
      "<mesh P=\"0.5 -0.2 3  1 -0.2 3  1 0.2 3  0.5 0.2 3\" nverts=\"4\" verts=\"0 1 2 3\" />\n"
      "<mesh P=\"-0.2 0.5 3  0.2 0.5 3  0.2 1 3  -0.2 1 3\" nverts=\"4\" verts=\"0 1 2 3\" />\n"
      "</state>\n</cycles>\n");
  render::RenderOptions opt;
  opt.samples = 4;
  const auto r = render_scene(path, opt);
  auto at = [&](int x, int y) { return r.combined[4 * (y * r.width + x)]; };
  EXPECT_GT(at(29, 20), 0.99f);  // right of centre (patch covers columns 27..31)
  EXPECT_EQ(at(7, 20), 0.0f);   // left of centre: nothing
  EXPECT_GT(at(20, 11), 0.99f);  // above centre (rows 8..13; row 0 is the top)
  EXPECT_EQ(at(20, 32), 0.0f);
}

TEST(Loader, PlyAndObjMeshes) {
  write_file("tri.ply",
             "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
             "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n");
  write_file("tri.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nf 1/1 2/2 3/3\n");
  const std::string path = write_file("meshes.xml", "<cycles>\n<mesh src=\"tri.ply\" />\n<mesh src=\"tri.obj\" />\n</cycles>\n");
  const scene::Scene s = scene::load_scene(path);
  ASSERT_EQ(s.meshes.size(), 2u);
  EXPECT_EQ(s.meshes[0].triangles.size(), 2u);
  EXPECT_EQ(s.meshes[1].triangles.size(), 1u);
  EXPECT_EQ(s.meshes[1].uv.size(), 3u);
  const std::string bad = write_file("badmesh.xml", "<cycles>\n\n<mesh src=\"nothing.ply\" />\n</cycles>\n");
  try {
    scene::load_scene(bad);
    FAIL() << "missing mesh file accepted";
  } catch (const scene::SceneError &e) {
    EXPECT_NE(std::string(e.what()).find("badmesh.xml:3:"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace glimmer::test
