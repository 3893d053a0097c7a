// Convergence measurement: RMSE against a high-sample reference of the same
// renderer at a ladder of sample counts, and the least-squares slope of
// log(RMSE) over log(spp) (and over log(render seconds)). Quasi-Monte Carlo on
// smooth integrands reaches about -1 (in spp); a purely random estimator -0.5.
// `glimmer bench convergence` prints it; tests use it to catch convergence
// regressions (e.g. a discrete choice that stops reusing its stratified sample).
#pragma once

#include <string>
#include <vector>

#include "host/plugin_library.h"
#include "scene/scene.h"

namespace glimmer::render {

struct ConvergenceOptions {
  std::vector<int> ladder{16, 32, 64, 128, 256};
  int reference_samples = 4096;
  int width = 0, height = 0;  // 0: the camera's
  int seed = 1;               // ladder seed; the reference uses another one
};

struct ConvergencePoint {
  int samples = 0;
  double seconds = 0.0;  // render phase
  double rmse = 0.0;     // over the RGB channels of every pixel
};

struct ConvergenceResult {
  std::vector<ConvergencePoint> points;
  double reference_seconds = 0.0;
  double slope_spp = 0.0;   // d log(RMSE) / d log(spp)
  double slope_time = 0.0;  // d log(RMSE) / d log(seconds)
};

// Least-squares slope of log(y) over log(x); needs >= 2 points with x, y > 0.
double fit_loglog_slope(const std::vector<double> &x, const std::vector<double> &y);

// Root-mean-square difference of the RGB channels of two RGBA images of the same size.
double rmse_rgb(const std::vector<float> &a, const std::vector<float> &b);

ConvergenceResult measure_convergence(const scene::Scene &scene, const host::PluginLibrary &plugin,
                                      const ConvergenceOptions &options);

}  // namespace glimmer::render
