// Glint benchmarks (issue 5), ratios measured side by side in one run:
//  glint/eval_vs_ggx/<log10 area>   glint eval vs microfacet_conductor (GGX)
//      eval, interleaved blocks of the same queries, footprint areas 1e-8..1
//      uv; counters glint_ns, ggx_ns, ratio (goal <= 2); with
//      $GLIMMER_BENCH_BASELINE_PLUGIN set (path of an older plugin build) also
//      that build's glint in the same blocks: base_ns, base_ratio, and
//      base_mismatches (queries whose f or pdf differs from it, bit for bit).
//  glint/eval_vs_ggx_aspect/<aspect>  the same at footprint area 1e-6 uv
//      (10 particles) with parallelograms of aspect 1..64, any rotation.
//  glint/eval_vs_ggx_beckmann/<log10 area>  the same for the GI scene's floor
//      glint (Beckmann 0.5, gamma 3, density 2e5) vs GGX at roughness 0.5.
//  glint/aniso_eval/<log10 area>  anisotropic base (roughness_u 0.55,
//      roughness_v 0.25: alpha 0.3 x 0.0625, P per query) vs the isotropic
//      glint (roughness 0.4) vs GGX eval, interleaved blocks of the same
//      queries; counters aniso_ns, iso_ns, ggx_ns, aniso_vs_iso, aniso_vs_ggx;
//      with $GLIMMER_BENCH_BASELINE_PLUGIN also that build's anisotropic
//      glint: base_aniso_ns, aniso_vs_base, base_mismatches.
//  glint/jakob14_eval/<log10 area>  the reference's eval cost at the same
//      queries (counter ratio_vs_glint).
//  glint/gi_scene_overhead          `glimmer render` of examples/glint.xml
//      against the same scene with every glint_bsdf replaced by a GGX
//      glossy_bsdf of the same roughness (subprocess, wall time of the render
//      phase), in rounds of one render each, in rotating order (as many
//      rounds per iteration as variants; the second iteration's orders
//      reversed). Ratios are medians over the rounds of each round's own
//      ratio: overhead (goal <= 0.10); overhead_of_sums is the ratio of the
//      summed times; glint_s, ggx_s, .. are median render times. With
//      $GLIMMER_BENCH_BASELINE_PLUGIN also base_s, base_overhead, glint_vs_base
//      (the glint scene rendered with that plugin in the same rounds). Also the
//      same-distribution twin (each glint_bsdf a glossy_bsdf of its own
//      distribution: the scene's floor glint is Beckmann): same_s,
//      overhead_vs_same (what the glint costs beyond its base distribution)
//      and same_vs_ggx (what that distribution costs over GGX).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <fstream>
#include <memory>
#include <numeric>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "glimmer/rng.h"
#include "host/closure_instance.h"
#include "host/plugin_library.h"

#include "glint_queries.h"

namespace {

using namespace glimmer;
using Clock = std::chrono::steady_clock;

host::PluginLibrary &glint_plugin() {
  static std::unique_ptr<host::PluginLibrary> library = host::PluginLibrary::load(GLIMMER_BENCH_PLUGIN_PATH);
  return *library;
}

// Optional second plugin (an older build, copied elsewhere) named by
// $GLIMMER_BENCH_BASELINE_PLUGIN: its glint is timed in the same interleaved
// blocks, so before/after ratios come from one run.
host::PluginLibrary *baseline_plugin() {
  static std::unique_ptr<host::PluginLibrary> library = [] {
    const char *path = std::getenv("GLIMMER_BENCH_BASELINE_PLUGIN");
    return path != nullptr && *path != '\0' ? host::PluginLibrary::load(path) : nullptr;
  }();
  return library.get();
}

std::unique_ptr<host::ClosureInstance> make(const std::string &name,
                                            const std::vector<std::pair<std::string, std::string>> &params,
                                            host::PluginLibrary &plugin = glint_plugin()) {
  const GlimmerClosureType *type = plugin.find(name);
  if (type == nullptr) return nullptr;
  host::ParamList list;
  for (const auto &[k, v] : params) list.set_from_text(*type, k, v);
  return std::make_unique<host::ClosureInstance>(*type, list);
}

using Query = bench::GlintQuery;  // benchmarks/glint_queries.h

// Thread CPU time (not wall time: the machine is shared, and preemption
// inflates wall-clock blocks several-fold), ns per eval.
double thread_cpu_ns() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) * 1e9 + static_cast<double>(t.tv_nsec);
}

