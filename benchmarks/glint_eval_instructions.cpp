// Instruction-count driver for glint eval (issue 10): not a Google Benchmark
// and not a test. Run it under callgrind with the script beside it,
// benchmarks/glint_eval_instructions.sh, which counts only eval_loop():
//   valgrind --tool=callgrind --collect-atstart=no --toggle-collect='*eval_loop*'
//       build/glint_eval_instructions <row> [plugin]
// Rows reproduce bench_glint.cpp's glint/eval_vs_ggx queries (4096 queries,
// Pcg32(11), square footprints of the given uv area, or rectangles of the
// given aspect at area 1e-6; gamma 2, density 1e7), evaluated twice each
// (2 x 4096 evals):
//   r04_a-8 r04_a-6 r04_a-4 r04_asp4 r04_asp16 r04_asp64   glint roughness 0.4
//   r02_a-8 r02_a-6 r02_a-4 r02_asp4 r02_asp16 r02_asp64   glint roughness 0.2
// (r0x_asp<N>: any aspect N >= 1, as glint/eval_vs_ggx_aspect/<N>; 4, 16 and 64 are the scripts' rows.)
//   ggx04 ggx02                         microfacet_conductor GGX at area 1e-4
// It prints the row, the number of evals and a 64-bit FNV-1a hash of the bits
// of every f and pdf (computed outside the counted loop), so two builds can be
// shown to give the same values.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "glimmer/rng.h"
#include "host/closure_instance.h"
#include "host/plugin_library.h"

#include "glint_queries.h"

namespace {

using namespace glimmer;

using Query = bench::GlintQuery;  // benchmarks/glint_queries.h

struct Result {
  Spectrum f;
  float pdf;
};

// The counted loop (callgrind --toggle-collect='*eval_loop*').
__attribute__((noinline)) void eval_loop(const host::ClosureInstance &c, const std::vector<Query> &q,
                                         std::vector<Result> &out) {
  for (std::size_t i = 0; i < q.size(); ++i) c.eval(q[i].ctx, q[i].wo, out[i].f, out[i].pdf);
}

std::uint64_t fnv1a(std::uint64_t h, const void *data, std::size_t n) {
  const auto *p = static_cast<const unsigned char *>(data);
  for (std::size_t i = 0; i < n; ++i) h = (h ^ p[i]) * 0x100000001b3ull;
  return h;
}

}  // namespace

int main(int argc, char **argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s <row> [plugin]\n", argv[0]);
    return 2;
  }
  const std::string row = argv[1];
  const char *plugin_path = argc > 2 ? argv[2] : GLIMMER_BENCH_PLUGIN_PATH;
  std::unique_ptr<host::PluginLibrary> plugin = host::PluginLibrary::load(plugin_path);
  if (!plugin) {
    std::fprintf(stderr, "cannot load %s\n", plugin_path);
    return 1;
  }
  std::string name = "glint", roughness;
  double area = 1e-4, aspect = 1.0;
  if (row.rfind("ggx", 0) == 0) {
    name = "microfacet_conductor";
    roughness = row == "ggx02" ? "0.2" : "0.4";
  } else if (row.size() > 4 && (row.rfind("r04_", 0) == 0 || row.rfind("r02_", 0) == 0)) {
    roughness = row[2] == '4' ? "0.4" : "0.2";
    const std::string tail = row.substr(4);
    char *end = nullptr;
    if (tail.rfind("asp", 0) == 0) {
      area = 1e-6;
      aspect = std::strtod(tail.c_str() + 3, &end);
      if (end == tail.c_str() + 3 || *end != '\0' || !(aspect >= 1.0)) {
        std::fprintf(stderr, "unknown row %s\n", row.c_str());
        return 2;
      }
    } else if (tail.rfind("a", 0) == 0) {
      area = std::pow(10.0, std::stod(tail.substr(1)));
    } else {
      std::fprintf(stderr, "unknown row %s\n", row.c_str());
      return 2;
    }
  } else {
    std::fprintf(stderr, "unknown row %s\n", row.c_str());
    return 2;
  }
  const GlimmerClosureType *type = plugin->find(name);
  if (type == nullptr) {
    std::fprintf(stderr, "no closure %s\n", name.c_str());
    return 1;
  }
  host::ParamList params;
  params.set_from_text(*type, "roughness", roughness);
  if (name == "glint") {
    params.set_from_text(*type, "gamma", "2");
    params.set_from_text(*type, "density", "1e7");
  } else {
    params.set_from_text(*type, "distribution", "ggx");
  }
  const host::ClosureInstance closure(*type, params);
  const std::vector<Query> q = bench::make_glint_queries(area, aspect);
  std::vector<Result> out(q.size());
  // One eval outside the counted loop builds or loads the lazily-built tables.
  // (Not through eval_loop, which callgrind counts.)
  closure.eval(q[0].ctx, q[0].wo, out[0].f, out[0].pdf);
  std::uint64_t hash = 0xcbf29ce484222325ull;
  constexpr int kPasses = 2;
  for (int pass = 0; pass < kPasses; ++pass) {
    eval_loop(closure, q, out);
    for (const Result &r : out) {
      hash = fnv1a(hash, &r.f, sizeof(r.f));
      hash = fnv1a(hash, &r.pdf, sizeof(r.pdf));
    }
  }
  std::printf("row %s evals %zu hash %016llx\n", row.c_str(), q.size() * kPasses,
              static_cast<unsigned long long>(hash));
  return 0;
}
