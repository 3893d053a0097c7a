// `glimmer bench convergence`: RMSE vs spp and vs time of one scene against a
// high-spp reference of the same renderer, with the fitted log-log slopes
// (render/convergence.h).
// `glimmer bench error-vs-time`: time-vs-error comparison of glint methods.
// For a scene using glint_bsdf, renders variants of it (glint_bsdf rewritten
// per method) at a ladder of sample counts by running `glimmer render` as a
// subprocess, measures the render-phase wall time and the RMSE against a
// converged render of the reference method (glint_jakob14), and writes a
// CSV and a log-log PNG plot. Methods:
//   jakob14         glint_jakob14_bsdf (Jakob 2014 reference)
//   dsm-unfiltered  glint_bsdf with filter_threshold = 1e9 (always counts glints)
//   dsm-filtered    glint_bsdf as written in the scene (filter threshold 16 by default)
//   ggx             glossy_bsdf (plain GGX of the same roughness, no glints)
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>
#include <unistd.h>

#include <tbb/global_control.h>

#include "cli/commands.h"
#include "render/convergence.h"
#include "scene/xml_loader.h"
#include "glimmer/atomic_file.h"
#include "render/image_io.h"
#include "render/image_output.h"

namespace glimmer::cli {
namespace {

struct BenchArgs {
  std::string scene;
  std::string methods = "jakob14,dsm-unfiltered,dsm-filtered,ggx";
  std::string ladder = "1,2,4,8,16,32";
  int reference_samples = 256;
  int width = 160, height = 100;
  int threads = 0;
  std::string out_dir = "docs";
  std::string name = "glint_error_vs_time";
  std::string from_csv;  // re-plot an existing CSV without rendering
};

std::string self_path() {
  char buf[4096];
  const ssize_t n = readlink("/proc/self/exe", buf, sizeof(buf) - 1);
  if (n <= 0) throw CliError(kExitBadInput, "cannot find the glimmer executable (/proc/self/exe)");
  buf[n] = '\0';
  return buf;
}

std::vector<std::string> split(const std::string &s, char sep) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, sep))
    if (!item.empty()) out.push_back(item);
  return out;
}

// The scene text rewritten for one method.
std::string rewrite_scene(const std::string &text, const std::string &method) {
  if (method == "dsm-filtered") return text;
  if (method == "dsm-unfiltered") {
    std::string t = std::regex_replace(text, std::regex(" filter_threshold=\"[^\"]*\""), "");
    return std::regex_replace(t, std::regex("<glint_bsdf "), "<glint_bsdf filter_threshold=\"1e9\" ");
  }
  if (method == "jakob14") {
    std::string t = std::regex_replace(text, std::regex(" filter_threshold=\"[^\"]*\""), "");
    return std::regex_replace(t, std::regex("<glint_bsdf "), "<glint_jakob14_bsdf ");
  }
  if (method == "ggx") {
    std::string t = std::regex_replace(text, std::regex("(<glint_bsdf[^>]*?)distribution=\"[a-z]+\""),
                                       "$1distribution=\"ggx\"");
    t = std::regex_replace(t, std::regex(" (gamma|density|uv_scale|seed|filter_threshold)=\"[^\"]*\""), "");
    return std::regex_replace(t, std::regex("<glint_bsdf"), "<glossy_bsdf");
  }
  throw CliError(kExitBadInput, "bench error-vs-time: unknown method '" + method +
                                    "' (expected jakob14, dsm-unfiltered, dsm-filtered or ggx)");
}

// Runs `glimmer render` and returns the render-phase seconds.
double render(const std::string &exe, const std::string &plugin, const std::string &scene, const std::string &out,
              int samples, const BenchArgs &a, int seed = -1) {
  std::string cmd = "'" + exe + "'";
  if (!plugin.empty()) cmd += " --plugin '" + plugin + "'";
  cmd += " render '" + scene + "' -o '" + out + "' --samples " + std::to_string(samples) + " --width " +
         std::to_string(a.width) + " --height " + std::to_string(a.height) + " --threads " +
         std::to_string(a.threads) + (seed >= 0 ? " --seed " + std::to_string(seed) : std::string()) +
         " --quiet --stats 2>&1";
  FILE *p = popen(cmd.c_str(), "r");
  if (p == nullptr) throw CliError(kExitBadInput, "cannot run " + cmd);
  std::string text;
  char buf[512];
  while (fgets(buf, sizeof(buf), p) != nullptr) text += buf;
  const int status = pclose(p);
  std::smatch m;
  if (status != 0 || !std::regex_search(text, m, std::regex("render=([0-9.eE+-]+)s")))
    throw CliError(kExitBadInput, "render failed (" + cmd + "):\n" + text);
  return std::stod(m[1].str());
}

