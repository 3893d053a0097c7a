#include "render/renderer.h"
#include "render/nodes/shading_normal.h"

#include <tbb/blocked_range2d.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <mutex>
#include <stdexcept>

#include "glimmer/exit_lobe.h"
#include "glimmer/rng.h"
#include "glimmer/sampling.h"
#include "host/log.h"
#include "render/accel.h"
#include "render/camera.h"
#include "render/environment_cone.h"
#include "render/film_filter.h"
#include "render/lights.h"
#include "render/object_space.h"
#include "render/path_state.h"
#include "render/sampler.h"

namespace glimmer::render {

namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

constexpr float kInf = std::numeric_limits<float>::infinity();

// The light set (2D) of light sampling at an exit lobe (integrate_exit_lobe) of path vertex v: far
// from the film, lens and per-bounce sets of render/sampler.h.
uint32_t exit_light_set(int vertex) { return 0x80000000u + static_cast<uint32_t>(vertex); }
// The set (2D: which point's visibility stands for each lamp, unused) of the lamps through an exit lobe.
uint32_t exit_lamp_set(int vertex) { return 0xc0000000u + static_cast<uint32_t>(vertex); }

// Offset a ray origin off the surface along the geometric normal, on the side of `dir`.
Vec3 offset_ray_origin(const Vec3 &P, const Vec3 &Ng, const Vec3 &dir) {
  const float scale = 1.0f + std::max(std::fabs(P.x), std::max(std::fabs(P.y), std::fabs(P.z)));
  const float eps = 3e-5f * scale;
  return dot(dir, Ng) >= 0.0f ? P + Ng * eps : P - Ng * eps;
}


// Cycles' kernel_accum_clamp: scale L so that the sum of its components is at most `limit`.
Spectrum clamp_contribution(const Spectrum &L, float limit) {
  if (limit <= 0.0f) return L;
  const float sum = std::fabs(L.x) + std::fabs(L.y) + std::fabs(L.z);
  return sum > limit ? L * (limit / sum) : L;
}

}  // namespace

struct Renderer::Impl {
  const scene::Scene &scene;
  const host::PluginLibrary &plugin;
  RenderOptions options;
  FeatureSet &features;
  std::vector<std::string> &warnings;

  std::unique_ptr<Accel> accel;
  GlimmerHostServices host{};
  std::string cache_dir;
  std::unique_ptr<ShaderSystem> shaders;
  EnvironmentCone environment_cone;  // the world over a cone (environment_lookup), built on first use
  std::vector<int> mesh_shader;  // compiled shader per mesh
  std::vector<ObjectSpace> mesh_object_space;  // per mesh: its object space (closure ABI 2.5 context fields)
  std::unique_ptr<LightSet> lights;
  uint32_t sampling_flags = 0;  // GlimmerShadingContext.sampling_flags of every shading point (set in prepare)
  Vec3 scene_center{0.0f};
  float scene_radius = 1.0f;

  int width = 0, height = 0;
  CameraFrame camera;  // per-image constants of the camera rays (set with width and height)
  int samples = 1;
  uint32_t seed = 0;
  FilmFilter filter;

  Impl(const scene::Scene &s, const host::PluginLibrary &p, const RenderOptions &o, FeatureSet &f,
       std::vector<std::string> &w)
      : scene(s), plugin(p), options(o), features(f), warnings(w) {}

