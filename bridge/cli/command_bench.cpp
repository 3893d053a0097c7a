// `glimmer bench convergence`: RMSE vs spp and vs time of one scene against a
// high-spp reference of the same renderer, with the fitted log-log slopes
// (render/convergence.h).
// `glimmer bench error-vs-time`: time-vs-error comparison of the methods of
// one material. Renders variants of the scene (the material's nodes rewritten
// per method) at a ladder of sample counts by running `glimmer render` as a
// subprocess, measures the render-phase wall time and the RMSE against a
// converged render of the material's reference method, and writes a CSV and a
// log-log PNG plot. Materials (--material, else the one the scene uses):
//  glint (glint_bsdf; reference jakob14):
//   jakob14         glint_jakob14_bsdf (Jakob 2014 reference)
//   dsm-unfiltered  glint_bsdf with filter_threshold = 1e9 (always counts glints)
//   dsm-filtered    glint_bsdf as written in the scene (filter threshold 16 by default)
//   ggx             glossy_bsdf (plain GGX of the same roughness, no glints)
//  frosted (frosted_glass_bsdf; reference path):
//   path, sg, auto  every frosted_glass_bsdf with method = path / sg / auto
// With --reference own every method is measured against its own converged
// render (its Monte Carlo error: two glint models are different particle
// fields, so against jakob14 a glint model's error stops at the difference of
// two realizations), and the RMSE between the converged renders is reported.
// --reference-seeds N renders N references on different seeds; their spread's
// variance of the mean is subtracted from every MSE (bench_error.h), so the
// figures are the methods' own errors, not the reference's noise. --regions
// adds the same figures per region of an id pass (one per shader) or of a
// mask image. --path-strategy sets the direct-light estimator (mis | bsdf) of
// the reference method's renders; path-mis / path-bsdf are frosted methods
// that render path with that estimator whatever --path-strategy is. --seed S --seeds N renders every rung on the
// seeds S .. S + N - 1 (default: one image on the scene's seed): the rung's MSE is the mean of the N images'
// (independent images, so two runs on other seeds agree within the estimate's noise), and with N >= 2 the log and
// the regions CSV also split it into noise (variance) and bias^2 (bench_error.h seed_errors).
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <regex>
#include <sstream>
#include <sys/resource.h>
#include <unistd.h>

#include <tbb/global_control.h>

#include "cli/bench_error.h"
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
  std::string material = "auto";  // glint | frosted | auto (the one the scene uses)
  std::string methods;            // empty: the material's default list
  double at_seconds = 60.0;       // the summary compares methods at the RMSE the reference reaches in this time
  std::string clock = "wall";     // wall: the render phase's wall time; cpu: the render process's CPU time
  std::string ladder = "1,2,4,8,16,32";
  int reference_samples = 256;
  int width = 160, height = 100;
  int threads = 0;
  std::string out_dir = "docs";
  std::string name;  // empty: <material>_error_vs_time
  std::string from_csv;  // re-plot an existing CSV without rendering
  std::string reference = "material";  // "material": the material's reference method (jakob14, path); "own": each method's own
  std::string path_strategy = "mis";   // direct-light estimator of the reference method's renders (ladder + reference)
  int reference_seeds = 1;             // references on different seeds; >= 2: their noise is subtracted
  std::string reference_images;        // comma list of EXRs used as the references instead of rendering them
  std::string regions = "none";        // none | auto (an id pass, one region per shader) | an id / mask image
  int seed = -1;                       // the methods' sampling seed (-1: the scene's integrator seed, no --seed)
  int seeds = 1;                       // images per rung, on seeds seed, seed + 1, ...: their MSEs are averaged
};

// The k-th converged reference's sampling seed (other seeds than the ladder's: see run()).
int reference_seed(int k) { return 7919 + 1013 * k; }

// The sampling seeds of every rung's images: {-1} (the scene's seed) by default, else seed .. seed + seeds - 1.
std::vector<int> ladder_seeds(const BenchArgs &a) {
  if (a.seed < 0) return {-1};
  std::vector<int> out;
  for (int k = 0; k < a.seeds; ++k) out.push_back(a.seed + k);
  return out;
}

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

// The glint scene text rewritten for one method.
std::string rewrite_glint(const std::string &text, const std::string &method) {
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
  return {};
}

