// The object-space fields of the shading context (closure ABI 2.5:
// P_object, dPdx_object, dPdy_object, Ng_object) as the renderer fills them,
// checked against the scene's own object transform: mapped back to world
// space they give the context's point, its uv footprint on the surface and
// its geometric normal.
#include <cstddef>

#include "render_test_util.h"

namespace glimmer::test {
namespace {

constexpr int kW = 64, kH = 48;

std::unique_ptr<render::Renderer> make_renderer(const std::string &name, const std::string &body, scene::Scene &scene) {
  const std::string path = write_file(name, "<cycles>\n<camera width=\"" + std::to_string(kW) + "\" height=\"" +
                                                std::to_string(kH) + "\" fov=\"0.6\" />\n<camera />\n" + body +
                                                "</cycles>\n");
  scene = scene::load_scene(path);
  render::RenderOptions opt;
  return std::make_unique<render::Renderer>(scene, plugin(), opt);
}

::testing::AssertionResult near(const Vec3 &a, const Vec3 &b, float tolerance) {
  if (length(a - b) <= tolerance) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "(" << a.x << ", " << a.y << ", " << a.z << ") vs (" << b.x << ", " << b.y
                                       << ", " << b.z << "), tolerance " << tolerance;
}

// A quad in its object space (z = 0, 2 x 2 around the origin, u = (x + 1) / 2)
// placed by a translation, a rotation and a non-uniform scale in front of the
// camera. At several pixels: object_to_world(P_object) = P; the object-space
// steps mapped to world equal the uv footprint's steps on the surface
// (dPdu duv_dx[0] + dPdv duv_dx[1], likewise y); Ng_object is unit and maps to
// +-Ng. Negative control: P_object is not the world point (the transform is
// not the identity), and the world steps are not the object steps.
TEST(ObjectSpaceContext, FieldsMapBackToTheWorldPointFootprintAndNormal) {
  scene::Scene scene;
  auto r = make_renderer("object_space_quad.xml",
                         "<transform translate=\"0.3 -0.2 4\" rotate=\"25 1 0.5 0\" scale=\"1.5 0.8 1\">\n"
                         "<mesh P=\"-1 -1 0  1 -1 0  1 1 0  -1 1 0\" nverts=\"4\" verts=\"0 1 2 3\" "
                         "UV=\"0 0 1 0 1 1 0 1\" />\n</transform>\n",
                         scene);
  ASSERT_EQ(scene.meshes.size(), 1u);
  const scene::Transform &m = scene.meshes[0].object_to_world;
  int probed = 0;
  for (const auto &[px, py] : std::vector<std::pair<float, float>>{{32, 24}, {28, 20}, {36, 27}}) {
    GlimmerShadingContext ctx{};
    ASSERT_TRUE(r->probe(px, py, ctx));
    ASSERT_TRUE(GLIMMER_HAS_FIELD(ctx.struct_size, GlimmerShadingContext, Ng_object));
    ++probed;
    const Vec3 P(ctx.P), P_object(ctx.P_object);
    EXPECT_TRUE(near(m.point(P_object), P, 1e-4f));
    EXPECT_LT(std::fabs(P_object.z), 1e-4f);  // on the object's z = 0 quad
    EXPECT_GT(length(P_object - P), 1.0f);     // control: not the world point
    const Vec3 dPdx = Vec3(ctx.dPdu) * ctx.duv_dx[0] + Vec3(ctx.dPdv) * ctx.duv_dx[1];
    const Vec3 dPdy = Vec3(ctx.dPdu) * ctx.duv_dy[0] + Vec3(ctx.dPdv) * ctx.duv_dy[1];
    const float step = length(dPdx);
    ASSERT_GT(step, 0.0f);
    EXPECT_TRUE(near(m.vector(Vec3(ctx.dPdx_object)), dPdx, 1e-3f * step));
    EXPECT_TRUE(near(m.vector(Vec3(ctx.dPdy_object)), dPdy, 1e-3f * step));
    EXPECT_GT(length(Vec3(ctx.dPdx_object) - dPdx), 0.05f * step);  // control: the scale shows
    const Vec3 n_object(ctx.Ng_object);
    EXPECT_NEAR(length(n_object), 1.0f, 1e-5f);
    EXPECT_NEAR(std::fabs(n_object.z), 1.0f, 1e-5f);  // the quad's object-space normal
    EXPECT_NEAR(std::fabs(dot(normalize(m.normal(n_object)), Vec3(ctx.Ng))), 1.0f, 1e-5f);
  }
  EXPECT_EQ(probed, 3);
}

}  // namespace
}  // namespace glimmer::test