  // ---- Host services for closures ----
  static int host_trace(void *data, const GlimmerRay *ray, GlimmerRayHit *hit) {
    auto *self = static_cast<Impl *>(data);
    SurfaceHit h;
    if (!self->accel->intersect(Vec3(ray->origin), Vec3(ray->direction), ray->t_min, ray->t_max, h)) return 0;
    self->fill_ray_hit(h, *ray, *hit);
    return 1;
  }
  // ABI 2.3: the hit and its shader's principal closure (largest sample weight, emission excluded) with the
  // values of that closure's varying parameters at the hit. filter_glossy is not applied (the instance is the
  // material's own, so a closure can recognise itself).
  static int host_trace_closure(void *data, const GlimmerRay *ray, GlimmerRayHit *hit, GlimmerHitClosure *out) {
    auto *self = static_cast<Impl *>(data);
    SurfaceHit h;
    if (!self->accel->intersect(Vec3(ray->origin), Vec3(ray->direction), ray->t_min, ray->t_max, h)) return 0;
    self->fill_ray_hit(h, *ray, *hit);
    if (out != nullptr && GLIMMER_HAS_FIELD(out->struct_size, GlimmerHitClosure, varying)) {
      const MeshHitClosure &m = self->mesh_hit_closure[h.mesh];
      if (m.constant)
        copy_hit_closure(m.description, *out);
      else
        self->describe_hit_closure(h, Vec3(ray->direction), *out);
    }
    return 1;
  }
  // Per mesh: its shader's hit-closure description when the shader is constant (CompiledShader::reads_footprint
  // false: every weight, mix factor and varying parameter is a constant, so the shader's closures, and the
  // principal one with its parameter values, are the same at every point). Made once in prepare, copied per ray
  // instead of evaluating the shader at every hit (describe_hit_closure).
  struct MeshHitClosure {
    bool constant = false;
    GlimmerHitClosure description{};
  };
  std::vector<MeshHitClosure> mesh_hit_closure;
  static void copy_hit_closure(const GlimmerHitClosure &from, GlimmerHitClosure &out) {
    out.type = from.type;
    out.instance = from.instance;
    out.varying_count = from.varying_count;
    for (uint32_t k = 0; k < from.varying_count; ++k) out.varying[k] = from.varying[k];
  }
  void describe_hit_closure(const SurfaceHit &h, const Vec3 &D, GlimmerHitClosure &out) const {
    ShadingData sd;
    setup_shading(h, D, sd);
    sd.tc.path.camera = false;
    ClosureSet cs;
    shaders->evaluate(sd.shader, sd.tc, cs);
    describe_principal_closure(cs, out);
  }
  // The description of a shader's closures: the principal closure (largest sample weight, emission excluded)
  // and its varying parameters' values.
  static void describe_principal_closure(const ClosureSet &cs, GlimmerHitClosure &out) {
    out.type = nullptr;
    out.instance = nullptr;
    out.varying_count = 0;
    const ActiveClosure *best = nullptr;
    for (int i = 0; i < cs.count; ++i) {
      const ActiveClosure &c = cs.closures[i];
      if (c.leaf->emissive || !c.leaf->instance || !(c.sample_weight > 0.0f)) continue;
      if (!best || c.sample_weight > best->sample_weight) best = &c;
    }
    if (!best) return;
    out.type = &best->leaf->instance->type();
    out.instance = best->leaf->instance->handle();
    out.varying_count = std::min<uint32_t>(best->varying_count, GLIMMER_HIT_MAX_VARYING);
    for (uint32_t k = 0; k < out.varying_count; ++k) out.varying[k] = best->varying[k];
  }
  void fill_ray_hit(const SurfaceHit &h, const GlimmerRay &ray, GlimmerRayHit &out) const {
    GlimmerRayHit *hit = &out;
    // surface_at's P, N, Ng and uv, the same bits without what only shading reads (Mesh::hit_geometry).
    const scene::HitGeometry s = scene.meshes[h.mesh].hit_geometry(h.prim, h.u, h.v);
    // As at a shading point (closure_abi.h): N and Ng face the ray's origin.
    hit->backfacing = dot(s.Ng, Vec3(ray.direction)) > 0.0f ? 1u : 0u;
    hit->t = h.t;
    hit->P = s.P;
    hit->N = hit->backfacing ? -s.N : s.N;
    hit->Ng = hit->backfacing ? -s.Ng : s.Ng;
    hit->uv[0] = s.uv[0];
    hit->uv[1] = s.uv[1];
    hit->object_id = static_cast<uint32_t>(h.mesh);
  }
  // Cone 0 (or a constant world) is the background itself; a cone reads the pre-filtered map (environment_cone.h).
  static void host_environment(void *data, GlimmerVec3 direction, float cone_angle, float out[3]) {
    const auto *self = static_cast<Impl *>(data);
    const Spectrum c = self->environment_cone.lookup(*self->shaders, normalize(Vec3(direction)), cone_angle);
    out[0] = c.x;
    out[1] = c.y;
    out[2] = c.z;
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
  PartInfo part;  // pixels and samples this render covers

  void prepare(PhaseTimes &times) {
    auto t0 = Clock::now();
    cache_dir = host::default_host_services()->cache_dir ? host::default_host_services()->cache_dir : "";
    host.struct_size = sizeof(GlimmerHostServices);
    host.abi_version = GLIMMER_ABI_VERSION;
    host.host_data = this;
    host.trace_ray = &host_trace;
    host.trace_ray_closure = &host_trace_closure;
    host.environment_lookup = &host_environment;
    host.log = &host::log_callback;
    host.resolve_asset = &host_resolve;
    host.cache_dir = cache_dir.empty() ? nullptr : cache_dir.c_str();

    filter = FilmFilter(scene.film.filter, scene.film.filter_width);
    const auto &cam = scene.camera;
    width = options.width > 0 ? options.width : cam.width;
    height = options.height > 0 ? options.height : cam.height;
    camera = camera_frame(cam, width, height);
    samples = options.samples > 0 ? options.samples : scene.integrator.samples;
    seed = static_cast<uint32_t>(options.seed >= 0 ? options.seed : scene.integrator.seed);
    part = describe_part(options, width, height, samples, seed);

    // Feature scan: compile only the shaders that geometry, lights and the background use.
    shaders = std::make_unique<ShaderSystem>(scene, plugin, &host, warnings, features);
    std::vector<bool> used(scene.shaders.size(), false);
    for (const auto &m : scene.meshes) {
      mesh_shader.push_back(shaders->compile(m.shader));
      mesh_object_space.emplace_back(m.object_to_world);
      if (m.shader >= 0) used[m.shader] = true;
    }
    shaders->compile_background(scene.background.shader);
    if (scene.background.shader >= 0) used[scene.background.shader] = true;
    for (const auto &l : scene.lights)
      if (l.shader >= 0) used[l.shader] = true;
    for (bool u : used) (u ? features.used_shaders : features.unused_shaders)++;
    // Constant shaders' hit-closure descriptions (trace_ray_closure): their inputs read no point, so any
    // shading point gives the same closures.
    mesh_hit_closure.resize(mesh_shader.size());
    for (size_t m = 0; m < mesh_shader.size(); ++m) {
      if (shaders->shader(mesh_shader[m]).reads_footprint) continue;
      TexCoords tc;
      tc.path.camera = false;
      ClosureSet cs;
      shaders->evaluate(mesh_shader[m], tc, cs);
      mesh_hit_closure[m].constant = true;
      describe_principal_closure(cs, mesh_hit_closure[m].description);
    }

    // Scene bounds (for sun/background power estimates).
    Vec3 lo(kInf), hi(-kInf);
    for (const auto &m : scene.meshes)
      for (const auto &p : m.P) { lo = min(lo, p); hi = max(hi, p); }
    if (lo.x <= hi.x) {
      scene_center = (lo + hi) * 0.5f;
      scene_radius = std::max(length(hi - lo) * 0.5f, 1e-3f);
    }
    lights = std::make_unique<LightSet>(scene, *shaders, mesh_shader, scene_center, scene_radius,
                                        options.strategy == LightStrategy::LightOnly,
                                        features, warnings);
    // No light strategy is MIS-combined with BSDF samples when nothing is light-sampled (ABI 2.4 flag; lights do
    // not vary per vertex, so it holds for every bounce of the render).
    sampling_flags = (!use_nee() || lights->count() == 0) ? static_cast<uint32_t>(GLIMMER_SAMPLING_UNCOMBINED) : 0u;
    times.prepare = seconds_since(t0);

    t0 = Clock::now();
    accel = std::make_unique<Accel>(scene.meshes);
    times.bvh = seconds_since(t0);
  }

  // ---- Shading points ----
  struct ShadingData {
    GlimmerShadingContext ctx{};
    TexCoords tc;
    Vec3 Ng;            // geometric normal, flipped to the incoming side
    Vec3 N;             // shading normal, same side
    Vec3 e1, e2;        // triangle edges (barycentric derivatives of P)
    Vec3 dn1{0.0f}, dn2{0.0f};  // barycentric derivatives of the (unnormalized) shading normal
    Vec3 dg1{0.0f}, dg2{0.0f};  // barycentric derivatives of the generated coordinates
    float duv1[2] = {1, 0}, duv2[2] = {0, 1};
    bool backfacing = false;
    int shader = -1;
    const ObjectSpace *object_space = nullptr;  // the hit mesh's (fills the context's object-space fields)
  };

  void setup_shading(const SurfaceHit &h, const Vec3 &D, ShadingData &sd) const {
    const scene::SurfacePoint s = scene.meshes[h.mesh].surface_at(h.prim, h.u, h.v);
    sd.e1 = s.e1;
    sd.e2 = s.e2;
    sd.dn1 = s.dn1;
    sd.dn2 = s.dn2;
    const Vec3 P = s.P;
    Vec3 Ng = s.Ng;
    Vec3 N = s.N;
    sd.backfacing = dot(Ng, D) > 0.0f;
    if (sd.backfacing) {  // Cycles flips both normals to the incoming side
      Ng = -Ng;
      N = -N;
      sd.dn1 = -sd.dn1;
      sd.dn2 = -sd.dn2;
    }
    sd.Ng = Ng;
    sd.N = N;
    const float uv[2] = {s.uv[0], s.uv[1]};
    const Vec3 dPdu = s.dPdu, dPdv = s.dPdv;
    for (int k = 0; k < 2; ++k) {
      sd.duv1[k] = s.duv1[k];
      sd.duv2[k] = s.duv2[k];
    }
    const Vec3 gen = s.generated;
    const int shader = mesh_shader[h.mesh];
    const scene::Mesh &mesh = scene.meshes[h.mesh];
    if (shaders->shader(shader).reads_footprint && mesh.generated.size() == mesh.P.size()) {  // texture footprint
      const auto &tri = mesh.triangles[h.prim];
      sd.dg1 = mesh.generated[tri[1]] - mesh.generated[tri[0]];
      sd.dg2 = mesh.generated[tri[2]] - mesh.generated[tri[0]];
    }
    sd.tc.P = P;
    sd.tc.N = N;
    sd.tc.generated = gen;
    sd.tc.uv[0] = uv[0];
    sd.tc.uv[1] = uv[1];
    sd.tc.direction = D;
    sd.tc.backfacing = sd.backfacing;
    GlimmerShadingContext &ctx = sd.ctx;  // zero-initialised with sd (every caller passes a fresh one)
    ctx.struct_size = sizeof(GlimmerShadingContext);
    ctx.wi = -D;
    ctx.P = P;
    // Every closure's normal bent so that wi's mirror direction stays above Ng (Cycles 3.4 does this for all
    // non-curve BSDFs in svm_node_closure_bsdf): at silhouettes of interpolated normals the closures would
    // otherwise see wi below N or reflect below the surface (docs/architecture.md, equal-error scene (a)).
    ctx.N = nodes::ensure_valid_reflection(Ng, -D, N);
    ctx.Ng = Ng;
    ctx.T = Frame::from_normal_tangent(Vec3(ctx.N), dPdu).s;
    ctx.uv[0] = uv[0];
    ctx.uv[1] = uv[1];
    ctx.dPdu = dPdu;
    ctx.dPdv = dPdv;
    ctx.backfacing = sd.backfacing ? 1u : 0u;
    ctx.host = &host;
    ctx.sampling_flags = sampling_flags;
    sd.shader = shader;
    sd.object_space = &mesh_object_space[h.mesh];
    sd.object_space->set_point(P, s.Ng, ctx);
    set_surface_derivatives(scene.meshes[h.mesh], s, sd);
  }

  // What the Bump, Normal Map and Tangent nodes read besides the point: Ng, the UV map's dP/du and dP/dv,
  // its tangent and the object's transform.
  static void set_surface_derivatives(const scene::Mesh &m, const scene::SurfacePoint &s, ShadingData &sd) {
    sd.tc.Ng = sd.Ng;
    sd.tc.dPdu = s.dPdu;
    sd.tc.dPdv = s.dPdv;
    sd.tc.tangent = s.tangent;
    sd.tc.tangent_sign = s.tangent_sign;
    sd.tc.object = &m.object_to_world;
  }

  // The closure's own frame (a Bump / Normal Map on its normal socket, a tangent or rotation), replacing
  // the point's N and T in its context (on wi's side, as every closure's N: closure_abi.h, ABI 2.3).
  static void perturb_shading_normal(const ActiveClosure &c, GlimmerShadingContext &ctx) {
    if (!c.own_frame) return;
    ctx.N = c.N;
    ctx.T = c.T;
  }

  // The context one closure sees: the shading point's, with its varying
  // parameter values (then a copy in `scratch`; without them no copy is made).
  static const GlimmerShadingContext &context_for(const ShadingData &sd, const ActiveClosure &c,
                                                  GlimmerShadingContext &scratch) {
    const GlimmerShadingContext &ctx = sd.ctx;
    if (c.varying_count == 0 && !c.own_frame) return ctx;
    scratch = ctx;
    scratch.varying_count = c.varying_count;
    scratch.varying = c.varying;
    perturb_shading_normal(c, scratch);
    return scratch;
  }

  // Image textures filter over the footprint of one sample, not the whole pixel: the pixel filter
  // already averages the samples, and a whole-pixel footprint on the tangent plane runs far past a
  // curved silhouette (a box-projected sphere's rim read 25 % darker than Cycles' point samples).
  // As pbrt-v4's camera differentials: scaled by max(1/8, 1/sqrt(spp)).
  void scale_texture_footprint(TexCoords &tc) const {
    const float s = std::max(0.125f, 1.0f / std::sqrt(static_cast<float>(std::max(samples, 1))));
    tc.dPdx = tc.dPdx * s;
    tc.dPdy = tc.dPdy * s;
    tc.dgenerated_dx = tc.dgenerated_dx * s;
    tc.dgenerated_dy = tc.dgenerated_dy * s;
    for (int k = 0; k < 2; ++k) {
      tc.duv_dx[k] *= s;
      tc.duv_dy[k] *= s;
    }
  }

  // Transfer the differentials to the hit plane and express them in barycentric
  // and uv space (Igehy 1999, eq. 10-12); fills the context's footprint. At the first
  // hit with depth of field, the aperture's share is added first (fold_lens_differentials).
  // The texture coordinates' footprint (image filters, Bump) only for a shader with some texture or node
  // program (CompiledShader::reads_footprint): nothing else reads it.
  void transfer_differentials(Differentials &rd, const Vec3 &D, float t, ShadingData &sd, float spread) const {
    fold_lens_differentials(rd, D, t, sd.Ng);  // depth of field: the circle of confusion joins the footprint
    const bool textures = shaders->shader(sd.shader).reads_footprint;
    const float width = textures ? 0.5f * (length(rd.dPdx + rd.dDdx * t) + length(rd.dPdy + rd.dDdy * t)) : 0.0f;
    rd.dPdx = footprint_on_plane(rd.dPdx, rd.dDdx, D, t, sd.Ng);
    rd.dPdy = footprint_on_plane(rd.dPdy, rd.dDdy, D, t, sd.Ng);
    if (sd.object_space) sd.object_space->set_footprint(rd.dPdx, rd.dPdy, sd.ctx);
    float bx[2], by[2];
    barycentric_step(sd, rd.dPdx, bx);
    barycentric_step(sd, rd.dPdy, by);
    for (int k = 0; k < 2; ++k) {
      const float x = sd.duv1[k] * bx[0] + sd.duv2[k] * bx[1];
      const float y = sd.duv1[k] * by[0] + sd.duv2[k] * by[1];
      sd.ctx.duv_dx[k] = std::isfinite(x) ? x : 0.0f;
      sd.ctx.duv_dy[k] = std::isfinite(y) ? y : 0.0f;
    }
    if (textures) set_texture_footprint(rd, bx, by, width, sd);
    sd.ctx.spread_angle = spread;
    // Normal derivatives for specular propagation (stored in dn1/dn2 as per-pixel values).
    const Vec3 dNx = sd.dn1 * bx[0] + sd.dn2 * bx[1];
    const Vec3 dNy = sd.dn1 * by[0] + sd.dn2 * by[1];
    sd.dn1 = dNx - sd.N * dot(sd.N, dNx);
    sd.dn2 = dNy - sd.N * dot(sd.N, dNy);
  }
  // The footprint the texture nodes read: image textures filter over the uv footprint of the context, the
  // position and generated steps; the Bump node over its own offsets (set_bump_footprint).
  void set_texture_footprint(const Differentials &rd, const float bx[2], const float by[2], float width,
                             ShadingData &sd) const {
    for (int k = 0; k < 2; ++k) {
      sd.tc.duv_dx[k] = sd.ctx.duv_dx[k];  // image textures filter over the same footprint
      sd.tc.duv_dy[k] = sd.ctx.duv_dy[k];
    }
    sd.tc.dPdx = rd.dPdx;
    sd.tc.dPdy = rd.dPdy;
    sd.tc.dgenerated_dx = sd.dg1 * bx[0] + sd.dg2 * bx[1];
    sd.tc.dgenerated_dy = sd.dg1 * by[0] + sd.dg2 * by[1];
    scale_texture_footprint(sd.tc);
    set_bump_footprint(width, sd);
  }

  // Cycles' shadow terminator softening for diffuse closures whose normal N was perturbed (Chiang, Li and
  // Burley 2019, "Taming the Shadow Terminator", eq. 3-4; Cycles' bump_shadowing_term): with the point's
  // unperturbed shading normal Ns (Cycles 3.4 passes sd->N) and g = cos(Ns, wo) / (cos(N, wo) cos(Ns, N)), the
  // eval is scaled by 1 for g >= 1, 0 for g < 0, else -g^3 + g^2 + g, so light the unperturbed surface does not
  // face fades out smoothly.
  static float bump_shadowing(const ShadingData &sd, const ActiveClosure &c, const Vec3 &wo) {
    if (!c.own_frame || !c.leaf->frame.bump_shadowing || (c.N.x == sd.N.x && c.N.y == sd.N.y && c.N.z == sd.N.z))
      return 1.0f;
    const float denominator = dot(c.N, wo) * dot(sd.N, c.N);
    const float g = denominator != 0.0f ? dot(sd.N, wo) / denominator : 0.0f;
    if (g >= 1.0f) return 1.0f;
    if (!(g >= 0.0f)) return 0.0f;
    return -g * g * g + g * g + g;
  }

  // A step dP on the triangle in barycentric derivatives (least squares on the edges e1, e2; 0 when degenerate).
  static void barycentric_step(const ShadingData &sd, const Vec3 &dP, float out[2]) {
    out[0] = out[1] = 0.0f;
    const float a11 = dot(sd.e1, sd.e1), a12 = dot(sd.e1, sd.e2), a22 = dot(sd.e2, sd.e2);
    const float det = a11 * a22 - a12 * a12;
    if (!(det > 0.0f)) return;
    const float inv = 1.0f / det;
    const float r1 = dot(sd.e1, dP), r2 = dot(sd.e2, dP);
    out[0] = (a22 * r1 - a12 * r2) * inv;
    out[1] = (a11 * r2 - a12 * r1) * inv;
  }

  // The Bump node's offset points as Cycles 3.4 places them (its compact differential, expanded by
  // differential_from_compact): two orthonormal directions of Ng's plane (make_orthonormals: (1, 1, 1) x Ng,
  // or (-1, 1, 1) x Ng when Ng's components are equal, then Ng x that) scaled by the footprint's width before
  // its projection onto the surface (ray_dP + t ray_dD, here the mean of the two pixel steps); with the uv
  // and generated coordinates' changes over those steps.
  static void set_bump_footprint(float width, ShadingData &sd) {
    const Vec3 &n = sd.Ng;
    const Vec3 a = normalize(n.x != n.y || n.x != n.z ? Vec3(n.z - n.y, n.x - n.z, n.y - n.x)
                                                       : Vec3(n.z - n.y, n.x + n.z, -n.y - n.x));
    sd.tc.bump_dPdx = a * width;
    sd.tc.bump_dPdy = cross(n, a) * width;
    float bx[2], by[2];
    barycentric_step(sd, sd.tc.bump_dPdx, bx);
    barycentric_step(sd, sd.tc.bump_dPdy, by);
    for (int k = 0; k < 2; ++k) {
      const float x = sd.duv1[k] * bx[0] + sd.duv2[k] * bx[1], y = sd.duv1[k] * by[0] + sd.duv2[k] * by[1];
      sd.tc.bump_duv_dx[k] = std::isfinite(x) ? x : 0.0f;
      sd.tc.bump_duv_dy[k] = std::isfinite(y) ? y : 0.0f;
    }
    sd.tc.bump_dgenerated_dx = sd.dg1 * bx[0] + sd.dg2 * bx[1];
    sd.tc.bump_dgenerated_dy = sd.dg1 * by[0] + sd.dg2 * by[1];
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
      GlimmerShadingContext scratch;
      c.instance->eval(context_for(sd, c, scratch), wo, f, pdf);
      if (!is_finite(f) || !std::isfinite(pdf)) continue;
      out.f += f * c.weight * bump_shadowing(sd, c, wo);
      out.pdf += pdf * c.sample_weight;
    }
    return out;
  }

