// Microfacet closures side by side in one run (make bench): ns per eval and
// per sample for the conductor, the dielectric and their energy-compensated
// (multi_ggx) variants, roughness 0.5, ior 1.5, and visible-normal sampling
// alone (microfacet_vndf/*). The compensation overhead is
// the ratio multi_ggx / ggx of the same operation in this run.
#include <benchmark/benchmark.h>

#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "glimmer/microfacet.h"
#include "glimmer/rng.h"
#include "host/closure_instance.h"
#include "host/plugin_library.h"

namespace {

using namespace glimmer;

host::PluginLibrary &mf_plugin() {
  static std::unique_ptr<host::PluginLibrary> library = host::PluginLibrary::load(GLIMMER_BENCH_PLUGIN_PATH);
  return *library;
}

std::unique_ptr<host::ClosureInstance> make(const std::string &name, const std::vector<std::string> &params) {
  const GlimmerClosureType *type = mf_plugin().find(name);
  if (type == nullptr) return nullptr;
  host::ParamList list;
  for (const auto &p : params) list.set_assignment(*type, p);
  return std::make_unique<host::ClosureInstance>(*type, list);
}

void BM_MicrofacetEval(benchmark::State &state, std::string name, std::vector<std::string> params) {
  auto instance = make(name, params);
  if (!instance) { state.SkipWithError("closure not in plugin"); return; }
  const GlimmerShadingContext ctx = host::make_local_context(Vec3(0.3f, 0.1f, 0.95f));
  Pcg32 rng(7);
  std::vector<Vec3> directions(1024);
  for (auto &d : directions)  // both hemispheres (reflection and transmission)
    d = normalize(Vec3(rng.next_float() - 0.5f, rng.next_float() - 0.5f, 2.0f * rng.next_float() - 1.0f));
  size_t i = 0;
  for (auto _ : state) {
    Spectrum f;
    float pdf;
    instance->eval(ctx, directions[i++ & 1023], f, pdf);
    benchmark::DoNotOptimize(f);
    benchmark::DoNotOptimize(pdf);
  }
}

void BM_MicrofacetSample(benchmark::State &state, std::string name, std::vector<std::string> params) {
  auto instance = make(name, params);
  if (!instance) { state.SkipWithError("closure not in plugin"); return; }
  const GlimmerShadingContext ctx = host::make_local_context(Vec3(0.3f, 0.1f, 0.95f));
  uint32_t i = 0;
  for (auto _ : state) {
    const float r[3] = {uint_to_unit_float(hash_u32x2(i, 1)), uint_to_unit_float(hash_u32x2(i, 2)),
                        uint_to_unit_float(hash_u32x2(i, 3))};
    ++i;
    GlimmerSample s = glimmer_blank_sample();
    benchmark::DoNotOptimize(instance->sample(ctx, r, s));
  }
}

// Visible-normal sampling alone (glimmer/microfacet.h), ns per sample at the
// incidence state.range(0) degrees, alpha 0.5: Beckmann inverts its slope CDF
// (erfc + exp per Halley step, plus an inverse erf), GGX is closed form.
void BM_VisibleNormalSample(benchmark::State &state, microfacet::Distribution dist) {
  const float theta = static_cast<float>(state.range(0)) * kPi / 180.0f;
  const Vec3 wi(std::sin(theta), 0.0f, std::cos(theta));
  uint32_t i = 0;
  for (auto _ : state) {
    const float u1 = uint_to_unit_float(hash_u32x2(i, 1)), u2 = uint_to_unit_float(hash_u32x2(i, 2));
    ++i;
    benchmark::DoNotOptimize(microfacet::sample_visible_normal(dist, wi, 0.5f, 0.5f, u1, u2));
  }
}
BENCHMARK_CAPTURE(BM_VisibleNormalSample, ggx, microfacet::Distribution::GGX)
    ->Name("microfacet_vndf/ggx")->Arg(30)->Arg(60)->Arg(85);
BENCHMARK_CAPTURE(BM_VisibleNormalSample, beckmann, microfacet::Distribution::Beckmann)
    ->Name("microfacet_vndf/beckmann")->Arg(30)->Arg(60)->Arg(85);

const bool registered = [] {
  const std::vector<std::pair<std::string, std::pair<std::string, std::vector<std::string>>>> configs = {
      {"conductor_ggx", {"microfacet_conductor", {"distribution=ggx", "roughness=0.5", "f0=0.9,0.6,0.3"}}},
      {"conductor_multi_ggx", {"microfacet_conductor", {"distribution=multi_ggx", "roughness=0.5", "f0=0.9,0.6,0.3"}}},
      {"conductor_beckmann", {"microfacet_conductor", {"distribution=beckmann", "roughness=0.5", "f0=0.9,0.6,0.3"}}},
      {"dielectric_ggx", {"microfacet_dielectric", {"distribution=ggx", "roughness=0.5", "ior=1.5"}}},
      {"dielectric_multi_ggx", {"microfacet_dielectric", {"distribution=multi_ggx", "roughness=0.5", "ior=1.5"}}},
      {"dielectric_beckmann", {"microfacet_dielectric", {"distribution=beckmann", "roughness=0.5", "ior=1.5"}}},
      {"random_walk_conductor", {"microfacet_random_walk", {"type=conductor", "roughness=0.5", "f0=0.9,0.6,0.3"}}},
      {"random_walk_dielectric", {"microfacet_random_walk", {"type=dielectric", "roughness=0.5", "ior=1.5"}}},
  };
  for (const auto &[label, config] : configs) {
    benchmark::RegisterBenchmark(("microfacet_eval/" + label).c_str(), BM_MicrofacetEval, config.first, config.second);
    benchmark::RegisterBenchmark(("microfacet_sample/" + label).c_str(), BM_MicrofacetSample, config.first,
                                 config.second);
  }
  return true;
}();

}  // namespace
