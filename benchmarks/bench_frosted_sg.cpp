// frosted_glass: the cost of carrying one path through a frosted unit sphere (analytic, a host answering
// trace_ray / trace_ray_closure) from the entry point to where it leaves, through the plugin's C ABI:
// method=path (a stochastic interface event per crossing until the path escapes) vs method=sg (one sample that
// traces the axis and 4 bounding rays and returns the exit point). Side by side in one run; the machine is shared,
// so compare the ratio only. The accuracy of sg is in tests/closures/test_frosted_sg.cpp.
#include <benchmark/benchmark.h>

#include <cmath>
#include <limits>
#include <memory>
#include <string>

#include "../tests/closures/frosted_test_host.h"
#include "glimmer/rng.h"
#include "host/closure_instance.h"
#include "host/plugin_library.h"

namespace {

using namespace glimmer;

host::PluginLibrary &frosted_plugin() {
  static std::unique_ptr<host::PluginLibrary> library = host::PluginLibrary::load(GLIMMER_BENCH_PLUGIN_PATH);
  return *library;
}

// The unit sphere; every hit reports `material` as its closure.
struct SphereHost {
  const GlimmerInstance *material = nullptr;
  GlimmerHostServices services{};
  SphereHost() { services = glimmer::test::tracing_host_services<&trace>(this); }
  static bool hit_sphere(const Vec3 &o, const Vec3 &d, float t_min, float &t) {
    const float b = dot(o, d), c = dot(o, o) - 1.0f, disc = b * b - c;
    if (disc < 0.0f) return false;
    t = -b - std::sqrt(disc);
    if (!(t > t_min)) t = -b + std::sqrt(disc);
    return t > t_min;
  }
  static int trace(void *data, const GlimmerRay *ray, GlimmerRayHit *hit, GlimmerHitClosure *c) {
    float t;
    if (!hit_sphere(Vec3(ray->origin), Vec3(ray->direction), ray->t_min, t)) return 0;
    hit->t = t;
    hit->P = Vec3(ray->origin) + Vec3(ray->direction) * t;
    hit->N = hit->Ng = normalize(Vec3(hit->P));
    c->instance = static_cast<SphereHost *>(data)->material;
    c->varying_count = 0;
    return 1;
  }
};

Vec3 offset(const Vec3 &P, const Vec3 &Ng, const Vec3 &dir) {
  const float eps = 3e-5f * (1.0f + std::max(std::fabs(P.x), std::max(std::fabs(P.y), std::fabs(P.z))));
  return dot(dir, Ng) >= 0.0f ? P + Ng * eps : P - Ng * eps;
}

void BM_FrostedThroughSphere(benchmark::State &state, std::string method) {
  const GlimmerClosureType *type = frosted_plugin().find("frosted_glass");
  if (type == nullptr) { state.SkipWithError("frosted_glass not in plugin"); return; }
  SphereHost sphere;
  host::ParamList params;
  params.set_from_text(*type, "roughness", "0.3");
  params.set_from_text(*type, "method", method);
  host::ClosureInstance instance(*type, params, &sphere.services);
  sphere.material = instance.handle();
  uint32_t i = 0;
  long interface_events = 0;
  for (auto _ : state) {
    // Entry at a point of the front hemisphere, camera ray down -z.
    const float x = 0.6f * (uint_to_unit_float(hash_u32x2(i, 7)) - 0.5f);
    const float y = 0.6f * (uint_to_unit_float(hash_u32x2(i, 8)) - 0.5f);
    Vec3 P(x, y, std::sqrt(1.0f - x * x - y * y)), D(0.0f, 0.0f, -1.0f);
    for (int event = 0; event < 256; ++event) {
      GlimmerShadingContext ctx = host::make_local_context(-D, &sphere.services);
      ctx.P = P;
      ctx.N = ctx.Ng = normalize(P);
      ctx.path_seed = hash_u32x2(i, uint32_t(event));
      const float r[3] = {uint_to_unit_float(hash_u32x3(i, uint32_t(event), 1)), uint_to_unit_float(hash_u32x3(i, uint32_t(event), 2)),
                          uint_to_unit_float(hash_u32x3(i, uint32_t(event), 3))};
      GlimmerSample s{};
      s.struct_size = sizeof s;
      ++interface_events;
      if (instance.sample(ctx, r, s) == GLIMMER_LABEL_NONE) break;
      const Vec3 wo(s.wo);
      const Vec3 o = (s.flags & GLIMMER_SAMPLE_MOVED) ? offset(Vec3(s.origin), Vec3(s.origin_Ng), wo)
                                                      : offset(P, Vec3(ctx.Ng), wo);
      float t;
      if (!SphereHost::hit_sphere(o, wo, 0.0f, t)) break;  // left the sphere
      P = o + wo * t;
      D = wo;
    }
    ++i;
  }
  state.counters["closure_calls_per_path"] = double(interface_events) / double(std::max<uint32_t>(i, 1));
}

const bool registered_frosted = [] {
  for (const char *m : {"path", "sg"})
    benchmark::RegisterBenchmark((std::string("frosted/through_sphere/") + m).c_str(), BM_FrostedThroughSphere,
                                 std::string(m));
  return true;
}();

}  // namespace
