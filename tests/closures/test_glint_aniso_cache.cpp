// The anisotropic glint energy table's disk cache (issue 10; docs/glints.md
// "Anisotropic base roughness"): built once, written as glint_A_<key>.bin in
// the private cache folder, loaded bit for bit by the next process; crafted
// or broken entries are rejected (the scheme of the isotropic tables,
// test_glint_cache_hostile.cpp) and rebuilt with a warning.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <vector>

#include "closures/cache_test_util.h"
#include "closures/closure_checks.h"
#include "glimmer/sha256.h"
#include "tables/glint_aniso.h"
#include "test_support.h"

namespace glimmer::test {
namespace {

namespace fs = std::filesystem;
namespace gl = plugin::glint;
namespace mf = glimmer::microfacet;

// File layout (glint_aniso_cache.cpp): magic 8, version 4, key 8,
// distribution 4, alpha_x 4, alpha_y 4, gamma 4, dims 16, then
// 5 x 91 x 10 float scales (level-major), then the 32-byte HMAC.
constexpr size_t kHeader = 52, kLevelFloats = 91 * 10, kLevels = 5;

void scale_levels(std::vector<char> &bytes, size_t first, size_t last, float factor) {
  for (size_t i = first * kLevelFloats; i < last * kLevelFloats; ++i) {
    float v;
    std::memcpy(&v, bytes.data() + kHeader + 4 * i, 4);
    v *= factor;
    std::memcpy(bytes.data() + kHeader + 4 * i, &v, 4);
  }
}

// roughness_u 0.5 x roughness_v 0.3 (alpha 0.25 x 0.09), gamma 2: a spec no other test uses.
host::ParamList brushed_params() {
  host::ParamList params;
  const GlimmerClosureType &type = closure_type("glint");
  params.set_from_text(type, "roughness_u", "0.5");
  params.set_from_text(type, "roughness_v", "0.3");
  params.set_from_text(type, "gamma", "2");
  params.set_from_text(type, "density", "1e12");
  return params;
}
gl::AnisoSpec brushed_spec() {
  gl::AnisoSpec s;
  s.distribution = mf::Distribution::GGX;
  s.alpha_x = 0.5f * 0.5f;
  s.alpha_y = 0.3f * 0.3f;
  s.gamma_deg = 2.0f;
  return s;
}

// Evaluations that read the table at every blur level and several incidences.
std::vector<float> evals(const GlimmerHostServices &host) {
  host::ClosureInstance c(closure_type("glint"), brushed_params(), &host);
  std::vector<float> out;
  for (const double theta : {0.0, 35.0, 70.0, 86.0})
    for (const float spread : {0.0f, 0.1f, 0.4f, 2.0f}) {
      const Vec3 wi = spherical_dir(theta, 20.0);
      GlimmerShadingContext ctx = footprint_context(wi, 0.3, 0.6, 0.02, 0.0, 0.0, 0.02);
      ctx.spread_angle = spread;
      Spectrum f;
      float pdf = 0.0f;
      c.eval(ctx, spherical_dir(theta + 2.0, 200.0), f, pdf);
      out.push_back(f.x);
      out.push_back(pdf);
    }
  return out;
}

// One cache folder per test binary run, filled once (the build costs ~10-20 s).
struct CachedEntry {
  std::string dir;
  fs::path entry;
  std::vector<char> original, key;
  std::vector<float> built_evals;
  bool build_logged = false;
};
const CachedEntry &cached_entry() {
  static const CachedEntry e = [] {
    CachedEntry c;
    const fs::path root = fs::path(GLIMMER_TEST_BINARY_DIR) / "test_cache_glint_aniso";
    fs::remove_all(root);
    c.dir = (root / "glimmer").string();
    const GlimmerHostServices host = host_caching_in(c.dir);
    g_cache_log.clear();
    c.built_evals = evals(host);
    c.build_logged = logged("precomputed anisotropic energy table");
    c.entry = gl::aniso_energy_cache_path(c.dir, brushed_spec());
    c.original = read_bytes(c.entry);
    c.key = read_bytes(fs::path(c.dir) / "secret.key");
    return c;
  }();
  return e;
}

TEST(GlintAnisoCache, RoundTripIsBitIdenticalAndSkipsTheBuild) {
  const CachedEntry &c = cached_entry();
  EXPECT_TRUE(c.build_logged) << "the first instance builds the table";
  ASSERT_EQ(c.original.size(), kHeader + 4 * kLevels * kLevelFloats + 32) << c.entry;
  struct stat st {};
  ASSERT_EQ(0, ::stat(c.entry.c_str(), &st));
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  ASSERT_EQ(0, ::stat(c.dir.c_str(), &st));
  EXPECT_EQ(st.st_mode & 0777, 0700u);

  // A new instance (the first one is gone, so nothing is shared in memory)
  // loads the file silently and evaluates bit for bit as the built table.
  const GlimmerHostServices host = host_caching_in(c.dir);
  g_cache_log.clear();
  EXPECT_EQ(evals(host), c.built_evals);
  EXPECT_FALSE(logged("precomputed")) << "loaded, not rebuilt";
  EXPECT_FALSE(logged("recomputing"));

  // load -> save reproduces the file byte for byte.
  std::string problem;
  const auto table = gl::load_aniso_energy(c.entry.string(), brushed_spec(), problem);
  ASSERT_TRUE(table) << problem;
  EXPECT_TRUE(table->loaded_from_cache);
  const fs::path copy = fs::path(c.dir) / "copy.bin";
  ASSERT_TRUE(gl::save_aniso_energy(copy.string(), *table, problem)) << problem;
  EXPECT_EQ(read_bytes(copy), c.original);
  fs::remove(copy);

  // Another spec has another file name (the key covers every parameter).
  for (int k = 0; k < 4; ++k) {
    gl::AnisoSpec other = brushed_spec();
    if (k == 0) other.alpha_x = 0.2501f;
    if (k == 1) other.alpha_y = 0.0901f;
    if (k == 2) other.gamma_deg = 2.5f;
    if (k == 3) other.distribution = mf::Distribution::Beckmann;
    EXPECT_NE(gl::aniso_energy_cache_path(c.dir, other), c.entry.string()) << k;
  }
}

// Crafted entries at the loader (no rebuild needed to see the verdict).
TEST(GlintAnisoCache, CraftedFilesAreRejected) {
  const CachedEntry &c = cached_entry();
  const gl::AnisoSpec spec = brushed_spec();
  const std::string path = c.entry.string();
  std::string problem;
  ASSERT_TRUE(gl::load_aniso_energy(path, spec, problem)) << "control: the untouched file loads: " << problem;
  std::vector<char> same = c.original;
  rewrite_mac(same, c.key);
  ASSERT_EQ(same, c.original) << "the test's HMAC must be the file's";

  struct Attack {
    const char *what;
    std::function<void(std::vector<char> &)> edit;
    bool knows_key;
    const char *expected;
  };
  const std::vector<Attack> attacks = {
      {"x1000, FNV recomputed", [](auto &b) { scale_levels(b, 0, kLevels, 1000.0f); }, false, "MAC mismatch"},
      {"x1.01, FNV recomputed", [](auto &b) { scale_levels(b, 0, kLevels, 1.01f); }, false, "MAC mismatch"},
      {"unblurred x1.5, MAC recomputed", [](auto &b) { scale_levels(b, 0, 1, 1.5f); }, true, "above 1"},
      {"unblurred x0.99, MAC recomputed", [](auto &b) { scale_levels(b, 0, 1, 0.99f); }, true,
       "does not match its recomputation"},
      {"blurred x1.01, MAC recomputed", [](auto &b) { scale_levels(b, 1, kLevels, 1.01f); }, true,
       "does not match its recomputation"},
      {"one NaN, MAC recomputed",
       [](auto &b) {
         const float nan = std::nanf("");
         std::memcpy(b.data() + kHeader + 4 * 1234, &nan, 4);
       },
       true, "non-finite"},
      {"alpha_x field edited, MAC recomputed",
       [](auto &b) {
         const float a = 0.3f;
         std::memcpy(b.data() + 24, &a, 4);
       },
       true, "parameters differ"},
      {"truncated", [](auto &b) { b.resize(b.size() - 100); }, false, "truncated"},
      {"trailing byte", [](auto &b) { b.push_back(0); }, false, "MAC mismatch"},
  };
  for (const Attack &a : attacks) {
    SCOPED_TRACE(a.what);
    std::vector<char> crafted = c.original;
    a.edit(crafted);
    if (a.knows_key) rewrite_mac(crafted, c.key);
    else if (crafted.size() == c.original.size()) rewrite_fnv(crafted);
    const fs::path p = fs::path(c.dir) / "crafted.bin";
    write_bytes(p, crafted);
    problem.clear();
    EXPECT_FALSE(gl::load_aniso_energy(p.string(), spec, problem));
    EXPECT_NE(problem.find(a.expected), std::string::npos) << problem;
    fs::remove(p);
  }
  // Another material's file under this one's name: its key differs.
  gl::AnisoSpec other = spec;
  other.gamma_deg = 3.0f;
  problem.clear();
  EXPECT_FALSE(gl::load_aniso_energy(path, other, problem));
  EXPECT_NE(problem.find("bad header"), std::string::npos) << problem;
  // Junk (a directory) at an entry path is removed.
  const fs::path junk = fs::path(c.dir) / "junk.bin";
  fs::create_directories(junk / "inner");
  problem.clear();
  EXPECT_FALSE(gl::load_aniso_energy(junk.string(), spec, problem));
  EXPECT_EQ(problem, "not a regular file; removed");
  EXPECT_FALSE(fs::exists(junk));
  problem.clear();
  EXPECT_FALSE(gl::load_aniso_energy((fs::path(c.dir) / "absent.bin").string(), spec, problem));
  EXPECT_EQ(problem, "missing");
}

// Through the closure: a crafted entry (key known, every scale x1.01) is
// rebuilt with a warning, the rebuilt table evaluates as the first build, and
// its file replaces the crafted one byte for byte.
TEST(GlintAnisoCache, CraftedEntryIsRebuiltAndReplaced) {
  const CachedEntry &c = cached_entry();
  std::vector<char> crafted = c.original;
  scale_levels(crafted, 0, kLevels, 0.99f);
  rewrite_mac(crafted, c.key);
  write_bytes(c.entry, crafted);
  const GlimmerHostServices host = host_caching_in(c.dir);
  g_cache_log.clear();
  EXPECT_EQ(evals(host), c.built_evals);
  EXPECT_TRUE(logged("recomputing")) << (g_cache_log.empty() ? "" : g_cache_log[0]);
  EXPECT_TRUE(logged("does not match its recomputation"));
  EXPECT_EQ(read_bytes(c.entry), c.original);
}

// The build hands nodes out dynamically: 1 and 3 threads give the same table
// bit for bit (two full builds: make stress only).
TEST(GlintAnisoCache, BuildIsIndependentOfThreadCountStress) {
  if (stress_scale() == 1) GTEST_SKIP() << "make stress only";
  const auto one = gl::AnisoEnergyTable::build(brushed_spec(), 1);
  const auto three = gl::AnisoEnergyTable::build(brushed_spec(), 3);
  EXPECT_EQ(one->scale, three->scale);
  std::printf("[aniso energy] build 1 thread %.2f s, 3 threads %.2f s\n", one->build_seconds, three->build_seconds);
}

}  // namespace
}  // namespace glimmer::test
