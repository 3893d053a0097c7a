// One type per light kind (render/light_<kind>.h): for every kind, the pdf and
// radiance that sample() gives for a direction equal what the BSDF-hit path
// (intersect() / pdf()) computes for the same direction, so NEE and BSDF-hit
// emission get their MIS weights from one formula. The sampled densities are
// also checked against a brute-force quantity (the light's solid angle or 4 pi).
#include <cmath>

#include "render/light_area.h"
#include "render/light_background.h"
#include "render/light_distant.h"
#include "render/light_point.h"
#include "render/light_spot.h"
#include "render/light_triangle.h"
#include "glimmer/sampling.h"
#include "render_test_util.h"

namespace glimmer::test {
namespace {

using render::LightHit;
using render::LightSample;

constexpr float kPick = 0.37f;  // any pick probability: both paths multiply by it
const Vec3 kShadingPoint(0.2f, -0.3f, 0.1f);

// Stratified (u, v) pairs away from the domain's edges.
template <typename F>
void for_each_uv(int n, F f) {
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) f((i + 0.5f) / n, (j + 0.5f) / n);
}

void expect_same(const LightSample &ls, const LightHit &h, const char *what) {
  EXPECT_NEAR(h.pdf, ls.pdf, 1e-4f * ls.pdf) << what;
  EXPECT_NEAR(h.t, ls.dist, 1e-4f * ls.dist) << what;
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(h.radiance[c], ls.radiance[c], 1e-5f * ls.radiance[c] + 1e-9f) << what;
}

// For a lamp kind with intersect(o, d, t_max, pick, hit): every sampled direction, traced from the shading
// point, hits the lamp with the sample's pdf, distance and radiance. Returns the number of samples taken.
template <typename Lamp>
int check_lamp_consistency(const Lamp &lamp, const char *what) {
  int taken = 0;
  for_each_uv(24, [&](float u, float v) {
    LightSample ls;
    if (!lamp.sample(u, v, kShadingPoint, kPick, ls)) return;
    ++taken;
    LightHit h;
    ASSERT_TRUE(lamp.intersect(kShadingPoint, ls.wi, std::numeric_limits<float>::infinity(), kPick, h)) << what;
    expect_same(ls, h, what);
  });
  return taken;
}

// Mean of 1 / pdf over sampled directions (pick 1): the solid angle the light covers when every
// direction toward it can be sampled (pdf > 0 over it), whatever the density.
template <typename Light>
double sampled_solid_angle(const Light &light, int n) {
  double sum = 0.0;
  for_each_uv(n, [&](float u, float v) {
    LightSample ls;
    if (light.sample(u, v, kShadingPoint, 1.0f, ls) && ls.pdf > 0.0f) sum += 1.0 / ls.pdf;
  });
  return sum / (n * n);
}

scene::Light lamp(scene::LightType type) {
  scene::Light l;
  l.type = type;
  l.co = Vec3(0.5f, 0.4f, 2.0f);
  l.dir = normalize(Vec3(-0.2f, -0.3f, -1.0f));
  return l;
}

TEST(LightKinds, PointDiskSampleMatchesIntersect) {
  scene::Light l = lamp(scene::LightType::Point);
  l.radius = 0.3f;
  const render::PointLight point(l, Spectrum(10.0f));
  EXPECT_EQ(check_lamp_consistency(point, "point"), 24 * 24);
  // Brute force: the disk of radius r at distance d facing P subtends 2 pi (1 - d / sqrt(d^2 + r^2)).
  const float d = length(l.co - kShadingPoint);
  const double omega = 2.0 * M_PI * (1.0 - d / std::sqrt(d * d + l.radius * l.radius));
  EXPECT_NEAR(sampled_solid_angle(point, 64), omega, 0.01 * omega);
  // A point lamp (radius 0) is a delta light that rays never hit.
  l.radius = 0.0f;
  const render::PointLight delta(l, Spectrum(10.0f));
  LightSample ls;
  ASSERT_TRUE(delta.sample(0.5f, 0.5f, kShadingPoint, kPick, ls));
  EXPECT_TRUE(ls.delta);
  EXPECT_EQ(ls.pdf, kPick);
  LightHit h;
  EXPECT_FALSE(delta.intersect(kShadingPoint, ls.wi, std::numeric_limits<float>::infinity(), kPick, h));
}

TEST(LightKinds, SpotSampleMatchesIntersect) {
  scene::Light l = lamp(scene::LightType::Spot);
  l.radius = 0.2f;
  l.dir = normalize(kShadingPoint - l.co);
  l.spot_angle = 1.2f;
  l.spot_smooth = 0.4f;
  const render::SpotLight spot(l, Spectrum(50.0f));
  EXPECT_EQ(check_lamp_consistency(spot, "spot"), 24 * 24);
  // Outside the cone: no sample, no hit.
  l.dir = -l.dir;
  const render::SpotLight away(l, Spectrum(50.0f));
  LightSample ls;
  EXPECT_FALSE(away.sample(0.5f, 0.5f, kShadingPoint, kPick, ls));
}

TEST(LightKinds, AreaQuadDiskAndSpreadSampleMatchesIntersect) {
  scene::Light l = lamp(scene::LightType::Area);
  l.axisu = Vec3(1, 0, 0);
  l.axisv = Vec3(0, 1, 0);
  l.sizeu = 1.2f;
  l.sizev = 0.8f;
  l.dir = Vec3(0, 0, -1);
  const render::AreaLight quad(l, Spectrum(10.0f));
  EXPECT_EQ(check_lamp_consistency(quad, "area quad"), 24 * 24);
  // Brute force: the quad's solid angle by midpoint integration of cos / d^2 over its area.
  double omega = 0.0;
  const int n = 400;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const Vec3 q = l.co + Vec3(((i + 0.5f) / n - 0.5f) * l.sizeu, ((j + 0.5f) / n - 0.5f) * l.sizev, 0.0f);
      const Vec3 to = q - kShadingPoint;
      const double d2 = length_squared(to);
      omega += (to.z / std::sqrt(d2)) / d2 * (l.sizeu * l.sizev) / (n * n);  // cos at the light (normal -z) / d^2
    }
  EXPECT_NEAR(sampled_solid_angle(quad, 64), omega, 0.01 * omega);
  l.round = true;
  const render::AreaLight disk(l, Spectrum(10.0f));
  EXPECT_GT(check_lamp_consistency(disk, "area disk"), 24 * 24 / 2);
  l.round = false;
  l.spread = 0.9f;
  const render::AreaLight spread(l, Spectrum(10.0f));
  check_lamp_consistency(spread, "area spread");
}