std::vector<float> read_pixels(const std::string &path, int &w, int &h) {
  try {
    return render::image_io().read_rgb(path, w, h);
  } catch (const std::runtime_error &e) {
    throw CliError(kExitBadInput, e.what());
  }
}

double rmse(const std::vector<float> &a, const std::vector<float> &b) {
  double s = 0.0;
  for (size_t i = 0; i < a.size(); ++i) s += (double(a[i]) - b[i]) * (double(a[i]) - b[i]);
  return std::sqrt(s / static_cast<double>(a.size()));
}

struct Row {
  std::string method;
  int samples;
  double seconds, error;
};

// Log-log plot of RMSE against time, one polyline per method.
void write_plot(const std::string &path, const std::vector<Row> &rows, const std::vector<std::string> &methods) {
  const int W = 720, H = 480, L = 80, R = 170, T = 30, B = 60;
  const char *dejavu = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";
  const std::string font = std::filesystem::exists(dejavu) ? dejavu : "";
  std::vector<float> img(static_cast<size_t>(W) * H * 3, 1.0f);  // white
  double t0 = 1e30, t1 = -1e30, e0 = 1e30, e1 = -1e30;
  for (const auto &r : rows) {
    if (r.seconds <= 0 || r.error <= 0) continue;
    t0 = std::min(t0, std::log10(r.seconds));
    t1 = std::max(t1, std::log10(r.seconds));
    e0 = std::min(e0, std::log10(r.error));
    e1 = std::max(e1, std::log10(r.error));
  }
  if (!(t1 > t0)) t1 = t0 + 1;
  if (!(e1 > e0)) e1 = e0 + 1;
  auto X = [&](double s) { return L + static_cast<int>((std::log10(s) - t0) / (t1 - t0) * (W - L - R)); };
  auto Y = [&](double e) { return H - B - static_cast<int>((std::log10(e) - e0) / (e1 - e0) * (H - T - B)); };
  const float black[3] = {0, 0, 0};
  const render::ImageIo &io = render::image_io();
  auto text = [&](int x, int y, const std::string &t, const float *c) { io.draw_text(img.data(), W, H, x, y, t, 14, font, c); };
  auto box = [&](int x0, int y0, int x1, int y1, const float *c) {
    for (int y = std::max(0, y0); y < std::min(H, y1 + 1); ++y)
      for (int x = std::max(0, x0); x < std::min(W, x1 + 1); ++x)
        for (int k = 0; k < 3; ++k) img[(static_cast<size_t>(y) * W + x) * 3 + k] = c[k];
  };
  box(L, H - B, W - R, H - B + 1, black);
  box(L - 1, T, L, H - B, black);
  const float colors[4][3] = {{0.8f, 0.1f, 0.1f}, {0.1f, 0.5f, 0.9f}, {0.1f, 0.7f, 0.2f}, {0.4f, 0.4f, 0.4f}};
  for (size_t m = 0; m < methods.size(); ++m) {
    const float *c = colors[m % 4];
    int px = -1, py = -1;
    for (const auto &r : rows) {
      if (r.method != methods[m] || r.seconds <= 0 || r.error <= 0) continue;
      const int x = X(r.seconds), y = Y(r.error);
      box(x - 3, y - 3, x + 3, y + 3, c);
      if (px >= 0) {
        const int steps = std::max(std::abs(x - px), std::abs(y - py));
        for (int s = 0; s <= steps; ++s) {
          const int lx = px + (x - px) * s / std::max(steps, 1), ly = py + (y - py) * s / std::max(steps, 1);
          box(lx, ly, lx + 1, ly + 1, c);
        }
      }
      px = x;
      py = y;
    }
    box(W - R + 15, T + 20 + 25 * static_cast<int>(m), W - R + 35, T + 30 + 25 * static_cast<int>(m), c);
    text(W - R + 42, T + 31 + 25 * static_cast<int>(m), methods[m], c);
  }
  char label[128];
  std::snprintf(label, sizeof(label), "time %.3g .. %.3g s (log)", std::pow(10.0, t0), std::pow(10.0, t1));
  text(L, H - 20, label, black);
  std::snprintf(label, sizeof(label), "RMSE %.3g .. %.3g (log)", std::pow(10.0, e0), std::pow(10.0, e1));
  text(10, 20, label, black);
  std::vector<unsigned char> bytes(img.size());  // 8-bit PNG, written through the one atomic writer
  for (size_t i = 0; i < img.size(); ++i)
    bytes[i] = static_cast<unsigned char>(std::lround(std::clamp(img[i], 0.0f, 1.0f) * 255.0f));
  render::write_8bit_image(path, W, H, 3, bytes.data());
}

