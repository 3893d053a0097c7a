#include "render/renderer.h"

#include <embree3/rtcore.h>
#include <tbb/blocked_range2d.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <mutex>

#include "glimmer/rng.h"
#include "glimmer/sampling.h"
#include "render/lights.h"
#include "render/sampler.h"

namespace glimmer::render {

namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

constexpr float kInf = std::numeric_limits<float>::infinity();

// Offset a ray origin off the surface along the geometric normal, on the side of `dir`.
Vec3 offset_ray_origin(const Vec3 &P, const Vec3 &Ng, const Vec3 &dir) {
  const float scale = 1.0f + std::max(std::fabs(P.x), std::max(std::fabs(P.y), std::fabs(P.z)));
  const float eps = 3e-5f * scale;
  return dot(dir, Ng) >= 0.0f ? P + Ng * eps : P - Ng * eps;
}


// Ray differentials (Igehy 1999): position and direction derivatives per pixel step.
struct Differentials {
  Vec3 dPdx{0.0f}, dPdy{0.0f}, dDdx{0.0f}, dDdy{0.0f};
};

// Cycles' kernel_accum_clamp: scale L so that the sum of its components is at most `limit`.
Spectrum clamp_contribution(const Spectrum &L, float limit) {
  if (limit <= 0.0f) return L;
  const float sum = std::fabs(L.x) + std::fabs(L.y) + std::fabs(L.z);
  return sum > limit ? L * (limit / sum) : L;
}

}  // namespace

struct SurfaceHit {
  int mesh = -1;
  int prim = -1;
  float u = 0, v = 0, t = kInf;
};

struct Renderer::Impl {
  const scene::Scene &scene;
  const host::PluginLibrary &plugin;
  RenderOptions options;
  FeatureSet &features;
  std::vector<std::string> &warnings;

  RTCDevice device = nullptr;
  RTCScene rtc_scene = nullptr;
  GlimmerHostServices host{};
  std::string cache_dir;
  std::unique_ptr<ShaderSystem> shaders;
  std::vector<int> mesh_shader;  // compiled shader per mesh
  std::unique_ptr<LightSet> lights;
  Vec3 scene_center{0.0f};
  float scene_radius = 1.0f;

  int width = 0, height = 0;
  int samples = 1;
  uint32_t seed = 0;
  FilmFilter filter;

  Impl(const scene::Scene &s, const host::PluginLibrary &p, const RenderOptions &o, FeatureSet &f,
       std::vector<std::string> &w)
      : scene(s), plugin(p), options(o), features(f), warnings(w) {}

  ~Impl() {
    if (rtc_scene) rtcReleaseScene(rtc_scene);
    if (device) rtcReleaseDevice(device);
  }

  // ---- Host services for closures ----
  static int host_trace(void *data, const GlimmerRay *ray, GlimmerRayHit *hit) {
    auto *self = static_cast<Impl *>(data);
    SurfaceHit h;
    if (!self->intersect(Vec3(ray->origin), Vec3(ray->direction), ray->t_min, ray->t_max, h)) return 0;
    const scene::Mesh &m = self->scene.meshes[h.mesh];
    const auto &tri = m.triangles[h.prim];
    const Vec3 p0 = m.P[tri[0]], p1 = m.P[tri[1]], p2 = m.P[tri[2]];
    Vec3 Ng = normalize(cross(p1 - p0, p2 - p0));
    hit->t = h.t;
    hit->P = p0 * (1 - h.u - h.v) + p1 * h.u + p2 * h.v;
    Vec3 N = Ng;
    if (m.smooth && !m.N.empty())
      N = normalize(m.N[tri[0]] * (1 - h.u - h.v) + m.N[tri[1]] * h.u + m.N[tri[2]] * h.v);
    hit->N = N;
    hit->Ng = Ng;
    hit->backfacing = dot(Ng, Vec3(ray->direction)) > 0.0f ? 1u : 0u;
    if (!m.uv.empty()) {
      for (int k = 0; k < 2; ++k)
        hit->uv[k] = m.uv[3 * h.prim][k] * (1 - h.u - h.v) + m.uv[3 * h.prim + 1][k] * h.u + m.uv[3 * h.prim + 2][k] * h.v;
    } else {
      hit->uv[0] = h.u;
      hit->uv[1] = h.v;
    }
    hit->object_id = static_cast<uint32_t>(h.mesh);
    return 1;
  }
  static void host_environment(void *data, GlimmerVec3 direction, float, float out[3]) {
    const Spectrum c = static_cast<Impl *>(data)->shaders->background(normalize(Vec3(direction)));
    out[0] = c.x;
    out[1] = c.y;
    out[2] = c.z;
  }
  static void host_log(void *, int level, const char *message) {
    static std::mutex mutex;
    std::lock_guard<std::mutex> lock(mutex);
    static const char *names[] = {"debug", "info", "warning", "error"};
    if (level == GLIMMER_LOG_DEBUG && std::getenv("GLIMMER_DEBUG") == nullptr) return;
    std::fprintf(stderr, "glimmer: %s: %s\n", names[std::clamp(level, 0, 3)], message);
  }
  static int host_resolve(void *data, const char *name, char *out, size_t size) {
    auto *self = static_cast<Impl *>(data);
    std::filesystem::path p(name);
    if (p.is_relative()) p = std::filesystem::path(self->scene.directory) / p;
    if (!std::filesystem::exists(p)) return 0;
    const std::string s = p.string();
    if (s.size() + 1 > size) return 0;
    std::memcpy(out, s.c_str(), s.size() + 1);
    return 1;
  }