  // Radiance along a shadow ray from `P` toward `wi` over `dist`: 0 when
  // blocked, else the product of transparent closure weights passed through.
  Spectrum shadow_transmittance(const Vec3 &P, const Vec3 &Ng, const Vec3 &wi, float dist) const {
    Vec3 o = offset_ray_origin(P, Ng, wi);
    float remaining = std::isfinite(dist) ? dist * (1.0f - 1e-4f) - 1e-4f : kInf;
    if (!features.transparent) return accel->occluded(o, wi, remaining) ? Spectrum(0.0f) : Spectrum(1.0f);
    Spectrum T(1.0f);
    for (int i = 0; i <= scene.integrator.transparent_max_bounce; ++i) {
      SurfaceHit h;
      if (!accel->intersect(o, wi, 0.0f, remaining, h)) return T;
      const int shader = mesh_shader[h.mesh];
      if (!shaders->shader(shader).has_transparent) return Spectrum(0.0f);
      ShadingData hsd;
      setup_shading(h, wi, hsd);
      hsd.tc.path.camera = false;  // Light Path node: a shadow ray
      hsd.tc.path.shadow = true;
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
    float alpha = 1.0f;  // 1 - the throughput that escaped to a transparent film's background
  };

  // The MIS weight of emission a BSDF-sampled ray found (lamps, background, mesh lights),
  // against the light-sampling pdf of the same point: 1 after a singular scatter or the
  // camera, 0 when only light sampling counts emission, else the power heuristic.
  float emission_mis_weight(const PathState &ps, float light_pdf) const {
    if (ps.last_singular) return 1.0f;
    if (options.strategy == LightStrategy::LightOnly) return 0.0f;
    return options.strategy != LightStrategy::BsdfOnly ? power_heuristic(ps.mis_ray_pdf, light_pdf) : 1.0f;
  }

  // filter_glossy (Cycles): blur_pdf = filter_glossy * min_ray_pdf; below 1 the glossy
  // closures get alpha >= 0.5 sqrt(1 - blur_pdf) (nearest lower precomputed variant).
  void apply_filter_glossy(const PathState &ps, ClosureSet &cs) const {
    const float filter_glossy = scene.integrator.filter_glossy;
    if (!(filter_glossy > 0.0f) || ps.min_ray_pdf == std::numeric_limits<float>::max()) return;
    const float blur_pdf = filter_glossy * ps.min_ray_pdf;
    if (blur_pdf >= 1.0f) return;
    const float blur_alpha = 0.5f * std::sqrt(1.0f - blur_pdf);
    ShaderSystem::apply_filter_glossy(cs, static_cast<int>(blur_alpha / ClosureLeaf::kBlurStep));
  }

  // Next-event estimation: one light sample, the closure mixture's f and pdf toward it,
  // power-heuristic MIS against BSDF sampling, and the shadow ray's transmittance.
  // Returns the path's contribution (throughput included).
  Spectrum sample_direct_light(const ClosureSet &cs, const ShadingData &sd, const Spectrum &throughput, float total_sw,
                               float lu, float lv) const {
    const auto mixture = [&](const Vec3 &wi) {
      MixtureEval me = eval_mixture(cs, sd, wi);
      me.pdf /= total_sw;
      return me;
    };
    return direct_light_at(sd.ctx.P, sd.Ng, mixture, throughput, lu, lv);
  }
  // One light sample seen from P (surface normal Ng) through `bsdf(wi) -> MixtureEval` (f and the density
  // with which the path samples wi), MIS-weighted against that density, times the shadow ray's transmittance.
  // without_world / without_lamps: a sample drawn from the world / a lamp counts 0 (estimated otherwise there).
  template <class Bsdf>
  Spectrum direct_light_at(const Vec3 &P, const Vec3 &Ng, const Bsdf &bsdf, const Spectrum &throughput, float lu,
                           float lv, bool without_world = false, bool without_lamps = false) const {
    LightSample ls;
    if (!lights->sample(lu, lv, P, ls) || !(ls.pdf > 0.0f) || (without_world && ls.world) ||
        (without_lamps && ls.lamp))
      return Spectrum(0.0f);
    const MixtureEval me = bsdf(ls.wi);
    if (is_zero(me.f)) return Spectrum(0.0f);
    const bool use_bsdf_emission = options.strategy != LightStrategy::LightOnly;
    const float w = (ls.delta || !use_bsdf_emission) ? 1.0f : power_heuristic(ls.pdf, me.pdf);
    const Spectrum contribution = throughput * me.f * ls.radiance * (w / ls.pdf);
    if (is_zero(contribution)) return contribution;
    return contribution * shadow_transmittance(P, Ng, ls.wi, ls.dist);
  }

  // Picks a closure by sample weight from `pick` in [0, total_sw): kTransparent for the
  // transparent pass-through, -1 for none. On return `pick` is the offset within the chosen
  // closure's share [0, sample_weight), so the caller can rescale and reuse it.
  static constexpr int kTransparent = -2;
  static int pick_closure(const ClosureSet &cs, float &pick, float transparent_weight) {
    if (pick < transparent_weight) return kTransparent;
    pick -= transparent_weight;
    int chosen = -1;
    for (int i = 0; i < cs.count; ++i) {
      if (cs.closures[i].sample_weight <= 0.0f) continue;
      chosen = i;
      if (pick < cs.closures[i].sample_weight) break;
      pick -= cs.closures[i].sample_weight;
    }
    return chosen;
  }

  // Sum of the closures' emission toward the viewer.
  static Spectrum surface_emission(const ClosureSet &cs, const GlimmerShadingContext &ctx) {
    Spectrum emission(0.0f);
    for (int i = 0; i < cs.count; ++i)
      if (cs.closures[i].leaf->emissive) emission += cs.closures[i].leaf->instance->emit(ctx) * cs.closures[i].weight;
    return emission;
  }

  // Albedo, normal and depth AOVs at the first non-transparent surface.
  static void write_first_hit_aovs(const ClosureSet &cs, const ShadingData &sd, float depth, PixelAov &aov) {
    aov.normal = sd.N;
    aov.depth = depth;
    for (int i = 0; i < cs.count; ++i) {
      const ActiveClosure &c = cs.closures[i];
      if (c.leaf->emissive || !c.leaf->instance) continue;
      GlimmerShadingContext scratch;
      aov.albedo += c.leaf->instance->albedo(context_for(sd, c, scratch)) * c.weight;
    }
  }

  // Ray differentials for the next segment: specular propagation after a singular
  // scatter, else a cone widened by beta = 2 alpha (Wang 2018, sec. 4.6). A singular sample
  // that reports a width (a thin pane's walk: many rough events as one sample) widens too.
  void next_differentials(Differentials &rd, const Vec3 &D, const Vec3 &wo, const ShadingData &sd,
                          const GlimmerSample &s, bool singular, float pixel_spread, PathState &ps) const {
    if (singular && !(s.roughness > 0.0f)) {
      propagate_specular(rd, D, wo, sd.N, sd.Ng, sd.dn1, sd.dn2, s.eta);
      return;
    }
    const float alpha = std::clamp(s.roughness, 0.0f, 1.0f);
    ps.spread += 2.0f * alpha;
    const float width_dir = pixel_spread + ps.spread;
    const Frame f = Frame::from_normal(wo);
    rd.dDdx = f.s * width_dir;
    rd.dDdy = f.t * width_dir;
  }

  // Russian roulette after min_bounce (Cycles' path_state_continuation_probability):
  // survive with q = min(sqrt(max throughput), 1) and divide by it.
  static bool survives_russian_roulette(const PathState &ps, const BounceLimits &limits, float rr,
                                        Spectrum &throughput) {
    if (ps.bounce <= limits.min_bounce) return true;
    const float q = std::min(std::sqrt(max_component(abs(throughput))), 1.0f);
    if (q <= 0.0f || rr >= q) return false;
    throughput /= q;
    return true;
  }

  // True when a non-singular closure can take a light sample (NEE).
  static bool has_smooth_closure(const ClosureSet &cs) {
    for (int i = 0; i < cs.count; ++i)
      if (cs.closures[i].sample_weight > 0.0f && !cs.closures[i].leaf->singular) return true;
    return false;
  }

  // The path's counters and seed in the shading context, and (ABI 2.9) the limits PathState::advance applies to them.
  void set_path_context(const PathState &ps, const BounceLimits &limits, uint32_t path_seed, ShadingData &sd) const {
    GlimmerShadingContext &ctx = sd.ctx;
    ctx.bounce = static_cast<uint32_t>(ps.bounce);
    ctx.diffuse_bounce = static_cast<uint32_t>(ps.diffuse_bounce);
    ctx.glossy_bounce = static_cast<uint32_t>(ps.glossy_bounce);
    ctx.transmission_bounce = static_cast<uint32_t>(ps.transmission_bounce);
    ctx.path_seed = path_seed;
    const auto limit = [&](int v) { return options.bounce_limits_in_context ? static_cast<uint32_t>(std::max(v, 0)) : 0u; };
    ctx.max_bounce = limit(limits.bounce);
    ctx.max_glossy_bounce = limit(limits.glossy);
    ctx.max_transmission_bounce = limit(limits.transmission);
  }

  // Samples closure `chosen` and updates the throughput with the one-sample MIS
  // estimate over the mixture (singular: the delta weight over its pick
  // probability), the MIS state and last_singular. False ends the path.
  bool scatter(const ClosureSet &cs, const ShadingData &sd, int chosen, const float r3[3], float total_sw,
               Spectrum &throughput, PathState &ps, GlimmerSample &s, uint64_t &nan_count) const {
    const ActiveClosure &c = cs.closures[chosen];
    GlimmerShadingContext scratch;
    const uint32_t label = c.instance->sample(context_for(sd, c, scratch), r3, s);
    if (label == GLIMMER_LABEL_NONE || !(s.pdf > 0.0f) || !std::isfinite(s.pdf)) return false;
    const Vec3 wo = normalize(Vec3(s.wo));
    const Spectrum s_eval = Spectrum(s.eval[0], s.eval[1], s.eval[2]) * bump_shadowing(sd, c, wo);
    if (!is_finite(s_eval)) {
      ++nan_count;
      return false;
    }
    const bool singular = (label & GLIMMER_LABEL_SINGULAR) != 0;
    if (singular) {
      throughput *= s_eval * c.weight * (total_sw / c.sample_weight);
    } else {
      MixtureEval me = eval_mixture(cs, sd, wo, chosen);
      me.f += s_eval * c.weight;
      me.pdf = (me.pdf + s.pdf * c.sample_weight) / total_sw;
      if (!(me.pdf > 0.0f)) return false;
      throughput *= me.f / me.pdf;
      ps.mis_ray_pdf = me.pdf;
      ps.min_ray_pdf = std::min(ps.min_ray_pdf, me.pdf);
    }
    if (!is_finite(throughput)) {
      ++nan_count;
      return false;
    }
    if (is_zero(throughput)) return false;
    ps.last_singular = singular;
    s.label = label;
    return true;
  }

  // ---- Path stages (Cycles' integrator kernels) ----
  // The ray of the current path segment with its differentials.
  struct PathRay {
    Vec3 org{0.0f}, D{0.0f, 0.0f, 1.0f};
    float tmin = 0.0f, tmax = kInf;
    Differentials rd;
    float cam_dir_z = 1.0f;      // cosine of the camera ray to the view axis (depth = t * cam_dir_z)
    float pixel_spread = 0.0f;   // the camera ray's angular width per pixel
  };
  // What one path accumulates: radiance, throughput, the non-finite contributions dropped.
  struct PathRadiance {
    Spectrum L{0.0f}, throughput{1.0f};
    uint64_t *nan_count = nullptr;
  };

  // The camera ray through film position (x, y) (Cycles' integrate_camera_ray), clipped to the camera's
  // near and far planes along its view axis; (lens_u, lens_v) picks the point on the aperture.
  PathRay camera_path_ray(float x, float y, float lens_u, float lens_v) const {
    PathRay ray;
    camera_ray(scene.camera, camera, x, y, ray.org, ray.D, ray.rd, ray.cam_dir_z, lens_u, lens_v);
    ray.tmin = scene.camera.nearclip / std::max(ray.cam_dir_z, 1e-6f);
    ray.tmax = scene.camera.farclip / std::max(ray.cam_dir_z, 1e-6f);
    ray.pixel_spread = std::max(length(ray.rd.dDdx), length(ray.rd.dDdy));
    return ray;
  }

  // The camera ray of one sample: filter-importance-sampled film position (film_uv: the camera set), lens point
  // with depth of field.
  PathRay sample_camera_ray(int px, int py, const float film_uv[2], const PixelSampler &sampler) const {
    const float ox = filter.offset(film_uv[0]), oy = filter.offset(film_uv[1]);
    float lens_u = 0.5f, lens_v = 0.5f;
    if (scene.camera.aperture_size > 0.0f) sampler.get2(kSetLens, lens_u, lens_v);
    return camera_path_ray(px + 0.5f + ox, py + 0.5f + oy, lens_u, lens_v);
  }

  // Adds a contribution found at bounce `at_bounce`, clamped (sample_clamp_direct / _indirect); non-finite
  // ones are dropped and counted.
  void add_contribution(PathRadiance &pr, const Spectrum &contribution, int at_bounce) const {
    if (!is_finite(contribution)) {
      ++*pr.nan_count;
      return;
    }
    const auto &integ = scene.integrator;
    pr.L += clamp_contribution(contribution, at_bounce > 0 ? integ.sample_clamp_indirect : integ.sample_clamp_direct);
  }

  // Emission Le found by the ray, weighted against light sampling (pdf light_pdf of the same point).
  void add_emission(PathRadiance &pr, const PathState &ps, const Spectrum &Le, float light_pdf) const {
    const float w = emission_mis_weight(ps, light_pdf);
    if (w > 0.0f) add_contribution(pr, pr.throughput * Le * w, ps.bounce);
  }

  bool use_nee() const { return options.strategy != LightStrategy::BsdfOnly; }

  // The world seen through the exit lobe the path just left (integrate_exit_lobe): one cone lookup.
  // A mixture (ABI 2.7) is looked up lobe by lobe: the weighted sum of its lobes' cone lookups.
  struct ExitWorld {
    bool active = false;
    int count = 0;
    Vec3 axis[ExitLobeMixture::kMaxLobes];
    double kappa[ExitLobeMixture::kMaxLobes] = {};  // the lobes' sharpness: the cone made in lookup (exit_world_cone)
    float weight[ExitLobeMixture::kMaxLobes] = {};
    bool lamps = false;  // the lamps were integrated against the lobe at the exit: the segment's lamp hits count 0
    // A mixture's lobe gets spiral points in proportion to its weight (at least kMixtureConePointsMin): 64 per lobe
    // made the 10-lobe mixture's world 640 lookups per escaped exit ray, ~70 % of an sg render's time under a
    // textured world (docs/history/frosted_glass_sessions.md "Error vs time on a fair scene"). One lobe keeps all 64.
    static constexpr int kMixtureConePointsMin = 16;
    Spectrum lookup(const EnvironmentCone &env, const ShaderSystem &shaders) const {
      Spectrum sum(0.0f);
      for (int k = 0; k < count; ++k) {
        const int points = count == 1 ? EnvironmentCone::kConePoints
                                      : std::clamp(int(std::ceil(float(EnvironmentCone::kConePoints) * weight[k])),
                                                   kMixtureConePointsMin, EnvironmentCone::kConePoints);
        // The cap's half-angle, radians; made here, only for an exit ray that escapes (session 29: in
        // integrate_exit_lobe it was made for every exit, a log1p, an expm1 and an asin per lobe; the same value).
        const float cone = static_cast<float>(exit_world_cone(kappa[k]));
        sum += env.lookup(shaders, axis[k], cone, points) * weight[k];
      }
      return sum;
    }
  };
  // Lamps (spheres, area lights) crossed before the surface at t_hit and, when the ray escapes, the sun disk
  // and the world (Cycles' integrate_light and integrate_background); as in Cycles lamps do not block the ray.
  // exit_world: the ray left an exit lobe whose world is one cone lookup (integrate_exit_lobe).
  void integrate_lights_and_background(const PathRay &ray, float t_hit, bool hit_surface, const PathState &ps,
                                       const ExitWorld &exit_world, PathRadiance &pr) const {
    if (!exit_world.lamps) {
      LightHits lhs;
      lights->intersect(ray.org, ray.D, t_hit, hit_surface, ps.bounce == 0, lhs);
      for (int i = 0; i < lhs.count; ++i) add_emission(pr, ps, lhs.hits[i].radiance, lhs.hits[i].pdf);
    }
    if (hit_surface || ps.transparent_background || !shaders->has_background()) return;
    if (exit_world.active)
      add_contribution(pr, pr.throughput * exit_world.lookup(environment_cone, *shaders), ps.bounce);
    else
      add_emission(pr, ps, shaders->background(ray.D), use_nee() ? lights->background_pdf(ray.D) : 0.0f);
  }

  // The shading point of a hit: geometry, footprint from the ray differentials, the path's counters, and
  // the closures of its shader (with filter_glossy applied).
  void shade_surface(const SurfaceHit &hit, PathRay &ray, const PathState &ps, const BounceLimits &limits,
                     uint32_t path_seed, ShadingData &sd, ClosureSet &cs) const {
    setup_shading(hit, ray.D, sd);
    sd.tc.path = nodes::path_info(ps.last_label, hit.t, ps.bounce, ps.diffuse_bounce, ps.glossy_bounce,
                                  ps.transparent_bounce, ps.transmission_bounce);
    transfer_differentials(ray.rd, ray.D, hit.t, sd, ps.spread);
    set_path_context(ps, limits, path_seed, sd);
    shaders->evaluate(sd.shader, sd.tc, cs);
    apply_filter_glossy(ps, cs);
  }

  // Emission of the surface (mesh lights), MIS against the light-sampling pdf (Cycles'
  // integrate_surface_emission).
  void integrate_surface_emission(const ClosureSet &cs, const ShadingData &sd, const SurfaceHit &hit,
                                  const PathRay &ray, const PathState &ps, PathRadiance &pr) const {
    const Spectrum emission = surface_emission(cs, sd.ctx);
    if (is_zero(emission)) return;
    add_emission(pr, ps, emission,
                 use_nee() ? lights->triangle_pdf(hit.mesh, hit.prim, ray.org, sd.ctx.P, sd.Ng, ray.D) : 0.0f);
  }

  // Next-event estimation at the surface (Cycles' integrate_surface_direct_light); skipped when only
  // singular closures are present.
  void integrate_surface_direct_light(const ClosureSet &cs, const ShadingData &sd, float total_sw,
                                      const float light_rand[2], const PathState &ps, PathRadiance &pr) const {
    if (!use_nee() || !has_smooth_closure(cs) || lights->count() == 0) return;
    const Spectrum direct = sample_direct_light(cs, sd, pr.throughput, total_sw, light_rand[0], light_rand[1]);
    if (!is_zero(direct)) add_contribution(pr, direct, ps.bounce);
  }

  // The scatter integrate_surface_bsdf_bounce took, for integrate_exit_state.
  struct ExitStateScatter {
    int chosen = -1;       // the closure sampled (-1: none, or the transparent pass-through)
    Spectrum scale{0.0f};  // the throughput before the scatter x the closure's weight / its pick probability
    int bounce = 0;        // the scatter's bounce (before it)
  };

  // ABI 2.4: a moved sample drawn from an exit lobe (frosted_glass sg: where light leaves the object). The lobe
  // is the BSDF at the exit point: f = the sample's weight x its density p (glimmer/exit_lobe.h), so the
  // singular sample's throughput (already applied) carries f / p and next-event estimation there sees p alone.
  //  - the world (RenderOptions::exit_lobe_environment): when the continued path escapes, the world seen through
  //    the lobe is one lookup of the pre-filtered environment along the lobe's axis over the cap that matches
  //    the lobe (exit_world_cone), counted whole (de Rousiers 2012's pre-convolved environment: the lighting
  //    integral over the lobe as a lookup, not a sampled direction); the world is then not light-sampled here.
  //    Visibility stays sampled: the lookup counts only when the continued ray escapes.
  //  - the lights (exit_lobe_nee): one light sample from the exit point, MIS (power heuristic) with the continued
  //    path, whose emission hits are then weighted against light sampling at p(wo) instead of counted whole.
  // ABI 2.7: with GLIMMER_SAMPLE_EXIT_MIXTURE the lobe is the whole mixture (glimmer::ExitLobeMixture, all lobes
  // at the sample's origin): its density for NEE and MIS, its lobes' lamp integrals and cone lookups summed by
  // weight, so that the host's estimators do not see which lobe drew wo. Otherwise the one lobe of ABI 2.4.
  // Session 24: a moved exit-lobe sample with an exit state (frosted_glass sg's rough pane) has its lamps valued by
  // the closure's eval_exit (the exact exit, ValuedExitLobe), the mixture their proposal (exact_lamps below).
  // Session 31 (frostedcost31): the flag test inline at the call (one call per path vertex, 92 % of them not a moved
  // exit-lobe sample: 23 instructions each for the call's prologue and epilogue), the rest out of line.
  [[gnu::always_inline]] void integrate_exit_lobe(const ClosureSet &cs, const ShadingData &sd,
                                                  const ExitStateScatter &xs, const GlimmerSample &s, const Vec3 &wo,
                                                  const PixelSampler &sampler, PathState &ps, PathRadiance &pr,
                                                  ExitWorld &exit_world) const {
    exit_world.active = false;
    exit_world.lamps = false;
    if (!(s.flags & GLIMMER_SAMPLE_EXIT_LOBE) || !(s.flags & GLIMMER_SAMPLE_MOVED)) return;
    integrate_moved_exit_lobe(cs, sd, xs, s, wo, sampler, ps, pr, exit_world);
  }
  [[gnu::noinline]] void integrate_moved_exit_lobe(const ClosureSet &cs, const ShadingData &sd,
                                                   const ExitStateScatter &xs, const GlimmerSample &s,
                                                   const Vec3 &wo, const PixelSampler &sampler, PathState &ps,
                                                   PathRadiance &pr, ExitWorld &exit_world) const {
    const Vec3 n = normalize(Vec3(s.origin_Ng));
    ExitLobeMixture lobe;
    if (!is_finite(n) || !exit_mixture_of(s, n, lobe)) return;
    exit_world.active = options.exit_lobe_environment;
    exit_world.count = lobe.count;
    for (int k = 0; k < lobe.count; ++k) {
      exit_world.axis[k] = lobe.lobe[k].axis;
      exit_world.kappa[k] = lobe.lobe[k].kappa;
      exit_world.weight[k] = static_cast<float>(lobe.weight[k]);
    }
    if (!options.exit_lobe_nee || !use_nee() || lights->count() == 0) return;
    for (int k = 0; k < lobe.count; ++k) lobe.lobe[k].below = vmf_fraction_below(lobe.lobe[k].axis, lobe.lobe[k].kappa, n);
    lobe.prepare();
    const float continued_pdf = static_cast<float>(lobe.pdf(wo));
    if (!(continued_pdf > 0.0f) || !std::isfinite(continued_pdf)) return;
    float lu, lv;  // a light set of its own per vertex (the vertex's light set served its entry point)
    sampler.get2(exit_light_set(ps.sample_vertex()), lu, lv);
    exit_world.lamps = options.exit_lobe_lamps && lights->lamp_count() > 0;
    if (exit_world.lamps) {
      ExactExit exact;
      if (exact_lamps(cs, sd, xs, s, exact))
        integrate_exit_lamps(Vec3(s.origin), n, ValuedExitLobe{&lobe, &ExactExit::value, &exact}, lu, lv, sampler,
                             ps, pr);
      else
        integrate_exit_lamps(Vec3(s.origin), n, lobe, lu, lv, sampler, ps, pr);
    }
    const auto exit_bsdf = [&](const Vec3 &wi) {
      MixtureEval me;
      me.pdf = static_cast<float>(lobe.pdf(wi));
      me.f = Spectrum(me.pdf);
      return me;
    };
    light_sample_at_exit(Vec3(s.origin), n, exit_bsdf, pr.throughput, ps.bounce, lu, lv, continued_pdf, ps, pr,
                         exit_world.active, exit_world.lamps);
  }

  // The tail of integrate_exit_lobe and integrate_exit_state: one light sample from exit point P (normal n) with
  // the exit's BSDF (its f cos and pdf; the world or the lamps left out when the exit integrates them itself),
  // added at `bounce` with `scale` (the path's throughput up to the exit), and the continued path's emission hits
  // weighted against light sampling at continued_pdf (the exit BSDF's pdf at the continued direction) from here on.
  template <class ExitBsdf>
  void light_sample_at_exit(const Vec3 &P, const Vec3 &n, const ExitBsdf &exit_bsdf, const Spectrum &scale,
                            int bounce, float lu, float lv, float continued_pdf, PathState &ps, PathRadiance &pr,
                            bool without_world = false, bool without_lamps = false) const {
    const Spectrum direct = direct_light_at(P, n, exit_bsdf, scale, lu, lv, without_world, without_lamps);
    if (!is_zero(direct)) add_contribution(pr, direct, bounce);
    ps.last_singular = false;
    ps.mis_ray_pdf = continued_pdf;
  }

  // The lobes of exit sample s about the exit normal n: the whole mixture (ABI 2.7) or the sample's one lobe, with
  // normalised weights (invalid lobes dropped); `below` not set (only NEE needs it). False: no valid lobe.
  static bool exit_mixture_of(const GlimmerSample &s, const Vec3 &n, ExitLobeMixture &m) {
    const auto add = [&](const Vec3 &axis_in, float kappa, float weight) {
      const Vec3 axis = normalize(axis_in);
      if (!is_finite(axis) || !(kappa > 0.0f) || !std::isfinite(kappa) || !(weight > 0.0f) || !std::isfinite(weight))
        return;
      m.lobe[m.count] = ExitLobe{axis, std::max(double(kappa), 1e-6), n, 0.0};
      m.weight[m.count++] = weight;
    };
    m.count = 0;
    if ((s.flags & GLIMMER_SAMPLE_EXIT_MIXTURE) && s.exit_mixture != nullptr) {
      const GlimmerExitMixture &x = *s.exit_mixture;
      const int count = static_cast<int>(std::min<uint32_t>(x.count, GLIMMER_EXIT_MAX_LOBES));
      for (int k = 0; k < count && m.count < ExitLobeMixture::kMaxLobes; ++k)
        add(Vec3(x.axis[k]), x.sharpness[k], x.weight[k]);
    }
    if (m.count == 0) add(Vec3(s.lobe_axis), s.lobe_sharpness, 1.0f);
    m.normalize();
    return m.count > 0;
  }

  // The lamps seen from exit point P (exit surface normal n) through the exit lobe (RenderOptions::exit_lobe_lamps):
  // each lamp integrated against the lobe (LightSet::lamp_through_lobe: stratified over the lamp and the lobe by
  // (lu, lv), balance heuristic), its visibility one shadow ray toward a point picked in proportion to its share.
  // The light of a lamp through the glass is then a low-noise integral, not one sampled direction (de Rousiers
  // 2012's SG lights, eq. 14/15, with the exact lamp and lobe instead of their SG product).
  // The exact exit of a moved exit-lobe sample's state (ValuedExitLobe's value: eval_exit's f cos, grey).
  struct ExactExit {
    const host::ClosureInstance *instance = nullptr;
    const GlimmerShadingContext *ctx = nullptr;
    const GlimmerExitState *state = nullptr;
    static double value(const void *self, const Vec3 &w) {
      const ExactExit &x = *static_cast<const ExactExit *>(self);
      Spectrum f(0.0f);
      float pdf = 0.0f;
      x.instance->eval_exit(*x.ctx, *x.state, w, f, pdf);
      const double v = average(f);
      return v > 0.0 && std::isfinite(v) ? v : 0.0;
    }
    GlimmerShadingContext scratch;
  };
  bool exact_lamps(const ClosureSet &cs, const ShadingData &sd, const ExitStateScatter &xs, const GlimmerSample &s,
                   ExactExit &x) const {
    if (!(s.flags & GLIMMER_SAMPLE_EXIT_STATE) || s.exit_state == nullptr || xs.chosen < 0) return false;
    const ActiveClosure &c = cs.closures[xs.chosen];
    if (!c.instance || !c.instance->has_eval_exit()) return false;
    x.instance = c.instance;
    x.ctx = &context_for(sd, c, x.scratch);
    x.state = s.exit_state;
    return true;
  }
  template <class Lobe>
  void integrate_exit_lamps(const Vec3 &P, const Vec3 &n, const Lobe &lobe, float lu, float lv,
                            const PixelSampler &sampler, const PathState &ps, PathRadiance &pr) const {
    float pick, unused;
    sampler.get2(exit_lamp_set(ps.sample_vertex()), pick, unused);
    for (int k = 0; k < lights->lamp_count(); ++k) {
      LampEstimate e;
      if (!lights->lamp_through_lobe(k, P, lobe, lu, lv, pick, e)) continue;
      const Spectrum c = pr.throughput * e.value;
      if (!is_zero(c)) add_contribution(pr, c * shadow_transmittance(P, n, e.wi, e.dist), ps.bounce);
    }
  }


  // ABI 2.8: a singular sample that stays at the shading point with an exit state (frosted_glass method=path's
  // thin pane: the walk's last interface). One light sample at the shading point through that interface
  // (eval_exit's f cos, which carries the walk's weight; the shadow ray leaves on the light's side), power
  // heuristic against eval_exit's pdf, and the continued path's emission hits weighted against eval_exit's pdf at
  // wo instead of counted whole. Both weights are functions of the state and the direction alone, so they sum to
  // 1 for every direction: unbiased for any such pdf (docs/frosted_glass.md "Light sampling at a pane's exit").
  void integrate_exit_state(const ClosureSet &cs, const ShadingData &sd, const ExitStateScatter &xs,
                            const GlimmerSample &s, const Vec3 &wo, const PixelSampler &sampler, PathState &ps,
                            PathRadiance &pr) const {
    if (!(s.flags & GLIMMER_SAMPLE_EXIT_STATE) || moved(s) || s.exit_state == nullptr || xs.chosen < 0) return;
    if (!options.exit_state_nee || !use_nee() || lights->count() == 0) return;
    const ActiveClosure &c = cs.closures[xs.chosen];
    if (!c.instance || !c.instance->has_eval_exit()) return;
    GlimmerShadingContext scratch;
    const GlimmerShadingContext &ctx = context_for(sd, c, scratch);
    const auto exit_bsdf = [&](const Vec3 &w) {
      MixtureEval me;
      c.instance->eval_exit(ctx, *s.exit_state, w, me.f, me.pdf);
      if (!is_finite(me.f) || !std::isfinite(me.pdf)) return MixtureEval{};
      me.f *= bump_shadowing(sd, c, w);
      return me;
    };
    const float continued_pdf = exit_bsdf(wo).pdf;
    if (!(continued_pdf > 0.0f)) return;
    float lu, lv;  // a light set of its own per vertex (the vertex's light set served the surface's own NEE)
    sampler.get2(exit_light_set(ps.sample_vertex()), lu, lv);
    light_sample_at_exit(sd.ctx.P, sd.Ng, exit_bsdf, xs.scale, xs.bounce, lu, lv, continued_pdf, ps, pr);
  }

  // ABI 2.3: the closure moved the path (e.g. to where light leaves a frosted object).
  static bool moved(const GlimmerSample &s) { return (s.flags & GLIMMER_SAMPLE_MOVED) != 0; }
  // The next segment after sample s: from the surface, or from the sample's origin when it moved the path.
  static bool continue_after_sample(PathRay &ray, const ShadingData &sd, const GlimmerSample &s, const Vec3 &wo) {
    if (!moved(s)) {
      continue_ray(ray, sd, wo);
      return true;
    }
    ray.org = offset_ray_origin(Vec3(s.origin), Vec3(s.origin_Ng), wo);
    ray.D = wo;
    ray.tmin = 0.0f;
    ray.tmax = kInf;
    return is_finite(ray.org);
  }

  // The next segment starts at the surface, offset along Ng toward `dir`.
  static void continue_ray(PathRay &ray, const ShadingData &sd, const Vec3 &dir) {
    ray.org = offset_ray_origin(sd.ctx.P, sd.Ng, dir);
    ray.D = dir;
    ray.tmin = 0.0f;
    ray.tmax = kInf;
  }

  // Picks a closure (or the transparent pass-through) with x of the bounce's BSDF set, rescaled and reused for
  // the direction, and scatters: the next ray, throughput and path state (Cycles'
  // integrate_surface_bsdf_bssrdf_bounce). False ends the path.
  // xs: the closure picked, the path's throughput times its weight over its pick probability, and the bounce
  // (for an exit state, integrate_exit_state).
  bool integrate_surface_bsdf_bounce(const ClosureSet &cs, const ShadingData &sd, const float bsdf_rand[4],
                                     float transparent_weight, float total_sw, const BounceLimits &limits,
                                     PathState &ps, PathRadiance &pr, PathRay &ray, GlimmerSample &s,
                                     ExitStateScatter &xs) const {
    float pick = bsdf_rand[0] * total_sw;
    const int chosen = pick_closure(cs, pick, transparent_weight);
    xs.chosen = -1;
    if (chosen == kTransparent) {
      // Transparent: continue straight on; does not count as a bounce.
      pr.throughput *= cs.transparent / (transparent_weight / total_sw);
      ps.advance_transparent(limits);
      continue_ray(ray, sd, ray.D);
      return true;
    }
    if (chosen < 0) return false;
    const float r3[3] = {std::clamp(pick / cs.closures[chosen].sample_weight, 0.0f, 0x1.fffffep-1f), bsdf_rand[1],
                         bsdf_rand[2]};
    xs.chosen = chosen;
    xs.scale = pr.throughput * cs.closures[chosen].weight * (total_sw / cs.closures[chosen].sample_weight);
    xs.bounce = ps.bounce;
    if (!scatter(cs, sd, chosen, r3, total_sw, pr.throughput, ps, s, *pr.nan_count)) return false;
    const Vec3 wo = normalize(Vec3(s.wo));
    ps.advance(s.label, limits);
    next_differentials(ray.rd, ray.D, wo, sd, s, ps.last_singular && !moved(s), ray.pixel_spread, ps);
    return continue_after_sample(ray, sd, s, wo);
  }

  // One path (Cycles' integrator loop: intersect_closest, shade_light / shade_background, shade_surface).
  // `start`: the path's camera set (film position and vertex 0's BSDF numbers, jointly stratified) and vertex
  // 0's light set (docs/architecture.md "Sample dimensions"), drawn by trace_row with those of other paths.
  // It also holds the path's sampler, path seed (hash_u32x3(seed, pixel, sample)) and vertex 1's set start.
  // `nee`: light samples are taken (use_nee() and the scene has lights), decided once per row by trace_row.
  Spectrum trace_path(int px, int py, const PathStart &start, bool nee, PixelAov &aov, uint64_t &nan_count) const {
    const BounceLimits limits(scene.integrator);
    const PixelSampler sampler(start);
    sampler_draw::NextVertex next = start.vertex1;
    const uint32_t path_seed = start.path_seed;
    const float film_uv[2] = {start.film()[0], start.film()[1]};
    float bsdf_rand[4] = {start.bsdf()[0], start.bsdf()[1], start.bsdf()[2], start.bsdf()[3]};
    float light_rand[2] = {start.light()[0], start.light()[1]};
    PathRay ray = sample_camera_ray(px, py, film_uv, sampler);
    PathRadiance pr;
    pr.nan_count = &nan_count;
    PathState ps;
    ps.transparent_background = scene.background.transparent;
    bool first_hit = true;
    ExitWorld exit_world;  // set by integrate_exit_lobe for the segment after an exit lobe
    for (int step = 0; step < 4 * 1024; ++step) {
      SurfaceHit hit;
      const bool hit_surface = accel->intersect(ray.org, ray.D, ray.tmin, ray.tmax, hit);
      integrate_lights_and_background(ray, hit_surface ? hit.t : kInf, hit_surface, ps, exit_world, pr);
      if (!hit_surface) {
        if (ps.transparent_background) aov.alpha -= average(pr.throughput);
        break;
      }
      ShadingData sd;
      ClosureSet cs;
      shade_surface(hit, ray, ps, limits, path_seed, sd, cs);
      integrate_surface_emission(cs, sd, hit, ray, ps, pr);
      if (first_hit && !(cs.count == 0 && !is_zero(cs.transparent))) {
        first_hit = false;
        if (options.aovs) write_first_hit_aovs(cs, sd, hit.t * ray.cam_dir_z, aov);  // else the film drops them
      }
      if (ps.terminate_next) break;
      // The vertex's 6D set: light (u, v), BSDF x, y (closure pick, then the closure's direction), z (the
      // closure's third number), rr (Russian roulette); light numbers only for a light sample, rr only where
      // roulette can fire (vertex 0's from the path start above; every iteration that goes on advances the vertex).
      if (ps.sample_vertex() > 0)  // each vertex's set start drawn ahead (`next`: vertex 1's with the path start)
        sampler.get_vertex(ps.sample_vertex(), next, bsdf_rand, light_rand, nee && has_smooth_closure(cs),
                           ps.bounce > limits.min_bounce);
      if (!survives_russian_roulette(ps, limits, bsdf_rand[3], pr.throughput)) break;
      const float transparent_weight = std::fabs(average(cs.transparent));
      const float total_sw = cs.sum_sample_weight + transparent_weight;
      if (total_sw <= 0.0f) break;
      integrate_surface_direct_light(cs, sd, total_sw, light_rand, ps, pr);
      GlimmerSample s = glimmer_blank_sample();
      GlimmerExitMixture exit_mixture;  // ABI 2.7: written by a closure that hands over a whole exit mixture
      s.exit_mixture = &exit_mixture;
      GlimmerExitState exit_state;  // ABI 2.8: written by a closure that hands over its last scatter
      s.exit_state = options.exit_state_nee && nee ? &exit_state : nullptr;
      ExitStateScatter xs;
      if (!integrate_surface_bsdf_bounce(cs, sd, bsdf_rand, transparent_weight, total_sw, limits, ps, pr, ray, s,
                                         xs))
        break;
      integrate_exit_lobe(cs, sd, xs, s, ray.D, sampler, ps, pr, exit_world);
      integrate_exit_state(cs, sd, xs, s, ray.D, sampler, ps, pr);
    }
    return pr.L;
  }

  // The samples [s, s + count) of the pixels [xb, xe) of row y, pixel by pixel and each pixel's in sample order,
  // into the film. The path starts are drawn kPathStartBatch at a time (draw_path_starts: the same values as
  // drawn path by path), so their dependent chains overlap instead of each stalling the start of its path.
  void trace_row(int y, int xb, int xe, int s, int count, Film &film, uint64_t &nans, uint64_t &traced) const {
    const bool nee = use_nee() && lights->count() > 0;
    const int items = (xe - xb) * count;
    int x = xb, k = 0;  // the next item to draw
    for (int j0 = 0; j0 < items; j0 += kPathStartBatch) {
      const int n = std::min(kPathStartBatch, items - j0);
      uint32_t pixels[kPathStartBatch], samples[kPathStartBatch];
      int xs[kPathStartBatch];
      for (int i = 0; i < n; ++i) {
        xs[i] = x;
        pixels[i] = static_cast<uint32_t>(y) * static_cast<uint32_t>(width) + static_cast<uint32_t>(x);
        samples[i] = static_cast<uint32_t>(s + k);
        if (++k == count) k = 0, ++x;
      }
      PathStart starts[kPathStartBatch];
      draw_path_starts(seed, pixels, samples, n, nee, starts);
      for (int i = 0; i < n; ++i) {
        PixelAov aov;
        const Spectrum L = trace_path(xs[i], y, starts[i], nee, aov, nans);
        if (!film.add(static_cast<size_t>(y) * width + xs[i], L, aov.alpha, aov.albedo, aov.normal, aov.depth))
          ++nans;  // a finite sample can still overflow the pixel's sum: dropped and counted
        ++traced;
      }
    }
  }

  // True when every closure at the shading point scatters singularly (probe() follows those).
  bool all_singular(const ClosureSet &cs, const ShadingData &sd) const {
    bool singular = cs.count > 0;
    for (int i = 0; i < cs.count; ++i)
      if (!cs.closures[i].leaf->singular && !cs.closures[i].leaf->emissive) {
        GlimmerSample s{};
        const float r3[3] = {0.5f, 0.5f, 0.5f};
        GlimmerShadingContext scratch;
        const uint32_t label = cs.closures[i].leaf->instance->sample(context_for(sd, cs.closures[i], scratch), r3, s);
        if (!(label & GLIMMER_LABEL_SINGULAR)) singular = false;
      }
    return singular;
  }

  // probe(): the camera ray through (x, y) (no jitter, lens centre), shaded by the path stages, followed
  // through singular scatters of the first closure to the first non-singular hit.
  bool probe(float x, float y, GlimmerShadingContext &out) const {
    const BounceLimits limits(scene.integrator);
    PathRay ray = camera_path_ray(x, y, 0.5f, 0.5f);
    PathState ps;
    for (int bounce = 0; bounce < 16; ++bounce) {
      SurfaceHit hit;
      if (!accel->intersect(ray.org, ray.D, ray.tmin, ray.tmax, hit)) return false;
      ShadingData sd;
      ClosureSet cs;
      shade_surface(hit, ray, ps, limits, 0, sd, cs);
      if (!all_singular(cs, sd)) {
        out = sd.ctx;
        return true;
      }
      GlimmerSample s = glimmer_blank_sample();
      const float r3[3] = {0.5f, 0.5f, 0.5f};
      const ActiveClosure &c = cs.closures[0];
      GlimmerShadingContext scratch;
      const uint32_t label = c.leaf->instance ? c.leaf->instance->sample(context_for(sd, c, scratch), r3, s)
                                              : static_cast<uint32_t>(GLIMMER_LABEL_NONE);
      if (label == GLIMMER_LABEL_NONE) return false;
      const Vec3 wo = normalize(Vec3(s.wo));
      ps.advance(label, limits);
      next_differentials(ray.rd, ray.D, wo, sd, s, !moved(s), ray.pixel_spread, ps);
      if (!continue_after_sample(ray, sd, s, wo)) return false;
    }
    return false;
  }
};

Renderer::Renderer(const scene::Scene &scene, const host::PluginLibrary &plugin, const RenderOptions &options)
    : impl_(std::make_unique<Impl>(scene, plugin, options, features_, warnings_)) {
  impl_->prepare(times_);
}

Renderer::~Renderer() = default;

bool Renderer::probe(float x, float y, GlimmerShadingContext &out) const { return impl_->probe(x, y, out); }

const GlimmerHostServices &Renderer::host_services() const { return impl_->host; }

int Renderer::trace_ray_closure_shaded(const GlimmerRay &ray, GlimmerRayHit &hit, GlimmerHitClosure &out) const {
  SurfaceHit h;
  if (!impl_->accel->intersect(Vec3(ray.origin), Vec3(ray.direction), ray.t_min, ray.t_max, h)) return 0;
  impl_->fill_ray_hit(h, ray, hit);
  impl_->describe_hit_closure(h, Vec3(ray.direction), out);
  return 1;
}

const PartInfo &Renderer::part() const { return impl_->part; }

// A batch of samples per parallel pass holds about this many paths (at most RenderOptions::max_samples_per_pass
// samples per pixel, so progress, checkpoints, cancel and the time limit still come every few seconds at most).
constexpr int64_t kPathsPerBatch = 1 << 16;

RenderResult Renderer::render(const std::function<void(int, int)> &progress, const Film *resume) {
  Impl &im = *impl_;
  const auto t0 = Clock::now();
  RenderResult res;
  res.width = im.width;
  res.height = im.height;
  PartInfo &part = res.part;
  part = im.part;
  res.samples_requested = part.sample_end - part.sample_begin;
  Film film = resume ? *resume : Film(im.width, im.height, im.options.aovs);
  if (film.width() != im.width || film.height() != im.height)
    throw std::invalid_argument("the film to resume is " + std::to_string(film.width()) + "x" +
                                std::to_string(film.height()) + ", the render " + std::to_string(im.width) + "x" +
                                std::to_string(im.height));
  if (film.aovs() && !im.options.aovs)  // its AOV passes would miss the new samples' values
    throw std::invalid_argument("the film to resume has AOV passes, the render computes none");
  std::atomic<uint64_t> paths{0};
  const int x0 = part.window[0], y0 = part.window[1], x1 = part.window[2], y1 = part.window[3];
  const int tile = std::max(1, im.options.tile_size);
  std::atomic<uint64_t> nan_total{0};
  im.shaders->reset_clamped_parameter_counts();  // this render's own (a Renderer may render again)
  // The out-of-range textured values of the samples in the film: a resumed checkpoint's and this render's.
  const ClampedParameterRecords resumed_clamped = film.clamped_parameters();
  auto clamped_so_far = [&] {
    ClampedParameterRecords all = resumed_clamped;
    add_clamped_records(all, im.shaders->clamped_parameter_records());
    return all;
  };
  // Passes of `batch` samples per pixel (the first pass one sample, for the first display): one parallel loop
  // per batch instead of per sample, so small images do not wait at a barrier 256 times. Each pixel still adds
  // its samples in sample order, so the image is the same for any batch.
  const int64_t window_pixels = int64_t(x1 - x0) * (y1 - y0);
  const int batch = static_cast<int>(std::clamp<int64_t>(kPathsPerBatch / std::max<int64_t>(window_pixels, 1), 1,
                                                         std::max(1, im.options.max_samples_per_pass)));
  for (int s = part.sample_begin + film.passes(); s < part.sample_end;) {
    if (im.options.cancel && im.options.cancel->load()) { res.interrupted = true; break; }
    const int count = std::min(film.passes() == 0 ? 1 : batch, part.sample_end - s);
    tbb::parallel_for(tbb::blocked_range2d<int>(y0, y1, tile, x0, x1, tile), [&](const tbb::blocked_range2d<int> &br) {
      uint64_t nans = 0, traced = 0;
      for (int y = br.rows().begin(); y < br.rows().end(); ++y) {
        if (im.options.cancel && im.options.cancel->load()) break;  // answer SIGINT within a tile row
        im.trace_row(y, br.cols().begin(), br.cols().end(), s, count, film, nans, traced);
      }
      if (nans) nan_total += nans;
      paths += traced;
    });
    // A pass cut short by an interrupt does not count: samples_done = complete passes (its samples still
    // average into the pixels they reached).
    if (im.options.cancel && im.options.cancel->load()) { res.interrupted = true; break; }
    for (int k = 0; k < count; ++k) {  // every sample of the batch is done: one progress line each
      film.end_pass();
      if (progress) progress(film.passes(), res.samples_requested);
    }
    s += count;
    if (im.options.after_pass) {
      film.set_clamped_parameters(clamped_so_far());  // a checkpoint's counts match its samples
      im.options.after_pass(film);
    }
    if (im.options.time_limit > 0.0 && seconds_since(t0) >= im.options.time_limit && s < part.sample_end) {
      res.time_limited = true;
      break;
    }
  }
  res.samples_done = film.passes();
  res.nan_samples = nan_total.load();
  res.clamped_parameters = clamped_so_far();
  res.warnings = clamped_parameter_warnings(res.clamped_parameters);
  res.paths = paths.load();
  film.resolve(im.scene.film.exposure, res);
  res.render_seconds = seconds_since(t0);
  return res;
}

}  // namespace glimmer::render