TEST(LightKinds, SunDiskSampleMatchesIntersect) {
  scene::Light l = lamp(scene::LightType::Sun);
  l.angle = 0.4f;
  const render::DistantLight sun(l, Spectrum(3.0f));
  int taken = 0;
  for_each_uv(24, [&](float u, float v) {
    LightSample ls;
    ASSERT_TRUE(sun.sample(u, v, kShadingPoint, kPick, ls));
    ++taken;
    LightHit h;
    EXPECT_FALSE(sun.intersect(kShadingPoint, ls.wi, std::numeric_limits<float>::infinity(), true, kPick, h))
        << "the sun is seen only by rays that escape";
    ASSERT_TRUE(sun.intersect(kShadingPoint, ls.wi, std::numeric_limits<float>::infinity(), false, kPick, h));
    EXPECT_TRUE(std::isinf(ls.dist) && std::isinf(h.t));
    ls.dist = h.t = 1.0f;
    expect_same(ls, h, "sun");
  });
  EXPECT_EQ(taken, 24 * 24);
  // Brute force: the cone of half-angle a/2 subtends 2 pi (1 - cos(a/2)).
  const double omega = 2.0 * M_PI * (1.0 - std::cos(0.5 * l.angle));
  EXPECT_NEAR(sampled_solid_angle(sun, 64), omega, 0.01 * omega);
}

