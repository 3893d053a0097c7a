// frosted_glass method=sg (issue 12, de Rousiers 2012 in a ray tracer):
//  - accuracy: the radiance transmitted through a sphere and through a slab
//    (roughness 0.1..0.8, IOR 1.33..1.7), lit by a smooth environment, per
//    pixel of a tiny image, sg vs a path-traced reference (method=path,
//    16384 paths per pixel) computed in the same test: mean relative error per
//    scene. Transport is a brute-force tracer over analytic geometry whose
//    host answers trace_ray / trace_ray_closure as the renderer does (the
//    closure at the hit is the material under test). The reference's own
//    noise is reported (its standard error). Negative control: sg without the
//    refraction at the exit (the lobe keeps the internal axis) must fail.
//    The rest of the accuracy set: a non-convex solid (a sphere with a
//    spherical air cavity), a sphere with textured roughness (per-point values
//    at the entry and at every exit hit), a small light behind a slab; fast
//    (4096 / 1024 paths per pixel) in make test, 16384 / 2048 under make stress.
//  - method=auto: per shading point the samples are sg's where the rule picks
//    sg (roughness <= 0.3, or after a diffuse / glossy bounce) and path's
//    elsewhere, bit for bit;
//  - stress: no NaN / Inf / negative raw outputs over 1e6 sg queries (1e8
//    under make stress), TIR-heavy (IOR 2.4, grazing), hosts answering odd
//    distances / normals / closures.
#include <gtest/gtest.h>
#include <tbb/parallel_for.h>

#include <array>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <functional>
#include <limits>
#include <span>
#include <string>
#include <utility>

#include "closures/angle_bands.h"
#include "closures/frosted_exit_mixture.h"
#include "closures/frosted_glass.h"
#include "closures/frosted_test_host.h"
#include "closures/microfacet_test_util.h"
#include "closures/raw_output_checks.h"
#include "glimmer/exit_lobe.h"
#include "glimmer/rng.h"
#include <bit>

namespace {

using namespace glimmer;
using namespace glimmer::plugin;
using glimmer::test::angle_band;
using glimmer::test::BandSums;
using glimmer::test::degrees_between;
using glimmer::test::exit_mixture_of;
using glimmer::test::stress_scale;  // 100 under make stress

std::unique_ptr<FrostedGlassClosure> create_method(float roughness, float ior, const char *method,
                                                  const Vec3 &absorb = Vec3(1.0f)) {
  const GlimmerParamValue values[] = {{"roughness", {roughness, 0, 0}, nullptr},
                                      {"ior", {ior, 0, 0}, nullptr},
                                      {"absorption_color", {absorb.x, absorb.y, absorb.z}, nullptr},
                                      {"method", {0, 0, 0}, method}};
  ParamReader reader(FrostedGlassClosure::kName, FrostedGlassClosure::params(), values);
  auto c = FrostedGlassClosure::create(reader);
  c->prepare(host::default_host_services());
  return c;
}
std::unique_ptr<FrostedGlassClosure> create_raw(float roughness, float ior, bool sg, const Vec3 &absorb = Vec3(1.0f)) {
  return create_method(roughness, ior, sg ? "sg" : "path", absorb);
}

// ---- Analytic scenes with the renderer's host services -----------------------
struct Hit {
  float t = 0.0f;
  Vec3 P{0.0f}, N{0.0f};  // N: outward
};

// A ray's nearest crossing of the sphere |x| = radius beyond t_min (false: none before t_max).
bool hit_sphere(const Vec3 &o, const Vec3 &d, float radius, float t_min, float t_max, float &t) {
  const float b = dot(o, d), c = dot(o, o) - radius * radius, disc = b * b - c;
  if (disc < 0.0f) return false;
  const float s = std::sqrt(disc);
  t = -b - s;
  if (!(t > t_min)) t = -b + s;
  return t > t_min && t < t_max;
}

struct AnalyticScene {
  // kShell: a non-convex solid, the unit sphere with a spherical air cavity of radius shell_cavity (paths leave
  // into the cavity and enter the glass again).
  enum Kind { kSphere, kSlab, kShell } kind = kSphere;
  float slab_thickness = 0.3f;
  float shell_cavity = 0.55f;
  bool textured_roughness = false;  // the closure's roughness varies over the surface (roughness_at)
  // The paths' diffuse bounces before the object (context_at): 1 where the object is seen from the floor, as the
  // renderer's floor vertex sees it (sg's sampled internal reflection is the camera-seen solid's only, session 25).
  uint32_t diffuse_bounce = 0;
  bool small_light = false;         // the environment is a dim sky and a small bright light behind the object
  uint32_t roughness_param = 0;     // the closure's roughness parameter index (textured_roughness)
  const GlimmerInstance *material = nullptr;  // the closure reported at every hit
  GlimmerHostServices services{};

  explicit AnalyticScene(Kind k) : kind(k) { services = glimmer::test::tracing_host_services<&trace_closure>(this); }

  // The roughness texture: 0.15..0.5, a stripe pattern a few times finer than the object.
  static float roughness_at(const Vec3 &P) { return 0.15f + 0.35f * (0.5f + 0.5f * std::sin(5.0f * P.x + 3.0f * P.y)); }
  GlimmerVaryingValue roughness_value(const Vec3 &P) const {
    GlimmerVaryingValue v{};
    v.param = roughness_param;
    v.value[0] = roughness_at(P);
    return v;
  }

  // Smooth environment: a sky gradient and a broad bright lobe behind the objects; or (small_light) a dim sky and
  // a small bright light behind them (a lobe ~3 degrees wide).
  static constexpr float kLightSharpness = 400.0f;
  Vec3 light_dir = normalize(Vec3(0.35f, 0.1f, -1.0f));  // the small light's (and the broad lobe's) direction
  bool sky = true;  // small_light: false = the small light alone (the exit-lobe harness)
  Vec3 light_axis() const { return light_dir; }
  // small_light: the small light alone (the part of environment() a reference can sample directly).
  Spectrum small_light_radiance(const Vec3 &d) const {
    const float light = 40.0f * std::exp(kLightSharpness * (dot(d, light_axis()) - 1.0f));
    return Spectrum(light, light * 0.8f, light * 0.6f);
  }
  Spectrum environment(const Vec3 &d) const {
    const Vec3 c = light_axis();
    if (small_light)
      return (sky ? Spectrum(0.05f + 0.05f * (d.x + 1.0f), 0.06f, 0.08f) : Spectrum(0.0f)) + small_light_radiance(d);
    const float lobe = 1.5f * std::exp(6.0f * (dot(d, c) - 1.0f));
    return Spectrum(0.3f + 0.25f * (d.x + 1.0f) + lobe, 0.35f + 0.2f * (d.y + 1.0f) + lobe,
                    0.5f + 0.3f * std::max(0.0f, -d.z) + lobe);
  }