  // ---- Set-up ----
  void prepare(PhaseTimes &times) {
    auto t0 = Clock::now();
    cache_dir = host::default_host_services()->cache_dir ? host::default_host_services()->cache_dir : "";
    host.abi_version = GLIMMER_ABI_VERSION;
    host.host_data = this;
    host.trace_ray = &host_trace;
    host.environment_lookup = &host_environment;
    host.log = &host_log;
    host.resolve_asset = &host_resolve;
    host.cache_dir = cache_dir.empty() ? nullptr : cache_dir.c_str();

    filter = FilmFilter(scene.film.filter, scene.film.filter_width);
    const auto &cam = scene.camera;
    width = options.width > 0 ? options.width : cam.width;
    height = options.height > 0 ? options.height : cam.height;
    samples = options.samples > 0 ? options.samples : scene.integrator.samples;
    seed = static_cast<uint32_t>(options.seed >= 0 ? options.seed : scene.integrator.seed);

    // Feature scan: compile only the shaders that geometry, lights and the background use.
    shaders = std::make_unique<ShaderSystem>(scene, plugin, &host, warnings, features);
    std::vector<bool> used(scene.shaders.size(), false);
    for (const auto &m : scene.meshes) {
      mesh_shader.push_back(shaders->compile(m.shader));
      if (m.shader >= 0) used[m.shader] = true;
    }
    shaders->compile_background(scene.background.shader);
    if (scene.background.shader >= 0) used[scene.background.shader] = true;
    for (const auto &l : scene.lights)
      if (l.shader >= 0) used[l.shader] = true;
    for (bool u : used) (u ? features.used_shaders : features.unused_shaders)++;

    // Scene bounds (for sun/background power estimates).
    Vec3 lo(kInf), hi(-kInf);
    for (const auto &m : scene.meshes)
      for (const auto &p : m.P) { lo = min(lo, p); hi = max(hi, p); }
    if (lo.x <= hi.x) {
      scene_center = (lo + hi) * 0.5f;
      scene_radius = std::max(length(hi - lo) * 0.5f, 1e-3f);
    }
    lights = std::make_unique<LightSet>(scene, *shaders, mesh_shader, scene_center, scene_radius, features, warnings);
    times.prepare = seconds_since(t0);

    t0 = Clock::now();
    build_bvh();
    times.bvh = seconds_since(t0);
  }

