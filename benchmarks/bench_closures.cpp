// Per-call cost of every closure in the plugin, side by side in one run:
// eval and sample at a fixed wi with a fixed default parameter set.
#include <benchmark/benchmark.h>

#include <memory>
#include <string>
#include <vector>

#include "glimmer/rng.h"
#include "host/closure_instance.h"
#include "host/plugin_library.h"

namespace {

using namespace glimmer;

host::PluginLibrary &plugin() {
  static std::unique_ptr<host::PluginLibrary> library = host::PluginLibrary::load(GLIMMER_BENCH_PLUGIN_PATH);
  return *library;
}

void BM_ClosureEval(benchmark::State &state, std::string name) {
  const GlimmerClosureType *type = plugin().find(name);
  if (type == nullptr) { state.SkipWithError("closure not in plugin"); return; }
  host::ClosureInstance instance(*type, host::ParamList{});
  const GlimmerShadingContext ctx = host::make_local_context(Vec3(0.3f, 0.1f, 0.95f));
  Pcg32 rng(7);
  std::vector<Vec3> directions(1024);
  for (auto &d : directions) d = normalize(Vec3(rng.next_float() - 0.5f, rng.next_float() - 0.5f, rng.next_float()));
  size_t i = 0;
  for (auto _ : state) {
    Spectrum f;
    float pdf;
    instance.eval(ctx, directions[i++ & 1023], f, pdf);
    benchmark::DoNotOptimize(f);
    benchmark::DoNotOptimize(pdf);
  }
}

void BM_ClosureSample(benchmark::State &state, std::string name) {
  const GlimmerClosureType *type = plugin().find(name);
  if (type == nullptr) { state.SkipWithError("closure not in plugin"); return; }
  host::ClosureInstance instance(*type, host::ParamList{});
  const GlimmerShadingContext ctx = host::make_local_context(Vec3(0.3f, 0.1f, 0.95f));
  uint32_t i = 0;
  for (auto _ : state) {
    const float r[3] = {uint_to_unit_float(hash_u32x2(i, 1)), uint_to_unit_float(hash_u32x2(i, 2)),
                        uint_to_unit_float(hash_u32x2(i, 3))};
    ++i;
    GlimmerSample s = glimmer_blank_sample();
    benchmark::DoNotOptimize(instance.sample(ctx, r, s));
  }
}

// One shading point of a render with a textured roughness: the host calls
// albedo (sample weights), eval (next-event estimation), sample and eval (the
// mixture's MIS) with the point's varying roughness. `points_per_value`
// shading points share a roughness value: 1 = every point its own value;
// the four calls of a point always share it. Time per shading point.
// `setting` = value of the closure's enum `setting_name` (distribution, or frosted_glass's method).
void BM_TexturedRoughnessShadingPoint(benchmark::State &state, std::string name, std::string setting_name,
                                      std::string setting) {
  const GlimmerClosureType *type = plugin().find(name);
  if (type == nullptr) { state.SkipWithError("closure not in plugin"); return; }
  host::ParamList params;
  params.set_from_text(*type, setting_name, setting);
  host::ClosureInstance instance(*type, params);
  const GlimmerParamSpec *roughness = host::find_param(*type, "roughness");
  GlimmerShadingContext ctx = host::make_local_context(Vec3(0.3f, 0.1f, 0.95f));
  GlimmerVaryingValue varying{host::param_index(*type, *roughness), {0.5f, 0.0f, 0.0f}};
  ctx.varying_count = 1;
  ctx.varying = &varying;
  uint32_t i = 0;
  for (auto _ : state) {
    varying.value[0] = 0.2f + 0.6f * uint_to_unit_float(hash_u32x2(i, 9));  // the texture's value at this point
    const float r[3] = {uint_to_unit_float(hash_u32x2(i, 1)), uint_to_unit_float(hash_u32x2(i, 2)),
                        uint_to_unit_float(hash_u32x2(i, 3))};
    const Vec3 light = normalize(Vec3(uint_to_unit_float(hash_u32x2(i, 4)) - 0.5f, 0.2f, 0.8f));
    ++i;
    Spectrum f;
    float pdf;
    benchmark::DoNotOptimize(instance.albedo(ctx));
    instance.eval(ctx, light, f, pdf);
    benchmark::DoNotOptimize(f);
    GlimmerSample s = glimmer_blank_sample();
    if (instance.sample(ctx, r, s) != 0) instance.eval(ctx, Vec3(s.wo), f, pdf);
    benchmark::DoNotOptimize(f);
  }
}

const bool registered = [] {
  for (const char *name : {"microfacet_conductor", "microfacet_dielectric"})
    benchmark::RegisterBenchmark((std::string("textured_roughness_point/") + name + "/multi_ggx").c_str(),
                                 BM_TexturedRoughnessShadingPoint, std::string(name), std::string("distribution"),
                                 std::string("multi_ggx"));
  // frosted_glass builds its interface lobe (multi_ggx, compensation rows) at every call of a textured point.
  benchmark::RegisterBenchmark("textured_roughness_point/frosted_glass/path", BM_TexturedRoughnessShadingPoint,
                               std::string("frosted_glass"), std::string("method"), std::string("path"));
  for (const auto *type : plugin().closures()) {
    benchmark::RegisterBenchmark((std::string("eval/") + type->name).c_str(), BM_ClosureEval, std::string(type->name));
    benchmark::RegisterBenchmark((std::string("sample/") + type->name).c_str(), BM_ClosureSample,
                                 std::string(type->name));
  }
  return true;
}();

}  // namespace