  bool intersect(const Vec3 &o, const Vec3 &d, float t_min, float t_max, Hit &h) const {
    if (kind == kShell) {  // the nearer of the outer surface (normal outward) and the cavity's (normal inward)
      float t_outer = t_max, t_inner = t_max;
      const bool outer = hit_sphere(o, d, 1.0f, t_min, t_max, t_outer);
      const bool inner = hit_sphere(o, d, shell_cavity, t_min, t_max, t_inner);
      if (!outer && !inner) return false;
      const bool at_inner = inner && (!outer || t_inner < t_outer);
      h.t = at_inner ? t_inner : t_outer;
      h.P = o + d * h.t;
      h.N = at_inner ? -normalize(h.P) : normalize(h.P);
      return true;
    }
    if (kind == kSphere) {  // unit sphere at the origin
      if (!hit_sphere(o, d, 1.0f, t_min, t_max, h.t)) return false;
      h.P = o + d * h.t;
      h.N = normalize(h.P);
      return true;
    }
    float best = t_max;  // slab: z = 0 (normal +z) and z = -L (normal -z)
    for (float plane : {0.0f, -slab_thickness}) {
      if (d.z == 0.0f) continue;
      const float t = (plane - o.z) / d.z;
      if (t > t_min && t < best) best = t;
    }
    if (!(best < t_max)) return false;
    h.t = best;
    h.P = o + d * best;
    h.N = Vec3(0.0f, 0.0f, h.P.z > -0.5f * slab_thickness ? 1.0f : -1.0f);
    return true;
  }
  static int trace_closure(void *data, const GlimmerRay *ray, GlimmerRayHit *out, GlimmerHitClosure *c) {
    const auto *self = static_cast<const AnalyticScene *>(data);
    Hit h;
    if (!self->intersect(Vec3(ray->origin), Vec3(ray->direction), ray->t_min, ray->t_max, h)) return 0;
    out->t = h.t;
    out->P = h.P;
    out->N = out->Ng = h.N;
    out->backfacing = dot(h.N, Vec3(ray->direction)) > 0.0f ? 1u : 0u;
    c->type = nullptr;
    c->instance = self->material;
    c->varying_count = 0;
    if (self->textured_roughness) {
      c->varying_count = 1;
      c->varying[0] = self->roughness_value(h.P);
    }
    return 1;
  }
};

// One sample of a closure at a shading point (the variant hook for the negative control).
using Sampler = std::function<bool(const ShadingPoint &, const Vec3 &, LocalSample &)>;
// A closure's own sample() as a Sampler (the closure outlives it).
Sampler sampler_of(const FrostedGlassClosure &closure) {
  return [&closure](const ShadingPoint &sp, const Vec3 &r, LocalSample &s) { return closure.sample(sp, r, s); };
}

// The reference's light sampling of the small light (scene.small_light): the exact closure's eval, used at every
// interface after the first (light reached through the object), power-heuristic MIS with the closure's own
// samples. Unbiased: the same expectation as counting environment() at escapes, far less noise (the light is ~3
// degrees wide, so a BTDF-sampled exit rarely finds it).
using Evaluator = std::function<LocalEval(const ShadingPoint &, const Vec3 &)>;

// The closure's shading context at `hit` for a ray travelling along D: position, normals, tangent and a path seed
// from rng (the caller adds per-point parameters such as textured roughness).
GlimmerShadingContext context_at(const AnalyticScene &scene, const Hit &hit, const Vec3 &D, Pcg32 &rng) {
  GlimmerShadingContext ctx = host::make_local_context(-D, &scene.services);
  ctx.P = hit.P;
  ctx.N = ctx.Ng = hit.N;
  ctx.T = Frame::from_normal(hit.N).s;
  ctx.path_seed = rng.next_u32();
  ctx.diffuse_bounce = scene.diffuse_bounce;
  return ctx;
}

// Radiance a path entering at the camera hit brings back through the object (0 when the first event
// reflects: transmitted light only); follows every later interface, moved samples from their origin. With
// `light_eval` (a small light, the exact closure) the light is also sampled at every later interface.
// `exit_nee` (sg, a small light): the renderer's light sampling at the exit (ABI 2.4 / 2.7): at an sg sample that
// carries its exit lobe (mixture), one light sample from the light's vMF weighted by the lobe's density there, MIS
// (power heuristic) with the lobe's own direction. The same expectation as without, less noise.
Spectrum transmitted_radiance(const AnalyticScene &scene, const Sampler &sample, Hit hit, Vec3 D, Pcg32 &rng,
                              const Evaluator *light_eval = nullptr, bool exit_nee = false) {
  const bool nee = light_eval != nullptr && scene.small_light;
  const bool lobe_nee = exit_nee && scene.small_light;
  const auto light_pdf = [&scene](const Vec3 &w) {
    return vmf_density(scene.light_axis(), AnalyticScene::kLightSharpness, w);
  };
  const auto escapes = [&](const Vec3 &P, const Vec3 &N, const Vec3 &w) {
    Hit unused;
    return !scene.intersect(frosted::offset_origin(P, N, w), w, 0.0f, std::numeric_limits<float>::infinity(), unused);
  };
  Spectrum L(0.0f);
  float bsdf_pdf_of_last = 0.0f;  // the closure's density of the direction the path left in (MIS at an escape)
  Spectrum throughput(1.0f);
  const auto schema = FrostedGlassClosure::params();
  for (int event = 0; event < 512; ++event) {
    GlimmerShadingContext ctx = context_at(scene, hit, D, rng);
    const GlimmerVaryingValue roughness = scene.roughness_value(hit.P);
    if (scene.textured_roughness) {
      ctx.varying_count = 1;
      ctx.varying = &roughness;
    }
    const ShadingPoint sp(&ctx, schema);
    if (nee && event > 0) {  // one light sample from the small light's own (vMF) distribution
      const float u1 = rng.next_float(), u2 = rng.next_float();
      const Vec3 wl = sample_vmf(scene.light_axis(), AnalyticScene::kLightSharpness, u1, u2);
      const LocalEval e = (*light_eval)(sp, sp.frame.to_local(wl));
      const double pl = light_pdf(wl), pb = e.pdf;
      if (!is_zero(e.f_cos) && pl > 0.0 && escapes(hit.P, hit.N, wl))
        L += throughput * e.f_cos * scene.small_light_radiance(wl) * float(pl / (pl * pl + pb * pb));
    }
    LocalSample s;
    GlimmerExitMixture buffer{};
    s.mixture_out = &buffer;
    if (!sample(sp, Vec3(rng.next_float(), rng.next_float(), rng.next_float()), s) || !(s.pdf > 0.0f)) return L;
    if (event == 0 && !(s.label & GLIMMER_LABEL_TRANSMIT)) return Spectrum(0.0f);
    throughput *= s.f_cos / s.pdf;
    bsdf_pdf_of_last = s.pdf;
    const Vec3 wo = normalize(sp.frame.to_world(s.wo));
    const bool at_exit = lobe_nee && s.moved && s.exit_lobe;
    glimmer::ExitLobeMixture lobe;
    if (at_exit) {  // the light sampled from the exit, weighted by the lobe's density (the lobe as the BSDF)
      lobe = exit_mixture_of(s, buffer);
      const float u1 = rng.next_float(), u2 = rng.next_float();
      const Vec3 wl = sample_vmf(scene.light_axis(), AnalyticScene::kLightSharpness, u1, u2);
      const double pl = light_pdf(wl), pm = lobe.pdf(wl);
      if (pm > 0.0 && pl > 0.0 && escapes(s.origin, s.origin_Ng, wl))
        L += throughput * scene.small_light_radiance(wl) * float(pm * pl / (pl * pl + pm * pm));
    }
    const Vec3 origin = s.moved ? frosted::offset_origin(s.origin, s.origin_Ng, wo)
                                : frosted::offset_origin(hit.P, hit.N, wo);
    Hit next;
    if (!scene.intersect(origin, wo, 0.0f, std::numeric_limits<float>::infinity(), next)) {
      if (at_exit) {  // the lobe's own direction: its MIS share of the light
        const double pm = lobe.pdf(wo), pl = light_pdf(wo);
        const Spectrum light = scene.small_light_radiance(wo);
        return L + throughput * (scene.environment(wo) - light + light * float(pm * pm / (pm * pm + pl * pl)));
      }
      if (!nee || event == 0) return L + throughput * scene.environment(wo);
      const double pb = bsdf_pdf_of_last, pl = light_pdf(wo);
      const Spectrum light = scene.small_light_radiance(wo);
      return L + throughput * (scene.environment(wo) - light + light * float(pb * pb / (pb * pb + pl * pl)));
    }
    hit = next;
    D = wo;
  }
  return L;
}

// The tiny image: camera hits and directions (sphere: 4x4 orthographic rays down -z over |x|, |y| < 0.7;
// slab: 8 incidence angles 0..70 degrees).
struct Pixel {
  Hit hit;
  Vec3 D;
};
std::vector<Pixel> camera_pixels(const AnalyticScene &scene) {
  std::vector<Pixel> px;
  if (scene.kind != AnalyticScene::kSlab) {
    for (int j = 0; j < 4; ++j)
      for (int i = 0; i < 4; ++i) {
        const Vec3 o(-0.525f + 0.35f * i, -0.525f + 0.35f * j, 5.0f), D(0, 0, -1);
        Pixel p{{}, D};
        if (scene.intersect(o, D, 0.0f, 100.0f, p.hit)) px.push_back(p);
      }
  } else {
    for (int a = 0; a < 8; ++a) {
      const float th = float(a) * 10.0f * float(M_PI) / 180.0f;
      const Vec3 D(std::sin(th), 0.0f, -std::cos(th));
      Pixel p{{}, D};
      scene.intersect(Vec3(0.0f) - D * 5.0f, D, 0.0f, 100.0f, p.hit);
      px.push_back(p);
    }
  }
  return px;
}

struct ImageEstimate {
  std::vector<Spectrum> mean;
  std::vector<double> se;  // standard error of the luminance mean per pixel
};
ImageEstimate render_tiny(const AnalyticScene &scene, const Sampler &sample, int spp, uint64_t seed,
                          const Evaluator *light_eval = nullptr, bool exit_nee = false) {
  const std::vector<Pixel> px = camera_pixels(scene);
  ImageEstimate out;
  out.mean.assign(px.size(), Spectrum(0.0f));
  out.se.assign(px.size(), 0.0);
  tbb::parallel_for(size_t(0), px.size(), [&](size_t k) {
    Pcg32 rng(seed, 17 + k);
    double sum[3] = {0, 0, 0}, sum2 = 0.0;
    for (int s = 0; s < spp; ++s) {
      const Spectrum L = transmitted_radiance(scene, sample, px[k].hit, px[k].D, rng, light_eval, exit_nee);
      for (int ch = 0; ch < 3; ++ch) sum[ch] += L[ch];
      sum2 += sqr(average(L));
    }
    out.mean[k] = Spectrum(float(sum[0] / spp), float(sum[1] / spp), float(sum[2] / spp));
    const double m = average(out.mean[k]);
    out.se[k] = std::sqrt(std::max(0.0, sum2 / spp - m * m) / spp);
  });
  return out;
}

// Mean over pixels of |L_sg - L_ref| / L_ref (luminance = channel average).
double mean_relative_error(const ImageEstimate &est, const ImageEstimate &ref) {
  double sum = 0.0;
  for (size_t k = 0; k < ref.mean.size(); ++k)
    sum += std::fabs(average(est.mean[k]) - average(ref.mean[k])) / std::max(double(average(ref.mean[k])), 1e-9);
  return sum / double(ref.mean.size());
}
double mean_relative_se(const ImageEstimate &ref) {
  double sum = 0.0;
  for (size_t k = 0; k < ref.mean.size(); ++k) sum += ref.se[k] / std::max(double(average(ref.mean[k])), 1e-9);
  return sum / double(ref.mean.size());
}

// de Rousiers' goal for convex objects (issue 12).
constexpr double kGoal = 0.05;

// Each configuration's bound per scene (sphere, slab): the goal where the model reaches it; else what it achieves
// (measured + ~30 %, see docs/frosted_glass.md: one SG per lobe, the exit lookup at the axis' incidence only, the
// Beer length along the axis only), so a regression still fails. The negative control is asserted where the exit
// refraction decides the result (roughness <= 0.3; wider lobes blur the axis' direction). Twelfth session: the slab
// (a planar exit) at roughness 0.5 / 0.5 absorbing / 0.8 takes the heavy-tail ladder: 0.0873 / 0.0532 / 0.0945 ->
// 0.0386 / 0.0281 / 0.0314, bounds 0.125 / 0.08 / 0.135 -> the goal.
struct Config {
  float roughness, ior;
  Vec3 absorb;
  double bound[2];
};
const Config kConfigs[] = {{0.1f, 1.33f, Vec3(1.0f), {kGoal, kGoal}},
                           {0.3f, 1.5f, Vec3(1.0f), {kGoal, kGoal}},
                           {0.5f, 1.7f, Vec3(1.0f), {kGoal, kGoal}},
                           {0.5f, 1.7f, Vec3(0.7f, 0.85f, 0.95f), {kGoal, kGoal}},
                           {0.8f, 1.5f, Vec3(1.0f), {0.175, kGoal}}};
constexpr int kReferenceSpp = 16384;
constexpr int kSgSpp = 2048;

struct SceneError {
  double sg = 0.0, control = 0.0, ref_se = 0.0, toksvig = 0.0;
  double noise_ratio = 0.0;  // sg's standard deviation per path over path's (relative, mean over pixels)
};
// A scene of the accuracy set.
struct SceneSetup {
  const char *name;
  AnalyticScene::Kind kind;
  bool textured_roughness = false, small_light = false;
};
uint32_t roughness_param_index() {
  const auto schema = FrostedGlassClosure::params();
  for (uint32_t i = 0; i < schema.size(); ++i)
    if (std::string(schema[i].name) == "roughness") return i;
  return 0;
}

SceneError measure(const SceneSetup &setup, const Config &c, int reference_spp = kReferenceSpp, int sg_spp = kSgSpp) {
  AnalyticScene scene(setup.kind);
  scene.textured_roughness = setup.textured_roughness;
  scene.small_light = setup.small_light;
  scene.roughness_param = roughness_param_index();
  auto path = create_raw(c.roughness, c.ior, false, c.absorb);
  auto sg = create_raw(c.roughness, c.ior, true, c.absorb);
  scene.material = reinterpret_cast<const GlimmerInstance *>(sg.get());
  const Sampler path_sampler = sampler_of(*path), sg_sampler = sampler_of(*sg);
  // Negative control: the exit refraction ignored (the SG keeps the axis it had inside).
  auto variant = [&](frosted::SgVariant v) {
    return Sampler([&path, &sg, v](const ShadingPoint &sp, const Vec3 &r, LocalSample &s) {
      if (!path->sample(sp, r, s)) return false;
      if (sg->uses_sg(sp) && (s.label & GLIMMER_LABEL_TRANSMIT)) sg->sample_sg(sp, r, s, v);
      return true;
    });
  };
  // The reference samples the small light too (exact closure's eval; unbiased, converged at fewer paths).
  const Evaluator path_eval = [&](const ShadingPoint &sp, const Vec3 &wo) { return path->eval(sp, wo); };
  const ImageEstimate ref = render_tiny(scene, path_sampler, reference_spp, 1, &path_eval);
  if (setup.small_light) {  // the light-sampled reference vs plain path tracing (at 1/4 the paths): the same
                           // image within the noise (a wrong MIS weight or light density fails it)
    const ImageEstimate plain = render_tiny(scene, path_sampler, reference_spp / 4, 3);
    double worst_z = 0.0;
    for (size_t k = 0; k < ref.mean.size(); ++k) {
      const double z = (average(ref.mean[k]) - average(plain.mean[k])) / std::hypot(ref.se[k], plain.se[k]);
      worst_z = std::max(worst_z, std::fabs(z));
      EXPECT_LT(std::fabs(z), 5.0) << "pixel " << k << ": light-sampled reference " << average(ref.mean[k])
                                   << ", plain " << average(plain.mean[k]);
    }
    std::printf("[frosted sg] small light, roughness %.2f: light-sampled reference se %.4f vs plain path %.4f "
                "at %d paths (relative, %d paths per pixel); worst |z| between them %.2f\n", double(c.roughness),
                mean_relative_se(ref), mean_relative_se(plain), reference_spp / 4, reference_spp, worst_z);
  }
  // The small light (thirteenth session): sg with the renderer's light sampling at the exit (exit_nee; without it
  // sg's own noise was about half of its error at 2048 paths, relative se 0.11 per pixel at roughness 0.3), checked
  // against sg reading the light through its lobe samples alone at 4x the paths (the same expectation: every pixel
  // within 5 combined standard errors; at 1x a rarely hit light's se is underestimated: |z| 5.2 at roughness 0.5).
  const ImageEstimate est_lobe_only = render_tiny(scene, sg_sampler, setup.small_light ? 4 * sg_spp : sg_spp, 2);
  const ImageEstimate est = setup.small_light ? render_tiny(scene, sg_sampler, sg_spp, 4, nullptr, true) : est_lobe_only;
  if (setup.small_light) {
    double worst_z = 0.0;
    for (size_t k = 0; k < est.mean.size(); ++k) {
      const double z = (average(est.mean[k]) - average(est_lobe_only.mean[k])) / std::hypot(est.se[k], est_lobe_only.se[k]);
      worst_z = std::max(worst_z, std::fabs(z));
      EXPECT_LT(std::fabs(z), 5.0) << "pixel " << k << ": sg with exit light sampling " << average(est.mean[k])
                                   << ", without " << average(est_lobe_only.mean[k]);
    }
    std::printf("[frosted sg] small light, roughness %.2f: sg without exit light sampling (%d paths): mean relative "
                "error %.4f, relative se %.4f; with it (%d paths): se %.4f; worst |z| between them %.2f\n",
                double(c.roughness), 4 * sg_spp, mean_relative_error(est_lobe_only, ref),
                mean_relative_se(est_lobe_only), sg_spp, mean_relative_se(est), worst_z);
  }
  if (setup.small_light) {  // per pixel (the slab's incidences 0..70 deg): where the error is
    std::printf("[frosted sg] small light, roughness %.2f, per pixel sg / reference:", double(c.roughness));
    for (size_t k = 0; k < ref.mean.size(); ++k)
      std::printf(" %.3f/%.3f", double(average(est.mean[k])), double(average(ref.mean[k])));
    // The error an unbiased sg would show from the noise alone: E|N(0, s)| = sqrt(2 / pi) s per pixel, s the
    // combined standard error of sg and the reference, relative to the reference, mean over the pixels.
    double floor = 0.0;
    for (size_t k = 0; k < ref.mean.size(); ++k)
      floor += std::sqrt(2.0 / M_PI) * std::hypot(est.se[k], ref.se[k]) / std::max(double(average(ref.mean[k])), 1e-9);
    std::printf("; noise floor of the mean relative error %.4f\n", floor / double(ref.mean.size()));
  }
  const ImageEstimate ctl = render_tiny(scene, variant(frosted::SgVariant::kNoExitRefraction), sg_spp, 2);
  const ImageEstimate toksvig = render_tiny(scene, variant(frosted::SgVariant::kToksvig), sg_spp, 2);
  SceneError e{mean_relative_error(est, ref), mean_relative_error(ctl, ref), mean_relative_se(ref),
               mean_relative_error(toksvig, ref),
               mean_relative_se(est) * std::sqrt(double(sg_spp)) / (mean_relative_se(ref) * std::sqrt(double(reference_spp)))};
  std::printf("[frosted sg] %s roughness %.2f ior %.2f%s: mean relative error sg %.4f (paper's Toksvig exit %.4f, "
              "no exit refraction %.4f), reference se %.4f (%d / %d paths per pixel); noise per path sg / path %.2f\n",
              setup.name, double(c.roughness), double(c.ior), c.absorb.x < 1.0f ? " absorbing" : "", e.sg,
              e.toksvig, e.control, e.ref_se, reference_spp, sg_spp, e.noise_ratio);
  return e;
}

void check_scene(AnalyticScene::Kind kind) {
  const int side = kind == AnalyticScene::kSphere ? 0 : 1;
  const SceneSetup setup{kind == AnalyticScene::kSphere ? "sphere" : "slab  ", kind};
  double worst = 0.0, sum = 0.0, sum_ctl = 0.0;
  int within_goal = 0;
  for (const Config &c : kConfigs) {
    const SceneError e = measure(setup, c);
    worst = std::max(worst, e.sg);
    sum += e.sg;
    sum_ctl += e.control;
    within_goal += e.sg < kGoal;
    EXPECT_LT(e.sg, c.bound[side]) << "roughness " << c.roughness << " ior " << c.ior;
    if (c.roughness <= 0.3f) {
      EXPECT_GT(e.control, 2.0 * kGoal) << "negative control passed: roughness " << c.roughness << " ior " << c.ior;
    }
  }
  const double n = double(std::size(kConfigs));
  std::printf("[frosted sg] %s: mean relative error over the %d configurations %.4f (worst %.4f), %d within the 5 %% "
              "goal; negative control (no exit refraction) %.4f\n",
              kind == AnalyticScene::kSphere ? "sphere" : "slab", int(n), sum / n, worst, within_goal, sum_ctl / n);
}

TEST(FrostedGlassSg, SphereMatchesThePathReference) { check_scene(AnalyticScene::kSphere); }
TEST(FrostedGlassSg, SlabMatchesThePathReference) { check_scene(AnalyticScene::kSlab); }

// The rest of the accuracy set (issue 12): a non-convex solid, textured roughness, a small light behind a slab.
// Fast in make test (4096 / 1024 paths per pixel), 16384 / 2048 (as above) under make stress. Bounds: the goal where
// it is met, else the measured error (16k reference) + ~30 %, so that a regression fails. The negative control
// (no exit refraction) must fail where `control` is set (where it measured > 2x the goal).
struct SetCase {
  float roughness, ior;
  double bound;
  bool control;
};
// mean_goal > 0: the scene's mean over the cases must be within it at make stress's paths (16384 / 2048 or more; at make
// test's 4096 / 1024 the reference's own noise is a large part of the small light's figure, ~0.034 at roughness 0.3).
void check_set_scene(const SceneSetup &setup, std::span<const SetCase> cases, double mean_goal = 0.0) {
  const bool full = stress_scale() > 1;
  int reference_spp = full ? kReferenceSpp : 4096, sg_spp = full ? kSgSpp : 1024;
  // GLIMMER_FROSTED_SET_SPP=N: N reference and N sg paths per pixel (separates sg's bias from its noise: at make
  // stress's 2048 sg paths the small light's sg noise alone is ~0.11 relative per pixel at roughness 0.3).
  if (const char *n = std::getenv("GLIMMER_FROSTED_SET_SPP"); n != nullptr && std::atoi(n) > 0)
    reference_spp = sg_spp = std::atoi(n);
  double sum = 0.0;
  for (const SetCase &c : cases) {
    const Config config{c.roughness, c.ior, Vec3(1.0f), {c.bound, c.bound}};
    const SceneError e = measure(setup, config, reference_spp, sg_spp);
    EXPECT_LT(e.sg, c.bound) << setup.name << " roughness " << c.roughness << " ior " << c.ior;
    if (c.control) {
      EXPECT_GT(e.control, 2.0 * kGoal) << "negative control passed: " << setup.name << " roughness " << c.roughness;
    }
    sum += e.sg;
  }
  std::printf("[frosted sg] %s: mean relative error over the %zu configurations %.4f\n", setup.name, cases.size(),
              sum / double(cases.size()));
  if (mean_goal > 0.0 && reference_spp >= kReferenceSpp && sg_spp >= kSgSpp) {
    EXPECT_LT(sum / double(cases.size()), mean_goal) << setup.name;
  }
}

TEST(FrostedGlassSg, NonConvexShellMatchesThePathReference) {
  // Measured (16k): 0.0081 / 0.109 / 0.129 / 0.076. The exit into the cavity and the re-entry are each one SG
  // event; the cavity's concave wall focuses the light the traced cone spreads (the paper's Toksvig exit: 0.061 /
  // 0.064 at 0.3 / 0.5).
  const SetCase cases[] = {
      {0.1f, 1.33f, kGoal, true}, {0.3f, 1.5f, 0.145, false}, {0.5f, 1.7f, 0.175, false}, {0.8f, 1.5f, 0.105, false}};
  check_set_scene({"shell (non-convex)", AnalyticScene::kShell}, cases);
}
TEST(FrostedGlassSg, TexturedRoughnessSphereMatchesThePathReference) {
  // Roughness 0.15..0.5 from the texture (the constant 0.3 unused). Measured (16k): 0.0070 / 0.0100 / 0.0194.
  const SetCase cases[] = {{0.3f, 1.33f, kGoal, true}, {0.3f, 1.5f, kGoal, true}, {0.3f, 1.7f, kGoal, true}};
  check_set_scene({"sphere, textured roughness", AnalyticScene::kSphere, true}, cases);
}
TEST(FrostedGlassSg, SmallLightBehindSlabMatchesThePathReference) {
  // Measured (16k, plain path reference): 0.0285 / 0.248 / 0.209: one SG exit lobe cannot follow the image of a
  // small light (a narrow peak through a rough slab). The reference now samples the light (transmitted_radiance's
  // light_eval): at make test's 4096 paths its relative se is 0.015 / 0.037 / 0.032 (plain path: 0.020 / 0.072 /
  // 0.072), sg's error against it 0.023 / 0.252 / 0.227. Twelfth session (a planar exit above roughness 0.4: the
  // heavy-tail ladder instead of the single SG, frosted_glass_sg.cpp solid_exit_mixture): roughness 0.5 0.227 ->
  // 0.122 (4096 / 1024; 16k: 0.211 -> 0.106), bound 0.29 -> 0.16; 0.1 / 0.3 unchanged. Thirteenth session: sg with
  // the renderer's light sampling at the exit (measure(): about half of 0.192 at roughness 0.3 was sg's own noise):
  // 0.0163 / 0.1125 / 0.1316 (4096 / 1024), 0.0097 / 0.1166 / 0.1392 (16k / 2048), 0.0125 / 0.1069 / 0.1405 with
  // 65536 / 65536 paths and no exit light sampling (the bias); bound at 0.3 0.33 -> 0.15. Then the planar ladder's
  // cores x 3 -> x 2 (frosted_glass_sg.cpp kPlanarSolidTail): roughness 0.5 0.1392 -> 0.0853 (16k; 4096 / 1024:
  // 0.1316 -> 0.0835), bound 0.16 -> 0.11. Fourteenth session: the reflected remainder leaves with its own axis at a
  // planar exit (frosted_glass_sg.cpp reflected_axis): 0.0097 / 0.1166 / 0.0853 -> 0.0097 / 0.0575 / 0.0773 (16k /
  // 2048; mean 0.0705 -> 0.0482), 0.0163 / 0.1125 / 0.0835 -> 0.0163 / 0.0814 / 0.0791 at 4096 / 1024 (mean 0.0708 ->
  // 0.0589); bounds at 0.3 / 0.5 0.15 / 0.11 -> 0.105 / 0.10 (the 4096 figures + ~30 %), and the 5 % goal on the
  // scene's mean at 16384 / 2048 (make stress).
  const SetCase cases[] = {{0.1f, 1.5f, kGoal, true}, {0.3f, 1.5f, 0.105, true}, {0.5f, 1.33f, 0.10, true}};
  check_set_scene({"slab, small light behind", AnalyticScene::kSlab, false, true}, cases, kGoal);
}

// ---- The exit-lobe harness (issue 12): a small light moved around the object ------------------------------
// The sphere and the slab above, the sky off, lit only by the small (~3 degree) light, which is moved from straight
// behind the object (-z) to 20, 35 and 60 degrees off (about y). The reference is path tracing with light sampling
// at every interface after the first (checked against plain path tracing in the same test); sg reads the light
// through its exit lobe alone, so its error here is the exit lobe's shape. Per direction: the signed error of the
// image's total and the L1 error sum |sg - ref| / sum ref over the pixels. Compared: the single SG (kTracedCone),
// the exit mixture (kMixture) at point variance shares v = 0..1, and the negative control (no exit refraction).
double image_total(const ImageEstimate &e) {
  double s = 0.0;
  for (const Spectrum &m : e.mean) s += average(m);
  return s;
}
double image_total_se(const ImageEstimate &e) {
  double s = 0.0;
  for (double se : e.se) s += se * se;
  return std::sqrt(s);
}
double image_l1(const ImageEstimate &est, const ImageEstimate &ref) {
  double d = 0.0;
  for (size_t k = 0; k < ref.mean.size(); ++k) d += std::fabs(average(est.mean[k]) - average(ref.mean[k]));
  return d / std::max(image_total(ref), 1e-12);
}

struct MixtureKnobs {
  float variance, tail;  // frosted::SgInputs::mixture_variance / mixture_tail
};
// The last one is the proposed rule (frosted::mixture_rule_variant: the mixture with kDefaultMixtureVariance and
// t = mixture_tail_for up to roughness kMixtureRoughnessMax, the single SG above; method=sg's default since ABI 2.7).
constexpr MixtureKnobs kHarnessMixtures[] = {{0.0f, 0.0f},  {0.5f, 0.0f}, {1.0f, 0.0f},  {0.0f, 0.15f},
                                             {0.0f, 0.2f},  {0.5f, 0.1f}, {0.5f, 0.15f}, {0.5f, 0.2f},
                                             {frosted::kDefaultMixtureVariance, frosted::kDefaultMixtureTail}};
constexpr int kHarnessV = int(std::size(kHarnessMixtures));
// Summed over the directions, in the reference's units (so the summary is the L1 over all pixels of all
// directions relative to their total: a direction the light barely reaches weighs by its light).
struct HarnessErrors {
  double reference = 0.0;
  double single = 0.0, control = 0.0, mixture[kHarnessV] = {};  // sum |sg - ref| over pixels
  double single_signed = 0.0, mixture_signed[kHarnessV] = {};   // |sum (sg - ref)| per direction
  double single_seconds = 0.0, default_seconds = 0.0;           // CPU time of the single SG's / the default's renders
  int directions = 0, checked = 0;  // checked: directions where plain path checked the reference
};

HarnessErrors exit_harness(AnalyticScene::Kind kind, float roughness, float ior, int reference_spp, int sg_spp) {
  HarnessErrors out;
  auto path = create_raw(roughness, ior, false);
  auto sg = create_raw(roughness, ior, true);
  AnalyticScene scene(kind);
  scene.small_light = true;
  scene.sky = false;
  scene.material = reinterpret_cast<const GlimmerInstance *>(sg.get());
  const Sampler path_sampler = [&](const ShadingPoint &sp, const Vec3 &r, LocalSample &s) {
    return path->sample(sp, r, s);
  };
  const Evaluator path_eval = [&](const ShadingPoint &sp, const Vec3 &wo) { return path->eval(sp, wo); };
  auto variant = [&](frosted::SgVariant v, MixtureKnobs m) {
    return Sampler([&path, &sg, v, m](const ShadingPoint &sp, const Vec3 &r, LocalSample &s) {
      if (!path->sample(sp, r, s)) return false;
      if (sg->uses_sg(sp) && (s.label & GLIMMER_LABEL_TRANSMIT)) sg->sample_sg(sp, r, s, v, m.variance, m.tail);
      return true;
    });
  };
  for (const float degrees : {0.0f, 20.0f, 35.0f, 60.0f}) {
    const float a = degrees * float(M_PI) / 180.0f;
    scene.light_dir = Vec3(std::sin(a), 0.0f, -std::cos(a));
    const ImageEstimate ref = render_tiny(scene, path_sampler, reference_spp, 1, &path_eval);
    const ImageEstimate plain = render_tiny(scene, path_sampler, reference_spp / 4, 3);
    // Plain path tracing checks the light-sampled reference where it sees the light often enough to have a
    // meaningful standard error (relative se < 20 %: where the light is reached by rare paths only, its se is
    // itself unreliable, e.g. 0.0008 +- 0.0002 against 0.0053 at roughness 0.1, 35 degrees).
    const double plain_rel_se = image_total_se(plain) / std::max(image_total(plain), 1e-12);
    const double z = (image_total(ref) - image_total(plain)) / std::hypot(image_total_se(ref), image_total_se(plain));
    if (plain_rel_se < 0.2) {
      ++out.checked;
      EXPECT_LT(std::fabs(z), 5.0) << "light-sampled reference vs plain path, " << degrees << " deg: "
                                   << image_total(ref) << " (se " << image_total_se(ref) << ") vs "
                                   << image_total(plain) << " (se " << image_total_se(plain) << ")";
    }
    const double total = image_total(ref);
    const std::clock_t c0 = std::clock();
    const ImageEstimate single = render_tiny(scene, variant(frosted::SgVariant::kTracedCone, {}), sg_spp, 2);
    out.single_seconds += double(std::clock() - c0) / CLOCKS_PER_SEC;
    const ImageEstimate ctl = render_tiny(scene, variant(frosted::SgVariant::kNoExitRefraction, {}), sg_spp, 2);
    const double e_single = image_total(single) / total - 1.0;
    out.reference += total;
    out.single += image_l1(single, ref) * total;
    out.single_signed += std::fabs(e_single) * total;
    out.control += image_l1(ctl, ref) * total;
    std::printf("[frosted harness] %s r %.1f light %2.0f deg: ref %.4g (se %.1f %%, |z| vs plain %.1f); single SG "
                "%+6.1f %% (L1 %5.1f %%); mixture v=", kind == AnalyticScene::kSphere ? "sphere" : "slab  ",
                double(roughness), double(degrees), total, 100.0 * image_total_se(ref) / total, std::fabs(z),
                100.0 * e_single, 100.0 * image_l1(single, ref));
    for (int i = 0; i < kHarnessV; ++i) {
      // The last column: the proposed rule (the mixture up to kMixtureRoughnessMax, the single SG above).
      const bool is_default = i == kHarnessV - 1;
      const std::clock_t c1 = std::clock();
      const ImageEstimate mix = render_tiny(
          scene, variant(is_default ? frosted::solid_sg_variant(roughness) : frosted::SgVariant::kMixture,
                         kHarnessMixtures[i]),
          sg_spp, 2);
      if (is_default) out.default_seconds += double(std::clock() - c1) / CLOCKS_PER_SEC;
      const double e = image_total(mix) / total - 1.0;
      out.mixture[i] += image_l1(mix, ref) * total;
      out.mixture_signed[i] += std::fabs(e) * total;
      std::printf("%s%.2f/t%.2f %+6.1f %% (L1 %5.1f %%)", i ? ", " : "", double(kHarnessMixtures[i].variance),
                  double(kHarnessMixtures[i].tail), 100.0 * e, 100.0 * image_l1(mix, ref));
    }
    std::printf("; no exit refraction L1 %.1f %%\n", 100.0 * image_l1(ctl, ref));
    ++out.directions;
  }
  return out;
}

// `make test` runs the roughnesses the rule's assertions are about (0.1, 0.3) at 4096 / 1024 paths; the *Stress
// twin (`make stress`) runs 0.1..0.8 at 16384 / 4096 (at 0.5 and 0.8 the rule falls back to the single SG: printed
// figures, the control and the reference check).
void expect_exit_harness(bool full) {
  const int reference_spp = full ? 16384 : 4096, sg_spp = full ? 4096 : 1024;
  const std::vector<float> roughnesses = full ? std::vector<float>{0.1f, 0.3f, 0.5f, 0.8f} : std::vector<float>{0.1f, 0.3f};
  for (const AnalyticScene::Kind kind : {AnalyticScene::kSphere, AnalyticScene::kSlab}) {
    for (const float roughness : roughnesses) {
      const HarnessErrors e = exit_harness(kind, roughness, 1.5f, reference_spp, sg_spp);
      const double n = e.reference;
      std::printf("[frosted harness] %s r %.1f over %d directions (light-weighted): L1 single %.1f %%, mixture",
                  kind == AnalyticScene::kSphere ? "sphere" : "slab", double(roughness), e.directions,
                  100.0 * e.single / n);
      for (int i = 0; i < kHarnessV; ++i)
        std::printf(" v%.2f/t%.2f %.1f %%", double(kHarnessMixtures[i].variance), double(kHarnessMixtures[i].tail),
                    100.0 * e.mixture[i] / n);
      std::printf("; |signed| single %.1f %%, mixture", 100.0 * e.single_signed / n);
      for (int i = 0; i < kHarnessV; ++i) std::printf(" %.1f %%", 100.0 * e.mixture_signed[i] / n);
      std::printf("; control %.1f %%\n", 100.0 * e.control / n);
      std::printf("[frosted harness] %s r %.1f: CPU time of the renders, mixture rule / single SG %.2f "
                  "(%.1f / %.1f s)\n",
                  kind == AnalyticScene::kSphere ? "sphere" : "slab", double(roughness),
                  e.default_seconds / std::max(e.single_seconds, 1e-9), e.default_seconds, e.single_seconds);
      // The mixture rule where it uses the mixture (roughness <= 0.4) against the single SG: measured light-weighted L1
      // at 1024 / 4096 paths, single -> default: sphere 0.1: 0.077 -> 0.094, 0.3: 0.527 -> 0.136; slab 0.1: 0.056
      // -> 0.029, 0.3: 0.425 -> 0.110. Bounds: at 0.3 the default at most half the single SG's error, and each
      // measured figure + ~30 %. Twelfth session: a curved exit below roughness 0.2 is the single SG (sphere 0.1:
      // 0.094 -> 0.077), bound 0.125 -> 0.10.
      const double default_l1 = e.mixture[kHarnessV - 1] / n, single_l1 = e.single / n;
      if (roughness == 0.3f) {
        EXPECT_LT(default_l1, 0.5 * single_l1) << "mixture vs single SG at roughness 0.3";
      }
      if (roughness <= 0.4f) {
        const double bound = kind == AnalyticScene::kSphere ? (roughness < 0.2f ? 0.10 : 0.18)
                                                            : (roughness < 0.2f ? 0.04 : 0.145);
        EXPECT_LT(default_l1, bound) << "roughness " << roughness;
      }
      // The harness can fail: the exit refraction ignored is far off where the lobe is narrow.
      if (roughness <= 0.3f) {
        EXPECT_GT(e.control, 1.5 * e.single) << "negative control: " << roughness;
      }
      EXPECT_GE(e.checked, 2) << "the reference was checked in too few directions";
    }
  }
}

TEST(FrostedSgExitHarness, SmallLightMovedAroundSphereAndSlab) { expect_exit_harness(false); }

TEST(FrostedSgExitHarness, SmallLightMovedAroundSphereAndSlabStress) {
  if (stress_scale() == 1) GTEST_SKIP() << "make stress only";
  expect_exit_harness(true);
}

// ---- The solid exit lobe's shape (issue 12, twelfth session) -------------------------------------------------
// The light transmitted through the slab and the sphere of the accuracy set, per camera pixel, binned by the angle
// of its escape direction off the pixel's exit axis (slab: the incident direction continued, as a pane's; sphere:
// the chief ray refracted by smooth interfaces at entry and exit): the fraction of the transmitted energy per band,
// method=path's exact walk vs sg (the default rule; the tenth session's per-ray kappa / 4 tails; the single SG).
// Summed over the pixels (each pixel's paths weigh equally). What a small light off axis needs is the mass
// 10-60 deg off axis (the slab's small light sits 20 deg off the normal, its pixels 0..70 deg).
constexpr int kShapeBands = 8;
constexpr double kShapeEdge[kShapeBands + 1] = {0, 2, 5, 10, 20, 30, 45, 60, 180};  // degrees

struct SolidBands {
  double mass[kShapeBands] = {}, se[kShapeBands] = {};  // fraction of the transmitted energy per band
  double total = 0.0;                                    // transmitted energy per entering path
  // Per pixel: the weighted sum of the leaving directions (its direction: the pixel's mean exit direction) and the
  // transmitted energy per entering path; the light-weighted mean angle off the pixel's exit axis (degrees).
  std::vector<Vec3> pixel_mean;
  std::vector<double> pixel_total;
  double mean_angle = 0.0;
  // Session 24: the spread within 30 deg of the pixel's exit axis along the pixel's radial direction (in the exit
  // axis' tangent plane, the sphere's plane of incidence) and across it (tangential), light-weighted over the pixels
  // (radians, about each pixel's own mean): the mean radial offset, the two standard deviations, the radial skewness.
  double radial_mean = 0.0, radial_sd = 0.0, tangential_sd = 0.0, radial_skew = 0.0;
};

// Smooth refraction of d (unit) at a surface with unit normal n facing against d, relative index eta = n1 / n2.
bool smooth_refract(const Vec3 &d, const Vec3 &n, float eta, Vec3 &out) {
  const float c = -dot(d, n), k = 1.0f - eta * eta * (1.0f - c * c);
  if (k < 0.0f) return false;
  out = normalize(d * eta + n * (eta * c - std::sqrt(k)));
  return true;
}
// The pixel's exit axis: the slab's incident direction; the sphere's chief ray through smooth interfaces.
Vec3 exit_axis(const AnalyticScene &scene, const Pixel &p, float ior) {
  if (scene.kind == AnalyticScene::kSlab) return p.D;
  Vec3 inside, out;
  if (!smooth_refract(p.D, p.hit.N, 1.0f / ior, inside)) return p.D;
  Hit far;
  if (!scene.intersect(frosted::offset_origin(p.hit.P, p.hit.N, inside), inside, 0.0f, 100.0f, far)) return p.D;
  return smooth_refract(inside, -far.N, ior, out) ? out : p.D;
}

// One path from the pixel through the object until it leaves: its weight and the direction it leaves in. False when
// it fails, reflects at the first event, stays inside (512 events) or leaves a slab back through its entry face.
bool trace_through(const AnalyticScene &scene, const Sampler &sample, const Pixel &px, Pcg32 &rng,
                   Spectrum &throughput, Vec3 &leaving, Vec3 *leaving_from = nullptr) {
  const auto schema = FrostedGlassClosure::params();
  Hit hit = px.hit;
  Vec3 D = px.D;
  throughput = Spectrum(1.0f);
  for (int event = 0; event < 512; ++event) {
    GlimmerShadingContext ctx = context_at(scene, hit, D, rng);
    const ShadingPoint sp(&ctx, schema);
    LocalSample s;
    if (!sample(sp, Vec3(rng.next_float(), rng.next_float(), rng.next_float()), s) || !(s.pdf > 0.0f)) return false;
    if (event == 0 && !(s.label & GLIMMER_LABEL_TRANSMIT)) return false;
    throughput *= s.f_cos / s.pdf;
    const Vec3 wo = normalize(sp.frame.to_world(s.wo));
    const Vec3 origin = s.moved ? frosted::offset_origin(s.origin, s.origin_Ng, wo)
                                : frosted::offset_origin(hit.P, hit.N, wo);
    Hit next;
    if (!scene.intersect(origin, wo, 0.0f, std::numeric_limits<float>::infinity(), next)) {
      leaving = wo;
      if (leaving_from != nullptr) *leaving_from = origin;
      return !(scene.kind == AnalyticScene::kSlab && wo.z > 0.0f);  // not back through the entry face
    }
    hit = next;
    D = wo;
  }
  return false;
}

SolidBands solid_bands(const AnalyticScene &scene, const Sampler &sample, float ior, int paths_per_pixel,
                       uint64_t seed) {
  const std::vector<Pixel> px = camera_pixels(scene);
  std::vector<BandSums<kShapeBands>> acc(px.size());
  std::vector<std::array<double, 4>> moments(px.size());  // sum w wo (x, y, z), sum w angle
  std::vector<std::array<double, 6>> spread(px.size());   // sum w, w u_r, w u_r^2, w u_r^3, w u_t, w u_t^2
  tbb::parallel_for(size_t(0), px.size(), [&](size_t k) {
    const Vec3 axis = exit_axis(scene, px[k], ior);
    const Vec3 radial(px[k].hit.P.x, px[k].hit.P.y, 0.0f);
    Vec3 er = radial - axis * dot(radial, axis);
    er = dot(er, er) > 1e-10f ? normalize(er) : Vec3(1.0f, 0.0f, 0.0f);
    const Vec3 et = normalize(cross(axis, er));
    Pcg32 rng(seed, 31 + k);
    for (int i = 0; i < paths_per_pixel; ++i) {
      Spectrum throughput;
      Vec3 wo;
      if (trace_through(scene, sample, px[k], rng, throughput, wo)) {
        const double w = average(throughput), deg = degrees_between(wo, axis);
        acc[k].add(angle_band(kShapeEdge, deg), w);
        if (deg < 30.0) {
          moments[k][0] += w * wo.x, moments[k][1] += w * wo.y, moments[k][2] += w * wo.z;
          const double ur = dot(wo, er), ut = dot(wo, et);
          auto &q = spread[k];
          q[0] += w, q[1] += w * ur, q[2] += w * ur * ur, q[3] += w * ur * ur * ur, q[4] += w * ut, q[5] += w * ut * ut;
        }
        moments[k][3] += w * deg;
      }
    }
  });
  BandSums<kShapeBands> sum;
  SolidBands out;
  double angle_sum = 0.0;
  for (size_t k = 0; k < px.size(); ++k) {
    sum += acc[k];
    out.pixel_mean.push_back(Vec3(float(moments[k][0]), float(moments[k][1]), float(moments[k][2])));
    out.pixel_total.push_back(acc[k].total / double(paths_per_pixel));
    angle_sum += moments[k][3];
  }
  double spread_weight = 0.0;
  for (size_t k = 0; k < px.size(); ++k) {
    const auto &q = spread[k];
    if (!(q[0] > 0.0)) continue;
    const double mr = q[1] / q[0], vr = std::max(q[2] / q[0] - mr * mr, 0.0);
    const double mt = q[4] / q[0], vt = std::max(q[5] / q[0] - mt * mt, 0.0);
    const double m3 = q[3] / q[0] - 3.0 * mr * q[2] / q[0] + 2.0 * mr * mr * mr;
    out.radial_mean += q[0] * mr;
    out.radial_sd += q[0] * std::sqrt(vr);
    out.tangential_sd += q[0] * std::sqrt(vt);
    out.radial_skew += q[0] * (vr > 0.0 ? m3 / (vr * std::sqrt(vr)) : 0.0);
    spread_weight += q[0];
  }
  if (spread_weight > 0.0) {
    out.radial_mean /= spread_weight, out.radial_sd /= spread_weight;
    out.tangential_sd /= spread_weight, out.radial_skew /= spread_weight;
  }
  const double n = double(paths_per_pixel) * double(px.size());
  sum.fractions(n, out.mass, out.se);
  out.total = sum.total / n;
  out.mean_angle = angle_sum / std::max(sum.total, 1e-30);
  return out;
}

double solid_band_sum(const SolidBands &m, int from, int to) {
  double s = 0.0;
  for (int b = from; b <= to; ++b) s += m.mass[b];
  return s;
}
double solid_band_l1(const SolidBands &sg, const SolidBands &ref) {
  double d = 0.0;
  for (int b = 0; b < kShapeBands; ++b) d += std::fabs(sg.mass[b] - ref.mass[b]);
  return d;
}
void print_solid_bands(const char *what, const SolidBands &m, const SolidBands *ref) {
  std::printf("  %-22s T %.4f |", what, m.total);
  for (int b = 0; b < kShapeBands; ++b) std::printf(" %.2e", m.mass[b]);
  if (ref != nullptr)
    std::printf(" | 10-60 %+.3f, L1 %.3f", solid_band_sum(m, 3, 6) / solid_band_sum(*ref, 3, 6) - 1.0,
                solid_band_l1(m, *ref));
  std::printf("\n");
}

// The pixels' mean exit directions of two measurements: the angle (degrees) between them, averaged over the
// pixels weighted by the reference's transmitted energy (an axis shift of the lobe, not its width).
double solid_axis_offset(const SolidBands &m, const SolidBands &ref) {
  double sum = 0.0, weight = 0.0;
  for (size_t k = 0; k < ref.pixel_mean.size() && k < m.pixel_mean.size(); ++k) {
    if (!(dot(ref.pixel_mean[k], ref.pixel_mean[k]) > 0.0f) || !(dot(m.pixel_mean[k], m.pixel_mean[k]) > 0.0f))
      continue;
    sum += ref.pixel_total[k] * degrees_between(normalize(m.pixel_mean[k]), normalize(ref.pixel_mean[k]));
    weight += ref.pixel_total[k];
  }
  return weight > 0.0 ? sum / weight : 0.0;
}
// The same offset's signed radial part on the sphere's pixels (orthographic rays down -z): the angle of the mean
// direction toward the pixel's radial direction (x, y, 0) minus the reference's, light-weighted; > 0: m leans
// further out than the reference (degrees).
double solid_radial_offset(const SolidBands &m, const SolidBands &ref, const std::vector<Pixel> &px) {
  double sum = 0.0, weight = 0.0;
  for (size_t k = 0; k < ref.pixel_mean.size() && k < m.pixel_mean.size() && k < px.size(); ++k) {
    const Vec3 radial(px[k].hit.P.x, px[k].hit.P.y, 0.0f);
    if (!(dot(radial, radial) > 1e-8f) || !(dot(ref.pixel_mean[k], ref.pixel_mean[k]) > 0.0f) ||
        !(dot(m.pixel_mean[k], m.pixel_mean[k]) > 0.0f))
      continue;
    const Vec3 r = normalize(radial);
    const double a = std::asin(std::clamp(double(dot(normalize(m.pixel_mean[k]), r)), -1.0, 1.0));
    const double b = std::asin(std::clamp(double(dot(normalize(ref.pixel_mean[k]), r)), -1.0, 1.0));
    sum += ref.pixel_total[k] * (a - b) * 180.0 / M_PI;
    weight += ref.pixel_total[k];
  }
  return weight > 0.0 ? sum / weight : 0.0;
}

// Measured (100000 / 25000 paths per pixel), band L1 default / per-ray kappa / 4 tails (tenth session) / single SG:
// slab r 0.1 0.158 / 0.158 / 0.272, r 0.3 0.050 / 0.050 / 0.431, r 0.5 0.169 / (single SG) / 0.257 (the ladder;
// the per-ray kappa / 4 tails would give 0.185); sphere r 0.1 0.011 (the single SG: a curved exit below 0.2) / 0.091
// / 0.011, r 0.3 0.153 / 0.153 / 0.435. Tried on the slab, not kept: the pane's ladder at 0.1 0.090, cores x3 +
// first 0.06 at 0.3 0.083 (the small light and the harness disagreed, docs "A tail for solids").
// Thirteenth session: the ladder's cores x 3 -> x 2: slab r 0.5 0.169 -> 0.086, bound 0.21 -> 0.11.
constexpr double kPlanarLadderBandL1 = 0.11;
// Eighteenth / nineteenth session: the sphere at roughness 0.5 / 0.6, the single SG split into a core and a tail
// (kCurvedTail); bound set from this session's measurement (docs/history/frosted_glass_sessions.md "Eighteenth /
// nineteenth session"). Session 22: kCurvedExitShape about the shifted axis, 0.135 / 0.130 -> 0.053 / 0.094 (the
// control, the single SG about the same axis, 0.222 / 0.166); bound 0.165 -> 0.12.
constexpr double kCurvedSplitBandL1 = 0.12;
TEST(FrostedGlassSg, ExitLobeShapeOfSolidsAgainstThePath) {
  const int ref_paths = stress_scale() > 1 ? 400000 : 100000, sg_paths = ref_paths / 4;
  struct ShapeCase {
    AnalyticScene::Kind kind;
    float roughness, ior;
  };
  const ShapeCase cases[] = {{AnalyticScene::kSlab, 0.1f, 1.5f},   {AnalyticScene::kSlab, 0.3f, 1.5f},
                             {AnalyticScene::kSlab, 0.5f, 1.5f},   {AnalyticScene::kSphere, 0.1f, 1.5f},
                             {AnalyticScene::kSphere, 0.3f, 1.5f}, {AnalyticScene::kSphere, 0.5f, 1.5f},
                             {AnalyticScene::kSphere, 0.6f, 1.5f}};
  for (const ShapeCase &c : cases) {
    auto path = create_raw(c.roughness, c.ior, false);
    auto sg = create_raw(c.roughness, c.ior, true);
    AnalyticScene scene(c.kind);
    scene.material = reinterpret_cast<const GlimmerInstance *>(sg.get());
    const Sampler path_sampler = sampler_of(*path), sg_sampler = sampler_of(*sg);
    auto variant = [&](frosted::SgVariant v, float tail) {
      return Sampler([&path, &sg, v, tail](const ShadingPoint &sp, const Vec3 &r, LocalSample &s) {
        if (!path->sample(sp, r, s)) return false;
        if (sg->uses_sg(sp) && (s.label & GLIMMER_LABEL_TRANSMIT))
          sg->sample_sg(sp, r, s, v, frosted::kDefaultMixtureVariance, tail);
        return true;
      });
    };
    const SolidBands ref = solid_bands(scene, path_sampler, c.ior, ref_paths, 1);
    const SolidBands now = solid_bands(scene, sg_sampler, c.ior, sg_paths, 2);
    const SolidBands old = solid_bands(scene, variant(frosted::SgVariant::kMixture, 0.2f), c.ior, sg_paths, 2);
    const SolidBands single = solid_bands(scene, variant(frosted::SgVariant::kTracedCone, 0.0f), c.ior, sg_paths, 2);
    std::printf("[frosted sg solid shape] %s roughness %.2f ior %.2f: fraction of T per band (deg) 0-2 2-5 5-10 "
                "10-20 20-30 30-45 45-60 60-180\n",
                c.kind == AnalyticScene::kSlab ? "slab" : "sphere", double(c.roughness), double(c.ior));
    print_solid_bands("path (reference)", ref, nullptr);
    std::printf("  %-22s          |", "path se");
    for (int b = 0; b < kShapeBands; ++b) std::printf(" %.2e", ref.se[b]);
    std::printf("\n");
    print_solid_bands("sg (default)", now, &ref);
    print_solid_bands("sg, kappa/4 tails (s10)", old, &ref);
    print_solid_bands("sg, single SG", single, &ref);
    // The sphere above kMixtureRoughnessMax (a curved exit: the single SG split into a core and a tail,
    // kCurvedExitShape since session 22, kCurvedTail before): its band L1 against the exact walk, bound measured
    // + ~25 %; the unsplit single SG (the control, curved_tail 0) must miss it.
    if (c.kind == AnalyticScene::kSphere && c.roughness > frosted::kMixtureRoughnessMax &&
        c.roughness <= frosted::kCurvedSplitMax) {
      const Sampler unsplit([&path, &sg](const ShadingPoint &sp, const Vec3 &r, LocalSample &s) {
        if (!path->sample(sp, r, s)) return false;
        if (sg->uses_sg(sp) && (s.label & GLIMMER_LABEL_TRANSMIT))
          sg->sample_sg(sp, r, s, frosted::SgVariant::kMixture, frosted::kDefaultMixtureVariance,
                        frosted::kDefaultMixtureTail, 0.0f);
        return true;
      });
      const SolidBands nosplit = solid_bands(scene, unsplit, c.ior, sg_paths, 2);
      print_solid_bands("sg, unsplit (control)", nosplit, &ref);
      EXPECT_LT(solid_band_l1(now, ref), kCurvedSplitBandL1) << "sphere roughness " << c.roughness;
      EXPECT_GT(solid_band_l1(nosplit, ref), kCurvedSplitBandL1) << "control passed: sphere " << c.roughness;
    }
    // The slab above kMixtureRoughnessMax (a planar exit: the ladder, where the rule had the single SG): the band
    // distribution's L1 against the exact walk, bound measured + ~25 %; the single SG (the control) must miss it.
    if (c.kind == AnalyticScene::kSlab && c.roughness > frosted::kMixtureRoughnessMax) {
      EXPECT_LT(solid_band_l1(now, ref), kPlanarLadderBandL1) << "slab roughness " << c.roughness;
      EXPECT_GT(solid_band_l1(single, ref), kPlanarLadderBandL1) << "control passed: slab " << c.roughness;
    }
    EXPECT_NEAR(now.total, ref.total, 0.04 * ref.total) << "transmitted energy, roughness " << c.roughness;
  }
}

// ---- The sphere's exit around the caustic bench (issue 12, session 22) ------------------------------------------
// The caustic bench's sphere is roughness 0.5, IOR 1.5 (benchmarks/scenes/frosted_fair_caustic.xml); its shadow zone
// (a small lamp seen through the sphere's exit lobe, off its axis) held sg's largest bias. Per (roughness, IOR) around
// it: the fraction of the transmitted energy per band of angle off the pixel's exit axis, path's exact walk vs sg (the
// default, and the unsplit single SG), the transmitted energy T, the light-weighted mean angle off the axis and the
// mean exit direction's offset from the path's (the axis itself).
struct SphereExitCase {
  float roughness, ior;
  double bound;    // the default's band L1 (measured + ~25 %, session 22); 0: printed only
  bool control;    // the single SG (the same axis) must miss the bound
  double drawn_bound;   // the drawn entry's band L1 (kCurvedExitShapeDrawn; session 29, measured + ~25 %); 0: printed
  bool drawn_control;   // the front SG's shape on the drawn entry (session 28's rule) must miss drawn_bound
};
struct SphereExitRow {
  // entry: session 28's kEntryAxis 1 (the camera-seen default) with its shape by the rule (kCurvedExitShapeDrawn since
  // session 29); entry_front_shape: the same entry under the front SG's shape (curved_exit_shape(r)), the control.
  SolidBands ref, now, unsplit, entry, entry_front_shape;
};
// For fits outside the test (benchmarks/frosted_sphere_exit_fit.cpp): writes into `dir` the single SG of every sg
// sample (float32 records: pixel, weight, axis xyz, sharpness, exit Ng xyz, the pixel's exit axis xyz) under the front
// SG's axis and width (<base>_sg.bin, samplers[0]) and under the drawn entry axis (<base>_drawn_sg.bin, samplers[1],
// session 29), and the path's band masses and T (<base>_path.txt, text).
void dump_sphere_exit(const char *dir, const SphereExitCase &c, const AnalyticScene &scene, const SolidBands &ref,
                      int sg_paths, const std::array<Sampler, 2> &samplers) {
  char name[512];
  std::snprintf(name, sizeof name, "%s/sphere_r%.2f_ior%.2f", dir, double(c.roughness), double(c.ior));
  const std::string base(name);
  if (FILE *f = std::fopen((base + "_path.txt").c_str(), "w")) {
    for (int b = 0; b < kShapeBands; ++b) std::fprintf(f, "%.9g ", ref.mass[b]);
    std::fprintf(f, "%.9g\n", ref.total);
    std::fclose(f);
  }
  const std::vector<Pixel> px = camera_pixels(scene);
  for (size_t which = 0; which < samplers.size(); ++which) {
    const Sampler &sampler = samplers[which];
    std::vector<std::vector<float>> rec(px.size());
    tbb::parallel_for(size_t(0), px.size(), [&](size_t k) {
      const Vec3 axis = exit_axis(scene, px[k], c.ior);
      const auto schema = FrostedGlassClosure::params();
      Pcg32 rng(2, 31 + k);
      for (int i = 0; i < sg_paths; ++i) {
        GlimmerShadingContext ctx = context_at(scene, px[k].hit, px[k].D, rng);
        const ShadingPoint sp(&ctx, schema);
        LocalSample smp;
        GlimmerExitMixture buffer{};
        smp.mixture_out = &buffer;
        if (!sampler(sp, Vec3(rng.next_float(), rng.next_float(), rng.next_float()), smp) || !(smp.pdf > 0.0f) ||
            !(smp.label & GLIMMER_LABEL_TRANSMIT) || !smp.moved || !smp.exit_lobe)
          continue;
        const Vec3 n = normalize(smp.origin_Ng);
        const float r[] = {float(k), average(smp.f_cos / smp.pdf), smp.lobe_axis.x, smp.lobe_axis.y, smp.lobe_axis.z,
                           smp.lobe_sharpness, n.x, n.y, n.z, axis.x, axis.y, axis.z};
        rec[k].insert(rec[k].end(), std::begin(r), std::end(r));
      }
    });
    if (FILE *f = std::fopen((base + (which == 0 ? "_sg.bin" : "_drawn_sg.bin")).c_str(), "wb")) {
      for (const auto &v : rec) std::fwrite(v.data(), sizeof(float), v.size(), f);
      std::fclose(f);
    }
  }
}
SphereExitRow measure_sphere_exit(const SphereExitCase &c, int ref_paths, int sg_paths) {
  auto path = create_raw(c.roughness, c.ior, false);
  auto sg = create_raw(c.roughness, c.ior, true);
  AnalyticScene scene(AnalyticScene::kSphere);
  scene.material = reinterpret_cast<const GlimmerInstance *>(sg.get());
  // The exit lobe's shape about the front SG's axis and width (entry_axis 0): what kCurvedExitShape was fitted to and
  // what the floor's view still uses. Session 28's drawn entry axis (kEntryAxis 1, the camera-seen default) leaves only
  // the exit's rough scatter in the shaped lobe: the front SG's shape there was wider than path's near the axis (band
  // L1 r 0.5 IOR 1.33 / 1.5 / 1.7 0.108 / 0.073 / 0.045 against the front SG's 0.055 / 0.058 / 0.055); session 29's
  // kCurvedExitShapeDrawn is its own shape, bounded (SphereExitCase::drawn_bound) with that rule as the control.
  const Sampler path_sampler = sampler_of(*path);
  const frosted::CurvedShape single{1, {1.0f}, {1.0f}}, front_shape = frosted::curved_exit_shape(c.roughness);
  // keep_lost: the single SG's row as before (its lost samples keep path's front sample); the others drop them.
  const auto with = [&path, &sg](float curved_tail, const frosted::CurvedShape *shape, int entry_axis, bool keep_lost) {
    return Sampler([&path, &sg, curved_tail, shape, entry_axis, keep_lost](const ShadingPoint &sp, const Vec3 &r,
                                                                          LocalSample &s) {
      if (!path->sample(sp, r, s)) return false;
      if (!sg->uses_sg(sp) || !(s.label & GLIMMER_LABEL_TRANSMIT)) return true;
      const bool kept = sg->sample_sg(sp, r, s, frosted::SgVariant::kMixture, frosted::kDefaultMixtureVariance,
                                      frosted::kDefaultMixtureTail, curved_tail, shape, -1, -1, -1.0f, -1.0f, entry_axis);
      return kept || keep_lost;
    });
  };
  const Sampler sg_sampler = with(-1.0f, nullptr, 0, false), unsplit = with(0.0f, &single, 0, true),
                entry = with(-1.0f, nullptr, 1, false), entry_front = with(-1.0f, &front_shape, 1, false);
  SphereExitRow row;
  row.ref = solid_bands(scene, path_sampler, c.ior, ref_paths, 1);
  // For fits outside the test (benchmarks/frosted_sphere_exit_fit.cpp): GLIMMER_SPHERE_EXIT_DUMP=<dir>.
  if (const char *dir = std::getenv("GLIMMER_SPHERE_EXIT_DUMP"); dir != nullptr && *dir != '\0')
    dump_sphere_exit(dir, c, scene, row.ref, sg_paths, {unsplit, with(0.0f, &single, 1, true)});
  row.now = solid_bands(scene, sg_sampler, c.ior, sg_paths, 2);
  row.unsplit = solid_bands(scene, unsplit, c.ior, sg_paths, 2);
  row.entry = solid_bands(scene, entry, c.ior, sg_paths, 2);
  row.entry_front_shape = solid_bands(scene, entry_front, c.ior, sg_paths, 2);
  return row;
}
void print_sphere_exit(const SphereExitCase &c, const SphereExitRow &r) {
  std::printf("[frosted sphere exit] roughness %.2f ior %.2f: T, fraction of T per band (deg) 0-2 2-5 5-10 10-20 "
              "20-30 30-45 45-60 60-180 | mean angle | axis offset vs path | L1\n",
              double(c.roughness), double(c.ior));
  auto line = [&](const char *what, const SolidBands &m, bool is_ref) {
    std::printf("  %-16s T %.4f |", what, m.total);
    for (int b = 0; b < kShapeBands; ++b)
      std::printf(is_ref ? " %.2e" : " %8.3f", is_ref ? m.mass[b] : m.mass[b] / std::max(r.ref.mass[b], 1e-12));
    std::printf(" | %5.2f deg", m.mean_angle);
    std::printf(" | radial mean %+.2f sd %.2f skew %+.2f, tangential sd %.2f deg", m.radial_mean * 180.0 / M_PI,
                m.radial_sd * 180.0 / M_PI, m.radial_skew, m.tangential_sd * 180.0 / M_PI);
    if (!is_ref)
      std::printf(" | %.2f deg (radial %+.2f) | L1 %.3f (T x%.3f)", solid_axis_offset(m, r.ref),
                  solid_radial_offset(m, r.ref, camera_pixels(AnalyticScene(AnalyticScene::kSphere))),
                  solid_band_l1(m, r.ref), m.total / r.ref.total);
    std::printf("\n");
  };
  line("path", r.ref, true);
  std::printf("  (sg rows: band fraction / path's)\n");
  line("sg (default)", r.now, false);
  line("sg, single SG", r.unsplit, false);
  line("sg, entry drawn", r.entry, false);
  line("drawn, front shape", r.entry_front_shape, false);
}
TEST(FrostedGlassSg, ExitOfTheSphereAroundTheCausticBench) {
  const int ref_paths = stress_scale() > 1 ? 200000 : 50000, sg_paths = ref_paths / 4;
  // Session 22 (kCurvedExitShape about the shifted axis), band L1 default / single SG: r 0.5 IOR 1.33 0.062 / 0.278,
  // 1.5 0.049 / 0.221, 1.7 0.052 / 0.225; r 0.6 1.5 0.093 / 0.168; r 0.65 1.33 0.125 / 0.186, 1.7 0.208 / 0.248 (the
  // nineteenth session's split: 0.128, 0.133, 0.137, 0.131, 0.153, 0.257). r 0.4 is the per-ray mixture (0.212).
  // Session 23 (the shape per roughness, kCurvedExitShapeWide from 0.6): r 0.6 0.093 -> 0.057, r 0.65 IOR 1.33
  // 0.125 -> 0.089, 1.7 0.208 -> 0.196 (r 0.5 unchanged); bounds 0.12 -> 0.075, 0.16 -> 0.11.
  // Session 29 (kCurvedExitShapeDrawn on the drawn entry axis, kEntryAxis 1), band L1 drawn default / the front SG's
  // shape there (session 28's rule, the control): r 0.5 IOR 1.33 0.057 / 0.108, 1.5 0.034 / 0.073, 1.7 0.037 /
  // 0.045; r 0.6 0.024 / 0.075; r 0.65 1.33 0.014 / 0.090, 1.7 0.053 / 0.053; r 0.4 (the per-ray mixture, no shape)
  // 0.189 either way. Bounds measured + ~25 % (r 0.65 IOR 1.33: + 0.006); the control must miss them where it is
  // apart (IOR 1.7: within the margin, bounded only).
  const SphereExitCase cases[] = {
      {0.4f, 1.5f, 0.0, false, 0.0, false},       {0.5f, 1.33f, 0.08, true, 0.071, true},
      {0.5f, 1.5f, 0.065, true, 0.043, true},     {0.5f, 1.7f, 0.065, true, 0.046, false},
      {0.6f, 1.5f, 0.075, true, 0.030, true},     {0.65f, 1.33f, 0.11, true, 0.020, true},
      {0.65f, 1.7f, 0.26, false, 0.066, false}};
  for (const SphereExitCase &c : cases) {
    const SphereExitRow r = measure_sphere_exit(c, ref_paths, sg_paths);
    print_sphere_exit(c, r);
    // sg's transmitted energy is the path's (measured within 0.2 % in every case): the shape, not the energy.
    EXPECT_NEAR(r.now.total, r.ref.total, 0.02 * r.ref.total) << "roughness " << c.roughness << " ior " << c.ior;
    if (c.bound > 0.0) {
      EXPECT_LT(solid_band_l1(r.now, r.ref), c.bound) << "roughness " << c.roughness << " ior " << c.ior;
    }
    if (c.control) {
      EXPECT_GT(solid_band_l1(r.unsplit, r.ref), c.bound) << "control passed: " << c.roughness << " " << c.ior;
    }
    EXPECT_NEAR(r.entry.total, r.ref.total, 0.02 * r.ref.total) << "drawn, roughness " << c.roughness;
    if (c.drawn_bound > 0.0) {
      EXPECT_LT(solid_band_l1(r.entry, r.ref), c.drawn_bound) << "drawn, roughness " << c.roughness << " " << c.ior;
    }
    if (c.drawn_control) {
      EXPECT_GT(solid_band_l1(r.entry_front_shape, r.ref), c.drawn_bound)
          << "drawn control passed: " << c.roughness << " " << c.ior;
    }
  }
}

// ---- The sphere's shadow of a far lamp, as on the caustic bench (issue 12, session 23) ---------------------------
// The caustic bench's sphere touches the floor; its shadow zone is lit by the small lamp (53 deg above the horizon)
// through the sphere: a floor point's paths enter the sphere's lower side and leave toward the lamp. Here the unit
// sphere on the plane z = -1, the lamp a far cone (kShadowLampDeg half-angle about the bench's lamp direction): for floor
// points along the shadow's axis (distance s from the contact point, in radii, toward the shadow's centre at 0.77),
// cosine-weighted directions from the floor point, the transmitted weight leaving within the cone, per floor point:
// path's exact walk vs sg (the process' default; the axis shift through GLIMMER_FROSTED_CURVED_SHIFT).
// The directions only: no finite lamp distance, no exit-point offset (the bench's lamp is 5.04 radii from the
// sphere's centre; SphereShadowDirectionsAroundTheLamp measures the difference it makes).
// The mean of per_path(rng) over `paths` paths and its standard error, in 16 chunks run in parallel (chunk c's paths
// c, c + 16, ... draw from Pcg32(seed, stream + c)): the same figures for any thread count. A path that does not
// count returns 0.
template <typename PerPath>
std::pair<double, double> chunked_mean(int paths, uint64_t seed, uint64_t stream, const PerPath &per_path) {
  constexpr int kChunks = 16;
  std::array<std::array<double, 2>, kChunks> acc{};
  tbb::parallel_for(0, kChunks, [&](int c) {
    Pcg32 rng(seed, stream + uint64_t(c));
    for (int i = c; i < paths; i += kChunks) {
      const double w = per_path(rng);
      acc[size_t(c)][0] += w;
      acc[size_t(c)][1] += w * w;
    }
  });
  double sum = 0.0, sum2 = 0.0;
  for (const auto &a : acc) sum += a[0], sum2 += a[1];
  const double m = sum / paths;
  return {m, std::sqrt(std::max(0.0, sum2 / paths - m * m) / paths)};
}
constexpr double kShadowLampDeg = 4.0;
struct ShadowPoint {
  double value = 0.0, se = 0.0;  // the lamp cone's transmitted weight per floor path
};
std::vector<ShadowPoint> sphere_shadow(const AnalyticScene &scene, const Sampler &sample, const Vec3 &lamp,
                                       const std::vector<Vec3> &floor_points, int paths, uint64_t seed) {
  std::vector<ShadowPoint> out(floor_points.size());
  const double cos_cone = std::cos(kShadowLampDeg * M_PI / 180.0);
  tbb::parallel_for(size_t(0), floor_points.size(), [&](size_t k) {
    const auto [m, se] = chunked_mean(paths, seed, 7 + 131 * k, [&](Pcg32 &rng) -> double {
      const float u1 = rng.next_float(), u2 = rng.next_float(), r = std::sqrt(u1), phi = 2.0f * float(M_PI) * u2;
      const Vec3 D(r * std::cos(phi), r * std::sin(phi), std::sqrt(std::max(0.0f, 1.0f - u1)));
      Pixel px{{}, D};
      if (!scene.intersect(floor_points[k], D, 0.0f, 100.0f, px.hit)) return 0.0;
      Spectrum throughput;
      Vec3 wo;
      if (!trace_through(scene, sample, px, rng, throughput, wo)) return 0.0;
      if (double(dot(normalize(wo), lamp)) < cos_cone) return 0.0;
      return double(average(throughput));
    });
    out[k] = {m, se};
  });
  return out;
}
// Measured (session 23, 2M / 0.5M paths per floor point), relative L1 default / the single SG about the same axis
// (the control): r 0.5 0.0589 / 0.2526, r 0.6 0.0433 / 0.1616. At 4M / 1M, r 0.5 / 0.6: 0.0562 / 0.0445; the axis
// rules at r 0.5: no shift 0.1016, the exit lobe's first moment 0.0835, session 22's smooth shift (the default)
// 0.0562; r 0.6 with session 22's shape 0.0478, the harness' best 0.75:1.5,0.25:0.25 0.0839. Bounds: measured + ~25 %;
// the control must miss them.
TEST(FrostedGlassSg, SphereShadowOfAFarLampAgainstThePath) {
  const int ref_paths = stress_scale() > 1 ? 8000000 : 2000000, sg_paths = ref_paths / 4;
  const Vec3 lamp = normalize(Vec3(0.9f, 1.6f, 2.4f));  // the bench's lamp seen from the sphere's centre
  const Vec3 toward = normalize(Vec3(-lamp.x, -lamp.y, 0.0f));
  std::vector<Vec3> floor_points;
  const std::vector<float> distances = {0.2f, 0.45f, 0.7f, 0.95f, 1.2f, 1.45f};
  for (const float d : distances) floor_points.push_back(Vec3(0.0f, 0.0f, -1.0f + 1e-4f) + toward * d);
  struct ShadowCase {
    float roughness, ior;
    double bound;
  };
  for (const auto &[roughness, ior, bound] : {ShadowCase{0.5f, 1.5f, 0.07}, ShadowCase{0.6f, 1.5f, 0.056}}) {
    auto path = create_raw(roughness, ior, false);
    auto sg = create_raw(roughness, ior, true);
    AnalyticScene scene(AnalyticScene::kSphere);
    scene.material = reinterpret_cast<const GlimmerInstance *>(sg.get());
    scene.diffuse_bounce = 1;  // the floor's view of the sphere (the renderer's floor vertex scattered diffusely)
    const Sampler path_sampler = sampler_of(*path), sg_sampler = sampler_of(*sg);
    const std::vector<ShadowPoint> ref = sphere_shadow(scene, path_sampler, lamp, floor_points, ref_paths, 1);
    const std::vector<ShadowPoint> now = sphere_shadow(scene, sg_sampler, lamp, floor_points, sg_paths, 2);
    const frosted::CurvedShape single{1, {1.0f}, {1.0f}};  // the control: the single SG about the same axis
    const Sampler single_sampler([&path, &sg, &single](const ShadingPoint &sp, const Vec3 &r, LocalSample &s) {
      if (!path->sample(sp, r, s)) return false;
      if (sg->uses_sg(sp) && (s.label & GLIMMER_LABEL_TRANSMIT))
        sg->sample_sg(sp, r, s, frosted::SgVariant::kMixture, frosted::kDefaultMixtureVariance,
                      frosted::kDefaultMixtureTail, 0.0f, &single);
      return true;
    });
    const std::vector<ShadowPoint> ctl = sphere_shadow(scene, single_sampler, lamp, floor_points, sg_paths, 2);
    std::printf("[frosted sphere shadow] roughness %.2f ior %.2f, lamp cone %.0f deg: floor distance | path (se) | "
                "sg / path (se) | single SG / path\n", double(roughness), double(ior), kShadowLampDeg);
    double l1 = 0.0, l1_ctl = 0.0, total = 0.0;
    for (size_t k = 0; k < floor_points.size(); ++k) {
      const double ratio = now[k].value / std::max(ref[k].value, 1e-30);
      std::printf("  %.2f | %.3e (%.1e) | %.3f (%.3f) | %.3f\n", double(distances[k]), ref[k].value, ref[k].se, ratio,
                  std::hypot(now[k].se, ref[k].se * ratio) / std::max(ref[k].value, 1e-30),
                  ctl[k].value / std::max(ref[k].value, 1e-30));
      l1 += std::fabs(now[k].value - ref[k].value);
      l1_ctl += std::fabs(ctl[k].value - ref[k].value);
      total += ref[k].value;
    }
    std::printf("  relative L1 over the floor points %.4f (single SG %.4f)\n", l1 / std::max(total, 1e-30),
                l1_ctl / std::max(total, 1e-30));
    EXPECT_LT(l1 / total, bound) << "roughness " << roughness;
    EXPECT_GT(l1_ctl / total, bound) << "control passed: roughness " << roughness;
  }
}

// ---- The lamp's caustic in direction space and at the bench's lamp distance (issue 12, session 24) --------------
// Measurement only (skipped unless GLIMMER_SHADOW_DIRECTIONS=1: it bounds nothing). At floor points of
// SphereShadowOfAFarLampAgainstThePath (0.2..1.2 radii; GLIMMER_SHADOW_SCAN=1: 0.5..1.0 by 0.05 at half the paths),
// path vs sg, r 0.5 IOR 1.5: the weight leaving within 2 / 4 / 8 / 16 / 32 / 180 deg of the lamp direction; within
// 15 deg the light-weighted mean, standard deviation and skewness along the lamp's "up" (the plane of the lamp, the
// zenith and the shadow's axis: the sphere's radial direction there) and sideways; and the weight whose leaving ray
// (from its own exit point: sg's is the mixture's one origin) hits the bench's lamp, a ball at its distance (5.04
// radii, the 0.25 x 0.25 square's cross-section; GLIMMER_SHADOW_LAMP_SCALE = s: s times as far and as large), and
// the same with every leaving ray moved to the exit point of the entry's smooth chief ray (one origin per entry, as
// sg's mixture has). The directions are the same at every lamp distance: what changes with it is where light leaves.
constexpr float kBenchLampDistance = 3.0216f / 0.6f, kBenchLampRadius = 0.141f / 0.6f;
struct LampDirections {
  double within[6] = {};  // weight per path leaving within 2 / 4 / 8 / 16 / 32 / 180 deg of the lamp
  double near = 0.0;      // weight per path whose leaving ray hits the bench's lamp (a ball at its distance)
  double near_at_axis = 0.0;  // the same with every leaving ray moved to the entry's smooth chief ray's exit point
  // Per entry, the leaving direction about the entry's smooth chief ray's exit direction c (within 30 deg of it):
  // along the lamp's "up" projected off c, and sideways (radians): weight, sums of u, u^2, u^3, v, v^2.
  double e_w = 0.0, e_u = 0.0, e_uu = 0.0, e_uuu = 0.0, e_v = 0.0, e_vv = 0.0;
  double w = 0.0, a = 0.0, aa = 0.0, aaa = 0.0, b = 0.0, bb = 0.0;  // within 15 deg, radians
};
LampDirections lamp_directions(const AnalyticScene &scene, const Sampler &sample, const Vec3 &lamp, const Vec3 &at,
                               int paths, uint64_t seed, float ior) {
  constexpr int kChunks = 16;
  std::array<LampDirections, kChunks> acc{};
  // GLIMMER_SHADOW_LAMP_SCALE = s: the lamp s times as far and as large (the same solid angle from the centre).
  const char *scale_env = std::getenv("GLIMMER_SHADOW_LAMP_SCALE");
  const float lamp_scale = scale_env != nullptr ? std::max(std::strtof(scale_env, nullptr), 0.01f) : 1.0f;
  const Vec3 up = normalize(Vec3(0.0f, 0.0f, 1.0f) - lamp * lamp.z), side = normalize(cross(lamp, up));
  tbb::parallel_for(0, kChunks, [&](int c) {
    Pcg32 rng(seed, 7 + uint64_t(c));
    LampDirections &o = acc[size_t(c)];
    for (int i = c; i < paths; i += kChunks) {
      const float u1 = rng.next_float(), u2 = rng.next_float(), r = std::sqrt(u1), phi = 2.0f * float(M_PI) * u2;
      const Vec3 D(r * std::cos(phi), r * std::sin(phi), std::sqrt(std::max(0.0f, 1.0f - u1)));
      Pixel px{{}, D};
      if (!scene.intersect(at, D, 0.0f, 100.0f, px.hit)) continue;
      Spectrum throughput;
      Vec3 wo, from;
      if (!trace_through(scene, sample, px, rng, throughput, wo, &from)) continue;
      const double deg = degrees_between(normalize(wo), lamp), w = average(throughput);
      // the bench's lamp: 3.02 / 0.6 radii from the sphere's centre, a ball of the square's cross-section
      auto hits_lamp = [&](const Vec3 &origin) {
        const Vec3 c = lamp * (kBenchLampDistance * lamp_scale) - origin, d = normalize(wo);
        const float along = dot(c, d), miss2 = dot(c, c) - along * along, r = kBenchLampRadius * lamp_scale;
        return along > 0.0f && miss2 < r * r;
      };
      if (hits_lamp(from)) o.near += w;
      Vec3 inside;  // the entry's smooth chief ray's exit point (where sg's mixture leaves from, nearly)
      Hit far;
      if (smooth_refract(D, px.hit.N, 1.0f / ior, inside) &&
          scene.intersect(frosted::offset_origin(px.hit.P, px.hit.N, inside), inside, 0.0f, 100.0f, far)) {
        if (hits_lamp(far.P)) o.near_at_axis += w;
        Vec3 chief;
        if (smooth_refract(inside, -far.N, ior, chief) && degrees_between(normalize(wo), chief) < 30.0) {
          Vec3 eu = up - chief * dot(up, chief);
          if (dot(eu, eu) > 1e-8f) {
            eu = normalize(eu);
            const Vec3 ev = normalize(cross(chief, eu));
            const double u = dot(normalize(wo), eu), v = dot(normalize(wo), ev);
            o.e_w += w, o.e_u += w * u, o.e_uu += w * u * u, o.e_uuu += w * u * u * u, o.e_v += w * v;
            o.e_vv += w * v * v;
          }
        }
      }
      for (int k = 0; k < 6; ++k)
        if (deg < 2.0 * double(1 << k) || k == 5) o.within[k] += w;
      if (deg < 15.0) {
        const double a = dot(wo, up), b = dot(wo, side);
        o.w += w, o.a += w * a, o.aa += w * a * a, o.aaa += w * a * a * a, o.b += w * b, o.bb += w * b * b;
      }
    }
  });
  LampDirections out;
  for (const auto &o : acc) {
    for (int k = 0; k < 6; ++k) out.within[k] += o.within[k] / paths;
    out.near += o.near / paths;
    out.near_at_axis += o.near_at_axis / paths;
    out.e_w += o.e_w, out.e_u += o.e_u, out.e_uu += o.e_uu, out.e_uuu += o.e_uuu, out.e_v += o.e_v, out.e_vv += o.e_vv;
    out.w += o.w, out.a += o.a, out.aa += o.aa, out.aaa += o.aaa, out.b += o.b, out.bb += o.bb;
  }
  return out;
}
TEST(FrostedGlassSg, SphereShadowDirectionsAroundTheLamp) {
  if (std::getenv("GLIMMER_SHADOW_DIRECTIONS") == nullptr) GTEST_SKIP() << "measurement: GLIMMER_SHADOW_DIRECTIONS=1";
  const char *scan = std::getenv("GLIMMER_SHADOW_SCAN");
  const int ref_paths = scan != nullptr ? 2000000 : 4000000, sg_paths = ref_paths / 4;
  const Vec3 lamp = normalize(Vec3(0.9f, 1.6f, 2.4f));
  const Vec3 toward = normalize(Vec3(-lamp.x, -lamp.y, 0.0f));
  const float roughness = 0.5f, ior = 1.5f;
  auto path = create_raw(roughness, ior, false);
  auto sg = create_raw(roughness, ior, true);
  AnalyticScene scene(AnalyticScene::kSphere);
  scene.material = reinterpret_cast<const GlimmerInstance *>(sg.get());
  scene.diffuse_bounce = 1;  // the floor's view of the sphere, as in SphereShadowOfAFarLampAgainstThePath
  const Sampler path_sampler = sampler_of(*path), sg_sampler = sampler_of(*sg);
  std::printf("[frosted shadow directions] roughness 0.50 ior 1.50: floor distance | method | within 2 / 4 / 8 deg "
              "| within 15 deg: up mean sd skew, side mean sd (deg)\n");
  std::vector<float> distances = {0.2f, 0.45f, 0.7f, 0.95f, 1.2f};
  if (scan != nullptr) {
    distances.clear();
    for (int i = 0; i <= 10; ++i) distances.push_back(0.5f + 0.05f * float(i));
  }
  for (const float d : distances) {
    const Vec3 at = Vec3(0.0f, 0.0f, -1.0f + 1e-4f) + toward * d;
    const LampDirections ref = lamp_directions(scene, path_sampler, lamp, at, ref_paths, 1, ior);
    const LampDirections now = lamp_directions(scene, sg_sampler, lamp, at, sg_paths, 2, ior);
    for (const auto &[what, m] : {std::pair<const char *, const LampDirections &>{"path", ref}, {"sg", now}}) {
      const double ma = m.a / m.w, sa = std::sqrt(std::max(m.aa / m.w - ma * ma, 0.0));
      const double m3 = m.aaa / m.w - 3.0 * ma * m.aa / m.w + 2.0 * ma * ma * ma;
      const double mb = m.b / m.w, sb = std::sqrt(std::max(m.bb / m.w - mb * mb, 0.0));
      constexpr double kDeg = 180.0 / M_PI;
      std::printf("  %.2f | %-4s | %.3e %.3e %.3e %.3e %.3e T %.3e | up %+.2f %.2f %+.2f, side %+.2f %.2f | w15 %.3e "
                  "| near lamp %.3e | from the axis' exit %.3e\n", double(d), what,
                  m.within[0], m.within[1], m.within[2], m.within[3], m.within[4], m.within[5], ma * kDeg, sa * kDeg, m3 / (sa * sa * sa + 1e-30),
                  mb * kDeg, sb * kDeg, m.w / (what[0] == 'p' ? ref_paths : sg_paths), m.near,
                  m.near_at_axis);
      const double eu = m.e_u / m.e_w, su = std::sqrt(std::max(m.e_uu / m.e_w - eu * eu, 0.0));
      const double ku = (m.e_uuu / m.e_w - 3.0 * eu * m.e_uu / m.e_w + 2.0 * eu * eu * eu) / (su * su * su + 1e-30);
      const double ev = m.e_v / m.e_w, sv = std::sqrt(std::max(m.e_vv / m.e_w - ev * ev, 0.0));
      std::printf("         per entry, about its chief ray's exit (within 30 deg): up %+.2f sd %.2f skew %+.2f, side "
                  "%+.2f sd %.2f deg\n", eu * kDeg, su * kDeg, ku, ev * kDeg, sv * kDeg);
    }
  }
}

// ---- The skew of the slab's oblique exit lobe (issue 12, thirteenth session) -----------------------------------
// The slab of the accuracy set at incidences 0 / 30 / 50 / 70 deg (the exit axis is the incident direction
// continued): each transmitted path binned by the angle of its escape direction off the exit axis and by its
// azimuth about the axis relative to the exit's plane of incidence: toward the normal (within 45 deg of the
// azimuth of the exit normal), sideways, toward grazing. A vMF about the axis is symmetric in azimuth; the exact
// lobe is not (the refraction's Jacobian stretches it toward grazing): the small light behind the slab sits 20 deg
// off the normal, so at 50 / 70 deg incidence it is 30 / 50 deg off axis toward the normal. Compared: the default
// and the thirteenth session's rule (the per-ray kappa / 4 tails at every planar exit up to kMixtureRoughnessMax; the
// skewed tail it was compared with there, SgVariant::kMixtureSkewed, was removed in the fourteenth session).
constexpr int kSkewBands = 7, kSkewSectors = 3;
constexpr double kSkewEdge[kSkewBands + 1] = {0, 5, 10, 20, 30, 45, 60, 180};  // degrees
struct SkewBands {
  double mass[kSkewBands][kSkewSectors] = {};  // fraction of the pixel's transmitted energy
  double total = 0.0;                          // transmitted energy per entering path
};
SkewBands skew_bands(const AnalyticScene &scene, const Sampler &sample, const Pixel &px, int paths, uint64_t seed) {
  constexpr int kChunks = 16;
  std::array<std::array<double, kSkewBands * kSkewSectors + 1>, kChunks> acc{};
  const Vec3 axis = px.D;
  // The exit normal (outward, -z) projected off the axis: azimuth 0 = toward the normal.
  Vec3 toward = Vec3(0.0f, 0.0f, -1.0f) - axis * dot(Vec3(0.0f, 0.0f, -1.0f), axis);
  toward = dot(toward, toward) > 1e-8f ? normalize(toward) : Vec3(-1.0f, 0.0f, 0.0f);
  tbb::parallel_for(0, kChunks, [&](int c) {
    auto &a = acc[size_t(c)];
    Pcg32 rng(seed, 101 + uint64_t(c));
    for (int i = c; i < paths; i += kChunks) {
      Spectrum throughput;
      Vec3 wo;
      if (!trace_through(scene, sample, px, rng, throughput, wo)) continue;
      const double w = average(throughput);
      const int b = angle_band(kSkewEdge, degrees_between(wo, axis));
      const Vec3 side = wo - axis * dot(wo, axis);
      const double cos_az = dot(side, side) > 1e-12f ? double(dot(normalize(side), toward)) : 1.0;
      const int sector = cos_az > std::sqrt(0.5) ? 0 : (cos_az > -std::sqrt(0.5) ? 1 : 2);
      a[size_t(b * kSkewSectors + sector)] += w;
      a[kSkewBands * kSkewSectors] += w;
    }
  });
  SkewBands out;
  for (const auto &a : acc) {
    for (int b = 0; b < kSkewBands; ++b)
      for (int s = 0; s < kSkewSectors; ++s) out.mass[b][s] += a[size_t(b * kSkewSectors + s)];
    out.total += a[kSkewBands * kSkewSectors];
  }
  for (auto &band : out.mass)
    for (double &m : band) m /= std::max(out.total, 1e-30);
  out.total /= double(paths);
  return out;
}
// L1 of the 2D band masses, and the mass toward the normal 20-60 deg off axis (where the small light is seen).
double skew_l1(const SkewBands &a, const SkewBands &b) {
  double d = 0.0;
  for (int k = 0; k < kSkewBands; ++k)
    for (int s = 0; s < kSkewSectors; ++s) d += std::fabs(a.mass[k][s] - b.mass[k][s]);
  return d;
}
double skew_toward_normal(const SkewBands &a) { return a.mass[3][0] + a.mass[4][0] + a.mass[5][0]; }
void print_skew(const char *what, const SkewBands &m, const SkewBands *ref) {
  std::printf("  %-16s T %.4f |", what, m.total);
  for (int b = 0; b < kSkewBands; ++b) {
    if (ref == nullptr) {
      std::printf(" %.1e/%.1e/%.1e", m.mass[b][0], m.mass[b][1], m.mass[b][2]);
    } else {
      auto ratio = [&](int s) { return m.mass[b][s] / std::max(ref->mass[b][s], 1e-12); };
      std::printf(" %7.2f/%.2f/%.2f", ratio(0), ratio(1), ratio(2));
    }
  }
  if (ref != nullptr)
    std::printf(" | L1 %.3f, toward normal 20-60 x%.2f", skew_l1(m, *ref), skew_toward_normal(m) / skew_toward_normal(*ref));
  std::printf("\n");
}

struct SkewResult {
  double l1_now = 0.0, l1_s13 = 0.0, normal_now = 0.0, normal_s13 = 0.0;  // summed over incidences
};
SkewResult measure_skew(float roughness, float ior, int ref_paths, int sg_paths) {
  auto path = create_raw(roughness, ior, false);
  auto sg = create_raw(roughness, ior, true);
  AnalyticScene scene(AnalyticScene::kSlab);
  scene.material = reinterpret_cast<const GlimmerInstance *>(sg.get());
  const Sampler path_sampler = sampler_of(*path), sg_sampler = sampler_of(*sg);
  const Sampler s13 = [&](const ShadingPoint &sp, const Vec3 &r, LocalSample &s) {  // per-ray kappa / 4 tails
    if (!path->sample(sp, r, s)) return false;
    if (sg->uses_sg(sp) && (s.label & GLIMMER_LABEL_TRANSMIT))
      sg->sample_sg(sp, r, s, frosted::SgVariant::kMixture, frosted::kDefaultMixtureVariance, 0.2f);
    return true;
  };
  SkewResult res;
  std::printf("[frosted sg skew] slab roughness %.2f ior %.2f: per band (deg) 0-5 5-10 10-20 20-30 30-45 45-60 "
              "60-180, sectors toward normal / sideways / toward grazing (path: mass; sg: ratio to path)\n",
              double(roughness), double(ior));
  for (const float degrees : {0.0f, 30.0f, 50.0f, 70.0f}) {
    const float th = degrees * float(M_PI) / 180.0f;
    Pixel px{{}, Vec3(std::sin(th), 0.0f, -std::cos(th))};
    scene.intersect(Vec3(0.0f) - px.D * 5.0f, px.D, 0.0f, 100.0f, px.hit);
    const SkewBands ref = skew_bands(scene, path_sampler, px, ref_paths, 1);
    const SkewBands now = skew_bands(scene, sg_sampler, px, sg_paths, 2);
    const SkewBands old = skew_bands(scene, s13, px, sg_paths, 2);
    std::printf(" incidence %2.0f deg\n", double(degrees));
    print_skew("path", ref, nullptr);
    print_skew("sg (default)", now, &ref);
    print_skew("sg (s13 tails)", old, &ref);
    // The reference's own check: at normal incidence the binning is symmetric (toward the normal = toward grazing
    // within 10 % over 0-20 deg); at 50 deg and roughness 0.3 the exact lobe is skewed (measured 20-30 deg: 2.3e-2
    // toward grazing against 1.2e-2 toward the normal; at 0.5 the horizon, 40 deg off axis, cuts the grazing side).
    const double normal_0_20 = ref.mass[0][0] + ref.mass[1][0] + ref.mass[2][0];
    const double grazing_0_20 = ref.mass[0][2] + ref.mass[1][2] + ref.mass[2][2];
    if (degrees == 0.0f) {
      EXPECT_NEAR(normal_0_20 / grazing_0_20, 1.0, 0.1) << "roughness " << roughness;
    }
    if (degrees == 50.0f && roughness < 0.4f) {
      EXPECT_GT(ref.mass[3][2], 1.5 * ref.mass[3][0]) << "roughness " << roughness;
    }
    res.l1_now += skew_l1(now, ref);
    res.l1_s13 += skew_l1(old, ref);
    res.normal_now += std::fabs(skew_toward_normal(now) / skew_toward_normal(ref) - 1.0);
    res.normal_s13 += std::fabs(skew_toward_normal(old) / skew_toward_normal(ref) - 1.0);
  }
  std::printf("[frosted sg skew] slab roughness %.2f: summed over the 4 incidences: 2D band L1 default %.3f / "
              "s13 tails %.3f; |toward normal 20-60 deg / path - 1| default %.3f / s13 tails %.3f\n",
              double(roughness), res.l1_now, res.l1_s13, res.normal_now, res.normal_s13);
  return res;
}

// Measured (100000 / 25000 paths per pixel), 2D band L1 summed over the 4 incidences, default / skewed tail:
// roughness 0.3 0.782 / 0.862, 0.5 0.601 / 0.601 (the ladder above kMixtureRoughnessMax is not skewed; with its
// former cores x 3: 0.773). Bounds: the default's measured + ~20 %, so a regression of the mixture's shape fails.
// Fourteenth session (the reflected remainder's own axis at planar exits): 0.782 -> 0.741, 0.601 -> 0.459; bounds
// 0.95 / 0.73 -> 0.89 / 0.55.
TEST(FrostedGlassSg, ExitLobeSkewOfTheSlabAgainstThePath) {
  const int ref_paths = stress_scale() > 1 ? 400000 : 100000, sg_paths = ref_paths / 4;
  for (const auto &[roughness, bound] : {std::pair{0.3f, 0.89}, std::pair{0.5f, 0.55}}) {
    const SkewResult r = measure_skew(roughness, 1.5f, ref_paths, sg_paths);
    EXPECT_LT(r.l1_now, bound) << "roughness " << roughness;
  }
}

// ---- method=auto ----------------------------------------------------------------
// Paths entering the unit sphere at random points from outside, with the bounce counters of a camera ray or of
// a path after a diffuse, glossy or transmission bounce: auto's samples must equal (bit for bit) those of the
// method its rule picks, and differ from the other method's (so the comparison can fail).
TEST(FrostedGlassAuto, SamplesAreSgsWhereTheRulePicksSgAndPathsElsewhere) {
  enum Bounce { kCamera, kAfterDiffuse, kAfterGlossy, kAfterTransmission };
  struct Case {
    float roughness;
    Bounce bounce;
    bool expect_sg;
  };
  const Case cases[] = {{0.1f, kCamera, true},         {0.3f, kCamera, true},          {0.31f, kCamera, false},
                        {0.6f, kCamera, false},        {0.6f, kAfterDiffuse, true},    {0.8f, kAfterGlossy, true},
                        {0.6f, kAfterTransmission, false}};
  const auto schema = FrostedGlassClosure::params();
  for (const Case &c : cases) {
    auto path = create_method(c.roughness, 1.5f, "path");
    auto sg = create_method(c.roughness, 1.5f, "sg");
    auto automatic = create_method(c.roughness, 1.5f, "auto");
    AnalyticScene scene(AnalyticScene::kSphere);
    int same_as_picked = 0, same_as_other = 0, moved = 0, n = 0;
    Pcg32 rng(77);
    for (int i = 0; i < 2000; ++i) {
      const Vec3 n_out = normalize(Vec3(rng.next_float() - 0.5f, rng.next_float() - 0.5f, rng.next_float() - 0.5f));
      const Frame f = Frame::from_normal(n_out);
      const Vec3 wi_local = normalize(Vec3(rng.next_float() - 0.5f, rng.next_float() - 0.5f, 0.2f + rng.next_float()));
      GlimmerShadingContext ctx = host::make_local_context(f.to_world(wi_local), &scene.services);
      ctx.P = n_out;
      ctx.N = ctx.Ng = n_out;
      ctx.T = f.s;
      ctx.path_seed = rng.next_u32();
      ctx.diffuse_bounce = c.bounce == kAfterDiffuse;
      ctx.glossy_bounce = c.bounce == kAfterGlossy;
      ctx.transmission_bounce = c.bounce == kAfterTransmission;
      ctx.bounce = c.bounce == kCamera ? 0u : 1u;
      const ShadingPoint sp(&ctx, schema);
      const Vec3 u(rng.next_float(), rng.next_float(), rng.next_float());
      LocalSample a, p, g;
      scene.material = reinterpret_cast<const GlimmerInstance *>(automatic.get());
      const bool ok_a = automatic->sample(sp, u, a);
      scene.material = reinterpret_cast<const GlimmerInstance *>(path.get());
      const bool ok_p = path->sample(sp, u, p);
      scene.material = reinterpret_cast<const GlimmerInstance *>(sg.get());
      const bool ok_g = sg->sample(sp, u, g);
      auto same = [&](bool ok, const LocalSample &s) {
        auto eq = [](const Vec3 &x, const Vec3 &y) { return x.x == y.x && x.y == y.y && x.z == y.z; };
        return ok == ok_a && (!ok || (eq(s.wo, a.wo) && eq(s.f_cos, a.f_cos) && s.pdf == a.pdf && s.moved == a.moved));
      };
      ++n;
      moved += ok_a && a.moved;
      same_as_picked += c.expect_sg ? same(ok_g, g) : same(ok_p, p);
      same_as_other += c.expect_sg ? same(ok_p, p) : same(ok_g, g);
    }
    EXPECT_EQ(same_as_picked, n) << "roughness " << c.roughness << " bounce " << c.bounce;
    EXPECT_LT(same_as_other, n * 9 / 10) << "roughness " << c.roughness << " bounce " << c.bounce;
    if (c.expect_sg) {
      EXPECT_GT(moved, n / 4) << "roughness " << c.roughness;
    } else {
      EXPECT_EQ(moved, 0) << "roughness " << c.roughness;
    }
  }
}

// ---- ABI 2.7: the whole exit mixture handed to the host ------------------------------------------------------
// Through the plugin's C entry point (ClosureAdapter::sample) on the analytic sphere, entry points with wi above
// and (every 8th) below the surface:
//  - a 2.7 host (full struct_size, a buffer): every moved sample at roughness 0.3 (the mixture rule) flags
//    GLIMMER_SAMPLE_EXIT_MIXTURE with 1..10 lobes, weights summing to 1, the picked lobe in lobe_axis among them;
//  - a 2.6 host (struct_size up to lobe_sharpness) with guard bytes after it: nothing written beyond its
//    struct_size (also on "no sample"), the same moved direction and picked lobe, EXIT_LOBE without the mixture
//    flag (it still gets the single-lobe behaviour);
//  - a 2.7 host with a NULL buffer: no mixture flag; roughness 0.6 (the sphere's split single SG) the mixture too,
//    roughness 0.8 (the single SG) none;
//  - negative control: the former whole-struct "no sample" trips the guard check.
TEST(FrostedGlassSg, ExitMixtureThroughTheAbiForNewAndOldHosts) {
  using Adapter = ClosureAdapter<FrostedGlassClosure>;
  {  // Negative control of the guard check: the plugin core's former "no sample" (a whole-struct assignment).
    constexpr size_t kOld = offsetof(GlimmerSample, exit_mixture);
    alignas(GlimmerSample) unsigned char raw[sizeof(GlimmerSample) + 64];
    std::memset(raw, 0xAB, sizeof raw);
    GlimmerSample *old = reinterpret_cast<GlimmerSample *>(raw);
    old->struct_size = uint32_t(kOld);
    *old = GlimmerSample{};
    int overwritten = 0;
    for (size_t b = kOld; b < sizeof raw; ++b) overwritten += raw[b] != 0xAB;
    EXPECT_GT(overwritten, 0);
  }
  // Roughness 0.3: the per-ray mixture; 0.6: the sphere's curved exit (a 2-lobe mixture, kCurvedExitShape); 0.8: the
  // single SG, no mixture.
  for (const float roughness : {0.3f, 0.6f, 0.8f}) {
    auto sg = create_method(roughness, 1.5f, "sg");
    const auto *inst = reinterpret_cast<const GlimmerInstance *>(sg.get());
    AnalyticScene scene(AnalyticScene::kSphere);
    scene.material = inst;
    Pcg32 rng(91);
    int moved = 0, mixtures = 0, bad = 0, none = 0;
    for (int i = 0; i < 1500; ++i) {
      const Vec3 n_out = normalize(Vec3(rng.next_float() - 0.5f, rng.next_float() - 0.5f, rng.next_float() - 0.5f));
      const Frame f = Frame::from_normal(n_out);
      const float z = i % 8 == 7 ? -0.5f : 0.2f + rng.next_float();
      const Vec3 wi_local = normalize(Vec3(rng.next_float() - 0.5f, rng.next_float() - 0.5f, z));
      GlimmerShadingContext ctx = host::make_local_context(f.to_world(wi_local), &scene.services);
      ctx.P = n_out;
      ctx.N = ctx.Ng = n_out;
      ctx.T = f.s;
      ctx.path_seed = rng.next_u32();
      const float r3[3] = {rng.next_float(), rng.next_float(), rng.next_float()};
      // 2.7 host.
      GlimmerExitMixture buffer{};
      GlimmerSample full = glimmer_blank_sample();
      full.exit_mixture = &buffer;
      const uint32_t label = Adapter::sample(inst, &ctx, r3, &full);
      // 2.6 host: its sample ends before exit_mixture; guard bytes after it.
      constexpr size_t kOld = offsetof(GlimmerSample, exit_mixture);
      alignas(GlimmerSample) unsigned char raw[sizeof(GlimmerSample) + 64];
      std::memset(raw, 0xAB, sizeof raw);
      GlimmerSample *old = reinterpret_cast<GlimmerSample *>(raw);
      old->struct_size = uint32_t(kOld);
      const uint32_t old_label = Adapter::sample(inst, &ctx, r3, old);
      for (size_t b = kOld; b < sizeof raw; ++b) bad += raw[b] != 0xAB;
      // 2.7 host without a buffer.
      GlimmerSample no_buffer = glimmer_blank_sample();
      Adapter::sample(inst, &ctx, r3, &no_buffer);
      bad += (no_buffer.flags & GLIMMER_SAMPLE_EXIT_MIXTURE) != 0;
      if (label == GLIMMER_LABEL_NONE) {
        ++none;
        bad += old_label != GLIMMER_LABEL_NONE;
        continue;
      }
      bad += old_label != label || old->wo.x != full.wo.x || old->wo.y != full.wo.y || old->wo.z != full.wo.z;
      if (!(full.flags & GLIMMER_SAMPLE_MOVED)) continue;
      ++moved;
      bad += (old->flags & GLIMMER_SAMPLE_EXIT_MIXTURE) != 0 || !(old->flags & GLIMMER_SAMPLE_EXIT_LOBE) ||
             old->lobe_sharpness != full.lobe_sharpness;
      if (!(full.flags & GLIMMER_SAMPLE_EXIT_MIXTURE)) continue;
      ++mixtures;
      double sum = 0.0;
      bool picked_listed = false;
      for (uint32_t k = 0; k < buffer.count && k < GLIMMER_EXIT_MAX_LOBES; ++k) {
        sum += buffer.weight[k];
        picked_listed |= buffer.axis[k].x == full.lobe_axis.x && buffer.axis[k].y == full.lobe_axis.y &&
                         buffer.axis[k].z == full.lobe_axis.z && buffer.sharpness[k] == full.lobe_sharpness;
      }
      bad += !(buffer.count >= 1 && buffer.count <= GLIMMER_EXIT_MAX_LOBES) || std::fabs(sum - 1.0) > 1e-4 ||
             !picked_listed;
    }
    std::printf("[frosted sg abi] roughness %.1f: %d moved samples, %d with the whole mixture; %d no-sample calls; "
                "%d bad (old host's guard bytes, labels, directions, flags, mixture contents)\n",
                double(roughness), moved, mixtures, none, bad);
    EXPECT_EQ(bad, 0) << "roughness " << roughness;
    EXPECT_GT(moved, 300) << "roughness " << roughness;
    EXPECT_GT(none, 100) << "roughness " << roughness;  // the no-sample path (clear) ran for the old host
    if (roughness <= frosted::kCurvedSplitMax)
      EXPECT_EQ(mixtures, moved);
    else
      EXPECT_EQ(mixtures, 0);
  }
}

// ---- Stress --------------------------------------------------------------------
using glimmer::test::bad_raw_outputs;

// A host answering with odd hits: distances 0 / tiny / huge / inf / NaN / negative, normals NaN / zero /
// random, the material itself or another closure or none.
struct OddHost {
  const GlimmerInstance *material = nullptr;
  GlimmerHostServices services{};
  explicit OddHost(const GlimmerInstance *m) : material(m) {
    services = glimmer::test::tracing_host_services<&answer>(this);
  }
  static int answer(void *data, const GlimmerRay *ray, GlimmerRayHit *hit, GlimmerHitClosure *c) {
    const auto *self = static_cast<const OddHost *>(data);
    const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
    const float ts[] = {0.0f, 1e-30f, 1e-3f, 1.0f, 1e30f, inf, nan, -1.0f};
    const uint32_t h = hash_u32x3(std::bit_cast<uint32_t>(ray->direction.x), std::bit_cast<uint32_t>(ray->origin.y),
                                  std::bit_cast<uint32_t>(ray->direction.z));
    hit->t = ts[h % 8];
    hit->P = Vec3(ray->origin) + Vec3(ray->direction) * hit->t;
    const Vec3 normals[] = {Vec3(nan, 0, 0), Vec3(0.0f), normalize(Vec3(ray->direction)),
                            -normalize(Vec3(ray->direction)), Vec3(0, 0, 1), normalize(Vec3(1, 2, 3))};
    hit->N = hit->Ng = normals[(h >> 3) % 6];
    const GlimmerInstance *others[] = {self->material, self->material, nullptr,
                                       reinterpret_cast<const GlimmerInstance *>(&self->services)};
    c->instance = others[(h >> 6) % 4];
    c->varying_count = (h >> 8) % 3 == 0 ? 1000u : 0u;  // a count beyond the array must be clamped
    return int((h >> 10) % 5 != 0);
  }
};

// Negative control of the stress's host-side check (bad_host_sample): real whole-mixture samples from the C entry
// point pass it, and each broken copy (a NaN or non-unit axis, sharpness 0 / inf, a negative weight, weights
// summing to 0.9, count 0 or 11, the picked lobe missing, the flag without the buffer) fails it.
TEST(FrostedGlassSg, HostSampleCheckCatchesBrokenMixtures) {
  auto sg = create_method(0.3f, 1.5f, "sg");
  const auto *inst = reinterpret_cast<const GlimmerInstance *>(sg.get());
  AnalyticScene scene(AnalyticScene::kSphere);
  scene.material = inst;
  Pcg32 rng(5);
  int checked = 0, missed = 0, valid_bad = 0;
  for (int i = 0; i < 400 && checked < 50; ++i) {
    const Vec3 n_out = normalize(Vec3(rng.next_float() - 0.5f, rng.next_float() - 0.5f, rng.next_float() - 0.5f));
    const Frame f = Frame::from_normal(n_out);
    GlimmerShadingContext ctx = host::make_local_context(
        f.to_world(normalize(Vec3(rng.next_float() - 0.5f, rng.next_float() - 0.5f, 0.2f + rng.next_float()))),
        &scene.services);
    ctx.P = n_out;
    ctx.N = ctx.Ng = n_out;
    ctx.T = f.s;
    ctx.path_seed = rng.next_u32();
    const float r3[3] = {rng.next_float(), rng.next_float(), rng.next_float()};
    GlimmerExitMixture buffer;
    GlimmerSample hs = glimmer_blank_sample();
    hs.exit_mixture = &buffer;
    const uint32_t label = ClosureAdapter<FrostedGlassClosure>::sample(inst, &ctx, r3, &hs);
    if (!(hs.flags & GLIMMER_SAMPLE_EXIT_MIXTURE) || buffer.count < 2) continue;
    ++checked;
    long mixtures = 0;
    valid_bad += int(glimmer::test::bad_host_sample(label, hs, buffer, 0.3f, 0.7f, mixtures));
    const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
    const uint32_t last = buffer.count - 1;  // not the picked lobe when the picked one is lobe 0
    const std::function<void(GlimmerSample &, GlimmerExitMixture &)> breaks[] = {
        [&](GlimmerSample &, GlimmerExitMixture &m) { m.axis[last].x = nan; },
        [&](GlimmerSample &, GlimmerExitMixture &m) { m.axis[last] = Vec3(m.axis[last]) * 1.1f; },
        [&](GlimmerSample &, GlimmerExitMixture &m) { m.sharpness[last] = 0.0f; },
        [&](GlimmerSample &, GlimmerExitMixture &m) { m.sharpness[last] = inf; },
        [&](GlimmerSample &, GlimmerExitMixture &m) { m.weight[last] = -m.weight[last]; },
        [&](GlimmerSample &, GlimmerExitMixture &m) {
          for (uint32_t k = 0; k < m.count; ++k) m.weight[k] *= 0.9f;
        },
        [&](GlimmerSample &, GlimmerExitMixture &m) { m.count = 0; },
        [&](GlimmerSample &, GlimmerExitMixture &m) { m.count = GLIMMER_EXIT_MAX_LOBES + 1; },
        [&](GlimmerSample &h, GlimmerExitMixture &) { h.lobe_sharpness *= 1.5f; },
        [&](GlimmerSample &h, GlimmerExitMixture &) { h.exit_mixture = nullptr; },
    };
    for (const auto &broken : breaks) {
      GlimmerExitMixture m = buffer;
      GlimmerSample h = hs;
      h.exit_mixture = &m;
      broken(h, m);
      long unused = 0;
      missed += glimmer::test::bad_host_sample(label, h, m, 0.3f, 0.7f, unused) == 0;
    }
  }
  std::printf("[frosted sg stress check] %d real whole-mixture samples: %d flagged bad; broken copies (10 kinds each) "
              "not flagged: %d\n", checked, valid_bad, missed);
  EXPECT_GE(checked, 20);
  EXPECT_EQ(valid_bad, 0);
  EXPECT_EQ(missed, 0);
}

TEST(FrostedGlassSg, StressRawOutputsFiniteNonNegative) {
  Pcg32 rng(21);
  const float roughs[] = {0.0f, 1e-3f, 0.04f, 0.1f, 0.5f, 1.0f};
  const float iors[] = {1.0f, 1.2f, 1.33f, 1.7f, 2.5f, 1e3f, 1.0f / 2.4f};
  std::vector<std::unique_ptr<FrostedGlassClosure>> pool;
  std::vector<float> pool_roughness;
  for (int i = 0; i < 60; ++i) {
    const float rough = (i & 1) ? roughs[rng.next_u32() % 6] : rng.next_float();
    const float ior = (i % 2 == 0) ? 2.4f : iors[rng.next_u32() % 7];  // half TIR-heavy
    const Vec3 absorb = (i % 4 == 1) ? Vec3(rng.next_float(), 0.0f, 1e-6f) : Vec3(1.0f);
    pool.push_back(create_raw(rough, ior, true, absorb));
    pool_roughness.push_back(rough);
  }
  const auto schema = FrostedGlassClosure::params();
  const long blocks = 64;
  // GLIMMER_STRESS_BLOCKS="first,end": only blocks [first, end) of the 64 (as the pane's stress): a block's queries
  // depend on its index alone, so runs over disjoint ranges together are exactly the whole make-stress run.
  long first = 0, end = blocks;
  if (const char *range = std::getenv("GLIMMER_STRESS_BLOCKS"))
    if (std::sscanf(range, "%ld,%ld", &first, &end) != 2 || !(0 <= first && first < end && end <= blocks))
      first = 0, end = blocks;
  const long calls = 1000000 * long(stress_scale()) / blocks * (end - first);
  std::atomic<long> bad_count{0}, moved{0}, samples{0}, mixture_moved{0}, mixture_written{0};
  std::atomic<long> host_queries{0}, host_moved{0}, host_mixtures{0}, planar_wide{0};
  tbb::parallel_for(first, end, [&](long b) {
    Pcg32 r(900 + b);
    for (long i = 0; i < calls / (end - first); ++i) {
      const size_t pick = r.next_u32() % pool.size();
      const FrostedGlassClosure &c = *pool[pick];
      const GlimmerInstance *self = reinterpret_cast<const GlimmerInstance *>(&c);
      const bool grazing = (i % 4) == 0;
      const int which = int(r.next_u32() % 3);  // sphere, slab, odd host
      AnalyticScene sphere(AnalyticScene::kSphere), slab(AnalyticScene::kSlab);
      sphere.material = slab.material = self;
      OddHost odd(self);
      const GlimmerHostServices *host = which == 0 ? &sphere.services : which == 1 ? &slab.services : &odd.services;
      const Vec3 n = which == 0 ? normalize(Vec3(r.next_float() - 0.5f, r.next_float() - 0.5f, r.next_float() - 0.5f))
                                : Vec3(0, 0, 1);
      const Frame f = Frame::from_normal(is_finite(n) ? n : Vec3(0, 0, 1));
      GlimmerShadingContext ctx = host::make_local_context(f.to_world(test::stress_direction(r, grazing, 4)), host);
      ctx.P = which == 0 ? f.n : Vec3(0.0f);
      ctx.N = ctx.Ng = f.n;
      ctx.T = f.s;
      ctx.path_seed = r.next_u32();
      const ShadingPoint sp(&ctx, schema);
      const Vec3 wo = test::stress_direction(r, grazing, 4);  // mostly outside: the sg path
      const Vec3 rand(r.next_float(), r.next_float(), r.next_float());
      long n_bad = glimmer::test::stress_eval_and_sample(c, sp, wo, rand, samples, moved);
      // The same query as the renderer makes it (C entry point, a 2.7 host's sample with its whole-mixture buffer):
      // what the host reads (bad_host_sample), mixture included wherever the default rule writes one.
      {
        long mixtures = 0;
        uint32_t flags = 0;
        n_bad += glimmer::test::bad_host_query(c, ctx, rand, r.next_float(), r.next_float(), flags, mixtures);
        host_queries.fetch_add(1, std::memory_order_relaxed);
        if (flags & GLIMMER_SAMPLE_MOVED) host_moved.fetch_add(1, std::memory_order_relaxed);
        if (mixtures) host_mixtures.fetch_add(1, std::memory_order_relaxed);
        // A planar exit above roughness 0.4: the heavy-tail ladder (twelfth session), read whole by the host.
        if (mixtures && which == 1 && pool_roughness[pick] > frosted::kMixtureRoughnessMax)
          planar_wide.fetch_add(1, std::memory_order_relaxed);
      }
      // The exit lobe mixture (method=sg's default up to roughness 0.4): the same queries through kMixture, v and
      // t at the ends of their ranges and NaN (clamped), the whole mixture written to a host buffer (ABI 2.7).
      if (i % 2 == 0) {
        LocalSample s;
        GlimmerExitMixture buffer;
        s.mixture_out = &buffer;
        if (c.sample(sp, rand, s) && c.uses_sg(sp) && (s.label & GLIMMER_LABEL_TRANSMIT)) {
          const float vs[] = {0.0f, 0.5f, 1.0f, std::numeric_limits<float>::quiet_NaN()};
          const float ts[] = {0.0f, 0.2f, 0.25f, -1.0f};
          c.sample_sg(sp, rand, s, frosted::SgVariant::kMixture, vs[i / 2 % 4], ts[i / 4 % 4]);
          n_bad += glimmer::test::bad_raw_outputs(LocalEval{}, true, s);
          if (s.moved) {
            mixture_moved.fetch_add(1);
            n_bad += glimmer::test::bad_moved_sample(s, sp.frame.to_world(s.wo));
            n_bad += glimmer::test::bad_exit_mixture(s, buffer, sp.frame.to_world(s.wo));
            mixture_written.fetch_add(s.exit_mixture ? 1 : 0);
          }
        }
      }
      if (n_bad) bad_count.fetch_add(n_bad);
    }
  });
  EXPECT_EQ(bad_count.load(), 0);
  EXPECT_GT(moved.load(), calls / 20);  // the sg estimator really ran
  EXPECT_GT(mixture_moved.load(), calls / 40);  // and the mixture
  EXPECT_GT(mixture_written.load(), mixture_moved.load() / 2);  // handed to the host whole
  EXPECT_GT(host_mixtures.load(), calls / 40);                  // and read whole through the C entry point
  EXPECT_GT(planar_wide.load(), calls / 1000);                  // the planar exits' ladder among them
  std::printf("[frosted sg stress] through the C entry point (2.7 host): %ld sample queries, %ld moved, %ld whole "
              "exit mixtures read (axes, sharpness, weights, host density at wo and a lamp-integral draw)\n",
              host_queries.load(), host_moved.load(), host_mixtures.load());
  std::printf("[frosted sg stress] exit lobe mixture: %ld moved samples (v 0..1 / NaN, t 0..0.25 / rule), %ld "
              "written whole to the host's buffer\n",
              mixture_moved.load(), mixture_written.load());
  std::printf("[frosted sg stress] blocks %ld..%ld of %ld: %ld eval + %ld sample calls (%ld sg moved samples), 1/4 "
              "grazing, half IOR 2.4; sphere / slab / odd host (t 0..inf, NaN, -1; NaN or zero normals; other "
              "closures): %ld bad; %ld whole mixtures of a planar exit above roughness 0.4 (the ladder)\n",
              first, end - 1, blocks, calls, samples.load(), moved.load(), bad_count.load(), planar_wide.load());
}

// ---- The curved exit's origin at the exit points' mean (issue 12, session 27, frostedexit27) --------------------
// What is near the sphere's exit sees where the light leaves as well as its direction: the floor through the sphere
// (the caustic bench's glass_L, its largest part) and a lamp a few radii away (the bench's shadow). Brute force:
// path's exact walk, each leaving ray from its own exit point; sg from its sample's origin (kCurvedExitCentroid,
// SgInputs::exit_centroid). The same unit sphere as the accuracy set (roughness 0.5, IOR 1.5, the bench's).
namespace centroid_test {
// The bench's unit sphere (the accuracy set's) as path and sg closures of one roughness and IOR, the scene's material
// the sg one (the exit-point and rim tests below).
struct BenchSphere {
  std::unique_ptr<FrostedGlassClosure> path, sg;
  AnalyticScene scene{AnalyticScene::kSphere};
  BenchSphere(float roughness, float ior)
      : path(create_raw(roughness, ior, false)), sg(create_raw(roughness, ior, true)) {
    scene.material = reinterpret_cast<const GlimmerInstance *>(sg.get());
  }
};
// sg with the exit-point centroid at `scale` and the waist at `waist` (-1: the rules, kCurvedExitCentroid /
// kCurvedExitWaist), under the front SG's axis and width (entry_axis 0: session 28's kEntryAxis draws the camera-seen
// internal axis with a narrow lobe, where the origin rules have nothing left to move; they act in the floor's view).
// `floor_exit` / `floor_origin` (>= 0): the floor view's mode (kFloorViewExit) and its origin rule's scale
// (kFloorViewOriginScale; 0: none), else the rule (the solid seen directly: neither acts).
Sampler sg_with_centroid(const FrostedGlassClosure &path, const FrostedGlassClosure &sg, float roughness, float scale,
                         float waist, int floor_exit = -1, float floor_origin = -1.0f) {
  return [&path, &sg, roughness, scale, waist, floor_exit, floor_origin](const ShadingPoint &sp, const Vec3 &r,
                                                                         LocalSample &s) {
    if (!path.sample(sp, r, s)) return false;
    if (sg.uses_sg(sp) && (s.label & GLIMMER_LABEL_TRANSMIT))
      return sg.sample_sg(sp, r, s, frosted::solid_sg_variant(roughness), frosted::kDefaultMixtureVariance,
                          frosted::kDefaultMixtureTail, -1.0f, nullptr, -1, -1, scale, waist, 0, floor_exit,
                          floor_origin);
    return true;
  };
}
struct Value {
  double mean = 0.0, se = 0.0;
};
// Per start (camera pixel or floor point): the mean over `paths` of throughput x target(leaving origin, direction)
// (0 for a path that does not leave).
template <class Start, class Target>
std::vector<Value> leaving_values(const AnalyticScene &scene, const Sampler &sample, const std::vector<Start> &starts,
                                  int paths, uint64_t seed, const Target &target) {
  std::vector<Value> out(starts.size());
  tbb::parallel_for(size_t(0), starts.size(), [&](size_t k) {
    const auto [m, se] = chunked_mean(paths, seed, 11 + 137 * k, [&](Pcg32 &rng) -> double {
      Pixel px;
      if (!starts[k](rng, px)) return 0.0;
      Spectrum throughput;
      Vec3 wo, from;
      if (!trace_through(scene, sample, px, rng, throughput, wo, &from)) return 0.0;
      return average(throughput) * target(from, normalize(wo));
    });
    out[k] = {m, se};
  });
  return out;
}
double relative_l1(const std::vector<Value> &now, const std::vector<Value> &ref) {
  double l1 = 0.0, total = 0.0;
  for (size_t k = 0; k < ref.size(); ++k) l1 += std::fabs(now[k].mean - ref[k].mean), total += ref[k].mean;
  return l1 / std::max(total, 1e-30);
}
// The combined standard error of relative_l1's numerator over its denominator (its noise floor).
double relative_se(const std::vector<Value> &now, const std::vector<Value> &ref) {
  double var = 0.0, total = 0.0;
  for (size_t k = 0; k < ref.size(); ++k) var += now[k].se * now[k].se + ref[k].se * ref[k].se, total += ref[k].mean;
  return std::sqrt(var) / std::max(total, 1e-30);
}
// The rule's relative L1 against path over the starts, and its two controls' (the axis' exit point: no origin rule,
// in the floor's view the one before session 31, kFloorViewExit 0; the centroid alone: no waist, nor the floor view's
// origin jitter), with the rule's noise: path (ref_paths, seed 1) vs sg (sg_paths, seed 2) for one target.
struct RuleAndControls {
  double rule = 0.0, axis_exit = 0.0, centroid_only = 0.0, se = 0.0;
  std::vector<Value> ref, now, axis_exit_values;  // per start: path, the rule, the first control
};
template <class Start, class Target>
RuleAndControls rule_and_controls(const AnalyticScene &scene, const Sampler &path_sampler,
                                  const FrostedGlassClosure &path, const FrostedGlassClosure &sg, float roughness,
                                  const std::vector<Start> &starts, int ref_paths, int sg_paths, const Target &target) {
  const auto values_with = [&](float scale, float waist, int floor_exit = -1, float floor_origin = -1.0f) {
    return leaving_values(scene, sg_with_centroid(path, sg, roughness, scale, waist, floor_exit, floor_origin), starts,
                          sg_paths, 2, target);
  };
  const auto ref = leaving_values(scene, path_sampler, starts, ref_paths, 1, target);
  const auto now = values_with(-1.0f, -1.0f), ctl = values_with(0.0f, 0.0f, 0), two = values_with(1.0f, 0.0f, -1, 0.0f);
  return {relative_l1(now, ref), relative_l1(ctl, ref), relative_l1(two, ref), relative_se(now, ref), ref, now, ctl};
}
}  // namespace centroid_test

// The floor seen through the camera-seen sphere: the accuracy set's 16 orthographic camera rays (down -z), a
// textured floor plane z = -1 - gap (1 + 0.8 sin(4 x + 3 y): a gradient at every point, so a lateral displacement of
// the leaving bundle shows), the rays that reach it. Relative L1 over the pixels, sg (the rule) against path.
// `make test`: the nearest and the farthest floor (gap 0.05 and 3 radii); the *Stress twin (`make stress`, 4x the
// paths) the three gaps.
void expect_floor_through_the_sphere(bool full) {
  using namespace centroid_test;
  const int ref_paths = stress_scale() > 1 ? 400000 : 100000, sg_paths = ref_paths / 2;
  const float roughness = 0.5f, ior = 1.5f;
  BenchSphere rig(roughness, ior);
  auto &path = rig.path, &sg = rig.sg;
  AnalyticScene &scene = rig.scene;
  std::vector<std::function<bool(Pcg32 &, Pixel &)>> starts;
  for (const Pixel &p : camera_pixels(scene)) starts.push_back([p](Pcg32 &, Pixel &out) { return out = p, true; });
  const Sampler path_sampler = sampler_of(*path);
  std::printf(
      "[frosted floor through the sphere] roughness %.2f ior %.2f: gap | rel. L1 sg (rule) | axis' exit point "
      "(control) | centroid only | noise (se)\n",
      double(roughness), double(ior));
  // Measured (session 27; deterministic: fixed seeds and chunks): gap 0.05 / 0.3 / 3 radii, the rules (centroid +
  // waist) 0.0795 / 0.0396 / 0.0138, the axis' exit point (main before, the control) 0.1353 / 0.0732 / 0.0333, the
  // centroid alone (the waist's control) 0.0975 / 0.0499 / 0.0329; noise ~0.001. Bounds measured + 15-20 %, which
  // both controls must miss.
  const struct {
    float gap;
    double bound;
  } cases[] = {{0.05f, 0.092}, {0.3f, 0.047}, {3.0f, 0.017}};
  for (const auto &[gap, bound] : cases) {
    if (!full && gap == 0.3f) continue;
    const auto floor_value = [gap](const Vec3 &from, const Vec3 &d) {
      const float z = -1.0f - gap;
      if (!(d.z < -1e-4f) || !(from.z > z)) return 0.0;
      const Vec3 p = from + d * ((z - from.z) / d.z);
      return 1.0 + 0.8 * std::sin(4.0 * p.x + 3.0 * p.y);
    };
    const RuleAndControls r =
        rule_and_controls(scene, path_sampler, *path, *sg, roughness, starts, ref_paths, sg_paths, floor_value);
    const double l1 = r.rule, l1_ctl = r.axis_exit, l1_two = r.centroid_only, se = r.se;
    std::printf("  %.2f | %.4f | %.4f | %.4f | %.4f\n", double(gap), l1, l1_ctl, l1_two, se);
    EXPECT_LT(l1, bound) << "gap " << gap;
    EXPECT_GT(l1_ctl, bound) << "control (axis' exit point) passed at gap " << gap;
    EXPECT_GT(l1_two, bound) << "control (centroid alone) passed at gap " << gap;
  }
}

TEST(FrostedGlassSg, FloorThroughTheSphereFromTheExitPointsMean) { expect_floor_through_the_sphere(false); }

TEST(FrostedGlassSg, FloorThroughTheSphereFromTheExitPointsMeanStress) {
  if (stress_scale() == 1) GTEST_SKIP() << "make stress only";
  expect_floor_through_the_sphere(true);
}

// A lamp a few radii away seen from the floor through the sphere (the caustic bench's shadow): the sphere on the
// floor z = -1, floor points along the shadow's axis (SphereShadowOfAFarLampAgainstThePath's), cosine-weighted
// directions (diffuse_bounce 1, the floor's view), the share of the transmitted weight whose leaving ray, from its
// own origin, hits a ball lamp (the far test's 4-deg cone at the bench's 5.04 radii from the centre; and 8x as far).
// `make test`: the bench's 5.04 radii (the bound and both controls); the *Stress twin (`make stress`, 4x the paths)
// both distances.
void expect_near_lamp_through_the_sphere(bool full) {
  using namespace centroid_test;
  const int ref_paths = stress_scale() > 1 ? 4000000 : 1000000, sg_paths = ref_paths / 2;
  const float roughness = 0.5f, ior = 1.5f;
  BenchSphere rig(roughness, ior);
  auto &path = rig.path, &sg = rig.sg;
  AnalyticScene &scene = rig.scene;
  scene.diffuse_bounce = 1;
  const Vec3 lamp = normalize(Vec3(0.9f, 1.6f, 2.4f));
  const Vec3 toward = normalize(Vec3(-lamp.x, -lamp.y, 0.0f));
  std::vector<std::function<bool(Pcg32 &, Pixel &)>> starts;
  for (const float s : {0.45f, 0.7f, 0.85f, 0.95f, 1.2f}) {
    const Vec3 P = Vec3(0.0f, 0.0f, -1.0f + 1e-4f) + toward * s;
    starts.push_back([P, &scene](Pcg32 &rng, Pixel &px) {
      const float u1 = rng.next_float(), u2 = rng.next_float(), r = std::sqrt(u1), phi = 2.0f * float(M_PI) * u2;
      px.D = Vec3(r * std::cos(phi), r * std::sin(phi), std::sqrt(std::max(0.0f, 1.0f - u1)));
      return scene.intersect(P, px.D, 0.0f, 100.0f, px.hit);
    });
  }
  const Sampler path_sampler = sampler_of(*path);
  std::printf(
      "[frosted near lamp through the sphere] roughness %.2f ior %.2f: lamp distance (radii) | rel. L1 sg "
      "(rule) | axis' exit point (control) | centroid only | noise (se)\n",
      double(roughness), double(ior));
  // Measured (session 27; deterministic): at the bench's 5.04 radii the rule 0.0336, the axis' exit point (main
  // before, the control) 0.0479, centroid x 2 0.0460 (noise 0.006); at 40.3 radii 0.0527 / 0.0545 / 0.0504 (the
  // directions' error, which the origin does not touch). The floor's view (diffuse bounce 1): no waist (drawn for
  // every direction it gave 0.0518 / 0.0571, worse than the control). Bound 0.040 at 5.04 (the control must miss it); at 40.3 no
  // worse than the control beyond 2 se. Session 31 (frostedshadow31): the floor view's shift x 1.6 and origin jitter
  // (kFloorViewExit 2): the rule 0.0212 / 0.0452; the control is the axis' exit point in the floor view before it
  // (kFloorViewExit 0; with the shift it read 0.0316 / 0.0444), and "centroid only" (no waist, no origin jitter: the
  // shift alone) is a second control at 5.04 radii, which must miss the bound too.
  for (const float distance : {5.04f, 40.3f}) {
    if (!full && distance > 10.0f) continue;
    const Vec3 centre = lamp * distance;
    const float radius = distance * float(std::sin(4.0 * M_PI / 180.0));
    const auto hits_lamp = [centre, radius](const Vec3 &from, const Vec3 &d) {
      const Vec3 oc = centre - from;
      const float along = dot(oc, d);
      return along > 0.0f && dot(oc, oc) - along * along < radius * radius ? 1.0 : 0.0;
    };
    const RuleAndControls r =
        rule_and_controls(scene, path_sampler, *path, *sg, roughness, starts, ref_paths, sg_paths, hits_lamp);
    const double l1 = r.rule, l1_ctl = r.axis_exit, l1_two = r.centroid_only, se = r.se;
    std::printf("  %.2f | %.4f | %.4f | %.4f | %.4f\n", double(distance), l1, l1_ctl, l1_two, se);
    if (distance < 10.0f) {
      EXPECT_LT(l1, 0.040);
      EXPECT_GT(l1_ctl, 0.040) << "control passed";
      EXPECT_GT(l1_two, 0.040) << "control passed: the floor view without its origin jitter";
    } else {
      EXPECT_LT(l1, l1_ctl + 2.0 * se);
    }
    for (size_t k = 0; k < r.ref.size(); ++k)
      std::printf("    point %zu: path %.4e, sg / path %.3f, control %.3f\n", k, r.ref[k].mean,
                  r.now[k].mean / r.ref[k].mean, r.axis_exit_values[k].mean / r.ref[k].mean);
  }
}

TEST(FrostedGlassSg, NearLampThroughTheSphereFromTheExitPointsMean) { expect_near_lamp_through_the_sphere(false); }

TEST(FrostedGlassSg, NearLampThroughTheSphereFromTheExitPointsMeanStress) {
  if (stress_scale() == 1) GTEST_SKIP() << "make stress only";
  expect_near_lamp_through_the_sphere(true);
}

// ---- The bench lamp's caustic through the sphere on a floor grid (issue 12, session 30, frostedshadow30) ----------
// The caustic bench's shadow bias is the caustic's 2 x 2 core
// (docs/history/frosted_glass_sessions.md "Session 29 (frostedshadow29)"):
// a 2-D shape error of the floor's view of the sphere's exit lobe. Floor points on a grid across the caustic (the
// sphere on the floor z = -1; the grid's axes along the shadow's axis and sideways), cosine-weighted directions
// (diffuse_bounce 1, the floor's view), the transmitted weight reaching the bench's lamp (a ball of the 0.25 x 0.25
// square's cross-section at its 5.04 radii, SphereShadowDirectionsAroundTheLamp's). Path: its exact walk, a leaving ray
// hits the ball or not. sg: the exit mixture's density integrated over the ball's cone from the mixture's origin (the
// host's lamp integral through the lobe; a fixed 4 x 8 quadrature of the cone, uniform in solid angle), or where no
// exit lobe was handed over, the walk on to its leaving ray as path's. The same expectation as sg's draws, less noise.
namespace caustic_grid {
struct Lamp {
  Vec3 centre;
  float radius;
};
// The cone of the ball from `from` integrated against the mixture's density (Omega / N sum pdf).
template <class Density>
double lamp_integral(const Density &density, const Vec3 &from, const Lamp &lamp) {
  const Vec3 c = lamp.centre - from;
  const float dist = length(c);
  if (!(dist > lamp.radius)) return 0.0;
  const double cos_a = std::sqrt(1.0 - double(lamp.radius) * lamp.radius / (double(dist) * dist));
  const Frame f = Frame::from_normal(c / dist);
  constexpr int kRings = 4, kPhi = 8;
  double sum = 0.0;
  for (int r = 0; r < kRings; ++r) {
    const double ct = 1.0 - (1.0 - cos_a) * (r + 0.5) / kRings, st = std::sqrt(std::max(0.0, 1.0 - ct * ct));
    for (int k = 0; k < kPhi; ++k) {
      const double phi = 2.0 * M_PI * (k + 0.5 * (r & 1)) / kPhi;
      const Vec3 w = normalize(f.to_world(Vec3(float(st * std::cos(phi)), float(st * std::sin(phi)), float(ct))));
      sum += density(w);
    }
  }
  return sum * 2.0 * M_PI * (1.0 - cos_a) / (kRings * kPhi);
}
bool hits(const Lamp &lamp, const Vec3 &from, const Vec3 &d) {
  const Vec3 oc = lamp.centre - from;
  const float along = dot(oc, d);
  return along > 0.0f && dot(oc, oc) - along * along < lamp.radius * lamp.radius;
}
// One floor path's value: the walk from the sphere's hit. `lobe_integral`: a moved exit-lobe sample's mixture
// integrated over the lamp (sg). `exact` (path): at every hit from inside the exact closure's f cos integrated over
// the lamp's cone (the light leaving there toward the lamp; the leaving rays then count nothing): the same
// expectation as path's leaving rays, far less noise.
double floor_path_value(const AnalyticScene &scene, const Sampler &sample, Hit hit, Vec3 D, Pcg32 &rng,
                        const Lamp &lamp, bool lobe_integral, const FrostedGlassClosure *exact = nullptr) {
  const auto schema = FrostedGlassClosure::params();
  double throughput = 1.0, value = 0.0;
  for (int event = 0; event < 512; ++event) {
    GlimmerShadingContext ctx = context_at(scene, hit, D, rng);
    const ShadingPoint sp(&ctx, schema);
    if (exact != nullptr && event > 0) {
      const Vec3 out_n = dot(D, hit.N) > 0.0f ? hit.N : -hit.N;  // outward: along the inside ray
      value += throughput * lamp_integral(
                                [&](const Vec3 &w) {
                                  return dot(w, out_n) > 0.0f ? double(average(exact->eval(sp, sp.frame.to_local(w)).f_cos))
                                                              : 0.0;
                                },
                                hit.P, lamp);
    }
    LocalSample s;
    GlimmerExitMixture buffer{};
    s.mixture_out = &buffer;
    if (!sample(sp, Vec3(rng.next_float(), rng.next_float(), rng.next_float()), s) || !(s.pdf > 0.0f)) return value;
    if (event == 0 && !(s.label & GLIMMER_LABEL_TRANSMIT)) return 0.0;
    throughput *= average(s.f_cos / s.pdf);
    const Vec3 wo = normalize(sp.frame.to_world(s.wo));
    if (lobe_integral && s.moved && s.exit_lobe) {
      const glimmer::ExitLobeMixture m = glimmer::test::exit_mixture_of(s, buffer);
      return value + throughput * lamp_integral([&m](const Vec3 &w) { return m.pdf(w); }, s.origin, lamp);
    }
    const Vec3 origin = s.moved ? frosted::offset_origin(s.origin, s.origin_Ng, wo)
                                : frosted::offset_origin(hit.P, hit.N, wo);
    Hit next;
    if (!scene.intersect(origin, wo, 0.0f, std::numeric_limits<float>::infinity(), next))
      return value + (exact == nullptr && hits(lamp, origin, wo) ? throughput : 0.0);
    hit = next;
    D = wo;
  }
  return value;
}
struct Grid {
  std::vector<Vec3> points;
  int n = 0;
};
// n x n floor points about `centre` along the shadow's axis, spacing h (radii).
Grid floor_grid(const Vec3 &toward, float centre, float h, int n) {
  Grid g{{}, n};
  const Vec3 side = normalize(cross(Vec3(0.0f, 0.0f, 1.0f), toward));
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      g.points.push_back(Vec3(0.0f, 0.0f, -1.0f + 1e-4f) + toward * (centre + h * float(i - n / 2)) +
                         side * (h * float(j - n / 2)));
  return g;
}
std::vector<centroid_test::Value> grid_values(const AnalyticScene &scene, const Sampler &sample, const Grid &g,
                                              const Lamp &lamp, int paths, uint64_t seed, bool lobe_integral,
                                              const FrostedGlassClosure *exact = nullptr) {
  std::vector<centroid_test::Value> out(g.points.size());
  for (size_t k = 0; k < g.points.size(); ++k) {
    const Vec3 P = g.points[k];
    const auto [m, se] = chunked_mean(paths, seed, 17 + 151 * k, [&](Pcg32 &rng) -> double {
      const float u1 = rng.next_float(), u2 = rng.next_float(), r = std::sqrt(u1), phi = 2.0f * float(M_PI) * u2;
      const Vec3 D(r * std::cos(phi), r * std::sin(phi), std::sqrt(std::max(0.0f, 1.0f - u1)));
      Hit hit;
      if (!scene.intersect(P, D, 0.0f, 100.0f, hit)) return 0.0;
      return floor_path_value(scene, sample, hit, D, rng, lamp, lobe_integral, exact);
    });
    out[k] = {m, se};
  }
  return out;
}
// The rms of (sg - path) over the points over the points' mean path value, and its noise (the same form from the se).
struct Rms {
  double rms = 0.0, noise = 0.0;
};
Rms relative_rms(const std::vector<centroid_test::Value> &now, const std::vector<centroid_test::Value> &ref) {
  double d2 = 0.0, n2 = 0.0, total = 0.0;
  for (size_t k = 0; k < ref.size(); ++k) {
    d2 += sqr(now[k].mean - ref[k].mean), n2 += sqr(now[k].se) + sqr(ref[k].se), total += ref[k].mean;
  }
  const double mean = total / double(std::max<size_t>(ref.size(), 1));
  return {std::sqrt(d2 / double(ref.size())) / std::max(mean, 1e-30),
          std::sqrt(n2 / double(ref.size())) / std::max(mean, 1e-30)};
}
// sg with a test's curved shape (nullptr: the rule), exit-point centroid scale (< 0: the rule) and floor view (mode
// kFloorViewExit and origin scale kFloorViewOriginScale; < 0: the rule).
Sampler sg_with_shape(const FrostedGlassClosure &path, const FrostedGlassClosure &sg, float roughness,
                      const frosted::CurvedShape *shape, float centroid = -1.0f, int floor_exit = -1,
                      float floor_origin = -1.0f) {
  return [&path, &sg, roughness, shape, centroid, floor_exit, floor_origin](const ShadingPoint &sp, const Vec3 &r,
                                                                            LocalSample &s) {
    if (!path.sample(sp, r, s)) return false;
    if (sg.uses_sg(sp) && (s.label & GLIMMER_LABEL_TRANSMIT))
      return sg.sample_sg(sp, r, s, frosted::solid_sg_variant(roughness), frosted::kDefaultMixtureVariance,
                          frosted::kDefaultMixtureTail, -1.0f, shape, -1, -1, centroid, -1.0f, -1, floor_exit,
                          floor_origin);
    return true;
  };
}
void print_grid(const char *name, const Grid &g, const std::vector<centroid_test::Value> &now,
                const std::vector<centroid_test::Value> &ref) {
  std::printf("  %s: sg / path (rows along the shadow's axis, away from the sphere downwards)\n", name);
  for (int i = 0; i < g.n; ++i) {
    std::printf("   ");
    for (int j = 0; j < g.n; ++j) {
      const size_t k = size_t(i * g.n + j);
      std::printf(" %.3f", now[k].mean / std::max(ref[k].mean, 1e-30));
    }
    std::printf("\n");
  }
}
}  // namespace caustic_grid

// Measured (session 30; deterministic: fixed seeds and chunks; 500k path / 62.5k sg paths per point): the rule
// (main's floor view) rms 0.0577 (noise 0.0141; its core 0.91..0.95 of path's, the far rows +4..10 %), the sharp
// core (control) 0.1330, the single SG 0.0654. Bound: the rule + 15 %. With 1M reference paths (GLIMMER_CAUSTIC_GRID_
// PATHS, noise 0.010): the rule 0.0529; the axis' exit point (centroid 0) 0.0653, centroid x 0.5 / 1.5 / 2 0.0577 /
// 0.0519 / 0.0555; axis shift x 0 / 1.3 / 1.6 / 2 (GLIMMER_FROSTED_CURVED_SHIFT) 0.1104 / 0.0448 / 0.0515 / 0.0769;
// the shape 0.6:2.0,0.4:0.45 at shift 1.0 / 1.3 / 1.6 0.0508 / 0.0308 / 0.0216 (session 30's floor view,
// GLIMMER_FROSTED_FLOOR_EXIT=1: not kept, far lamps go wrong; frosted_glass_sg.h kFloorViewExit).
// Session 31 (frostedshadow31): the rule is the floor view's shift x 1.6 with main's shape and the origin jittered
// over the exit points' spread (kFloorViewExit 2): rms 0.0261 (noise 0.0141); bound 0.066 -> 0.030 (+15 %), which
// the shift without the jitter (0.0545), session 30's floor view (0.0577) and the sharp core (0.1330) miss.
constexpr double kCausticGridBound = 0.030;
TEST(FrostedGlassSg, BenchLampCausticThroughTheSphereOnAFloorGrid) {
  using namespace caustic_grid;
  // Measurement only: GLIMMER_CAUSTIC_GRID_SCAN = "c w1 f1 w2 f2;..." (the centroid scale and a shape per variant; the
  // axis shift by GLIMMER_FROSTED_CURVED_SHIFT) against one reference of GLIMMER_CAUSTIC_GRID_PATHS paths; no bounds.
  const char *scan = std::getenv("GLIMMER_CAUSTIC_GRID_SCAN");
  const char *paths_env = std::getenv("GLIMMER_CAUSTIC_GRID_PATHS");  // the scan's reference paths
  const int ref_paths = scan != nullptr && paths_env != nullptr ? std::atoi(paths_env)
                        : stress_scale() > 1                    ? 2000000
                                                                : 500000;
  const int sg_paths = ref_paths / 8;
  const float roughness = 0.5f, ior = 1.5f;
  centroid_test::BenchSphere rig(roughness, ior);
  AnalyticScene &scene = rig.scene;
  scene.diffuse_bounce = 1;
  const Vec3 lamp_dir = normalize(Vec3(0.9f, 1.6f, 2.4f));
  const Vec3 toward = normalize(Vec3(-lamp_dir.x, -lamp_dir.y, 0.0f));
  const Lamp lamp{lamp_dir * kBenchLampDistance, kBenchLampRadius};
  const float centre = std::getenv("GLIMMER_CAUSTIC_GRID_CENTRE") ? std::strtof(std::getenv("GLIMMER_CAUSTIC_GRID_CENTRE"), nullptr) : 0.8f;
  const float h = std::getenv("GLIMMER_CAUSTIC_GRID_H") ? std::strtof(std::getenv("GLIMMER_CAUSTIC_GRID_H"), nullptr) : 0.1f;
  const Grid g = floor_grid(toward, centre, h, 5);
  // Measurement only: GLIMMER_CAUSTIC_GRID_REF = file: the reference read from it when it holds this grid's points
  // (written there when not), so that a scan over the environment's knobs (one process each) pays for it once.
  const char *ref_file = scan != nullptr ? std::getenv("GLIMMER_CAUSTIC_GRID_REF") : nullptr;
  std::vector<centroid_test::Value> ref;
  if (ref_file != nullptr) {
    if (FILE *f = std::fopen(ref_file, "r")) {
      centroid_test::Value v;
      while (std::fscanf(f, "%lf %lf", &v.mean, &v.se) == 2) ref.push_back(v);
      std::fclose(f);
    }
    if (ref.size() != g.points.size()) ref.clear();
  }
  if (ref.empty()) {
    ref = grid_values(scene, sampler_of(*rig.path), g, lamp, ref_paths, 1, false, rig.path.get());
    if (ref_file != nullptr)
      if (FILE *f = std::fopen(ref_file, "w")) {
        for (const auto &v : ref) std::fprintf(f, "%.17g %.17g\n", v.mean, v.se);
        std::fclose(f);
      }
  }
  std::printf("[frosted caustic grid] roughness %.2f ior %.2f, bench lamp (%.2f radii, ball %.3f), grid 5 x 5 about "
              "%.2f radii along the shadow's axis, spacing %.2f: path per point\n",
              double(roughness), double(ior), double(kBenchLampDistance), double(kBenchLampRadius), double(centre),
              double(h));
  for (int i = 0; i < g.n; ++i) {
    std::printf("   ");
    for (int j = 0; j < g.n; ++j) std::printf(" %.3e", ref[size_t(i * g.n + j)].mean);
    std::printf("\n");
  }
  const auto run = [&](const char *name, const frosted::CurvedShape *shape, float centroid = -1.0f,
                       int floor_exit = -1, float floor_origin = -1.0f) {
    const auto now = grid_values(scene, sg_with_shape(*rig.path, *rig.sg, roughness, shape, centroid, floor_exit,
                                                      floor_origin),
                                 g, lamp, sg_paths, 2, true);
    const Rms r = relative_rms(now, ref);
    print_grid(name, g, now, ref);
    std::printf("  %s: rms %.4f (noise %.4f)\n", name, r.rms, r.noise);
    return r;
  };
  const Rms rule = run("rule", nullptr);
  if (scan != nullptr) {
    for (const char *e = scan; e != nullptr && *e != '\0';) {
      float v[5];
      int got = 0;
      char *end = const_cast<char *>(e);
      for (; got < 5; ++got) {
        const char *from = end;
        v[got] = std::strtof(from, &end);
        if (end == from) break;
      }
      if (got < 5) break;
      const frosted::CurvedShape shape{2, {v[1], v[3]}, {v[2], v[4]}};
      char name[96];
      std::snprintf(name, sizeof name, "c %.2f shape %.2f:%.2f,%.2f:%.2f", double(v[0]), double(v[1]), double(v[2]),
                    double(v[3]), double(v[4]));
      run(name, &shape, v[0]);
      e = std::strchr(end, ';');
      if (e != nullptr) ++e;
    }
    return;
  }
  // Negative controls: the floor view's shift without its origin rule (session 31's kFloorViewOriginScale 0), main's
  // floor view before session 31 (kFloorViewExit 0), a sharper core (0.75:2.6, 0.25:0.4; session 29's caustic crop
  // 0.0498 against main's 0.0159).
  const Rms ctl_shift = run("shift without the origin rule (control)", nullptr, -1.0f, 2, 0.0f);
  const Rms ctl_main = run("session 30's floor view (control)", nullptr, -1.0f, 0);
  const frosted::CurvedShape sharp{2, {0.75f, 0.25f}, {2.6f, 0.4f}};
  const Rms ctl_sharp = run("sharp core (control)", &sharp);
  EXPECT_LT(rule.rms, kCausticGridBound);
  EXPECT_GT(ctl_shift.rms, kCausticGridBound) << "control passed: the shift without the origin rule";
  EXPECT_GT(ctl_main.rms, kCausticGridBound) << "control passed: session 30's floor view";
  EXPECT_GT(ctl_sharp.rms, kCausticGridBound) << "control passed: the sharp core";
}

// ---- The camera-seen sphere's rim (issue 12, session 28, frostedbias28) -------------------------------------------
// The caustic bench's sphere seen by the camera is too bright where it leaves directly (its glass +3..5 %, its bottom
// rim +40..+87 %: event split, docs/history/frosted_glass_sessions.md "Session 28 (frostedbias28)"); with the internal
// axis drawn at the entry the split's excess left. Brute force: path's exact walk; sg with kEntryAxis
// (SgInputs::entry_axis) against the front SG's axis and width (0, main before: the control). Orthographic camera rays
// down -z at impact radii 0.5 .. 0.97 (the rim: grazing entries) over 6 azimuths, a textured floor just below the
// sphere (gap 0.02 radii, the bench's floor touches it) and a far world with a gradient; relative L1 over the starts.
TEST(FrostedGlassSg, RimOfTheCameraSeenSphereWithTheEntryAxisDrawn) {
  using namespace centroid_test;
  const int ref_paths = stress_scale() > 1 ? 200000 : 50000, sg_paths = ref_paths / 2;
  const float roughness = 0.5f, ior = 1.5f;
  BenchSphere rig(roughness, ior);
  auto &path = rig.path, &sg = rig.sg;
  AnalyticScene &scene = rig.scene;
  std::vector<std::function<bool(Pcg32 &, Pixel &)>> starts;
  for (const float rho : {0.5f, 0.8f, 0.9f, 0.97f})
    for (int a = 0; a < 6; ++a) {
      const float phi = float(a) * float(M_PI) / 3.0f + 0.2f;
      Pixel p{{}, Vec3(0.0f, 0.0f, -1.0f)};
      if (!scene.intersect(Vec3(rho * std::cos(phi), rho * std::sin(phi), 5.0f), p.D, 0.0f, 100.0f, p.hit)) continue;
      starts.push_back([p](Pcg32 &, Pixel &out) { return out = p, true; });
    }
  ASSERT_EQ(starts.size(), 24u);
  const Sampler path_sampler = sampler_of(*path);
  const auto with_entry = [&](int mode) {
    return Sampler([&path, &sg, mode](const ShadingPoint &sp, const Vec3 &r, LocalSample &s) {
      if (!path->sample(sp, r, s)) return false;
      if (sg->uses_sg(sp) && (s.label & GLIMMER_LABEL_TRANSMIT))
        return sg->sample_sg(sp, r, s, frosted::SgVariant::kMixture, frosted::kDefaultMixtureVariance,
                             frosted::kDefaultMixtureTail, -1.0f, nullptr, -1, -1, -1.0f, -1.0f, mode);
      return true;
    });
  };
  const auto floor_value = [](const Vec3 &from, const Vec3 &d) {
    const float z = -1.02f;
    if (!(d.z < -1e-4f) || !(from.z > z)) return 0.0;
    const Vec3 p = from + d * ((z - from.z) / d.z);
    return 1.0 + 0.8 * std::sin(4.0 * p.x + 3.0 * p.y);
  };
  const auto world_value = [](const Vec3 &, const Vec3 &d) { return 1.0 + 0.8 * d.x + 0.6 * d.z; };
  std::printf("[frosted rim of the camera-seen sphere] roughness %.2f ior %.2f: target | rel. L1 sg (rule, "
              "kEntryAxis %d) | front SG's axis (control) | noise (se)\n",
              double(roughness), double(ior), frosted::kEntryAxis);
  const auto run = [&](const char *name, const auto &target, double bound) {
    const auto ref = leaving_values(scene, path_sampler, starts, ref_paths, 1, target);
    const auto now = leaving_values(scene, with_entry(-1), starts, sg_paths, 2, target);
    const auto ctl = leaving_values(scene, with_entry(0), starts, sg_paths, 2, target);
    const double l1 = relative_l1(now, ref), l1_ctl = relative_l1(ctl, ref), se = relative_se(now, ref);
    std::printf("  %s | %.4f | %.4f | %.4f\n", name, l1, l1_ctl, se);
    for (size_t k = 0; k < ref.size(); k += 6)
      std::printf("    radius %zu: path %.4e, sg / path %.3f, control %.3f\n", k / 6, ref[k].mean,
                  now[k].mean / ref[k].mean, ctl[k].mean / ref[k].mean);
    EXPECT_LT(l1, bound) << name;
    EXPECT_GT(l1_ctl, bound) << "control passed: " << name;
  };
  // Measured (session 28; deterministic: fixed seeds and chunks): floor 0.0065 (control 0.1257: +8..+18 % per
  // radius), world 0.0060 (control 0.0359), noise 0.0016 / 0.0015. Bounds the rule + 3 se, which the control misses.
  run("floor", floor_value, 0.012);
  run("world", world_value, 0.011);
}
}  // namespace
