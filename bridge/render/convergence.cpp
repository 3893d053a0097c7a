#include "render/convergence.h"

#include <cmath>
#include <stdexcept>

#include "render/renderer.h"

namespace glimmer::render {

double fit_loglog_slope(const std::vector<double> &x, const std::vector<double> &y) {
  if (x.size() != y.size() || x.size() < 2) throw std::invalid_argument("fit_loglog_slope: needs >= 2 (x, y) pairs");
  double sx = 0.0, sy = 0.0, sxx = 0.0, sxy = 0.0;
  for (size_t i = 0; i < x.size(); ++i) {
    if (!(x[i] > 0.0) || !(y[i] > 0.0)) throw std::invalid_argument("fit_loglog_slope: x and y must be > 0");
    const double lx = std::log(x[i]), ly = std::log(y[i]);
    sx += lx;
    sy += ly;
    sxx += lx * lx;
    sxy += lx * ly;
  }
  const double n = static_cast<double>(x.size());
  const double denom = n * sxx - sx * sx;
  if (!(denom > 0.0)) throw std::invalid_argument("fit_loglog_slope: all x are equal");
  return (n * sxy - sx * sy) / denom;
}

double rmse_rgb(const std::vector<float> &a, const std::vector<float> &b) {
  if (a.size() != b.size() || a.empty()) throw std::invalid_argument("rmse_rgb: images differ in size");
  double sum = 0.0;
  size_t n = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    if (i % 4 == 3) continue;  // alpha
    const double d = static_cast<double>(a[i]) - b[i];
    sum += d * d;
    ++n;
  }
  return std::sqrt(sum / static_cast<double>(n));
}

ConvergenceResult measure_convergence(const scene::Scene &scene, const host::PluginLibrary &plugin,
                                      const ConvergenceOptions &options) {
  if (options.ladder.size() < 2) throw std::invalid_argument("convergence: the ladder needs >= 2 sample counts");
  for (int spp : options.ladder)
    if (spp < 1 || spp >= options.reference_samples)
      throw std::invalid_argument("convergence: every ladder sample count must be >= 1 and below the reference's (" +
                                  std::to_string(options.reference_samples) + ")");
  auto render_at = [&](int samples, int seed) {
    RenderOptions opt;
    opt.samples = samples;
    opt.width = options.width;
    opt.height = options.height;
    opt.seed = seed;
    opt.aovs = false;
    Renderer renderer(scene, plugin, opt);
    return renderer.render();
  };
  ConvergenceResult out;
  // Another seed than the ladder's: the ladder's samples must not be the reference's own first samples
  // (that correlation would fake convergence).
  const RenderResult reference = render_at(options.reference_samples, options.seed + 7919);
  out.reference_seconds = reference.render_seconds;
  std::vector<double> spp, seconds, errors;
  for (int samples : options.ladder) {
    const RenderResult r = render_at(samples, options.seed);
    ConvergencePoint p{samples, r.render_seconds, rmse_rgb(r.combined, reference.combined)};
    out.points.push_back(p);
    spp.push_back(samples);
    seconds.push_back(std::max(p.seconds, 1e-9));
    errors.push_back(std::max(p.rmse, 1e-30));
  }
  out.slope_spp = fit_loglog_slope(spp, errors);
  out.slope_time = fit_loglog_slope(seconds, errors);
  return out;
}

}  // namespace glimmer::render