// A scene with an emissive quad and a textured world, for the kinds that need the shader system.
struct ShadedScene {
  scene::Scene scene;
  std::vector<std::string> warnings;
  render::FeatureSet features;
  std::unique_ptr<render::ShaderSystem> shaders;
  int emissive = -1;
  ShadedScene() {
    scene = scene::load_scene(write_file(
        "light_kinds.xml",
        "<cycles>\n<camera width=\"8\" height=\"8\" />\n<camera />\n"
        "<background><checker_texture name=\"c\" scale=\"3\" color1=\"0.9 0.8 0.7\" color2=\"0.05 0.05 0.1\" />"
        "<background name=\"bg\" strength=\"1\" /><connect from=\"c color\" to=\"bg color\" />"
        "<connect from=\"bg background\" to=\"output surface\" /></background>\n"
        "<shader name=\"glow\"><emission name=\"e\" color=\"0.2 1 0.3\" strength=\"3\" />"
        "<connect from=\"e emission\" to=\"output surface\" /></shader>\n"
        "<state shader=\"glow\"><mesh P=\"-1 1 0.2  0.5 1.2 0.4  -0.3 1.5 1.6\" nverts=\"3\" verts=\"0 1 2\" /></state>\n"
        "</cycles>\n"));
    shaders = std::make_unique<render::ShaderSystem>(scene, plugin(), nullptr, warnings, features);
    emissive = shaders->compile(scene.meshes[0].shader);
    shaders->compile_background(scene.background.shader);
  }
};

TEST(LightKinds, TriangleSampleMatchesHitPdf) {
  ShadedScene s;
  const scene::Mesh &mesh = s.scene.meshes[0];
  const auto &tri = mesh.triangles[0];
  const float area = 0.5f * length(cross(mesh.P[tri[1]] - mesh.P[tri[0]], mesh.P[tri[2]] - mesh.P[tri[0]]));
  const render::TriangleLight light(mesh, 0, area, *s.shaders, s.emissive);
  ASSERT_TRUE(light.power().has_value());
  int taken = 0;
  for_each_uv(24, [&](float u, float v) {
    LightSample ls;
    if (!light.sample(u, v, kShadingPoint, kPick, ls)) return;
    ++taken;
    // What a BSDF ray along wi finds: the hit point and normal from the mesh, the light's pdf for it.
    const Vec3 P = kShadingPoint + ls.wi * ls.dist;
    const Vec3 Ng = normalize(cross(mesh.P[tri[1]] - mesh.P[tri[0]], mesh.P[tri[2]] - mesh.P[tri[0]]));
    EXPECT_NEAR(light.pdf(kPick, kShadingPoint, P, Ng, ls.wi), ls.pdf, 1e-4f * ls.pdf);
    EXPECT_NEAR(ls.radiance.y, 3.0f, 1e-4f);  // emission color * strength
  });
  EXPECT_EQ(taken, 24 * 24);
  // Negative control: a pdf without the cosine (a known class of bug) is caught by the same tolerance.
  LightSample ls;
  ASSERT_TRUE(light.sample(0.3f, 0.2f, kShadingPoint, kPick, ls));
  const float wrong = kPick * ls.dist * ls.dist / area;
  EXPECT_GT(std::fabs(wrong - ls.pdf), 1e-4f * ls.pdf);
}

TEST(LightKinds, BackgroundSampleMatchesEscapePdf) {
  ShadedScene s;
  ASSERT_FALSE(s.shaders->background_is_constant());
  const render::BackgroundLight world(*s.shaders);
  for_each_uv(24, [&](float u, float v) {
    LightSample ls;
    ASSERT_TRUE(world.sample(u, v, kShadingPoint, kPick, ls));
    EXPECT_NEAR(kPick * world.pdf(ls.wi), ls.pdf, 1e-5f * ls.pdf);
    const Spectrum L = s.shaders->background(ls.wi);
    for (int c = 0; c < 3; ++c) EXPECT_EQ(ls.radiance[c], L[c]);
  });
  // Brute force: the map's density covers the whole sphere, so the mean of 1 / pdf over its samples is 4 pi,
  // and the mean of pdf over uniform directions is 1 / (4 pi) (the pdf integrates to 1).
  EXPECT_NEAR(sampled_solid_angle(world, 200), 4.0 * M_PI, 0.02 * 4.0 * M_PI);
  double mean_pdf = 0.0;
  const int n = 200;
  for_each_uv(n, [&](float u, float v) { mean_pdf += world.pdf(sample_uniform_sphere(u, v)) / (n * n); });
  EXPECT_NEAR(mean_pdf * 4.0 * M_PI, 1.0, 0.02);
}

}  // namespace
}  // namespace glimmer::test
