// ABI 2.10 prefetch (GlimmerClosureType.prefetch): the host reads it only from a type whose struct_size holds it,
// and the renderer hands next-event estimation's light direction to it before the BSDF sample, so that the eval
// toward the light that follows finds its loads started. The fixture plugin (tests/fixtures/prefetch_plugin.cpp)
// names its closure "diffuse" and marks in its eval whether a prefetch toward the same direction came first with
// a BSDF sample in between (green), without one (blue), or no prefetch toward it (red).
#include <gtest/gtest.h>

#include <cstddef>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>

#include <unistd.h>

#include "host/closure_instance.h"
#include "host/plugin_library.h"
#include "render/renderer.h"
#include "scene/xml_loader.h"

namespace glimmer::test {
namespace {

namespace fs = std::filesystem;

TEST(ClosurePrefetch, ReadOnlyFromATypeWhoseStructSizeHoldsIt) {
  const auto library = host::PluginLibrary::load(GLIMMER_TEST_FIXTURE_PREFETCH);
  const GlimmerClosureType *type = library->find("diffuse");
  ASSERT_NE(type, nullptr);
  ASSERT_NE(type->prefetch, nullptr);
  EXPECT_TRUE(host::ClosureInstance(*type, host::ParamList{}).has_prefetch());
  // The same type as a 2.9 plugin's (struct_size ends before the field): the pointer that sits there is not read.
  GlimmerClosureType older = *type;
  older.struct_size = static_cast<uint32_t>(offsetof(GlimmerClosureType, prefetch));
  EXPECT_FALSE(host::ClosureInstance(older, host::ParamList{}).has_prefetch());
  // The fixture built against 2.9 has no field at all.
  const auto library_2_9 = host::PluginLibrary::load(GLIMMER_TEST_FIXTURE_PREFETCH_2_9);
  const GlimmerClosureType *type_2_9 = library_2_9->find("diffuse");
  ASSERT_NE(type_2_9, nullptr);
  EXPECT_EQ(host::abi_version_name(host::closure_abi_version(*type_2_9)), "2.9");
  EXPECT_LT(type_2_9->struct_size, offsetof(GlimmerClosureType, prefetch) + sizeof(type->prefetch));
  EXPECT_FALSE(host::ClosureInstance(*type_2_9, host::ParamList{}).has_prefetch());
  // The real plugin: glint has one (its direction table), a closure without tables none (NULL).
  const auto plugin = host::PluginLibrary::load(GLIMMER_TEST_PLUGIN_PATH);
  ASSERT_NE(plugin->find("glint"), nullptr);
  EXPECT_NE(plugin->find("glint")->prefetch, nullptr);
  EXPECT_EQ(plugin->find("diffuse")->prefetch, nullptr);
  EXPECT_EQ(plugin->find("microfacet_conductor")->prefetch, nullptr);
}

// A diffuse plane filling the view under a constant world, light sampling only (the BSDF's hits count 0): every eval is NEE's, so
// the image's red channel is NEE without a prefetch toward its direction first, green with one and the BSDF sample
// in between, blue with one but no sample in between. The plane fills the view (no world in the image).
render::RenderResult render_plane(const char *plugin_path, bool closure_prefetch) {
  const fs::path dir = fs::path(GLIMMER_TEST_BINARY_DIR) / "test_host_tmp" / std::to_string(::getpid());
  fs::create_directories(dir);
  const fs::path path = dir / "prefetch_plane.xml";
  std::ofstream(path) << "<cycles>\n<camera width=\"16\" height=\"12\" fov=\"0.8\" />\n"
                         "<transform translate=\"0 -3 2\" rotate=\"55 1 0 0\" scale=\"1 1 -1\"><camera /></transform>\n"
                         "<integrator max_bounce=\"2\" sample_clamp_indirect=\"0\" />\n"
                         "<background><background name=\"bg\" color=\"1 1 1\" strength=\"1\" />"
                         "<connect from=\"bg background\" to=\"output surface\" /></background>\n"
                         "<shader name=\"plane\"><diffuse_bsdf name=\"d\" color=\"1 1 1\" />"
                         "<connect from=\"d bsdf\" to=\"output surface\" /></shader>\n"
                         "<state shader=\"plane\"><mesh P=\"-40 -40 0  40 -40 0  40 40 0  -40 40 0\" nverts=\"4\" "
                         "verts=\"0 1 2 3\" /></state>\n</cycles>\n";
  const auto library = host::PluginLibrary::load(plugin_path);
  const scene::Scene scene = scene::load_scene(path.string());
  render::RenderOptions opt;
  opt.samples = 4;
  opt.strategy = render::LightStrategy::LightOnly;
  opt.closure_prefetch = closure_prefetch;
  render::Renderer renderer(scene, *library, opt);
  return renderer.render();
}

double channel_sum(const render::RenderResult &r, int c) {
  double sum = 0.0;
  for (size_t i = c; i < r.combined.size(); i += 4) sum += r.combined[i];
  return sum;
}

TEST(ClosurePrefetch, EveryNeeEvalFollowsAPrefetchTowardTheLight) {
  const render::RenderResult with = render_plane(GLIMMER_TEST_FIXTURE_PREFETCH, true);
  EXPECT_GT(channel_sum(with, 1), 0.0);
  EXPECT_EQ(channel_sum(with, 0), 0.0);  // no eval without a prefetch toward its own direction
  EXPECT_EQ(channel_sum(with, 2), 0.0);  // none right after its prefetch: the BSDF sample ran in between
  // Negative controls: the option off, and the 2.9 plugin (no prefetch): every eval red.
  const render::RenderResult without = render_plane(GLIMMER_TEST_FIXTURE_PREFETCH, false);
  const render::RenderResult older = render_plane(GLIMMER_TEST_FIXTURE_PREFETCH_2_9, true);
  for (const render::RenderResult *r : {&without, &older}) {
    EXPECT_EQ(channel_sum(*r, 1), 0.0);
    EXPECT_EQ(channel_sum(*r, 2), 0.0);
    EXPECT_GT(channel_sum(*r, 0), 0.0);
  }
  // The prefetch changes no value: the green image with it is the red one without it, pixel for pixel.
  ASSERT_EQ(with.combined.size(), without.combined.size());
  for (size_t i = 0; i < with.combined.size(); i += 4)
    ASSERT_EQ(std::memcmp(&with.combined[i + 1], &without.combined[i], sizeof(float)), 0) << "pixel " << i / 4;
}

}  // namespace
}  // namespace glimmer::test