// Time a method needs to reach `target` RMSE (log-log interpolation; <0 if never).
double time_at_error(const std::vector<Row> &rows, const std::string &method, double target) {
  const Row *prev = nullptr;
  for (const auto &r : rows) {
    if (r.method != method) continue;
    if (r.error <= target) {
      if (prev == nullptr) return r.seconds;
      const double f = (std::log(prev->error) - std::log(target)) / (std::log(prev->error) - std::log(r.error));
      return std::exp(std::log(prev->seconds) + f * (std::log(r.seconds) - std::log(prev->seconds)));
    }
    prev = &r;
  }
  return -1.0;
}

void report(const std::vector<Row> &rows, const std::vector<std::string> &methods);

void plot_only(const BenchArgs &a) {
  std::ifstream f(a.from_csv);
  if (!f) throw CliError(kExitBadInput, "cannot read " + a.from_csv);
  std::string line;
  std::getline(f, line);
  std::vector<Row> rows;
  std::vector<std::string> methods;
  while (std::getline(f, line)) {
    const auto parts = split(line, ',');
    if (parts.size() != 4) throw CliError(kExitBadInput, a.from_csv + ": malformed line '" + line + "'");
    rows.push_back({parts[0], std::stoi(parts[1]), std::stod(parts[2]), std::stod(parts[3])});
    if (std::find(methods.begin(), methods.end(), parts[0]) == methods.end()) methods.push_back(parts[0]);
  }
  const std::string png = (std::filesystem::path(a.out_dir) / (a.name + ".png")).string();
  write_plot(png, rows, methods);
  std::printf("wrote %s\n", png.c_str());
  report(rows, methods);
}