double time_block(const host::ClosureInstance &c, const std::vector<Query> &q) {
  const double t0 = thread_cpu_ns();
  for (const auto &x : q) {
    Spectrum f;
    float pdf;
    c.eval(x.ctx, x.wo, f, pdf);
    benchmark::DoNotOptimize(f);
    benchmark::DoNotOptimize(pdf);
  }
  return (thread_cpu_ns() - t0) / static_cast<double>(q.size());
}

// Queries whose eval (f and pdf) differs between two closures, bit for bit:
// a speed change that keeps the particles gives 0 against the older build.
int differing_evals(const host::ClosureInstance &a, const host::ClosureInstance &b, const std::vector<Query> &q) {
  int differing = 0;
  for (const auto &x : q) {
    Spectrum fa, fb;
    float pa = 0.0f, pb = 0.0f;
    a.eval(x.ctx, x.wo, fa, pa);
    b.eval(x.ctx, x.wo, fb, pb);
    differing += std::memcmp(&fa, &fb, sizeof(Spectrum)) != 0 || std::memcmp(&pa, &pb, sizeof(float)) != 0;
  }
  return differing;
}

// The median of per-block or per-round values (the middle element, or the mean of the two middle ones for an even
// count: the eval benchmarks' 25 blocks, the GI benchmark's rounds).
double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 == 1 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// glint and GGX eval on the same queries, interleaved blocks; median ns.
const std::vector<std::pair<std::string, std::string>> kGgxGlint = {
    {"roughness", "0.4"}, {"gamma", "2"}, {"density", "1e7"}};
void glint_vs_ggx(benchmark::State &state, const std::vector<Query> &q,
                  const std::vector<std::pair<std::string, std::string>> &params = kGgxGlint) {
  auto glint = make("glint", params);
  auto ggx = make("microfacet_conductor", {{"roughness", params[0].second}, {"distribution", "ggx"}});
  if (!glint || !ggx) {
    state.SkipWithError("glint or microfacet_conductor missing");
    return;
  }
  std::unique_ptr<host::ClosureInstance> base;
  if (host::PluginLibrary *b = baseline_plugin()) base = make("glint", params, *b);
  if (base) state.counters["base_mismatches"] = static_cast<double>(differing_evals(*glint, *base, q));
  std::vector<double> g_ns, m_ns, b_ns;
  for (auto _ : state) {
    g_ns.push_back(time_block(*glint, q));
    m_ns.push_back(time_block(*ggx, q));
    if (base) b_ns.push_back(time_block(*base, q));
  }
  const double g = median(g_ns), m = median(m_ns);
  state.counters["glint_ns"] = g;
  state.counters["ggx_ns"] = m;
  state.counters["ratio"] = g / m;
  if (base) {
    state.counters["base_ns"] = median(b_ns);
    state.counters["base_ratio"] = median(b_ns) / m;
  }
}

void BM_GlintVsGgxEval(benchmark::State &state) {
  glint_vs_ggx(state, bench::make_glint_queries(std::pow(10.0, static_cast<double>(state.range(0)))));
}
BENCHMARK(BM_GlintVsGgxEval)->Name("glint/eval_vs_ggx")->DenseRange(-8, 0, 2)->Iterations(25)->Unit(benchmark::kMillisecond);

// The GI scene's floor glint (examples/glint.xml: Beckmann, roughness 0.5,
// gamma 3, density 2e5; 0.2 particles per footprint at 1e-6, filtered at 1)
// against a GGX conductor of the same roughness, as in the scene's twin.
void BM_GlintBeckmannVsGgxEval(benchmark::State &state) {
  glint_vs_ggx(state, bench::make_glint_queries(std::pow(10.0, static_cast<double>(state.range(0)))),
               {{"roughness", "0.5"}, {"distribution", "beckmann"}, {"gamma", "3"}, {"density", "2e5"}});
}
BENCHMARK(BM_GlintBeckmannVsGgxEval)
    ->Name("glint/eval_vs_ggx_beckmann")
    ->DenseRange(-6, 0, 2)
    ->Iterations(25)
    ->Unit(benchmark::kMillisecond);

void BM_GlintVsGgxEvalAspect(benchmark::State &state) {
  glint_vs_ggx(state, bench::make_glint_queries(1e-6, static_cast<double>(state.range(0))));
}
BENCHMARK(BM_GlintVsGgxEvalAspect)
    ->Name("glint/eval_vs_ggx_aspect")
    ->Arg(1)->Arg(4)->Arg(16)->Arg(64)
    ->Iterations(25)
    ->Unit(benchmark::kMillisecond);

