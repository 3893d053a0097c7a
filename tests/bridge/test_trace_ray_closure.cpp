// Host service trace_ray_closure (ABI 2.3, issue 12): a ray traced for a
// closure returns the hit (distance, point, shading and geometric normals,
// backfacing) and the closure found there with its varying parameter values at
// the hit. Scene: a frosted_glass quad at z = 3 whose roughness is a 2x2 uv
// checker (0.15 / 0.65), IOR 1.7, and a diffuse quad at z = 5 behind it.
// Checks: both checker cells report their own roughness (a host that handed
// the instance's constant, or the other cell's value, fails); the instance is
// the scene's frosted material itself (a closure recognises "the same
// material"); the diffuse quad reports a different type; a miss returns 0; the
// hit's backfacing follows the ray's side; a GlimmerHitClosure whose
// struct_size does not hold the fields (an older plugin's buffer) is not written.
#include <cstring>
#include <random>

#include "render_test_util.h"

namespace glimmer::test {
namespace {

std::string frosted_quads_scene() {
  return write_file(
      "trace_closure.xml",
      "<cycles>\n<camera width=\"8\" height=\"8\" fov=\"0.7\" />\n<camera />\n"
      "<shader name=\"frost\">\n<texture_coordinate name=\"tc\" />\n"
      "<checker_texture name=\"c\" scale=\"2\" color1=\"0.15 0.15 0.15\" color2=\"0.65 0.65 0.65\" />\n"
      "<connect from=\"tc uv\" to=\"c vector\" />\n"
      "<frosted_glass_bsdf name=\"g\" roughness=\"0.3\" ior=\"1.7\" />\n"
      "<connect from=\"c color\" to=\"g roughness\" />\n"
      "<connect from=\"g bsdf\" to=\"output surface\" />\n</shader>\n"
      "<shader name=\"matte\">\n<diffuse_bsdf name=\"d\" color=\"0.5 0.5 0.5\" />\n"
      "<connect from=\"d bsdf\" to=\"output surface\" />\n</shader>\n"
      "<state shader=\"frost\"><mesh P=\"-1 -1 3  1 -1 3  1 1 3  -1 1 3\" nverts=\"4\" verts=\"0 1 2 3\" "
      "UV=\"0 0 1 0 1 1 0 1\" /></state>\n"
      "<state shader=\"matte\"><mesh P=\"-4 -4 5  4 -4 5  4 4 5  -4 4 5\" nverts=\"4\" verts=\"0 1 2 3\" /></state>\n"
      "</cycles>\n");
}

struct Traced {
  int hit = 0;
  GlimmerRayHit h{};
  GlimmerHitClosure c{};
};

Traced trace(const GlimmerHostServices &host, const Vec3 &o, const Vec3 &d) {
  Traced t;
  GlimmerRay ray{};
  ray.struct_size = sizeof ray;
  ray.origin = o;
  ray.direction = d;
  ray.t_min = 0.0f;
  ray.t_max = 1e30f;
  t.h.struct_size = sizeof t.h;
  t.c.struct_size = sizeof t.c;
  t.hit = host.trace_ray_closure(host.host_data, &ray, &t.h, &t.c);
  return t;
}

float varying_value(const GlimmerHitClosure &c, const char *param) {
  for (uint32_t i = 0; i < c.varying_count; ++i)
    if (std::strcmp(c.type->params[c.varying[i].param].name, param) == 0) return c.varying[i].value[0];
  return -1.0f;
}

TEST(TraceRayClosure, ReturnsHitNormalsAndTheClosureWithItsValuesThere) {
  const scene::Scene scene = scene::load_scene(frosted_quads_scene());
  render::RenderOptions opt;
  opt.samples = 1;
  render::Renderer renderer(scene, plugin(), opt);
  const GlimmerHostServices &host = renderer.host_services();
  ASSERT_TRUE(GLIMMER_HAS_FIELD(host.struct_size, GlimmerHostServices, trace_ray_closure));
  ASSERT_NE(host.trace_ray_closure, nullptr);

  // uv = (x + 1) / 2: the checker (scale 2) has cell (0, 0) at x, y < 0 and cell (1, 0) at x > 0, y < 0.
  const Traced a = trace(host, Vec3(-0.5f, -0.5f, 0.0f), Vec3(0, 0, 1));
  const Traced b = trace(host, Vec3(0.5f, -0.5f, 0.0f), Vec3(0, 0, 1));
  ASSERT_EQ(a.hit, 1);
  ASSERT_EQ(b.hit, 1);
  EXPECT_NEAR(a.h.t, 3.0f, 1e-5f);
  EXPECT_NEAR(a.h.P.z, 3.0f, 1e-5f);
  EXPECT_NEAR(std::fabs(a.h.Ng.z), 1.0f, 1e-6f);
  EXPECT_NEAR(std::fabs(a.h.N.z), 1.0f, 1e-5f);
  // ABI 2.3 convention (closure_abi.h): N and Ng face the ray's origin; the ray travels along +z.
  EXPECT_LT(a.h.Ng.z, 0.0f);
  EXPECT_LT(a.h.N.z, 0.0f);
  ASSERT_NE(a.c.type, nullptr);
  EXPECT_STREQ(a.c.type->name, "frosted_glass");
  EXPECT_NE(a.c.instance, nullptr);
  EXPECT_EQ(a.c.instance, b.c.instance);  // one material: the same instance at both points
  const float ra = varying_value(a.c, "roughness"), rb = varying_value(b.c, "roughness");
  EXPECT_NEAR(ra + rb, 0.8f, 1e-5f);  // one cell 0.15, the other 0.65 (not the constant 0.3)
  EXPECT_NEAR(std::fabs(ra - rb), 0.5f, 1e-5f);
  std::printf("[trace_ray_closure] t %.6f, Ng.z %+.1f, backfacing %u, %s, roughness %.3f / %.3f at the two cells\n",
              double(a.h.t), double(a.h.Ng.z), a.h.backfacing, a.c.type->name, double(ra), double(rb));

  // From the other side: backfacing flips.
  const Traced back = trace(host, Vec3(-0.5f, -0.5f, 4.0f), Vec3(0, 0, -1));
  ASSERT_EQ(back.hit, 1);
  EXPECT_NEAR(back.h.t, 1.0f, 1e-5f);
  EXPECT_NE(back.h.backfacing, a.h.backfacing);
  EXPECT_GT(back.h.Ng.z, 0.0f);  // facing the origin above
  EXPECT_GT(back.h.N.z, 0.0f);
  EXPECT_EQ(back.c.instance, a.c.instance);

  // Past the frosted quad: the diffuse one, another type and instance.
  const Traced d = trace(host, Vec3(2.0f, 0.0f, 0.0f), Vec3(0, 0, 1));
  ASSERT_EQ(d.hit, 1);
  EXPECT_NEAR(d.h.t, 5.0f, 1e-5f);
  ASSERT_NE(d.c.type, nullptr);
  EXPECT_STREQ(d.c.type->name, "diffuse");
  EXPECT_NE(d.c.instance, a.c.instance);

  // A miss.
  EXPECT_EQ(trace(host, Vec3(0, 0, 0), Vec3(0, 0, -1)).hit, 0);

  // An older plugin's buffer (struct_size without the fields) is left alone.
  GlimmerRay ray{sizeof(GlimmerRay), Vec3(-0.5f, -0.5f, 0.0f), Vec3(0, 0, 1), 0.0f, 1e30f};
  GlimmerRayHit h{};
  h.struct_size = sizeof h;
  GlimmerHitClosure small{};
  small.struct_size = offsetof(GlimmerHitClosure, varying);
  small.varying_count = 77;
  ASSERT_EQ(host.trace_ray_closure(host.host_data, &ray, &h, &small), 1);
  EXPECT_EQ(small.varying_count, 77u);
  EXPECT_EQ(small.type, nullptr);
}


// trace_ray_closure copies, for a mesh whose shader is constant (CompiledShader::reads_footprint false), a
// description made once per mesh instead of evaluating the shader at every hit. Checked against what evaluating
// the shader at the hit finds (Renderer::trace_ray_closure_shaded) at 4000 rays through a scene of constant
// shaders (a frosted sphere-like box, a constant mix of a diffuse and a glossy whose glossy has the larger
// weight, an emission + diffuse add whose emission is skipped, a frosted quad with a constant roughness) and
// the textured frosted quad (not constant: described per hit): every hit's type, instance and varying values
// are equal. Negative control: the textured quad described once (its first hit's description copied to every
// hit, what the cache would do if it took a varying shader for constant) differs at many of its hits.
bool same_description(const GlimmerHitClosure &a, const GlimmerHitClosure &b) {
  if (a.type != b.type || a.instance != b.instance || a.varying_count != b.varying_count) return false;
  for (uint32_t i = 0; i < a.varying_count; ++i)
    if (a.varying[i].param != b.varying[i].param ||
        std::memcmp(a.varying[i].value, b.varying[i].value, sizeof a.varying[i].value) != 0)
      return false;
  return true;
}

TEST(TraceRayClosure, ConstantShadersAreDescribedAsShadingFindsThem) {
  const std::string xml = write_file(
      "trace_closure_constant.xml",
      "<cycles>\n<camera width=\"8\" height=\"8\" fov=\"0.7\" />\n<camera />\n"
      "<shader name=\"frost_tex\">\n<texture_coordinate name=\"tc\" />\n"
      "<checker_texture name=\"c\" scale=\"4\" color1=\"0.15 0.15 0.15\" color2=\"0.65 0.65 0.65\" />\n"
      "<connect from=\"tc uv\" to=\"c vector\" />\n"
      "<frosted_glass_bsdf name=\"g\" roughness=\"0.3\" ior=\"1.7\" />\n"
      "<connect from=\"c color\" to=\"g roughness\" />\n"
      "<connect from=\"g bsdf\" to=\"output surface\" />\n</shader>\n"
      "<shader name=\"frost\"><frosted_glass_bsdf name=\"g\" roughness=\"0.5\" ior=\"1.5\" />"
      "<connect from=\"g bsdf\" to=\"output surface\" /></shader>\n"
      "<shader name=\"mix\"><diffuse_bsdf name=\"d\" color=\"0.8 0.8 0.8\" />"
      "<glossy_bsdf name=\"gl\" distribution=\"ggx\" roughness=\"0.4\" color=\"1 1 1\" />"
      "<mix_closure name=\"m\" fac=\"0.7\" /><connect from=\"d bsdf\" to=\"m closure1\" />"
      "<connect from=\"gl bsdf\" to=\"m closure2\" /><connect from=\"m closure\" to=\"output surface\" /></shader>\n"
      "<shader name=\"glowing\"><emission name=\"e\" color=\"4 4 4\" strength=\"1\" />"
      "<diffuse_bsdf name=\"d\" color=\"0.3 0.3 0.3\" /><add_closure name=\"a\" />"
      "<connect from=\"e emission\" to=\"a closure1\" /><connect from=\"d bsdf\" to=\"a closure2\" />"
      "<connect from=\"a closure\" to=\"output surface\" /></shader>\n"
      "<state shader=\"frost_tex\"><mesh P=\"-1 -1 3  1 -1 3  1 1 3  -1 1 3\" nverts=\"4\" verts=\"0 1 2 3\" "
      "UV=\"0 0 1 0 1 1 0 1\" /></state>\n"
      "<state shader=\"frost\"><mesh P=\"1.2 -1 3  3 -1 3  3 1 3  1.2 1 3\" nverts=\"4\" verts=\"0 1 2 3\" /></state>\n"
      "<state shader=\"mix\"><mesh P=\"-3 -1 3  -1.2 -1 3  -1.2 1 3  -3 1 3\" nverts=\"4\" verts=\"0 1 2 3\" /></state>\n"
      "<state shader=\"glowing\"><mesh P=\"-4 -4 5  4 -4 5  4 4 5  -4 4 5\" nverts=\"4\" verts=\"0 1 2 3\" /></state>\n"
      "</cycles>\n");
  const scene::Scene scene = scene::load_scene(xml);
  render::RenderOptions opt;
  opt.samples = 1;
  render::Renderer renderer(scene, plugin(), opt);
  const GlimmerHostServices &host = renderer.host_services();

  std::mt19937 gen(20261204u);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  const auto uniform = [&] { return u01(gen); };
  int hits = 0, equal = 0, textured_hits = 0, control_differs = 0;
  int per_mesh[4] = {0, 0, 0, 0};
  bool have_first_textured = false;
  GlimmerHitClosure first_textured{};
  for (int i = 0; i < 4000; ++i) {
    // From both sides of the quads (backfacing hits too), toward points spread over them.
    const bool front = i % 2 == 0;
    const Vec3 o(float(uniform() * 2.0 - 1.0), float(uniform() * 2.0 - 1.0), front ? 0.0f : 4.0f);
    const Vec3 target(float(uniform() * 7.0 - 3.5), float(uniform() * 2.4 - 1.2), 3.0f);
    const Vec3 d = normalize(target - o);
    const Traced cached = trace(host, o, d);
    GlimmerRay ray{sizeof(GlimmerRay), o, d, 0.0f, 1e30f};
    GlimmerRayHit h{};
    h.struct_size = sizeof h;
    GlimmerHitClosure shaded{};
    shaded.struct_size = sizeof shaded;
    const int hit = renderer.trace_ray_closure_shaded(ray, h, shaded);
    ASSERT_EQ(hit, cached.hit);
    if (!hit) continue;
    ++hits;
    ASSERT_EQ(h.object_id, cached.h.object_id);
    ASSERT_LT(h.object_id, 4u);
    ++per_mesh[h.object_id];
    if (same_description(cached.c, shaded)) ++equal;
    if (h.object_id == 0) {  // the textured quad
      ++textured_hits;
      if (!have_first_textured) {
        first_textured = shaded;
        have_first_textured = true;
      }
      if (!same_description(first_textured, shaded)) ++control_differs;
    }
  }
  std::printf("[trace_ray_closure constant] %d hits (per mesh %d / %d / %d / %d), %d descriptions equal; control: "
              "the textured quad described once differs at %d of %d hits\n",
              hits, per_mesh[0], per_mesh[1], per_mesh[2], per_mesh[3], equal, control_differs, textured_hits);
  for (int m = 0; m < 4; ++m) EXPECT_GT(per_mesh[m], 200) << "mesh " << m;
  EXPECT_EQ(equal, hits);
  EXPECT_GT(control_differs, textured_hits / 4);
  // What the constant shaders' descriptions hold: the mix's glossy (weight 0.7 > 0.3), the add's diffuse (the
  // emission is skipped), the frosted quad's instance with no varying values.
  const Traced mix = trace(host, Vec3(-2.0f, 0.0f, 0.0f), Vec3(0, 0, 1));
  ASSERT_EQ(mix.hit, 1);
  ASSERT_NE(mix.c.type, nullptr);
  EXPECT_STREQ(mix.c.type->name, "microfacet_conductor");
  const Traced glow = trace(host, Vec3(0.0f, 3.0f, 0.0f), Vec3(0, 0, 1));
  ASSERT_EQ(glow.hit, 1);
  ASSERT_NE(glow.c.type, nullptr);
  EXPECT_STREQ(glow.c.type->name, "diffuse");
  const Traced frost = trace(host, Vec3(2.0f, 0.0f, 0.0f), Vec3(0, 0, 1));
  ASSERT_EQ(frost.hit, 1);
  ASSERT_NE(frost.c.type, nullptr);
  EXPECT_STREQ(frost.c.type->name, "frosted_glass");
  EXPECT_EQ(frost.c.varying_count, 0u);
}

}  // namespace
}  // namespace glimmer::test