void run(const BenchArgs &a, CliContext &ctx) {
  if (!a.from_csv.empty()) return plot_only(a);
  std::ifstream in(a.scene);
  if (!in) throw CliError(kExitBadInput, "cannot read scene " + a.scene);
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string text = ss.str();
  if (text.find("<glint_bsdf") == std::string::npos)
    throw CliError(kExitBadInput, a.scene + ": the scene has no <glint_bsdf> node to compare methods on");
  const std::vector<std::string> methods = split(a.methods, ',');
  for (const auto &m : methods) rewrite_scene(text, m);  // validates every method name before any file is written
  std::vector<int> ladder;
  for (const auto &s : split(a.ladder, ',')) ladder.push_back(std::stoi(s));
  const std::string exe = self_path();
  const std::filesystem::path scene_dir = std::filesystem::absolute(a.scene).parent_path();
  // A fresh private folder with a random name (mkdtemp: 0700, never an existing one).
  std::string work_template = (std::filesystem::temp_directory_path() / "glimmer_bench_XXXXXX").string();
  if (::mkdtemp(work_template.data()) == nullptr)
    throw CliError(kExitBadInput, "cannot create a temporary folder: " + std::string(std::strerror(errno)));
  const std::filesystem::path work = work_template;
  std::filesystem::create_directories(a.out_dir);
  // Variant scenes are written beside the scene so relative assets resolve;
  // they and the work folder are removed however this function exits.
  struct Cleanup {
    std::map<std::string, std::string> &scenes;
    std::filesystem::path work;
    ~Cleanup() {
      std::error_code ec;
      for (const auto &[m, p] : scenes) std::filesystem::remove(p, ec);
      std::filesystem::remove_all(work, ec);
    }
  };
  std::map<std::string, std::string> scenes;
  const Cleanup cleanup{scenes, work};
  auto variant = [&](const std::string &method) {
    const std::string p = (scene_dir / (".bench_" + method + ".xml")).string();
    if (const std::string problem = write_file_atomically(p, rewrite_scene(text, method)); !problem.empty())
      throw CliError(kExitBadInput, problem);
    return p;
  };
  for (const auto &m : methods) scenes[m] = variant(m);
  if (!scenes.count("jakob14")) scenes["jakob14"] = variant("jakob14");

  std::printf("reference: jakob14 at %d spp...\n", a.reference_samples);
  std::fflush(stdout);
  const std::string ref_path = (work / "reference.exr").string();
  // Another sampling seed than the ladder: the ladder's first samples must not
  // be the reference's own samples (that correlation would fake convergence).
  const double ref_time = render(exe, ctx.plugin_path, scenes["jakob14"], ref_path, a.reference_samples, a, 7919);
  int w = 0, h = 0;
  const std::vector<float> ref = read_pixels(ref_path, w, h);
  std::printf("reference: %.2f s\n", ref_time);

  std::vector<Row> rows;
  for (const auto &m : methods)
    for (int spp : ladder) {
      const std::string out = (work / (m + "_" + std::to_string(spp) + ".exr")).string();
      const double t = render(exe, ctx.plugin_path, scenes[m], out, spp, a);
      int w2 = 0, h2 = 0;
      const double e = rmse(read_pixels(out, w2, h2), ref);
      rows.push_back({m, spp, t, e});
      std::printf("%-15s %5d spp  %8.3f s  RMSE %.5f\n", m.c_str(), spp, t, e);
      std::fflush(stdout);
    }

  const std::string csv = (std::filesystem::path(a.out_dir) / (a.name + ".csv")).string();
  std::ostringstream table;
  table << "method,samples,seconds,rmse\n";
  for (const auto &r : rows) table << r.method << "," << r.samples << "," << r.seconds << "," << r.error << "\n";
  if (const std::string problem = write_file_atomically(csv, table.str()); !problem.empty())
    throw CliError(kExitBadInput, problem);
  const std::string png = (std::filesystem::path(a.out_dir) / (a.name + ".png")).string();
  write_plot(png, rows, methods);
  std::printf("wrote %s and %s\n", csv.c_str(), png.c_str());

  report(rows, methods);
}

// Speed-up at equal RMSE: the jakob14 errors, reached by each other method.
void report(const std::vector<Row> &rows, const std::vector<std::string> &methods) {
  for (const auto &m : methods) {
    if (m == "jakob14" || m == "ggx") continue;
    for (const auto &r : rows) {
      if (r.method != "jakob14") continue;
      const double t = time_at_error(rows, m, r.error);
      if (t > 0) std::printf("equal RMSE %.5f: jakob14 %.3f s, %s %.3f s, speed-up %.1fx\n", r.error, r.seconds,
                             m.c_str(), t, r.seconds / t);
    }
  }
}

struct ConvergenceArgs {
  std::string scene;
  std::string ladder = "16,32,64,128,256";
  int reference_samples = 4096;
  int width = 0, height = 0, threads = 0, seed = 1;
  std::string csv;
};

