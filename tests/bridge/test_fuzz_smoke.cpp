// A short, deterministic fuzz smoke run for `make test` (the long runs are
// `make fuzz`, docs/hostile-input.md): the fuzz seeds and a few thousand
// byte-level mutations of them go through the same entry points as the
// libFuzzer targets; every input must load or fail with a SceneError.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "scene/mesh_files.h"
#include "scene/xml_loader.h"

namespace glimmer::test {
namespace {

namespace fs = std::filesystem;

std::vector<std::string> read_all(const std::vector<fs::path> &folders, const std::string &extension) {
  std::vector<std::string> texts;
  for (const auto &folder : folders) {
    if (!fs::is_directory(folder)) continue;
    for (const auto &e : fs::directory_iterator(folder)) {
      if (!extension.empty() && e.path().extension() != extension) continue;
      std::ifstream in(e.path(), std::ios::binary);
      texts.emplace_back(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    }
  }
  return texts;
}

// Flips, inserts, deletes and duplicates bytes, as libFuzzer's simplest mutators do.
std::string mutate(std::string s, std::mt19937 &rng) {
  const char interesting[] = {'<', '>', '"', '/', ' ', '0', '9', '-', 'e', '.', '\n', '\0', '\xff'};
  const int edits = 1 + static_cast<int>(rng() % 8);
  for (int i = 0; i < edits; ++i) {
    const size_t at = s.empty() ? 0 : rng() % s.size();
    switch (rng() % 4) {
      case 0: if (!s.empty()) s[at] = static_cast<char>(rng()); break;
      case 1: s.insert(at, 1, interesting[rng() % sizeof(interesting)]); break;
      case 2: if (!s.empty()) s.erase(at, 1 + rng() % 16); break;
      default: if (!s.empty()) s.insert(at, s.substr(at, 1 + rng() % 64)); break;
    }
  }
  return s;
}

// Runs `parse` on every seed and `mutations` mutants of each; returns how many loaded without error.
template <typename Parse>
int smoke(const std::vector<std::string> &seeds, int mutations, Parse parse) {
  std::mt19937 rng(14);
  int accepted = 0;
  for (const auto &seed : seeds) {
    for (int m = 0; m <= mutations; ++m) {
      const std::string input = m == 0 ? seed : mutate(seed, rng);
      try {
        parse(input);
        ++accepted;
      } catch (const scene::SceneError &) {
      }
    }
  }
  return accepted;
}

const fs::path kSource = GLIMMER_TEST_SOURCE_DIR;

TEST(FuzzSmoke, XmlLoader) {
  const auto seeds = read_all({kSource / "examples", kSource / "tests/bridge/data"}, ".xml");
  ASSERT_GE(seeds.size(), 3u);
  const int accepted =
      smoke(seeds, 300, [](const std::string &t) { scene::load_scene_text(t, (kSource / "examples/fuzz.xml").string()); });
  EXPECT_GT(accepted, 0) << "the unmutated seeds must load";
}

TEST(FuzzSmoke, MeshReaders) {
  for (const char *format : {"obj", "ply"}) {
    SCOPED_TRACE(format);
    const auto seeds = read_all({kSource / "fuzz/seeds" / format}, "");
    ASSERT_FALSE(seeds.empty());
    const std::string path = std::string("fuzz.") + format;
    const int accepted = smoke(seeds, 2000, [&](const std::string &t) {
      scene::parse_mesh_text(t, path, scene::SourceLocation{"fuzz.xml", 1});
    });
    EXPECT_GT(accepted, 0);
  }
}

}  // namespace
}  // namespace glimmer::test