  void build_bvh() {
    device = rtcNewDevice("threads=0");
    if (!device) throw std::runtime_error("Embree: cannot create a device");
    rtc_scene = rtcNewScene(device);
    rtcSetSceneBuildQuality(rtc_scene, RTC_BUILD_QUALITY_HIGH);
    for (size_t i = 0; i < scene.meshes.size(); ++i) {
      const scene::Mesh &m = scene.meshes[i];
      RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
      auto *vb = static_cast<float *>(
          rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), m.P.size()));
      for (size_t k = 0; k < m.P.size(); ++k) {
        vb[3 * k] = m.P[k].x;
        vb[3 * k + 1] = m.P[k].y;
        vb[3 * k + 2] = m.P[k].z;
      }
      auto *ib = static_cast<uint32_t *>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                                 3 * sizeof(uint32_t), m.triangles.size()));
      for (size_t k = 0; k < m.triangles.size(); ++k)
        for (int c = 0; c < 3; ++c) ib[3 * k + c] = m.triangles[k][c];
      rtcCommitGeometry(g);
      rtcAttachGeometryByID(rtc_scene, g, static_cast<unsigned>(i));
      rtcReleaseGeometry(g);
    }
    rtcCommitScene(rtc_scene);
  }

  // Debian's Embree asserts ray.valid(): origin and direction components within +-1.844e18
  // (its FLT_LARGE; NaN and Inf fail too) and tnear/tfar not NaN. Other rays never reach it.
  static bool traceable_ray(const Vec3 &o, const Vec3 &d, float tmin, float tmax) {
    constexpr float kEmbreeLargest = 1.8e18f;
    auto bounded = [](const Vec3 &v) {
      return std::fabs(v.x) <= kEmbreeLargest && std::fabs(v.y) <= kEmbreeLargest && std::fabs(v.z) <= kEmbreeLargest;
    };
    return bounded(o) && bounded(d) && tmin >= 0.0f && tmin <= tmax;  // false for NaN
  }

  bool intersect(const Vec3 &o, const Vec3 &d, float tmin, float tmax, SurfaceHit &hit) const {
    if (!traceable_ray(o, d, tmin, tmax)) return false;
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    RTCRayHit rh;
    rh.ray.org_x = o.x; rh.ray.org_y = o.y; rh.ray.org_z = o.z;
    rh.ray.dir_x = d.x; rh.ray.dir_y = d.y; rh.ray.dir_z = d.z;
    rh.ray.tnear = tmin;
    rh.ray.tfar = tmax;
    rh.ray.time = 0.0f;
    rh.ray.mask = 0xffffffffu;
    rh.ray.id = 0;
    rh.ray.flags = 0;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(rtc_scene, &ctx, &rh);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return false;
    hit.mesh = static_cast<int>(rh.hit.geomID);
    hit.prim = static_cast<int>(rh.hit.primID);
    hit.u = rh.hit.u;
    hit.v = rh.hit.v;
    hit.t = rh.ray.tfar;
    return true;
  }

  bool occluded(const Vec3 &o, const Vec3 &d, float tmax) const {
    if (!traceable_ray(o, d, 0.0f, tmax)) return true;  // no light along a ray that cannot be traced
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    RTCRay r;
    r.org_x = o.x; r.org_y = o.y; r.org_z = o.z;
    r.dir_x = d.x; r.dir_y = d.y; r.dir_z = d.z;
    r.tnear = 0.0f;
    r.tfar = tmax;
    r.time = 0.0f;
    r.mask = 0xffffffffu;
    r.id = 0;
    r.flags = 0;
    rtcOccluded1(rtc_scene, &ctx, &r);
    return r.tfar < 0.0f;
  }

  // ---- Shading points ----
  struct ShadingData {
    GlimmerShadingContext ctx{};
    GlimmerShadingContext ctx_front{};  // N/Ng/T of the front face (transmissive closures)
    TexCoords tc;
    Vec3 Ng;            // geometric normal, flipped to the incoming side
    Vec3 N;             // shading normal, same side
    Vec3 e1, e2;        // triangle edges (barycentric derivatives of P)
    Vec3 dn1{0.0f}, dn2{0.0f};  // barycentric derivatives of the (unnormalized) shading normal
    float duv1[2] = {1, 0}, duv2[2] = {0, 1};
    bool backfacing = false;
    int shader = -1;
  };

  void setup_shading(const SurfaceHit &h, const Vec3 &D, ShadingData &sd) const {
    const scene::Mesh &m = scene.meshes[h.mesh];
    const auto &tri = m.triangles[h.prim];
    const Vec3 p0 = m.P[tri[0]], p1 = m.P[tri[1]], p2 = m.P[tri[2]];
    const float b0 = 1.0f - h.u - h.v;
    sd.e1 = p1 - p0;
    sd.e2 = p2 - p0;
    const Vec3 P = p0 * b0 + p1 * h.u + p2 * h.v;
    Vec3 Ng = normalize(cross(sd.e1, sd.e2));
    Vec3 N = Ng;
    if (m.smooth && !m.N.empty()) {
      const Vec3 n = m.N[tri[0]] * b0 + m.N[tri[1]] * h.u + m.N[tri[2]] * h.v;
      if (length_squared(n) > 0.0f) {
        N = normalize(n);
        sd.dn1 = m.N[tri[1]] - m.N[tri[0]];
        sd.dn2 = m.N[tri[2]] - m.N[tri[0]];
      }
    }
    sd.backfacing = dot(Ng, D) > 0.0f;
    if (sd.backfacing) {  // Cycles flips both normals to the incoming side
      Ng = -Ng;
      N = -N;
      sd.dn1 = -sd.dn1;
      sd.dn2 = -sd.dn2;
    }
    sd.Ng = Ng;
    sd.N = N;
    float uv[2] = {h.u, h.v};
    Vec3 dPdu = sd.e1, dPdv = sd.e2;
    if (!m.uv.empty()) {
      const auto &a = m.uv[3 * h.prim], &b = m.uv[3 * h.prim + 1], &c = m.uv[3 * h.prim + 2];
      for (int k = 0; k < 2; ++k) {
        uv[k] = a[k] * b0 + b[k] * h.u + c[k] * h.v;
        sd.duv1[k] = b[k] - a[k];
        sd.duv2[k] = c[k] - a[k];
      }
      // Solve [e1 e2] = [dPdu dPdv] [[du1 du2] [dv1 dv2]] for dPdu, dPdv.
      const float det = sd.duv1[0] * sd.duv2[1] - sd.duv2[0] * sd.duv1[1];
      if (std::fabs(det) > 1e-12f) {
        const float inv = 1.0f / det;
        dPdu = (sd.e1 * sd.duv2[1] - sd.e2 * sd.duv1[1]) * inv;
        dPdv = (sd.e2 * sd.duv1[0] - sd.e1 * sd.duv2[0]) * inv;
      }
    } else {
      sd.duv1[0] = 1; sd.duv1[1] = 0;
      sd.duv2[0] = 0; sd.duv2[1] = 1;
    }
    const Vec3 gen = m.generated[tri[0]] * b0 + m.generated[tri[1]] * h.u + m.generated[tri[2]] * h.v;
    sd.tc.P = P;
    sd.tc.N = N;
    sd.tc.generated = gen;
    sd.tc.uv[0] = uv[0];
    sd.tc.uv[1] = uv[1];
    sd.tc.direction = D;
    GlimmerShadingContext &ctx = sd.ctx;
    ctx = GlimmerShadingContext{};
    ctx.wi = -D;
    ctx.P = P;
    ctx.N = N;
    ctx.Ng = Ng;
    ctx.T = Frame::from_normal_tangent(N, dPdu).s;
    ctx.uv[0] = uv[0];
    ctx.uv[1] = uv[1];
    ctx.dPdu = dPdu;
    ctx.dPdv = dPdv;
    ctx.backfacing = sd.backfacing ? 1u : 0u;
    ctx.host = &host;
    sd.shader = mesh_shader[h.mesh];
  }

  // Copies the per-bounce fields into the front-face context.
  static void sync_front(ShadingData &sd) {
    sd.ctx_front = sd.ctx;
    if (sd.backfacing) {
      sd.ctx_front.N = -Vec3(sd.ctx.N);
      sd.ctx_front.Ng = -Vec3(sd.ctx.Ng);
    }
  }
  static const GlimmerShadingContext &context_for(const ShadingData &sd, const ClosureLeaf &leaf) {
    return leaf.front_normal ? sd.ctx_front : sd.ctx;
  }

  // Transfer the differentials to the hit plane and express them in barycentric
  // and uv space (Igehy 1999, eq. 10-12); fills the context's footprint.
  void transfer_differentials(Differentials &rd, const Vec3 &D, float t, ShadingData &sd, float spread) const {
    auto to_plane = [&](const Vec3 &dP, const Vec3 &dD) {
      const Vec3 p = dP + dD * t;
      const float dn = dot(D, sd.Ng);
      const float dt = std::fabs(dn) > 1e-8f ? -dot(p, sd.Ng) / dn : 0.0f;
      return p + D * dt;
    };
    rd.dPdx = to_plane(rd.dPdx, rd.dDdx);
    rd.dPdy = to_plane(rd.dPdy, rd.dDdy);
    const float a11 = dot(sd.e1, sd.e1), a12 = dot(sd.e1, sd.e2), a22 = dot(sd.e2, sd.e2);
    const float det = a11 * a22 - a12 * a12;
    float bx[2] = {0, 0}, by[2] = {0, 0};
    if (det > 0.0f) {
      const float inv = 1.0f / det;
      auto solve = [&](const Vec3 &dP, float out[2]) {
        const float r1 = dot(sd.e1, dP), r2 = dot(sd.e2, dP);
        out[0] = (a22 * r1 - a12 * r2) * inv;
        out[1] = (a11 * r2 - a12 * r1) * inv;
      };
      solve(rd.dPdx, bx);
      solve(rd.dPdy, by);
    }
    for (int k = 0; k < 2; ++k) {
      const float x = sd.duv1[k] * bx[0] + sd.duv2[k] * bx[1];
      const float y = sd.duv1[k] * by[0] + sd.duv2[k] * by[1];
      sd.ctx.duv_dx[k] = std::isfinite(x) ? x : 0.0f;
      sd.ctx.duv_dy[k] = std::isfinite(y) ? y : 0.0f;
    }
    sd.ctx.spread_angle = spread;
    // Normal derivatives for specular propagation (stored in dn1/dn2 as per-pixel values).
    const Vec3 dNx = sd.dn1 * bx[0] + sd.dn2 * bx[1];
    const Vec3 dNy = sd.dn1 * by[0] + sd.dn2 * by[1];
    sd.dn1 = dNx - sd.N * dot(sd.N, dNx);
    sd.dn2 = dNy - sd.N * dot(sd.N, dNy);
  }

  // ---- Closure mixture evaluation ----
  struct MixtureEval {
    Spectrum f{0.0f};
    float pdf = 0.0f;
  };
  // Sum of weight * eval over the non-singular closures, pdf = sum(sw * pdf) / sum(sw).
  MixtureEval eval_mixture(const ClosureSet &cs, const ShadingData &sd, const Vec3 &wo, int skip = -1) const {
    MixtureEval out;
    for (int i = 0; i < cs.count; ++i) {
      const ActiveClosure &c = cs.closures[i];
      if (i == skip || c.sample_weight <= 0.0f || c.leaf->singular || !c.instance) continue;
      Spectrum f;
      float pdf = 0.0f;
      c.instance->eval(context_for(sd, *c.leaf), wo, f, pdf);
      if (!is_finite(f) || !std::isfinite(pdf)) continue;
      out.f += f * c.weight;
      out.pdf += pdf * c.sample_weight;
    }
    return out;
  }

  // Radiance along a shadow ray from `P` toward `wi` over `dist`: 0 when
  // blocked, else the product of transparent closure weights passed through.
  Spectrum shadow_transmittance(const ShadingData &sd, const Vec3 &wi, float dist) const {
    Vec3 o = offset_ray_origin(sd.ctx.P, sd.Ng, wi);
    float remaining = std::isfinite(dist) ? dist * (1.0f - 1e-4f) - 1e-4f : kInf;
    if (!features.transparent) return occluded(o, wi, remaining) ? Spectrum(0.0f) : Spectrum(1.0f);
    Spectrum T(1.0f);
    for (int i = 0; i <= scene.integrator.transparent_max_bounce; ++i) {
      SurfaceHit h;
      if (!intersect(o, wi, 0.0f, remaining, h)) return T;
      const int shader = mesh_shader[h.mesh];
      if (!shaders->shader(shader).has_transparent) return Spectrum(0.0f);
      ShadingData hsd;
      setup_shading(h, wi, hsd);
      ClosureSet cs;
      shaders->evaluate(shader, hsd.tc, cs);
      T *= cs.transparent;
      if (is_zero(T)) return T;
      o = offset_ray_origin(hsd.ctx.P, hsd.Ng, wi);
      remaining = std::isfinite(remaining) ? remaining - h.t : kInf;
      if (remaining <= 0.0f) return T;
    }
    return Spectrum(0.0f);
  }

  // ---- One path ----
  struct PixelAov {
    Spectrum albedo{0.0f};
    Vec3 normal{0.0f};
    float depth = 1e10f;
  };

  Spectrum trace_path(int px, int py, uint32_t sample_index, PixelAov &aov, uint64_t &nan_count) const {
    const auto &integ = scene.integrator;
    // Cycles' kernel limits (scene/integrator.cpp): the settings plus one, "so that a bounce of 0 indicates
    // no global illumination, only direct illumination"; transparent_max_bounce is used as is.
    const auto plus_one = [](int v) { return v < std::numeric_limits<int>::max() ? v + 1 : v; };
    const int limit_min_bounce = plus_one(integ.min_bounce);
    const int limit_bounce = plus_one(integ.max_bounce);
    const int limit_diffuse = plus_one(integ.max_diffuse_bounce);
    const int limit_glossy = plus_one(integ.max_glossy_bounce);
    const int limit_transmission = plus_one(integ.max_transmission_bounce);
    const uint32_t pixel_index = static_cast<uint32_t>(py) * static_cast<uint32_t>(width) + static_cast<uint32_t>(px);
    const PixelSampler sampler(seed, pixel_index, sample_index);
    const uint32_t path_seed = hash_u32x3(seed, pixel_index, sample_index);

    // Camera ray through the filter-importance-sampled film position.
    float fu, fv;
    sampler.get2(kPairFilm, fu, fv);
    const float ox = filter.offset(fu), oy = filter.offset(fv);
    Vec3 D, org;
    Differentials rd;
    float cam_dir_z = 1.0f;
    float lens_u = 0.5f, lens_v = 0.5f;
    if (scene.camera.aperture_size > 0.0f) sampler.get2(kPairLens, lens_u, lens_v);
    camera_ray(px + 0.5f + ox, py + 0.5f + oy, org, D, rd, cam_dir_z, lens_u, lens_v);
    float tmin = scene.camera.nearclip / std::max(cam_dir_z, 1e-6f);
    float tmax = scene.camera.farclip / std::max(cam_dir_z, 1e-6f);
    const float pixel_spread = std::max(length(rd.dDdx), length(rd.dDdy));

    Spectrum L(0.0f), throughput(1.0f);
    int bounce = 0, diffuse_bounce = 0, glossy_bounce = 0, transmission_bounce = 0, transparent_bounce = 0;
    bool terminate_next = false;
    bool last_singular = true;  // camera rays count as singular: no MIS on emission
    float mis_ray_pdf = 0.0f;
    float min_ray_pdf = std::numeric_limits<float>::max();
    float spread = 0.0f;
    bool first_hit = true;

    auto add = [&](const Spectrum &contribution, int at_bounce) {
      if (!is_finite(contribution)) {
        ++nan_count;
        return;
      }
      L += clamp_contribution(contribution, at_bounce > 0 ? integ.sample_clamp_indirect : integ.sample_clamp_direct);
    };
    const bool use_nee = options.strategy != LightStrategy::BsdfOnly;
    const bool use_bsdf_emission = options.strategy != LightStrategy::LightOnly;

    for (int step = 0; step < 4 * 1024; ++step) {
      SurfaceHit hit;
      const bool hit_surface = intersect(org, D, tmin, tmax, hit);
      const float t_hit = hit_surface ? hit.t : kInf;
      // Lamps (spheres, area lights) before the surface and the sun disk on escape;
      // as in Cycles they do not block the ray.
      LightHits lhs;
      lights->intersect(org, D, t_hit, hit_surface, bounce == 0, lhs);
      for (int i = 0; i < lhs.count; ++i) {
        const LightHit &lh = lhs.hits[i];
        if (last_singular) {
          add(throughput * lh.radiance, bounce);
        } else if (use_bsdf_emission) {
          const float w = use_nee ? power_heuristic(mis_ray_pdf, lh.pdf) : 1.0f;
          add(throughput * lh.radiance * w, bounce);
        }
      }
      if (!hit_surface) {
        if (shaders->has_background()) {
          const Spectrum Le = shaders->background(D);
          if (last_singular) {
            add(throughput * Le, bounce);
          } else if (use_bsdf_emission) {
            const float w = use_nee ? power_heuristic(mis_ray_pdf, lights->background_pdf(D)) : 1.0f;
            add(throughput * Le * w, bounce);
          }
        }
        break;
      }

      ShadingData sd;
      setup_shading(hit, D, sd);
      transfer_differentials(rd, D, hit.t, sd, spread);
      GlimmerShadingContext &ctx = sd.ctx;
      ctx.bounce = static_cast<uint32_t>(bounce);
      ctx.diffuse_bounce = static_cast<uint32_t>(diffuse_bounce);
      ctx.glossy_bounce = static_cast<uint32_t>(glossy_bounce);
      ctx.transmission_bounce = static_cast<uint32_t>(transmission_bounce);
      ctx.path_seed = path_seed;
      sync_front(sd);

      ClosureSet cs;
      shaders->evaluate(sd.shader, sd.tc, cs);
      // filter_glossy (Cycles): blur_pdf = filter_glossy * min_ray_pdf; below 1 the glossy
      // closures get alpha >= 0.5 sqrt(1 - blur_pdf) (nearest lower precomputed variant).
      if (integ.filter_glossy > 0.0f && min_ray_pdf < std::numeric_limits<float>::max()) {
        const float blur_pdf = integ.filter_glossy * min_ray_pdf;
        if (blur_pdf < 1.0f) {
          const float blur_alpha = 0.5f * std::sqrt(1.0f - blur_pdf);
          const int k = std::min(static_cast<int>(blur_alpha / ClosureLeaf::kBlurStep), ClosureLeaf::kBlurLevels);
          for (int i = 0; i < cs.count; ++i)
            if (k > 0 && !cs.closures[i].leaf->blurred.empty()) cs.closures[i].instance = cs.closures[i].leaf->blurred[k];
        }
      }

      // Emission (mesh lights), MIS against the light-sampling pdf.
      Spectrum emission(0.0f);
      for (int i = 0; i < cs.count; ++i)
        if (cs.closures[i].leaf->emissive) emission += cs.closures[i].leaf->instance->emit(ctx) * cs.closures[i].weight;
      if (!is_zero(emission)) {
        if (last_singular) {
          add(throughput * emission, bounce);
        } else if (use_bsdf_emission) {
          const float light_pdf = use_nee ? lights->triangle_pdf(hit.mesh, hit.prim, org, sd.ctx.P, sd.Ng, D) : 0.0f;
          add(throughput * emission * power_heuristic(mis_ray_pdf, light_pdf), bounce);
        }
      }

      if (first_hit && !(cs.count == 0 && !is_zero(cs.transparent))) {
        first_hit = false;
        aov.normal = sd.N;
        aov.depth = hit.t * cam_dir_z;
        for (int i = 0; i < cs.count; ++i)
          if (!cs.closures[i].leaf->emissive && cs.closures[i].leaf->instance)
            aov.albedo += cs.closures[i].leaf->instance->albedo(context_for(sd, *cs.closures[i].leaf)) * cs.closures[i].weight;
      }

      if (terminate_next) break;

      // Russian roulette (Cycles' path_state_continuation_probability).
      float ru, rr;
      sampler.get2(bounce_pair(bounce, kPairBsdfTerminate), ru, rr);
      if (bounce > limit_min_bounce) {
        const float q = std::min(std::sqrt(max_component(abs(throughput))), 1.0f);
        if (q <= 0.0f || rr >= q) break;
        throughput /= q;
      }

      float transparent_weight = std::fabs(average(cs.transparent));
      const float total_sw = cs.sum_sample_weight + transparent_weight;
      if (total_sw <= 0.0f) break;

      float select_light, select_closure;
      sampler.get2(bounce_pair(bounce, kPairSelect), select_light, select_closure);

      // Next-event estimation (skipped when only singular closures are present).
      bool any_smooth = false;
      for (int i = 0; i < cs.count; ++i)
        if (cs.closures[i].sample_weight > 0.0f && !cs.closures[i].leaf->singular) any_smooth = true;
      if (use_nee && any_smooth && lights->count() > 0) {
        float lu, lv;
        sampler.get2(bounce_pair(bounce, kPairLight), lu, lv);
        LightSample ls;
        if (lights->sample(select_light, lu, lv, sd.ctx.P, ls) && ls.pdf > 0.0f) {
          const bool transmit_side = dot(ls.wi, sd.Ng) < 0.0f;
          (void)transmit_side;
          MixtureEval me = eval_mixture(cs, sd, ls.wi);
          me.pdf /= total_sw;
          if (!is_zero(me.f)) {
            const float w = (ls.delta || !use_bsdf_emission) ? 1.0f : power_heuristic(ls.pdf, me.pdf);
            const Spectrum contribution = throughput * me.f * ls.radiance * (w / ls.pdf);
            if (!is_zero(contribution)) {
              const Spectrum T = shadow_transmittance(sd, ls.wi, ls.dist);
              if (!is_zero(T)) add(contribution * T, bounce);
            }
          }
        }
      }

      // Pick a closure by sample weight (or the transparent pass-through).
      float pick = select_closure * total_sw;
      if (pick < transparent_weight) {
        // Transparent: continue straight on; does not count as a bounce.
        throughput *= cs.transparent / (transparent_weight / total_sw);
        if (++transparent_bounce >= integ.transparent_max_bounce) terminate_next = true;
        org = offset_ray_origin(sd.ctx.P, sd.Ng, D);
        tmin = 0.0f;
        tmax = kInf;
        continue;
      }
      pick -= transparent_weight;
      int chosen = -1;
      for (int i = 0; i < cs.count; ++i) {
        if (cs.closures[i].sample_weight <= 0.0f) continue;
        chosen = i;
        if (pick < cs.closures[i].sample_weight) break;
        pick -= cs.closures[i].sample_weight;
      }
      if (chosen < 0) break;
      const ActiveClosure &c = cs.closures[chosen];
      float r3[3];
      sampler.get2(bounce_pair(bounce, kPairBsdf), r3[0], r3[1]);
      r3[2] = ru;
      GlimmerSample s{};
      const uint32_t label = c.instance->sample(context_for(sd, *c.leaf), r3, s);
      if (label == GLIMMER_LABEL_NONE || !(s.pdf > 0.0f) || !std::isfinite(s.pdf)) break;
      const Vec3 wo = normalize(Vec3(s.wo));
      const Spectrum s_eval(s.eval[0], s.eval[1], s.eval[2]);
      if (!is_finite(s_eval)) { ++nan_count; break; }
      const bool singular = (label & GLIMMER_LABEL_SINGULAR) != 0;
      if (singular) {
        throughput *= s_eval * c.weight * (total_sw / c.sample_weight);
      } else {
        MixtureEval me = eval_mixture(cs, sd, wo, chosen);
        me.f += s_eval * c.weight;
        me.pdf = (me.pdf + s.pdf * c.sample_weight) / total_sw;
        if (!(me.pdf > 0.0f)) break;
        throughput *= me.f / me.pdf;
        mis_ray_pdf = me.pdf;
        min_ray_pdf = std::min(min_ray_pdf, me.pdf);
      }
      if (!is_finite(throughput)) { ++nan_count; break; }
      if (is_zero(throughput)) break;
      last_singular = singular;

      // Bounce counters by label (Cycles' path_state_next).
      ++bounce;
      if (bounce >= limit_bounce) terminate_next = true;
      if (label & GLIMMER_LABEL_REFLECT) {
        if (label & GLIMMER_LABEL_DIFFUSE) {
          if (++diffuse_bounce >= limit_diffuse) terminate_next = true;
        } else if (++glossy_bounce >= limit_glossy) {
          terminate_next = true;
        }
      } else if (++transmission_bounce >= limit_transmission) {
        terminate_next = true;
      }

      // Ray differentials for the next segment.
      if (singular) {
        propagate_specular(rd, D, wo, sd, s.eta);
      } else {
        const float alpha = std::clamp(s.roughness, 0.0f, 1.0f);
        spread += 2.0f * alpha;  // widen by beta = 2 alpha (Wang 2018, sec. 4.6)
        const float width_dir = pixel_spread + spread;
        const Frame f = Frame::from_normal(wo);
        rd.dDdx = f.s * width_dir;
        rd.dDdy = f.t * width_dir;
      }
      org = offset_ray_origin(sd.ctx.P, sd.Ng, wo);
      D = wo;
      tmin = 0.0f;
      tmax = kInf;
    }
    return L;
  }

  // Reflect or refract the direction differentials (Igehy 1999, eq. 14-15, 18-19).
  void propagate_specular(Differentials &rd, const Vec3 &D, const Vec3 &wo, const ShadingData &sd, float eta) const {
    const Vec3 &N = sd.N;
    const float DN = dot(D, N);
    const bool reflect_dir = dot(wo, sd.Ng) > 0.0f;  // Ng faces the incoming side
    auto one = [&](const Vec3 &dD, const Vec3 &dN) -> Vec3 {
      const float dDN = dot(dD, N) + dot(D, dN);
      if (reflect_dir) return dD - 2.0f * (N * dDN + dN * DN);
      // Refraction: wo = mu_eta * D - mu * N.
      const Vec3 Dt = D - N * DN, Tt = wo - N * dot(wo, N);
      float ratio = length(Dt) > 1e-4f ? length(Tt) / length(Dt) : (eta > 0.0f ? 1.0f / eta : 1.0f);
      if (!std::isfinite(ratio) || ratio <= 0.0f) ratio = 1.0f;
      const float TN = dot(wo, N);
      const float mu = ratio * DN - TN;
      const float dmu = std::fabs(TN) > 1e-6f ? (ratio - ratio * ratio * DN / TN) * dDN : 0.0f;
      return dD * ratio - (dN * mu + N * dmu);
    };
    rd.dDdx = one(rd.dDdx, sd.dn1);
    rd.dDdy = one(rd.dDdy, sd.dn2);
    if (!is_finite(rd.dDdx) || !is_finite(rd.dDdy)) rd.dDdx = rd.dDdy = Vec3(0.0f);
  }

  // Pinhole camera: looks along +Z of camera space, +Y up, fov across the
  // shorter image side (Cycles' viewplane).
  // Camera ray through film position (x, y); (lens_u, lens_v) picks the point on the thin-lens aperture.
  void camera_ray(float x, float y, Vec3 &org, Vec3 &dir, Differentials &rd, float &dir_z, float lens_u = 0.5f,
                  float lens_v = 0.5f) const {
    const auto &cam = scene.camera;
    const float aspect = static_cast<float>(width) / static_cast<float>(height);
    float half_w, half_h;
    if (width >= height) { half_w = aspect; half_h = 1.0f; }
    else { half_w = 1.0f; half_h = 1.0f / aspect; }
    const float t = std::tan(0.5f * cam.fov);
    const float sx = (2.0f * x / width - 1.0f) * half_w * t;
    const float sy = (1.0f - 2.0f * y / height) * half_h * t;
    const Vec3 v(sx, sy, 1.0f);
    const Vec3 dvx(2.0f / width * half_w * t, 0.0f, 0.0f), dvy(0.0f, -2.0f / height * half_h * t, 0.0f);
    const float len = length(v);
    dir_z = 1.0f / len;
    // World-space direction and its derivative d(normalize(v))/dx = (v.v dv - v (v.dv)) / |v|^3.
    const Vec3 vw = cam.camera_to_world.vector(v);
    const Vec3 dvxw = cam.camera_to_world.vector(dvx), dvyw = cam.camera_to_world.vector(dvy);
    const float lw = length(vw);
    dir = vw / lw;
    auto ddir = [&](const Vec3 &dv) { return (dv * dot(vw, vw) - vw * dot(vw, dv)) / (lw * lw * lw); };
    rd.dDdx = ddir(dvxw);
    rd.dDdy = ddir(dvyw);
    rd.dPdx = rd.dPdy = Vec3(0.0f);
    org = cam.camera_to_world.point(Vec3(0.0f));
    if (cam.aperture_size > 0.0f) {
      // Cycles' thin lens (kernel/camera/camera.h): the point on the plane z = focaldistance seen through the
      // pinhole, reached from a uniform point on the aperture disk of radius aperturesize. The pinhole
      // differentials are kept (an approximation: the footprint ignores the defocus).
      float lx, ly;
      sample_uniform_disk_concentric(lens_u, lens_v, lx, ly);
      const Vec3 lens_point(lx * cam.aperture_size, ly * cam.aperture_size, 0.0f);
      const Vec3 focus_point = v * cam.focal_distance;  // v.z = 1
      const Vec3 w = cam.camera_to_world.vector(focus_point - lens_point);
      dir = normalize(w);
      org = cam.camera_to_world.point(lens_point);
    }
    // Depth of the first hit is measured along camera +Z in world units.
    dir_z = dot(dir, normalize(cam.camera_to_world.vector(Vec3(0, 0, 1))));
  }
};