// The frosted glass scene text with every frosted_glass_bsdf's method set to `method`.
// path-mis / path-bsdf are method=path (rendered with that direct-light strategy, strategy_of below).
std::string rewrite_frosted(const std::string &text, const std::string &method_name) {
  const std::string method = method_name.rfind("path-", 0) == 0 ? "path" : method_name;
  if ((method != "path" && method != "sg" && method != "auto") ||
      (method_name != method && method_name != "path-mis" && method_name != "path-bsdf"))
    return {};
  const std::string t = std::regex_replace(text, std::regex("(<frosted_glass_bsdf\\b[^>]*?)\\s+method=\"[^\"]*\""), "$1");
  return std::regex_replace(t, std::regex("<frosted_glass_bsdf\\b"), "<frosted_glass_bsdf method=\"" + method + "\"");
}

// A material whose methods the bench compares.
struct Material {
  const char *name;
  const char *node;       // the XML node the methods rewrite
  const char *reference;  // the method of the converged reference
  const char *methods;    // default list
  const char *accepted;   // every accepted name
  const char *unrated;    // a method shown but not given a speed-up (not an estimator of the reference), or ""
  std::string (*rewrite)(const std::string &text, const std::string &method);
};
constexpr Material kMaterials[] = {
    {"glint", "glint_bsdf", "jakob14", "jakob14,dsm-unfiltered,dsm-filtered,ggx",
     "jakob14,dsm-unfiltered,dsm-filtered,ggx", "ggx", rewrite_glint},
    {"frosted", "frosted_glass_bsdf", "path", "path,sg", "path,sg,auto,path-mis,path-bsdf", "", rewrite_frosted},
};

bool uses_node(const std::string &text, const Material &m) {
  return std::regex_search(text, std::regex(std::string("<") + m.node + "\\b"));
}

// --material, or the one material of the scene (`text`) / of the CSV's methods.
const Material &pick_material(const std::string &requested, const std::string &text,
                              const std::vector<std::string> &csv_methods) {
  for (const Material &m : kMaterials)
    if (requested == m.name) return m;
  if (requested != "auto") throw CliError(kExitBadInput, "bench error-vs-time: unknown --material '" + requested +
                                                             "' (expected glint, frosted or auto)");
  const Material *found = nullptr;
  for (const Material &m : kMaterials) {
    const bool used = csv_methods.empty() ? uses_node(text, m)
                                          : std::count(csv_methods.begin(), csv_methods.end(), m.reference) > 0;
    if (!used) continue;
    if (found != nullptr)
      throw CliError(kExitBadInput, std::string("bench error-vs-time: the ") +
                                        (csv_methods.empty() ? "scene has both <" + std::string(found->node) +
                                                                   "> and <" + m.node + "> nodes"
                                                             : std::string("CSV holds both materials' references")) +
                                        ": choose one with --material " + found->name + " or --material " + m.name);
    found = &m;
  }
  if (found == nullptr)
    throw CliError(kExitBadInput,
                   csv_methods.empty()
                       ? std::string("the scene has no <glint_bsdf> or <frosted_glass_bsdf> node to compare methods on")
                       : std::string("the CSV has no reference method (jakob14 or path)"));
  return *found;
}

// The scene text rewritten for one method of the material (a clear error for an unknown one).
std::string rewrite_scene(const std::string &text, const Material &material, const std::string &method) {
  std::string t = material.rewrite(text, method);
  if (t.empty())
    throw CliError(kExitBadInput, "bench error-vs-time: unknown method '" + method + "' for " + material.name +
                                      " (expected one of " + material.accepted + ")");
  return t;
}

