// Helpers for the renderer tests: temporary scene files, in-process renders,
// running the CLI, and noise-aware image statistics.
#pragma once

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include <unistd.h>

#include "host/plugin_library.h"
#include "render/renderer.h"
#include "scene/xml_loader.h"
#include "test_support.h"

namespace glimmer::test {

// One folder per test process: ctest runs tests of this executable in parallel processes.
inline std::filesystem::path temp_dir() {
  const auto dir = std::filesystem::path(GLIMMER_TEST_BINARY_DIR) / "test_bridge_tmp" / std::to_string(::getpid());
  std::filesystem::create_directories(dir);
  return dir;
}

inline std::string write_file(const std::string &name, const std::string &text) {
  const auto path = temp_dir() / name;
  std::ofstream(path) << text;
  return path.string();
}

inline render::RenderResult render_scene(const std::string &path, render::RenderOptions opt) {
  const scene::Scene scene = scene::load_scene(path);
  render::Renderer renderer(scene, plugin(), opt);
  return renderer.render();
}

// A render with at most `threads` worker threads and tiles of `tile_size` pixels (determinism tests).
inline render::RenderResult render_scene_with(const std::string &path, render::RenderOptions opt, int threads,
                                              int tile_size) {
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, static_cast<size_t>(threads));
  opt.tile_size = tile_size;
  return render_scene(path, opt);
}

// A unit UV sphere centred at (0, 0, z) with exact normals, as a <mesh> element (use it smooth).
inline std::string uv_sphere_mesh(int rings, int segments, double z) {
  std::string P, N, verts, nverts;
  char buf[96];
  for (int i = 0; i <= rings; ++i)
    for (int j = 0; j <= segments; ++j) {
      const double theta = M_PI * i / rings, phi = 2.0 * M_PI * j / segments;
      const double x = std::sin(theta) * std::cos(phi), y = std::cos(theta), s = std::sin(theta) * std::sin(phi);
      std::snprintf(buf, sizeof(buf), "%.7f %.7f %.7f ", x, y, s + z);
      P += buf;
      std::snprintf(buf, sizeof(buf), "%.7f %.7f %.7f ", x, y, s);
      N += buf;
    }
  for (int i = 0; i < rings; ++i)
    for (int j = 0; j < segments; ++j) {
      const int a = i * (segments + 1) + j, b = a + segments + 1;
      std::snprintf(buf, sizeof(buf), "%d %d %d %d ", a, a + 1, b + 1, b);
      verts += buf;
      nverts += "4 ";
    }
  return "<mesh P=\"" + P + "\" N=\"" + N + "\" nverts=\"" + nverts + "\" verts=\"" + verts + "\" />";
}

// Renders `path` in process with `samples` per pixel; fills `warnings` when given; expects no NaN sample.
inline render::RenderResult render_with_warnings(const std::string &path, int samples,
                                                 std::vector<std::string> *warnings = nullptr) {
  const scene::Scene scene = scene::load_scene(path);
  render::RenderOptions opt;
  opt.samples = samples;
  render::Renderer renderer(scene, plugin(), opt);
  render::RenderResult r = renderer.render();
  if (warnings) *warnings = renderer.warnings();
  EXPECT_EQ(r.nan_samples, 0u);
  return r;
}

// Runs the CLI; returns its exit code and fills `output` with stdout+stderr.
inline int run_cli(const std::string &args, std::string &output) {
  const auto log = temp_dir() / "cli_output.txt";
  const std::string cmd = std::string("'") + GLIMMER_TEST_CLI_PATH + "' " + args + " > '" + log.string() + "' 2>&1";
  const int status = std::system(cmd.c_str());
  std::ifstream in(log);
  output.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// Mean of channel c over a rectangle of an RGBA image.
inline double mean_channel(const render::RenderResult &r, int c, int x0 = 0, int y0 = 0, int x1 = -1, int y1 = -1) {
  if (x1 < 0) x1 = r.width;
  if (y1 < 0) y1 = r.height;
  double s = 0.0;
  for (int y = y0; y < y1; ++y)
    for (int x = x0; x < x1; ++x) s += r.combined[4 * (static_cast<size_t>(y) * r.width + x) + c];
  return s / ((x1 - x0) * (y1 - y0));
}

// Sample mean and its standard error (sample standard deviation / sqrt(n)).
struct MeanAndError {
  double mean = 0.0, standard_error = 0.0;
};
inline MeanAndError mean_and_standard_error(const std::vector<double> &v) {
  MeanAndError r;
  for (double x : v) r.mean += x;
  r.mean /= v.size();
  double var = 0.0;
  for (double x : v) var += (x - r.mean) * (x - r.mean);
  r.standard_error = std::sqrt(var / (v.size() - 1) / v.size());
  return r;
}

// Channel c of every pixel of an RGBA image, minus `offset`.
inline std::vector<double> channel_values(const render::RenderResult &r, int c, double offset = 0.0) {
  std::vector<double> v;
  for (size_t i = 0; i < static_cast<size_t>(r.width) * r.height; ++i) v.push_back(r.combined[4 * i + c] - offset);
  return v;
}

// z-score of the mean per-pixel difference between two independent renders of
// the same expectation over a rectangle: mean(D) / (std(D) / sqrt(n)).
// Pixels use independent random numbers, so std(D) measures the noise of both.
inline double difference_z(const render::RenderResult &a, const render::RenderResult &b, int c, int x0, int y0, int x1,
                           int y1) {
  std::vector<double> d;
  for (int y = y0; y < y1; ++y)
    for (int x = x0; x < x1; ++x) {
      const size_t i = 4 * (static_cast<size_t>(y) * a.width + x) + c;
      d.push_back(static_cast<double>(a.combined[i]) - b.combined[i]);
    }
  const MeanAndError e = mean_and_standard_error(d);
  return e.standard_error > 0.0 ? e.mean / e.standard_error : (e.mean == 0.0 ? 0.0 : 1e9);
}

}  // namespace glimmer::test
