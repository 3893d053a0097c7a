// Cost of one shading-point evaluation of node programs (bridge/render/nodes/): Noise 3D at detail 0 / 2 / 8,
// Voronoi F1 3D, Wave with distortion, and a five-node Math/Mix chain, against a Gradient texture baseline
// (the cheapest program: one node). Figures are per evaluation; compare them side by side in one run.
#include <benchmark/benchmark.h>

#include <map>
#include <memory>
#include <string>

#include "render/nodes/node_program.h"

namespace {

using glimmer::Vec3;
using namespace glimmer::render;

struct Program {
  glimmer::scene::ShaderGraph graph;
  nodes::NodeProgram program;
};

// `nodes` (type, name, attributes) in order; links as (from node, from socket, to node, to socket); the
// program is the output `out` of node `last`.
std::unique_ptr<Program> build(const std::vector<std::tuple<std::string, std::string, std::map<std::string, std::string>>> &ns,
                               const std::vector<std::array<std::string, 4>> &links, const std::string &last,
                               const std::string &out) {
  auto p = std::make_unique<Program>();
  p->graph.name = "bench";
  for (const auto &[type, name, attributes] : ns) p->graph.nodes.push_back({type, name, attributes, {"bench.xml", 1}});
  p->graph.nodes.push_back({"emission", "e", {}, {"bench.xml", 1}});
  for (const auto &l : links) p->graph.links.push_back({l[0], l[1], l[2], l[3], {"bench.xml", 1}});
  const glimmer::scene::ShaderLink result{last, out, "e", "color", {"bench.xml", 1}};
  p->graph.links.push_back(result);
  nodes::BuildHooks hooks;
  hooks.external = [](const glimmer::scene::ShaderLink &, nodes::SocketType &) { return -1; };
  hooks.warn = [](const glimmer::scene::SourceLocation &, const std::string &) {};
  p->program = nodes::compile_program(p->graph, result, hooks);
  return p;
}

void run(benchmark::State &state, const Program &p) {
  nodes::ShadingPoint sp;
  float t = 0.0f;
  for (auto _ : state) {
    sp.generated = Vec3(0.37f + t, 0.61f - t, 0.23f + 0.5f * t);
    t += 1e-4f;
    benchmark::DoNotOptimize(p.program.eval(sp, [](int, const nodes::ShadingPoint &) { return Vec3(0.0f); }));
  }
}

void BM_NodeGradient(benchmark::State &state) {  // baseline: one cheap node
  static const auto p = build({{"gradient_texture", "n", {}}}, {}, "n", "fac");
  run(state, *p);
}
void BM_NodeNoise3D(benchmark::State &state) {
  static std::map<int64_t, std::unique_ptr<Program>> cache;
  auto &p = cache[state.range(0)];
  if (!p) p = build({{"noise_texture", "n", {{"detail", std::to_string(state.range(0))}}}}, {}, "n", "color");
  run(state, *p);
}
void BM_NodeVoronoiF1(benchmark::State &state) {
  static const auto p = build({{"voronoi_texture", "n", {}}}, {}, "n", "distance");
  run(state, *p);
}
void BM_NodeWaveDistorted(benchmark::State &state) {
  static const auto p = build({{"wave_texture", "n", {{"distortion", "2"}}}}, {}, "n", "fac");
  run(state, *p);
}
void BM_NodeMathChain(benchmark::State &state) {
  static const auto p = build({{"texture_coordinate", "tc", {}},
                               {"separate_xyz", "s", {}},
                               {"math", "m1", {{"math_type", "multiply"}, {"value2", "3"}}},
                               {"math", "m2", {{"math_type", "sine"}}},
                               {"mix", "mx", {{"mix_type", "overlay"}, {"color2", "0.2 0.5 0.9"}}}},
                              {{{"tc", "generated", "s", "vector"}},
                               {{"s", "x", "m1", "value1"}},
                               {{"m1", "value", "m2", "value1"}},
                               {{"m2", "value", "mx", "fac"}},
                               {{"tc", "generated", "mx", "color1"}}},
                              "mx", "color");
  run(state, *p);
}

BENCHMARK(BM_NodeGradient);
BENCHMARK(BM_NodeNoise3D)->Arg(0)->Arg(2)->Arg(8);
BENCHMARK(BM_NodeVoronoiF1);
BENCHMARK(BM_NodeWaveDistorted);
BENCHMARK(BM_NodeMathChain);

}  // namespace