Renderer::Renderer(const scene::Scene &scene, const host::PluginLibrary &plugin, const RenderOptions &options)
    : impl_(std::make_unique<Impl>(scene, plugin, options, features_, warnings_)) {
  impl_->prepare(times_);
}

Renderer::~Renderer() = default;

bool Renderer::probe(float x, float y, GlimmerShadingContext &out) const {
  const Impl &im = *impl_;
  Vec3 org, D;
  Differentials rd;
  float dir_z = 1.0f;
  im.camera_ray(x, y, org, D, rd, dir_z);
  float tmin = 0.0f;
  for (int bounce = 0; bounce < 16; ++bounce) {
    SurfaceHit hit;
    if (!im.intersect(org, D, tmin, kInf, hit)) return false;
    Impl::ShadingData sd;
    im.setup_shading(hit, D, sd);
    im.transfer_differentials(rd, D, hit.t, sd, 0.0f);
    Impl::sync_front(sd);
    ClosureSet cs;
    im.shaders->evaluate(sd.shader, sd.tc, cs);
    bool all_singular = cs.count > 0;
    for (int i = 0; i < cs.count; ++i)
      if (!cs.closures[i].leaf->singular && !cs.closures[i].leaf->emissive) {
        GlimmerSample s{};
        const float r3[3] = {0.5f, 0.5f, 0.5f};
        const uint32_t label = cs.closures[i].leaf->instance->sample(Impl::context_for(sd, *cs.closures[i].leaf), r3, s);
        if (!(label & GLIMMER_LABEL_SINGULAR)) all_singular = false;
      }
    if (!all_singular) {
      out = sd.ctx;
      return true;
    }
    GlimmerSample s{};
    const float r3[3] = {0.5f, 0.5f, 0.5f};
    const ClosureLeaf &leaf = *cs.closures[0].leaf;
    if (!leaf.instance || leaf.instance->sample(Impl::context_for(sd, leaf), r3, s) == GLIMMER_LABEL_NONE) return false;
    const Vec3 wo = normalize(Vec3(s.wo));
    im.propagate_specular(rd, D, wo, sd, s.eta);
    org = offset_ray_origin(sd.ctx.P, sd.Ng, wo);
    D = wo;
  }
  return false;
}

