// `glimmer render scene.xml -o out.exr|png`: load a Cycles XML scene, render it
// with the DSO's closures and write the image atomically.
#include <tbb/global_control.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <iostream>
#include <new>
#include <sstream>

#include "cli/commands.h"
#include "render/image_output.h"
#include "render/renderer.h"
#include "scene/xml_loader.h"

namespace glimmer::cli {

namespace {

std::atomic<bool> g_interrupted{false};

// The first SIGINT/SIGTERM asks loading, preparation and rendering to stop;
// a second one terminates at once (the default action).
extern "C" void on_signal(int sig) {
  g_interrupted.store(true);
  std::signal(sig, SIG_DFL);
}

}  // namespace

void install_render_interrupt_handlers() {
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
}

namespace {

struct RenderArgs {
  std::string scene, output, region, frames, strategy = "mis";
  int samples = 0, threads = 0, width = 0, height = 0, seed = -1, tile_size = 32;
  double time_limit = 0.0;
  bool quiet = false, stats = false;
};

std::vector<int> parse_frames(const std::string &spec) {
  std::vector<int> frames;
  std::stringstream in(spec);
  std::string part;
  while (std::getline(in, part, ',')) {
    if (part.empty()) continue;
    try {
      const auto dash = part.find('-', 1);
      size_t used = 0;
      if (dash == std::string::npos) {
        frames.push_back(std::stoi(part, &used));
        if (used != part.size()) throw std::invalid_argument(part);
      } else {
        const int a = std::stoi(part.substr(0, dash)), b = std::stoi(part.substr(dash + 1), &used);
        if (used != part.size() - dash - 1 || b < a || b - a > 100000) throw std::invalid_argument(part);
        for (int f = a; f <= b; ++f) frames.push_back(f);
      }
    } catch (const std::exception &) {
      throw CliError(kExitBadInput, "--frames: '" + part + "' is not a frame or range (e.g. 1-10,12)");
    }
  }
  if (frames.empty()) throw CliError(kExitBadInput, "--frames: no frames in '" + spec + "'");
  return frames;
}

void parse_region(const std::string &text, int out[4]) {
  std::string t = text;
  for (char &c : t)
    if (c == ',') c = ' ';
  std::istringstream in(t);
  std::string rest;
  if (!(in >> out[0] >> out[1] >> out[2] >> out[3]) || (in >> rest) || out[0] < 0 || out[1] < 0 || out[2] <= out[0] ||
      out[3] <= out[1])
    throw CliError(kExitBadInput, "--region must be x0,y0,x1,y1 with 0 <= x0 < x1 and 0 <= y0 < y1, got '" + text + "'");
}

void print_progress(int done, int total, bool tty, bool quiet) {
  if (quiet) return;
  if (tty) {
    const int width = 40, filled = total > 0 ? done * width / total : width;
    std::printf("\r[%s%s] Sample %d/%d", std::string(filled, '#').c_str(), std::string(width - filled, ' ').c_str(),
                done, total);
    if (done == total) std::printf("\n");
  } else {
    std::printf("Sample %d/%d\n", done, total);
  }
  std::fflush(stdout);
}

int render_one(CliContext &ctx, const RenderArgs &a, const std::string &scene_path, const std::string &output) {
  using Clock = std::chrono::steady_clock;
  auto t0 = Clock::now();
  auto since = [](Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); };
  try {
    render::check_output_path(output);  // before any work: a bad output must not cost a render
  } catch (const std::exception &e) {
    throw CliError(kExitBadInput, e.what());
  }
  scene::Scene scene;
  try {
    scene = scene::load_scene(scene_path, &g_interrupted);
  } catch (const scene::LoadCancelled &e) {
    throw CliError(kExitInterrupted, std::string(e.what()) + "; '" + output + "' left unchanged");
  } catch (const scene::SceneError &e) {
    throw CliError(kExitBadInput, e.what());
  }
  const double load_seconds = since(t0);
  auto &plugin = ctx.plugin();

  render::RenderOptions opt;
  opt.samples = a.samples;
  opt.width = a.width;
  opt.height = a.height;
  opt.seed = a.seed;
  opt.time_limit = a.time_limit;
  opt.tile_size = a.tile_size;
  opt.cancel = &g_interrupted;
  if (!a.region.empty()) parse_region(a.region, opt.region);
  if (a.strategy == "light") opt.strategy = render::LightStrategy::LightOnly;
  else if (a.strategy == "bsdf") opt.strategy = render::LightStrategy::BsdfOnly;
  else if (a.strategy != "mis") throw CliError(kExitBadInput, "--strategy must be mis, light or bsdf");

  std::unique_ptr<render::Renderer> renderer;
  try {
    renderer = std::make_unique<render::Renderer>(scene, plugin, opt);
  } catch (const scene::SceneError &e) {
    for (const auto &w : scene.warnings) std::fprintf(stderr, "%s\n", w.c_str());
    throw CliError(kExitBadInput, e.what());
  } catch (const std::bad_alloc &) {
    throw CliError(kExitBadInput, "out of memory preparing '" + scene_path + "' (geometry, textures, tables)");
  }
  for (const auto &w : scene.warnings) std::fprintf(stderr, "%s\n", w.c_str());
  for (const auto &w : renderer->warnings()) std::fprintf(stderr, "%s\n", w.c_str());

