// Renderer throughput: samples (camera paths) per second on fixed scenes,
// side by side in one run: the demo scene (diffuse + microfacet + area light)
// and the golden-test scene. Counter `samples_per_second` = pixels x spp / s.
#include <benchmark/benchmark.h>

#include <memory>
#include <string>

#include "host/plugin_library.h"
#include "render/renderer.h"
#include "scene/xml_loader.h"

namespace {

using namespace glimmer;

host::PluginLibrary &render_plugin() {
  static std::unique_ptr<host::PluginLibrary> library = host::PluginLibrary::load(GLIMMER_BENCH_PLUGIN_PATH);
  return *library;
}

void BM_Render(benchmark::State &state, std::string scene_file, int width, int height, int samples) {
  const scene::Scene scene = scene::load_scene(std::string(GLIMMER_BENCH_SOURCE_DIR) + "/" + scene_file);
  render::RenderOptions opt;
  opt.width = width;
  opt.height = height;
  opt.samples = samples;
  render::Renderer renderer(scene, render_plugin(), opt);
  uint64_t paths = 0;
  for (auto _ : state) {
    const auto r = renderer.render();
    paths += r.paths;
    benchmark::DoNotOptimize(r.combined.data());
  }
  state.counters["samples_per_second"] = benchmark::Counter(static_cast<double>(paths), benchmark::Counter::kIsRate);
}

BENCHMARK_CAPTURE(BM_Render, demo_160x100_16spp, "examples/demo.xml", 160, 100, 16)
    ->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Render, golden_48x32_64spp, "tests/bridge/data/golden.xml", 48, 32, 64)
    ->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