void BM_GlintAnisoEval(benchmark::State &state) {
  const std::vector<Query> q = bench::make_glint_queries(std::pow(10.0, static_cast<double>(state.range(0))));
  const std::vector<std::pair<std::string, std::string>> aniso_params = {
      {"roughness_u", "0.55"}, {"roughness_v", "0.25"}, {"gamma", "2"}, {"density", "1e7"}};
  auto aniso = make("glint", aniso_params);
  auto iso = make("glint", {{"roughness", "0.4"}, {"gamma", "2"}, {"density", "1e7"}});
  auto ggx = make("microfacet_conductor", {{"roughness", "0.4"}, {"distribution", "ggx"}});
  if (!aniso || !iso || !ggx) {
    state.SkipWithError("glint or microfacet_conductor missing");
    return;
  }
  // With $GLIMMER_BENCH_BASELINE_PLUGIN: that build's anisotropic glint in the same blocks.
  std::unique_ptr<host::ClosureInstance> base;
  if (host::PluginLibrary *b = baseline_plugin()) base = make("glint", aniso_params, *b);
  if (base) state.counters["base_mismatches"] = static_cast<double>(differing_evals(*aniso, *base, q));
  std::vector<double> a_ns, i_ns, m_ns, b_ns;
  for (auto _ : state) {
    a_ns.push_back(time_block(*aniso, q));
    i_ns.push_back(time_block(*iso, q));
    m_ns.push_back(time_block(*ggx, q));
    if (base) b_ns.push_back(time_block(*base, q));
  }
  const double a = median(a_ns), i = median(i_ns), m = median(m_ns);
  state.counters["aniso_ns"] = a;
  state.counters["iso_ns"] = i;
  state.counters["ggx_ns"] = m;
  state.counters["aniso_vs_iso"] = a / i;
  state.counters["aniso_vs_ggx"] = a / m;
  if (base) {
    state.counters["base_aniso_ns"] = median(b_ns);
    state.counters["aniso_vs_base"] = a / median(b_ns);
  }
}
BENCHMARK(BM_GlintAnisoEval)->Name("glint/aniso_eval")->DenseRange(-8, 0, 2)->Iterations(25)->Unit(benchmark::kMillisecond);

void BM_Jakob14Eval(benchmark::State &state) {
  const double area = std::pow(10.0, static_cast<double>(state.range(0)));
  auto glint = make("glint", {{"roughness", "0.4"}, {"gamma", "2"}, {"density", "1e7"}});
  auto jakob = make("glint_jakob14", {{"roughness", "0.4"}, {"gamma", "2"}, {"density", "1e7"}});
  std::vector<Query> q = bench::make_glint_queries(area);
  q.resize(256);
  double j = 0.0, g = 0.0;
  for (auto _ : state) {
    j += time_block(*jakob, q);
    g += time_block(*glint, q);
  }
  state.counters["jakob14_ns"] = j / static_cast<double>(state.iterations());
  state.counters["glint_ns"] = g / static_cast<double>(state.iterations());
  state.counters["ratio_vs_glint"] = j / g;
}
BENCHMARK(BM_Jakob14Eval)->Name("glint/jakob14_eval")->DenseRange(-8, -2, 2)->Iterations(3)->Unit(benchmark::kMillisecond);

// Render phase seconds from `glimmer render --stats` ("render=1.234s").
double render_seconds(const std::string &scene, const std::string &out, const char *plugin = nullptr) {
  const std::string cmd = std::string(GLIMMER_BENCH_CLI_PATH) +
                          (plugin != nullptr ? std::string(" --plugin '") + plugin + "'" : std::string()) +
                          " render " + scene + " -o " + out +
                          " --samples 16 --width 320 --height 200 --threads 1 --quiet --stats 2>&1";
  FILE *p = popen(cmd.c_str(), "r");
  if (p == nullptr) return -1.0;
  std::string text;
  char buf[512];
  while (fgets(buf, sizeof(buf), p) != nullptr) text += buf;
  if (pclose(p) != 0) return -1.0;
  std::smatch m;
  if (!std::regex_search(text, m, std::regex("render=([0-9.]+)s"))) return -1.0;
  return std::stod(m[1].str());
}