  const bool tty = ::isatty(STDOUT_FILENO) != 0;
  render::RenderResult result;
  try {
    result = renderer->render([&](int done, int total) { print_progress(done, total, tty, a.quiet); });
  } catch (const std::bad_alloc &) {
    throw CliError(kExitBadInput, "out of memory for the image buffers of '" + scene_path + "' (" +
                                      std::to_string(opt.width > 0 ? opt.width : scene.camera.width) + "x" +
                                      std::to_string(opt.height > 0 ? opt.height : scene.camera.height) + ")");
  }
  if (tty && !a.quiet && result.samples_done < result.samples_requested) std::printf("\n");
  if (result.interrupted && result.samples_done == 0)
    throw CliError(kExitInterrupted, "interrupted before the first sample; '" + output + "' left unchanged");
  t0 = Clock::now();
  try {
    render::write_image(output, result);
  } catch (const std::exception &e) {
    throw CliError(kExitBadInput, e.what());
  }
  const double write_seconds = since(t0);
  if (result.nan_samples > 0)
    std::fprintf(stderr, "glimmer: warning: %llu non-finite sample contributions were dropped\n",
                 static_cast<unsigned long long>(result.nan_samples));
  if (a.stats) {
    const auto &f = renderer->features();
    auto join = [](const std::set<std::string> &s) {
      std::string out;
      for (const auto &x : s) out += (out.empty() ? "" : ",") + x;
      return out.empty() ? std::string("none") : out;
    };
    std::printf("features: closures=%s lights=%s emissive_triangles=%d background=%s environment_map=%s "
                "textures=%s transparent=%s volumes=%s shaders_used=%d shaders_unused=%d\n",
                join(f.closures).c_str(), join(f.light_types).c_str(), f.emissive_triangles,
                f.background ? "yes" : "no", f.environment_map ? "yes" : "no", join(f.textures).c_str(),
                f.transparent ? "yes" : "no", f.volumes ? "ignored" : "no", f.used_shaders, f.unused_shaders);
    std::printf("time: load=%.3fs bvh=%.3fs prepare=%.3fs render=%.3fs write=%.3fs\n", load_seconds,
                renderer->times().bvh, renderer->times().prepare, result.render_seconds, write_seconds);
    std::printf("render: %dx%d samples=%d/%d paths=%llu samples_per_second=%.0f nan_dropped=%llu\n", result.width,
                result.height, result.samples_done, result.samples_requested,
                static_cast<unsigned long long>(result.paths),
                result.render_seconds > 0 ? static_cast<double>(result.paths) / result.render_seconds : 0.0,
                static_cast<unsigned long long>(result.nan_samples));
  }
  std::fflush(stdout);
  if (result.interrupted) {
    std::fprintf(stderr, "glimmer: interrupted after %d/%d samples; partial image written to %s\n",
                 result.samples_done, result.samples_requested, output.c_str());
    return kExitInterrupted;
  }
  if (result.time_limited && !a.quiet)
    std::fprintf(stderr, "glimmer: time limit reached after %d/%d samples\n", result.samples_done,
                 result.samples_requested);
  return kExitOk;
}

}  // namespace

void add_render_command(CLI::App &app, CliContext &ctx) {
  auto args = std::make_shared<RenderArgs>();
  auto *cmd = app.add_subcommand("render", "render a Cycles XML scene to an image");
  cmd->add_option("scene", args->scene, "scene file (Cycles XML; #### is replaced by the frame number)")->required();
  cmd->add_option("-o,--output", args->output, "output image: .exr (float, multilayer AOVs) or .png (sRGB)")->required();
  cmd->add_option("--samples", args->samples, "samples per pixel (default: the scene's integrator samples)")
      ->check(CLI::Range(1, 1 << 24));
  cmd->add_option("--threads", args->threads, "worker threads (0 = all cores)")->check(CLI::Range(0, 4096));
  cmd->add_option("--width", args->width, "image width (default: the camera's)")->check(CLI::Range(1, 65536));
  cmd->add_option("--height", args->height, "image height (default: the camera's)")->check(CLI::Range(1, 65536));
  cmd->add_option("--seed", args->seed, "sampling seed (default: the scene's integrator seed)")
      ->check(CLI::Range(0, 2147483647));
  cmd->add_option("--region", args->region, "render only pixels x0,y0,x1,y1 (x1, y1 exclusive); the rest is black");
  cmd->add_option("--frames", args->frames, "frames to render, e.g. 1-10,12; #### in scene/output names is the frame");
  cmd->add_option("--time-limit", args->time_limit, "stop after the sample pass that exceeds this many seconds")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--tile-size", args->tile_size, "tile edge in pixels (does not change the image)")
      ->check(CLI::Range(1, 4096));
  cmd->add_option("--strategy", args->strategy, "direct light estimator: mis (default), light (NEE only), bsdf");
  cmd->add_flag("--quiet", args->quiet, "no progress output");
  cmd->add_flag("--stats", args->stats, "print the feature set and the time per phase");
  cmd->callback([&ctx, args] {
    install_render_interrupt_handlers();  // again: main() installs them only when it sees "render"
    if (g_interrupted.load())
      throw CliError(kExitInterrupted, "interrupted before loading; '" + args->output + "' left unchanged");
    std::unique_ptr<tbb::global_control> threads;
    if (args->threads > 0)
      threads = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                      static_cast<size_t>(args->threads));
    if (args->frames.empty()) {
      ctx.exit_code = render_one(ctx, *args, args->scene, args->output);
      return;
    }
    const auto frames = parse_frames(args->frames);
    if (frames.size() > 1 && args->output.find('#') == std::string::npos)
      throw CliError(kExitBadInput, "rendering several frames needs #### in the output name");
    for (int f : frames) {
      const int code = render_one(ctx, *args, render::frame_path(args->scene, f), render::frame_path(args->output, f));
      if (code != kExitOk) {
        ctx.exit_code = code;
        return;
      }
    }
  });
}

}  // namespace glimmer::cli