RenderResult Renderer::render(const std::function<void(int, int)> &progress) {
  Impl &im = *impl_;
  const auto t0 = Clock::now();
  RenderResult res;
  res.width = im.width;
  res.height = im.height;
  res.samples_requested = im.samples;
  const size_t npix = static_cast<size_t>(im.width) * im.height;
  std::vector<Spectrum> sum(npix, Spectrum(0.0f)), albedo(npix, Spectrum(0.0f)), normal(npix, Spectrum(0.0f));
  std::vector<float> depth(npix, 0.0f);
  // Samples per pixel: an interrupt stops the current pass mid-way, so pixels can differ by one.
  std::vector<uint32_t> count(npix, 0u);
  std::atomic<uint64_t> paths{0};
  int x0 = 0, y0 = 0, x1 = im.width, y1 = im.height;
  const auto &r = im.options.region;
  if (r[0] != 0 || r[1] != 0 || r[2] != 0 || r[3] != 0) {
    x0 = std::clamp(r[0], 0, im.width);
    y0 = std::clamp(r[1], 0, im.height);
    x1 = std::clamp(r[2], x0, im.width);
    y1 = std::clamp(r[3], y0, im.height);
  }
  const int tile = std::max(1, im.options.tile_size);
  std::atomic<uint64_t> nan_total{0};
  int done = 0;
  for (int s = 0; s < im.samples; ++s) {
    if (im.options.cancel && im.options.cancel->load()) { res.interrupted = true; break; }
    tbb::parallel_for(tbb::blocked_range2d<int>(y0, y1, tile, x0, x1, tile), [&](const tbb::blocked_range2d<int> &br) {
      uint64_t nans = 0, traced = 0;
      for (int y = br.rows().begin(); y < br.rows().end(); ++y) {
        if (im.options.cancel && im.options.cancel->load()) break;  // answer SIGINT within a tile row
        for (int x = br.cols().begin(); x < br.cols().end(); ++x) {
          Impl::PixelAov aov;
          const Spectrum L = im.trace_path(x, y, static_cast<uint32_t>(s), aov, nans);
          const size_t i = static_cast<size_t>(y) * im.width + x;
          const Spectrum next = sum[i] + L;  // a finite sample can still overflow the sum
          if (is_finite(next)) sum[i] = next;
          else ++nans;
          count[i]++;
          ++traced;
          if (im.options.aovs) {
            albedo[i] += aov.albedo;
            normal[i] += aov.normal;
            depth[i] += aov.depth;
          }
        }
      }
      if (nans) nan_total += nans;
      paths += traced;
    });
    // A pass cut short by an interrupt does not count: samples_done = complete passes.
    if (im.options.cancel && im.options.cancel->load()) { res.interrupted = true; break; }
    done = s + 1;
    if (progress) progress(done, im.samples);
    if (im.options.time_limit > 0.0 && seconds_since(t0) >= im.options.time_limit && done < im.samples) {
      res.time_limited = true;
      break;
    }
  }
  res.samples_done = done;
  res.nan_samples = nan_total.load();
  res.paths = paths.load();
  const float exposure = im.scene.film.exposure;
  res.combined.assign(npix * 4, 0.0f);
  res.albedo.assign(npix * 3, 0.0f);
  res.normal.assign(npix * 3, 0.0f);
  res.depth.assign(npix, 0.0f);
  for (size_t i = 0; i < npix; ++i) {
    const float inv = count[i] > 0 ? 1.0f / static_cast<float>(count[i]) : 0.0f;
    Spectrum c = sum[i] * (inv * exposure);
    if (!is_finite(c)) {  // exposure pushed the mean past the float range
      c = Spectrum(0.0f);
      ++res.nan_samples;
    }
    res.combined[4 * i] = c.x;
    res.combined[4 * i + 1] = c.y;
    res.combined[4 * i + 2] = c.z;
    res.combined[4 * i + 3] = 1.0f;
    const Spectrum a = albedo[i] * inv, n = normal[i] * inv;
    for (int k = 0; k < 3; ++k) {
      res.albedo[3 * i + k] = a[k];
      res.normal[3 * i + k] = n[k];
    }
    res.depth[i] = depth[i] * inv;
  }
  res.render_seconds = seconds_since(t0);
  return res;
}

}  // namespace glimmer::render
