// Renderer throughput: samples (camera paths) per second on fixed scenes,
// side by side in one run: the demo scene (diffuse + microfacet + area light),
// the demo with image textures (an 8-bit 2048^2 floor image and a float
// equirectangular environment, written here with OIIO into the build folder:
// demo_textured/) and the golden-test scene. Counter `samples_per_second` =
// pixels x spp / s.
#include <OpenImageIO/imageio.h>
#include <benchmark/benchmark.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "host/plugin_library.h"
#include "render/renderer.h"
#include "scene/xml_loader.h"

namespace {

using namespace glimmer;

host::PluginLibrary &render_plugin() {
  static std::unique_ptr<host::PluginLibrary> library = host::PluginLibrary::load(GLIMMER_BENCH_PLUGIN_PATH);
  return *library;
}

void write_image(const std::string &path, int w, int h, bool eight_bit, float (*value)(int x, int y, int c)) {
  std::vector<float> px(static_cast<size_t>(w) * h * 3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) px[(static_cast<size_t>(y) * w + x) * 3 + c] = value(x, y, c);
  auto out = OIIO::ImageOutput::create(path);
  OIIO::ImageSpec spec(w, h, 3, eight_bit ? OIIO::TypeDesc::UINT8 : OIIO::TypeDesc::HALF);
  if (!out || !out->open(path, spec) || !out->write_image(OIIO::TypeDesc::FLOAT, px.data()) || !out->close())
    throw std::runtime_error("cannot write " + path);
}

// examples/demo.xml with image textures: the floor's checker becomes a 2048^2 sRGB image
// (tiles with fine stripes, repeated 4 times across the floor) and the background colour an
// equirectangular sky (1024 x 512 half float). Also what `glimmer render` of an older
// build reads for the before/after comparison (docs/architecture.md). Returns the scene path.
std::string demo_textured_scene() {
  namespace fs = std::filesystem;
  const fs::path dir = fs::current_path() / "demo_textured";
  fs::create_directories(dir);
  const std::string floor = (dir / "floor.png").string(), sky = (dir / "sky.exr").string();
  if (!fs::exists(floor))
    write_image(floor, 2048, 2048, true, [](int x, int y, int c) {
      const bool tile = ((x / 256) + (y / 256)) % 2 == 0;
      const float stripe = 0.5f + 0.5f * std::sin(static_cast<float>(x + 2 * y) * 0.7f);
      return (tile ? 0.75f : 0.18f) * (0.8f + 0.2f * stripe) * (c == 2 ? 0.95f : 1.0f);
    });
  if (!fs::exists(sky))
    write_image(sky, 1024, 512, false, [](int x, int y, int c) {
      const float up = 1.0f - static_cast<float>(y) / 512.0f;
      const float sun = std::exp(-0.002f * static_cast<float>((x - 300) * (x - 300) + (y - 150) * (y - 150)));
      const float base[3] = {0.45f, 0.55f, 0.75f};
      return base[c] * (0.3f + 0.7f * up) + 20.0f * sun;
    });
  std::ifstream in(std::string(GLIMMER_BENCH_SOURCE_DIR) + "/examples/demo.xml");
  std::stringstream text;
  text << in.rdbuf();
  std::string xml = text.str();
  auto replace = [&xml](const std::string &from, const std::string &to) {
    const size_t at = xml.find(from);
    if (at == std::string::npos) throw std::runtime_error("demo.xml changed: '" + from + "' not found");
    xml.replace(at, from.size(), to);
  };
  replace("<checker_texture name=\"check\" scale=\"8\" color1=\"0.75 0.75 0.72\" color2=\"0.18 0.18 0.2\" />",
          "<image_texture name=\"check\" filename=\"" + floor + "\" />");
  replace("UV=\"0 0  1 0  1 1  0 1\"", "UV=\"0 0  4 0  4 4  0 4\"");
  replace("<background name=\"sky\" color=\"0.55 0.65 0.8\" strength=\"0.35\" />",
          "<environment_texture name=\"env\" filename=\"" + sky +
              "\" /><background name=\"sky\" strength=\"0.35\" /><connect from=\"env color\" to=\"sky color\" />");
  replace("<mesh src=\"sphere.obj\" />", "<mesh src=\"" + std::string(GLIMMER_BENCH_SOURCE_DIR) + "/examples/sphere.obj\" />");
  replace("<mesh src=\"sphere.obj\" />", "<mesh src=\"" + std::string(GLIMMER_BENCH_SOURCE_DIR) + "/examples/sphere.obj\" />");
  const std::string path = (dir / "demo_textured.xml").string();
  std::ofstream(path) << xml;
  return path;
}

void BM_Render(benchmark::State &state, std::string scene_file, int width, int height, int samples) {
  const std::string path =
      scene_file.empty() ? demo_textured_scene() : std::string(GLIMMER_BENCH_SOURCE_DIR) + "/" + scene_file;
  const scene::Scene scene = scene::load_scene(path);
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
// The scene of demo_textured_scene() (empty name).
BENCHMARK_CAPTURE(BM_Render, demo_textured_160x100_16spp, "", 160, 100, 16)
    ->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Render, golden_48x32_64spp, "tests/bridge/data/golden.xml", 48, 32, 64)
    ->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