double children_cpu_seconds() {
  rusage u{};
  getrusage(RUSAGE_CHILDREN, &u);
  return double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) + 1e-6 * double(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

// Runs `glimmer render` and returns its seconds: the render phase's wall time (--clock wall), or the render
// process's whole CPU time (--clock cpu: loading included, steadier than wall time on a shared machine).
double render(const std::string &exe, const std::string &plugin, const std::string &scene, const std::string &out,
              int samples, const BenchArgs &a, int seed = -1, const std::string &strategy = "") {
  std::string cmd = "'" + exe + "'";
  if (!plugin.empty()) cmd += " --plugin '" + plugin + "'";
  cmd += " render '" + scene + "' -o '" + out + "' --samples " + std::to_string(samples) + " --width " +
         std::to_string(a.width) + " --height " + std::to_string(a.height) + " --threads " +
         std::to_string(a.threads) + (seed >= 0 ? " --seed " + std::to_string(seed) : std::string()) +
         (strategy.empty() ? std::string() : " --strategy " + strategy) +
         " --quiet --stats 2>&1";
  const double cpu_before = children_cpu_seconds();
  FILE *p = popen(cmd.c_str(), "r");
  if (p == nullptr) throw CliError(kExitBadInput, "cannot run " + cmd);
  std::string text;
  char buf[512];
  while (fgets(buf, sizeof(buf), p) != nullptr) text += buf;
  const int status = pclose(p);
  std::smatch m;
  if (status != 0 || !std::regex_search(text, m, std::regex("render=([0-9.eE+-]+)s")))
    throw CliError(kExitBadInput, "render failed (" + cmd + "):\n" + text);
  return a.clock == "cpu" ? children_cpu_seconds() - cpu_before : std::stod(m[1].str());
}

std::vector<float> read_pixels(const std::string &path, int &w, int &h) {
  try {
    return render::image_io().read_rgb(path, w, h);
  } catch (const std::runtime_error &e) {
    throw CliError(kExitBadInput, e.what());
  }
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

// RMSE of a method after `seconds` (log-log interpolation between its ladder points; <0 outside the ladder).
double error_at_time(const std::vector<Row> &rows, const std::string &method, double seconds) {
  const Row *prev = nullptr;
  for (const auto &r : rows) {
    if (r.method != method) continue;
    if (prev != nullptr && prev->seconds <= seconds && seconds <= r.seconds && r.seconds > prev->seconds) {
      const double f = (std::log(seconds) - std::log(prev->seconds)) / (std::log(r.seconds) - std::log(prev->seconds));
      return std::exp(std::log(prev->error) + f * (std::log(r.error) - std::log(prev->error)));
    }
    prev = &r;
  }
  return -1.0;
}

// The RMSE of the (unbiased) reference method after `seconds` beyond its ladder: MSE x time is constant for an
// unbiased estimator, taken as the mean of error^2 x seconds over its last (up to) 3 rungs; <0 when the ladder
// already reaches `seconds` or has no rung.
double extrapolated_error(const std::vector<Row> &rows, const std::string &method, double seconds) {
  std::vector<const Row *> own;
  for (const auto &r : rows)
    if (r.method == method && r.seconds > 0 && r.error > 0) own.push_back(&r);
  if (own.empty() || own.back()->seconds >= seconds) return -1.0;
  double sum = 0.0;
  const size_t first = own.size() > 3 ? own.size() - 3 : 0;
  for (size_t k = first; k < own.size(); ++k) sum += own[k]->error * own[k]->error * own[k]->seconds;
  return std::sqrt(sum / static_cast<double>(own.size() - first) / seconds);
}

void report(const std::vector<Row> &rows, const std::vector<std::string> &methods, const Material &material,
            double at_seconds);
void report_at(const std::vector<Row> &rows, const std::vector<std::string> &methods, const Material &material,
               double at_seconds, const std::string &label);

std::string output_name(const BenchArgs &a, const Material &material) {
  return a.name.empty() ? std::string(material.name) + "_error_vs_time" : a.name;
}

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
  const Material &material = pick_material(a.material, {}, methods);
  std::filesystem::create_directories(a.out_dir);
  const std::string png = (std::filesystem::path(a.out_dir) / (output_name(a, material) + ".png")).string();
  write_plot(png, rows, methods);
  std::printf("wrote %s\n", png.c_str());
  report(rows, methods, material, a.at_seconds);
}

// The direct-light strategy a method renders with ("" = the renderer's default, mis).
std::string strategy_of(const std::string &method, const Material &material, const BenchArgs &a) {
  if (method == "path-mis") return "mis";
  if (method == "path-bsdf") return "bsdf";
  return method == material.reference ? a.path_strategy : std::string();
}

// The scene as an id pass: no lamps, a black world, and shader k an emitter of the binary colour k + 1 (bits R, G,
// B; bench_error.h binary_id_regions). Returns the shader names in order; more than 7 shaders is an error.
std::string id_scene(const std::string &text, std::vector<std::string> &shaders) {
  std::string t = std::regex_replace(text, std::regex("<light\\b[^>]*/>"), "");
  t = std::regex_replace(t, std::regex("<background>[\\s\\S]*?</background>"),
                         "<background><background name=\"sky\" color=\"0 0 0\" strength=\"0\" />"
                         "<connect from=\"sky background\" to=\"output surface\" /></background>");
  const std::regex shader("<shader\\s+name=\"([^\"]+)\"[^>]*>[\\s\\S]*?</shader>");
  std::string out;
  auto last = t.cbegin();
  for (std::sregex_iterator it(t.begin(), t.end(), shader), end; it != end; ++it) {
    shaders.push_back((*it)[1].str());
    const int k = static_cast<int>(shaders.size());
    if (k > 7)
      throw CliError(kExitBadInput, "bench error-vs-time --regions auto: more than 7 shaders; pass an id image "
                                    "(--regions FILE) instead");
    const std::string colour = std::to_string(k & 1) + " " + std::to_string((k >> 1) & 1) + " " +
                               std::to_string((k >> 2) & 1);
    out.append(last, (*it)[0].first);
    out += "<shader name=\"" + shaders.back() + "\"><emission name=\"bench_id\" color=\"" + colour +
           "\" strength=\"1\" /><connect from=\"bench_id emission\" to=\"output surface\" /></shader>";
    last = (*it)[0].second;
  }
  out.append(last, t.cend());
  return out;
}

// Per-pixel regions (bench_error.h) and their names: index 0 = black ("world" for the id pass), 1..7 = shader
// k or id colour k, 8 = "edges" (mixed ids).
struct Regions {
  std::vector<int> index;  // empty: no regions
  std::vector<std::string> names;
};

struct RunContext {
  const BenchArgs &a;
  const Material &material;
  std::string exe, plugin;
  std::filesystem::path work;
  std::map<std::string, std::string> &scenes;
};

Regions make_regions(const RunContext &c, const std::string &text, const std::string &scene_dir_variant) {
  Regions r;
  if (c.a.regions == "none") return r;
  std::vector<float> ids;
  int w = 0, h = 0;
  std::vector<std::string> shaders;
  if (c.a.regions == "auto") {
    const std::string id_text = id_scene(text, shaders);
    if (const std::string problem = write_file_atomically(scene_dir_variant, id_text); !problem.empty())
      throw CliError(kExitBadInput, problem);
    c.scenes["(ids)"] = scene_dir_variant;
    const std::string out = (c.work / "ids.exr").string();
    render(c.exe, c.plugin, scene_dir_variant, out, 16, c.a, 1);
    ids = read_pixels(out, w, h);
  } else {
    ids = read_pixels(c.a.regions, w, h);
    if (w != c.a.width || h != c.a.height)
      throw CliError(kExitBadInput, "--regions " + c.a.regions + ": " + std::to_string(w) + "x" + std::to_string(h) +
                                        ", the bench renders " + std::to_string(c.a.width) + "x" +
                                        std::to_string(c.a.height));
  }
  r.index = bench::binary_id_regions(ids);
  r.names.push_back(c.a.regions == "auto" ? "world" : "id0");
  // A shader named like one of the bench's own regions ("all": the whole image, "world", "edges") is "shader:NAME".
  const auto shader_region = [](const std::string &name) {
    return (name == "all" || name == "world" || name == "edges") ? "shader:" + name : name;
  };
  for (int k = 1; k <= 7; ++k)
    r.names.push_back(c.a.regions == "auto" ? (k <= static_cast<int>(shaders.size()) ? shader_region(shaders[k - 1])
                                                                                        : "id" + std::to_string(k))
                                            : "id" + std::to_string(k));
  r.names.push_back("edges");
  return r;
}

// The converged reference of a method's source (N seeds, or the given images), combined (bench_error.h).
bench::Reference render_reference(const RunContext &c, const std::string &source) {
  std::vector<std::vector<float>> images;
  if (!c.a.reference_images.empty()) {
    for (const auto &path : split(c.a.reference_images, ',')) {
      int w = 0, h = 0;
      images.push_back(read_pixels(path, w, h));
      if (w != c.a.width || h != c.a.height)
        throw CliError(kExitBadInput, "--reference-images " + path + ": not " + std::to_string(c.a.width) + "x" +
                                          std::to_string(c.a.height));
    }
    std::printf("reference: %s from %zu image(s)\n", source.c_str(), images.size());
  } else {
    const std::string strategy = strategy_of(source, c.material, c.a);
    for (int k = 0; k < c.a.reference_seeds; ++k) {
      const int seed = reference_seed(k);
      std::printf("reference: %s at %d spp%s (seed %d)...\n", source.c_str(), c.a.reference_samples,
                  strategy.empty() ? "" : (", strategy " + strategy).c_str(), seed);
      std::fflush(stdout);
      const std::string ref_path = (c.work / ("reference_" + source + "_" + std::to_string(k) + ".exr")).string();
      const double t = render(c.exe, c.plugin, c.scenes[source], ref_path, c.a.reference_samples, c.a, seed, strategy);
      int w = 0, h = 0;
      images.push_back(read_pixels(ref_path, w, h));
      std::printf("reference: %s %.2f s\n", source.c_str(), t);
    }
  }
  bench::Reference ref = bench::combine_references(images);
  if (ref.count >= 2) {
    const auto all = bench::region_errors(ref.mean, ref, {}, 0).back();
    std::printf("reference: %d images, RMS noise of their mean %.5f over the image (each region's own noise is "
                "subtracted from its MSE)\n", ref.count, std::sqrt(all.var_ref_mean));
  }
  return ref;
}

// Every method at every rung of the ladder: the rows over all pixels, per region, and the regions CSV's text.
struct Ladder {
  std::vector<Row> rows;
  std::vector<std::vector<Row>> region_rows;
  std::ostringstream region_csv;
};

// One rung: method `m` at `spp` on every ladder seed; the mean of the images' seconds (one image's time) and their
// errors (bench_error.h seed_errors).
bench::SeedErrors measure_rung(const RunContext &c, const std::string &m, int spp, const bench::Reference &ref,
                               const Regions &regions, double &seconds) {
  const std::vector<int> seeds = ladder_seeds(c.a);
  std::vector<std::vector<float>> images;
  seconds = 0.0;
  for (int seed : seeds) {
    const std::string image = (c.work / (m + "_" + std::to_string(spp) +
                                         (seed < 0 ? std::string() : "_s" + std::to_string(seed)) + ".exr")).string();
    seconds += render(c.exe, c.plugin, c.scenes[m], image, spp, c.a, seed, strategy_of(m, c.material, c.a)) /
               static_cast<double>(seeds.size());
    int w = 0, h = 0;
    images.push_back(read_pixels(image, w, h));
  }
  return bench::seed_errors(images, ref, regions.index, static_cast<int>(regions.names.size()));
}

// The rung's log lines: the whole image's RMSE (the reference's noise subtracted; "raw" without), once per method
// the reference's noise per region, then each region's; with several seeds, each line's noise / bias split.
void print_rung(const std::string &m, int spp, double t, bool first_rung, const bench::SeedErrors &s,
                const bench::Reference &ref, const Regions &regions) {
  const auto split_of = [&](size_t k) {
    if (s.bias2.empty()) return std::string();
    char buf[96];
    std::snprintf(buf, sizeof(buf), " noise %.5f bias %.5f (bias^2 %.3g)", std::sqrt(std::max(s.variance[k], 0.0)),
                  std::sqrt(std::max(s.bias2[k], 0.0)), s.bias2[k]);
    return std::string(buf);
  };
  const bench::RegionError &all = s.errors.back();
  std::printf("%-15s %5d spp  %8.3f s  RMSE %.5f", m.c_str(), spp, t, all.rmse());
  if (ref.count >= 2) std::printf(" (raw %.5f)", all.rmse_raw());
  std::printf("%s%s\n", s.count > 1 ? (" over " + std::to_string(s.count) + " seeds").c_str() : "",
              split_of(s.errors.size() - 1).c_str());
  if (first_rung && ref.count >= 2 && !regions.names.empty()) {  // once per method: the same for every rung
    std::printf("    reference noise per region (RMS of their mean, subtracted):");
    for (size_t k = 0; k < regions.names.size(); ++k)
      if (s.errors[k].pixels > 0) std::printf(" %s %.5f", regions.names[k].c_str(), std::sqrt(s.errors[k].var_ref_mean));
    std::printf("\n");
  }
  for (size_t k = 0; k < regions.names.size(); ++k)
    if (s.errors[k].pixels > 0)
      std::printf("    %-14s %5zu px  RMSE %.5f (raw %.5f)%s\n", regions.names[k].c_str(), s.errors[k].pixels,
                  s.errors[k].rmse(), s.errors[k].rmse_raw(), split_of(k).c_str());
}

void measure_ladder(const RunContext &c, const std::vector<std::string> &methods, const std::vector<int> &ladder,
                    const Regions &regions, const std::function<const bench::Reference &(const std::string &)> &reference_of,
                    Ladder &out) {
  const bool split = ladder_seeds(c.a).size() >= 2;  // the CSV's noise / bias columns (only then: else as before)
  out.region_rows.resize(regions.names.size());
  out.region_csv << "method,samples,seconds,region,pixels,rmse,rmse_raw" << (split ? ",seeds,variance,bias2" : "")
                 << "\n";
  for (const auto &m : methods)
    for (int spp : ladder) {
      const bench::Reference &ref = reference_of(m);
      double t = 0.0;
      const bench::SeedErrors s = measure_rung(c, m, spp, ref, regions, t);
      out.rows.push_back({m, spp, t, s.errors.back().rmse()});
      print_rung(m, spp, t, spp == ladder.front(), s, ref, regions);
      // Each region, then the whole image as region "all": the fit and plot scripts read every region, "all"
      // included, from this one file.
      for (size_t k = 0; k < s.errors.size(); ++k) {
        const bench::RegionError &e = s.errors[k];
        const bool whole = k + 1 == s.errors.size();
        if (e.pixels == 0 || (whole && regions.index.empty())) continue;
        if (!whole) out.region_rows[k].push_back({m, spp, t, e.rmse()});
        out.region_csv << m << "," << spp << "," << t << "," << (whole ? std::string("all") : regions.names[k]) << ","
                       << e.pixels << "," << e.rmse() << "," << e.rmse_raw();
        if (split) out.region_csv << "," << s.count << "," << s.variance[k] << "," << s.bias2[k];
        out.region_csv << "\n";
      }
      std::fflush(stdout);
    }
}

void write_outputs(const BenchArgs &a, const Material &material, const std::vector<Row> &rows,
                   const std::vector<std::string> &methods, const std::string &region_csv) {
  const std::string csv = (std::filesystem::path(a.out_dir) / (output_name(a, material) + ".csv")).string();
  std::ostringstream table;
  table << "method,samples,seconds,rmse\n";
  for (const auto &r : rows) table << r.method << "," << r.samples << "," << r.seconds << "," << r.error << "\n";
  if (const std::string problem = write_file_atomically(csv, table.str()); !problem.empty())
    throw CliError(kExitBadInput, problem);
  const std::string png = (std::filesystem::path(a.out_dir) / (output_name(a, material) + ".png")).string();
  write_plot(png, rows, methods);
  std::printf("wrote %s and %s\n", csv.c_str(), png.c_str());
  if (region_csv.empty()) return;
  const std::string rcsv = (std::filesystem::path(a.out_dir) / (output_name(a, material) + "_regions.csv")).string();
  if (const std::string problem = write_file_atomically(rcsv, region_csv); !problem.empty())
    throw CliError(kExitBadInput, problem);
  std::printf("wrote %s\n", rcsv.c_str());
}

std::string read_scene_text(const std::string &path) {
  std::ifstream in(path);
  if (!in) throw CliError(kExitBadInput, "cannot read scene " + path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// The material whose methods the bench compares in the scene (--material, or the one the scene uses).
const Material &scene_material(const BenchArgs &a, const std::string &text) {
  const Material &material = [&]() -> const Material & {
    try {
      return pick_material(a.material, text, {});
    } catch (const CliError &e) {
      throw CliError(kExitBadInput, a.scene + ": " + e.what());
    }
  }();
  if (!uses_node(text, material))
    throw CliError(kExitBadInput, a.scene + ": the scene has no <" + material.node + "> node to compare methods on");
  return material;
}

// --seeds N >= 2 needs --seed; no ladder image may share a rendered reference's seed (7919 + 1013 k: the
// reference would then hold the image's own samples and fake convergence).
void check_seeds(const BenchArgs &a) {
  if (a.seeds >= 2 && a.seed < 0)
    throw CliError(kExitBadInput, "bench error-vs-time: --seeds " + std::to_string(a.seeds) +
                                      " needs --seed (the first of the seeds)");
  if (!a.reference_images.empty()) return;
  for (int seed : ladder_seeds(a))
    for (int k = 0; k < a.reference_seeds; ++k)
      if (seed == reference_seed(k))
        throw CliError(kExitBadInput, "bench error-vs-time: --seed: seed " + std::to_string(seed) +
                                          " is a reference's seed (7919 + 1013 k); choose others");
}

void run(const BenchArgs &a, CliContext &ctx) {
  if (!a.from_csv.empty()) return plot_only(a);
  const std::string text = read_scene_text(a.scene);
  const Material &material = scene_material(a, text);
  const std::vector<std::string> methods = split(a.methods.empty() ? material.methods : a.methods, ',');
  for (const auto &m : methods) rewrite_scene(text, material, m);  // validates every name before any file is written
  if (!a.reference_images.empty() && a.reference == "own")
    throw CliError(kExitBadInput, "bench error-vs-time: --reference-images needs --reference material");
  check_seeds(a);
  std::vector<int> ladder;
  for (const auto &s : split(a.ladder, ',')) ladder.push_back(std::stoi(s));
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
  // Named after the private work folder too: two runs on one scene never write or remove each other's variants.
  auto variant_path = [&](const std::string &method) {
    return (scene_dir / (".bench_" + work.filename().string() + "_" + method + ".xml")).string();
  };
  auto variant = [&](const std::string &method) {
    const std::string p = variant_path(method);
    if (const std::string problem = write_file_atomically(p, rewrite_scene(text, material, method)); !problem.empty())
      throw CliError(kExitBadInput, problem);
    return p;
  };
  for (const auto &m : methods) scenes[m] = variant(m);
  if (!scenes.count(material.reference)) scenes[material.reference] = variant(material.reference);
  const RunContext c{a, material, self_path(), ctx.plugin_path, work, scenes};
  const Regions regions = make_regions(c, text, variant_path("ids"));

  // The converged renders. Other sampling seeds than the ladder: the ladder's
  // first samples must not be the reference's own samples (that correlation
  // would fake convergence).
  std::map<std::string, bench::Reference> references;
  auto reference_of = [&](const std::string &m) -> const bench::Reference & {
    const std::string source = a.reference == "own" ? m : std::string(material.reference);
    if (!references.count(source)) {
      references[source] = render_reference(c, source);
      if (source != material.reference && references.count(material.reference))
        std::printf("converged %s vs converged %s: RMSE %.5f\n", source.c_str(), material.reference,
                    bench::region_errors(references[source].mean, references[material.reference], {}, 0)
                        .back().rmse_raw());
    }
    return references[source];
  };
  reference_of(material.reference);

  // One 1-spp render per method before the clock counts: lazily built tables (glint, frosted sg) reach the cache.
  for (const auto &m : methods)
    render(c.exe, c.plugin, scenes[m], (work / "warm_up.exr").string(), 1, a, -1, strategy_of(m, material, a));

  Ladder out;
  measure_ladder(c, methods, ladder, regions, reference_of, out);
  write_outputs(a, material, out.rows, methods, regions.index.empty() ? std::string() : out.region_csv.str());
  report(out.rows, methods, material, a.at_seconds);
  for (size_t k = 0; k < out.region_rows.size(); ++k)
    if (!out.region_rows[k].empty())
      report_at(out.region_rows[k], methods, material, a.at_seconds, "region " + regions.names[k] + ": ");
}

// At the RMSE the reference method reaches in `at_seconds`: each other method's time to it (`label` prefixes
// every line).
void report_at(const std::vector<Row> &rows, const std::vector<std::string> &methods, const Material &material,
               double at_seconds, const std::string &label) {
  const std::string ref = material.reference;
  double target = error_at_time(rows, ref, at_seconds);
  if (target < 0) target = extrapolated_error(rows, ref, at_seconds);
  if (target < 0) {
    std::printf("%s%s's ladder does not span %.4g s: no comparison at its %.4g-s RMSE\n", label.c_str(), ref.c_str(),
                at_seconds, at_seconds);
    return;
  }
  if (error_at_time(rows, ref, at_seconds) < 0)
    std::printf("%s%s's %.4g-s RMSE %.5f is extrapolated from its last rungs (MSE x time constant: the reference "
                "method is unbiased)\n", label.c_str(), ref.c_str(), at_seconds, target);
  for (const auto &m : methods) {
    if (m == ref || m == material.unrated) continue;
    const double t = time_at_error(rows, m, target);
    if (t > 0) std::printf("%sat %s's %.4g-s RMSE %.5f: %s %.3f s, speed-up %.1fx\n", label.c_str(), ref.c_str(),
                           at_seconds, target, m.c_str(), t, at_seconds / t);
    else std::printf("%sat %s's %.4g-s RMSE %.5f: %s never reaches it on the ladder\n", label.c_str(), ref.c_str(),
                     at_seconds, target, m.c_str());
  }
}

// Speed-up at equal RMSE: the reference method's errors (and the one it reaches in `at_seconds`), reached by
// each other method; a method that never gets there (a biased one's plateau) is said so.
void report(const std::vector<Row> &rows, const std::vector<std::string> &methods, const Material &material,
            double at_seconds) {
  const std::string ref = material.reference;
  for (const auto &m : methods) {
    if (m == ref || m == material.unrated) continue;
    for (const auto &r : rows) {
      if (r.method != ref) continue;
      const double t = time_at_error(rows, m, r.error);
      if (t > 0) std::printf("equal RMSE %.5f: %s %.3f s, %s %.3f s, speed-up %.1fx\n", r.error, ref.c_str(),
                             r.seconds, m.c_str(), t, r.seconds / t);
      else std::printf("equal RMSE %.5f: %s %.3f s, %s never reaches it on the ladder\n", r.error, ref.c_str(),
                       r.seconds, m.c_str());
    }
  }
  report_at(rows, methods, material, at_seconds, "");
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
  auto *evt = bench->add_subcommand("error-vs-time", "RMSE against a converged reference render vs render time, per "
                                                     "method of a material (glint: jakob14 reference; frosted: path)");
  evt->add_option("scene", args->scene,
                  "scene with at least one <glint_bsdf> or <frosted_glass_bsdf> (not needed with --from-csv)");
  evt->add_option("--material", args->material,
                  "glint or frosted (default auto: the one the scene uses, or whose reference the CSV holds)");
  evt->add_option("--methods", args->methods,
                  "comma list; glint: jakob14,dsm-unfiltered,dsm-filtered,ggx (default all); frosted: path,sg,auto "
                  "(default path,sg)");
  evt->add_option("--at-seconds", args->at_seconds, "summary: each method's time to the RMSE the reference method "
                                                    "reaches in this many seconds (interpolated on its ladder)")
      ->check(CLI::PositiveNumber);
  evt->add_option("--clock", args->clock, "wall (render phase, default) or cpu (the render process's CPU time)")
      ->check(CLI::IsMember({"wall", "cpu"}));
  evt->add_option("--samples", args->ladder, "comma list of samples per pixel (the ladder)");
  evt->add_option("--reference-samples", args->reference_samples, "samples of the converged reference (jakob14 / path)")
      ->check(CLI::Range(1, 1 << 20));
  evt->add_option("--width", args->width, "image width")->check(CLI::Range(1, 65536));
  evt->add_option("--height", args->height, "image height")->check(CLI::Range(1, 65536));
  evt->add_option("--threads", args->threads, "render threads (0 = all cores)")->check(CLI::Range(0, 4096));
  evt->add_option("--out-dir", args->out_dir, "folder for the CSV and the PNG plot");
  evt->add_option("--name", args->name, "base name of the CSV and PNG files (default <material>_error_vs_time)");
  evt->add_option("--from-csv", args->from_csv, "only re-plot (and report on) an existing CSV");
  evt->add_option("--reference", args->reference,
                  "material: every method against one converged render of the material's reference method (glint: "
                  "jakob14, frosted: path); own: each method against its own converged render (Monte Carlo error only)")
      ->check(CLI::IsMember({"material", "own"}));
  evt->add_option("--path-strategy", args->path_strategy,
                  "direct-light estimator of the reference method's renders, its ladder and its converged reference: "
                  "mis (default) or bsdf (BSDF sampling only; the firefly-free path through frosted panes)")
      ->check(CLI::IsMember({"mis", "bsdf"}));
  evt->add_option("--reference-seeds", args->reference_seeds,
                  "converged references on this many seeds; >= 2: every MSE has the variance of their mean (from their "
                  "spread) subtracted, so the RMSE is the method's own (default 1: nothing subtracted)")
      ->check(CLI::Range(1, 64));
  evt->add_option("--reference-images", args->reference_images,
                  "comma list of EXRs (same scene, size and reference method) used as the references instead of "
                  "rendering them; 2 or more: their noise is subtracted as with --reference-seeds")
      ->excludes("--reference-seeds");
  evt->add_option("--regions", args->regions,
                  "none (default); auto: an id pass (lamps off, black world, shader k an emitter of a binary colour) "
                  "gives one region per shader, 'world' and 'edges'; or an id / mask image of the bench's size whose "
                  "pixels are 0 or 1 per channel (regions id0..id7, other values 'edges'): RMSE and the speed-up "
                  "summary also per region, and <name>_regions.csv (with the whole image as region 'all')");
  evt->add_option("--seed", args->seed,
                  "sampling seed of the methods' ladder renders (default: the scene's integrator seed, as before)")
      ->check(CLI::Range(0, 1 << 30));
  evt->add_option("--seeds", args->seeds,
                  "images per rung on the seeds --seed, --seed + 1, ... (default 1): each rung's MSE is the mean of "
                  "theirs, and with 2 or more the log and the regions CSV (columns seeds,variance,bias2) split it into "
                  "one image's noise variance and the mean squared bias (bench_error.h seed_errors)")
      ->check(CLI::Range(1, 64));
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