void run_convergence(const ConvergenceArgs &a, CliContext &ctx) {
  scene::Scene scene;
  try {
    scene = scene::load_scene(a.scene);
  } catch (const scene::SceneError &e) {
    throw CliError(kExitBadInput, e.what());
  }
  render::ConvergenceOptions opt;
  opt.ladder.clear();
  for (const auto &s : split(a.ladder, ',')) {
    try {
      opt.ladder.push_back(std::stoi(s));
    } catch (const std::exception &) {
      throw CliError(kExitBadInput, "bench convergence: --samples: '" + s + "' is not a sample count");
    }
  }
  opt.reference_samples = a.reference_samples;
  opt.width = a.width;
  opt.height = a.height;
  opt.seed = a.seed;
  std::unique_ptr<tbb::global_control> threads;
  if (a.threads > 0)
    threads = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                    static_cast<size_t>(a.threads));
  render::ConvergenceResult r;
  try {
    r = render::measure_convergence(scene, ctx.plugin(), opt);
  } catch (const std::invalid_argument &e) {
    throw CliError(kExitBadInput, std::string("bench convergence: ") + e.what());
  } catch (const scene::SceneError &e) {
    throw CliError(kExitBadInput, e.what());
  }
  std::printf("reference: %d spp, %.3f s\n", a.reference_samples, r.reference_seconds);
  std::printf("%8s %10s %12s\n", "spp", "seconds", "rmse");
  for (const auto &p : r.points) std::printf("%8d %10.4f %12.6g\n", p.samples, p.seconds, p.rmse);
  std::printf("slope vs spp: %.3f\nslope vs time: %.3f\n", r.slope_spp, r.slope_time);
  if (!a.csv.empty()) {
    std::ostringstream f;
    f << "samples,seconds,rmse\n";
    for (const auto &p : r.points) f << p.samples << "," << p.seconds << "," << p.rmse << "\n";
    if (const std::string problem = write_file_atomically(a.csv, f.str()); !problem.empty())
      throw CliError(kExitBadInput, "cannot write " + a.csv + ": " + problem);
  }
}

}  // namespace

void add_bench_command(CLI::App &app, CliContext &ctx) {
  auto *bench = app.add_subcommand("bench", "benchmarks that render scenes (error vs time)");
  bench->require_subcommand(1);
  auto args = std::make_shared<BenchArgs>();
  auto *evt = bench->add_subcommand("error-vs-time", "RMSE against a converged jakob14 render vs render time, per glint method");
  evt->add_option("scene", args->scene, "scene with at least one <glint_bsdf> (not needed with --from-csv)");
  evt->add_option("--methods", args->methods, "comma list of jakob14,dsm-unfiltered,dsm-filtered,ggx");
  evt->add_option("--samples", args->ladder, "comma list of samples per pixel (the ladder)");
  evt->add_option("--reference-samples", args->reference_samples, "samples of the converged jakob14 reference")
      ->check(CLI::Range(1, 1 << 20));
  evt->add_option("--width", args->width, "image width")->check(CLI::Range(1, 65536));
  evt->add_option("--height", args->height, "image height")->check(CLI::Range(1, 65536));
  evt->add_option("--threads", args->threads, "render threads (0 = all cores)")->check(CLI::Range(0, 4096));
  evt->add_option("--out-dir", args->out_dir, "folder for the CSV and the PNG plot");
  evt->add_option("--name", args->name, "base name of the CSV and PNG files");
  evt->add_option("--from-csv", args->from_csv, "only re-plot (and report on) an existing CSV");
  evt->callback([args, &ctx] { run(*args, ctx); });

  auto cargs = std::make_shared<ConvergenceArgs>();
  auto *conv = bench->add_subcommand("convergence", "RMSE vs spp and vs time against a high-spp reference of the same "
                                                    "renderer, with the fitted log-log slopes");
  conv->add_option("scene", cargs->scene, "scene file")->required();
  conv->add_option("--samples", cargs->ladder, "comma list of samples per pixel (the ladder)");
  conv->add_option("--reference-samples", cargs->reference_samples, "samples of the reference (above the ladder)")
      ->check(CLI::Range(2, 1 << 24));
  conv->add_option("--width", cargs->width, "image width (0 = the camera's)")->check(CLI::Range(0, 65536));
  conv->add_option("--height", cargs->height, "image height (0 = the camera's)")->check(CLI::Range(0, 65536));
  conv->add_option("--threads", cargs->threads, "render threads (0 = all cores)")->check(CLI::Range(0, 4096));
  conv->add_option("--seed", cargs->seed, "sampling seed of the ladder (the reference uses seed + 7919)");
  conv->add_option("--csv", cargs->csv, "also write samples,seconds,rmse to this CSV");
  conv->callback([cargs, &ctx] { run_convergence(*cargs, ctx); });
}

}  // namespace glimmer::cli
