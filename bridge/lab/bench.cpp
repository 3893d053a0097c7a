// Timing of eval() and sample(): single-threaded, inputs generated before the
// clock starts, median over repetitions.
#include <algorithm>
#include <chrono>
#include <vector>

#include "glimmer/sampling.h"
#include "lab/closure_lab.h"
#include "lab/lab_internal.h"

namespace glimmer::lab {

BenchResult bench(const host::ClosureInstance &instance, const GlimmerShadingContext &ctx, uint64_t iterations,
                  int repetitions) {
  BenchResult result;
  result.iterations = std::max<uint64_t>(1, iterations);
  result.repetitions = std::max(1, repetitions);
  const uint64_t n = result.iterations;

  // Evaluation directions: the closure's own samples (so eval() runs on its
  // lobe, as in rendering), a uniform direction where sample() absorbs.
  std::vector<float> rand(3 * n);
  std::vector<Vec3> directions(n);
  const Frame frame = detail::shading_frame(ctx);
  for (uint64_t i = 0; i < n; ++i) {
    sample_random3(0x6c616221ULL, i, &rand[3 * i]);
    GlimmerSample s{};
    if (instance.sample(ctx, &rand[3 * i], s) != GLIMMER_LABEL_NONE && detail::is_unit_direction(Vec3(s.wo)))
      directions[i] = Vec3(s.wo);
    else
      directions[i] = frame.to_world(sample_uniform_sphere(rand[3 * i], rand[3 * i + 1]));
  }

  using Clock = std::chrono::steady_clock;
  std::vector<double> eval_ns, sample_ns;
  volatile float sink = 0.0f;
  for (int r = 0; r < result.repetitions; ++r) {
    float acc = 0.0f;
    auto start = Clock::now();
    for (uint64_t i = 0; i < n; ++i) {
      Spectrum f;
      float pdf;
      instance.eval(ctx, directions[i], f, pdf);
      acc += f.x + pdf;
    }
    auto stop = Clock::now();
    eval_ns.push_back(std::chrono::duration<double, std::nano>(stop - start).count() / static_cast<double>(n));

    start = Clock::now();
    for (uint64_t i = 0; i < n; ++i) {
      GlimmerSample s = glimmer_blank_sample();
      instance.sample(ctx, &rand[3 * i], s);
      acc += s.pdf;
    }
    stop = Clock::now();
    sample_ns.push_back(std::chrono::duration<double, std::nano>(stop - start).count() / static_cast<double>(n));
    sink = sink + acc;
  }
  auto median = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    const size_t m = v.size() / 2;
    return v.size() % 2 ? v[m] : 0.5 * (v[m - 1] + v[m]);
  };
  result.ns_per_eval = median(eval_ns);
  result.ns_per_sample = median(sample_ns);
  return result;
}

}  // namespace glimmer::lab