void BM_GiSceneOverhead(benchmark::State &state) {
  const std::string src = std::string(GLIMMER_BENCH_SOURCE_DIR) + "/examples/glint.xml";
  std::ifstream in(src);
  std::stringstream ss;
  ss << in.rdbuf();
  // Plain-GGX twin: every glint_bsdf becomes a glossy_bsdf GGX with the same roughness; the same-distribution twin
  // keeps each glint's distribution (benchmarks/glint_gi_twin.py makes both the same way).
  const auto twin = [](std::string text, bool keep_distribution) {
    if (!keep_distribution)
      text = std::regex_replace(text, std::regex("<glint_bsdf([^>]*?)distribution=\"[a-z]+\""),
                                "<glint_bsdf$1distribution=\"ggx\"");
    text = std::regex_replace(text, std::regex(" (gamma|density|uv_scale|seed|filter_threshold)=\"[^\"]*\""), "");
    return std::regex_replace(text, std::regex("<glint_bsdf"), "<glossy_bsdf");
  };
  const std::string dir = std::string(GLIMMER_BENCH_SOURCE_DIR) + "/examples/";
  const std::string plain = dir + ".bench_glint_plain.xml", same = dir + ".bench_glint_same.xml";
  std::ofstream(plain) << twin(ss.str(), false);
  std::ofstream(same) << twin(ss.str(), true);
  const char *baseline = std::getenv("GLIMMER_BENCH_BASELINE_PLUGIN");
  if (baseline != nullptr && *baseline == '\0') baseline = nullptr;
  // Rounds: every variant rendered once, in an order that rotates from round to round, as many rounds per iteration
  // as variants, so each variant renders first, second, .. equally often (session 44; before, the twins always
  // rendered first and 2 rounds gave one ratio of sums: its repetitions ranged over +8..+52 % on this project's VM,
  // whose speed moves by 10 % and more within a minute). The counters are medians over the rounds of each round's
  // own ratio (both renders seconds apart); `overhead_of_sums` keeps the old estimator.
  struct Variant {
    const std::string *scene;
    const char *out;
    const char *plugin;
    std::vector<double> seconds;
  };
  std::vector<Variant> v = {{&plain, "/tmp/glimmer_bench_plain.png", nullptr, {}},
                            {&same, "/tmp/glimmer_bench_same.png", nullptr, {}},
                            {&src, "/tmp/glimmer_bench_glint.png", nullptr, {}}};
  if (baseline != nullptr) v.push_back({&src, "/tmp/glimmer_bench_base.png", baseline, {}});
  // Every variant first once per iteration (balanced positions); odd iterations run each round's order backwards, so
  // with 3 variants each one follows each other one equally often (a Williams design: carry-over balanced too).
  std::string failed;
  int64_t iteration = 0;
  for (auto _ : state) {
    for (size_t first = 0; first < v.size() && failed.empty(); ++first)
      for (size_t k = 0; k < v.size() && failed.empty(); ++k) {
        const size_t step = iteration % 2 == 0 ? k : v.size() - 1 - k;
        Variant &x = v[(first + step) % v.size()];
        const double t = render_seconds(*x.scene, x.out, x.plugin);
        if (!(t > 0.0))
          failed = "glimmer render failed: " + *x.scene + (x.plugin ? std::string(" with ") + x.plugin : "");
        x.seconds.push_back(t);
      }
    ++iteration;
  }
  std::remove(plain.c_str());
  std::remove(same.c_str());
  if (!failed.empty()) {
    state.SkipWithError(failed.c_str());
    return;
  }
  auto ratio = [&](const Variant &a, const Variant &b) {  // median over the rounds of a / b, minus 1
    std::vector<double> r;
    for (size_t i = 0; i < a.seconds.size(); ++i) r.push_back(a.seconds[i] / b.seconds[i]);
    return median(r) - 1.0;
  };
  auto sum = [](const Variant &a) { return std::accumulate(a.seconds.begin(), a.seconds.end(), 0.0); };
  const Variant &t_plain = v[0], &t_same = v[1], &t_glint = v[2];
  state.counters["glint_s"] = median(t_glint.seconds);
  state.counters["ggx_s"] = median(t_plain.seconds);
  state.counters["overhead"] = ratio(t_glint, t_plain);
  state.counters["overhead_of_sums"] = sum(t_glint) / sum(t_plain) - 1.0;
  state.counters["same_s"] = median(t_same.seconds);
  state.counters["overhead_vs_same"] = ratio(t_glint, t_same);
  state.counters["same_vs_ggx"] = ratio(t_same, t_plain);
  if (baseline != nullptr) {
    state.counters["base_s"] = median(v[3].seconds);
    state.counters["base_overhead"] = ratio(v[3], t_plain);
    state.counters["glint_vs_base"] = ratio(t_glint, v[3]);
  }
}
BENCHMARK(BM_GiSceneOverhead)->Name("glint/gi_scene_overhead")->Iterations(2)->Unit(benchmark::kSecond);

}  // namespace
