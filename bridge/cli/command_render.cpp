// `glimmer render scene.xml -o out.exr|png`: load a Cycles XML scene, render it
// with the DSO's closures and write the image atomically.
#include <tbb/global_control.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <csignal>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <iostream>
#include <mutex>
#include <thread>
#include <new>
#include <optional>
#include <sstream>

#include "cli/commands.h"
#include "cli/render_parts.h"
#include "host/log.h"
#include "render/image_io.h"
#include "render/image_output.h"
#include "render/renderer.h"
#include "scene/parse_number.h"
#include "scene/xml_loader.h"

namespace glimmer::cli {

namespace {

std::atomic<bool> g_interrupted{false};  // stop loading, preparing, rendering (a signal; serve: a new command)
std::atomic<bool> g_signalled{false};

// The first SIGINT/SIGTERM asks loading, preparation and rendering to stop;
// a second one terminates at once (the default action).
extern "C" void on_signal(int sig) {
  g_interrupted.store(true);
  g_signalled.store(true);
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
  bool no_exit_state_nee = false;
  bool no_bounce_limits_in_closures = false;
  std::string sample_range, sample_split, tile, progress_format = "sample";
  double checkpoint_every = -1.0;  // seconds between checkpoints; < 0 = none
  std::string display;             // the image so far, for a viewer (render::write_display_image)
  double display_every = 0.0;      // seconds between display images (0: every pass)
  bool resume = false;
  int samples = 0, threads = 0, width = 0, height = 0, seed = -1, tile_size = 32;
  double time_limit = 0.0;
  bool quiet = false, stats = false;
  bool no_aovs = false;  // Combined only: the first hit's albedo, normal and depth are not computed
};

void parse_region(const std::string &text, int out[4]) {
  std::vector<int> v;
  try {
    v = scene::parse_int_list(text, 0);
  } catch (const scene::NumberError &) {
    v.clear();
  }
  if (v.size() != 4 || v[2] <= v[0] || v[3] <= v[1])
    throw CliError(kExitBadInput, "--region must be x0,y0,x1,y1 with 0 <= x0 < x1 and 0 <= y0 < y1, got '" + text + "'");
  std::copy(v.begin(), v.end(), out);
}

std::string clock_text(double seconds) {
  char text[32];
  const int minutes = static_cast<int>(seconds / 60.0);
  std::snprintf(text, sizeof text, "%02d:%05.2f", minutes, seconds - 60.0 * minutes);
  return text;
}

// "blender": Blender's command-line progress shape, for farm adaptors written for Blender.
void print_progress(int done, int total, bool tty, bool quiet, const std::string &format, int frame, double elapsed) {
  if (quiet) return;
  if (format == "blender") {
    const double remaining = done > 0 ? elapsed * (total - done) / done : 0.0;
    std::printf("Fra:%d Time:%s | Remaining:%s | Sample %d/%d\n", frame, clock_text(elapsed).c_str(),
                clock_text(remaining).c_str(), done, total);
  } else if (tty) {
    const int width = 40, filled = total > 0 ? done * width / total : width;
    std::printf("\r[%s%s] Sample %d/%d", std::string(filled, '#').c_str(), std::string(width - filled, ' ').c_str(),
                done, total);
    if (done == total) std::printf("\n");
  } else {
    std::printf("Sample %d/%d\n", done, total);
  }
  std::fflush(stdout);
}

// --region/--tile and --sample-range/--sample-split into the options (the scene gives the defaults).
void set_part(const RenderArgs &a, const scene::Scene &scene, render::RenderOptions &opt) {
  if (!a.region.empty()) parse_region(a.region, opt.region);
  if (!a.tile.empty()) {
    const auto [k, n] = parse_split("--tile", a.tile);
    const int width = a.width > 0 ? a.width : scene.camera.width, height = a.height > 0 ? a.height : scene.camera.height;
    const auto [y0, y1] = split_range("--tile", k, n, height);
    opt.region[0] = 0;
    opt.region[1] = y0;
    opt.region[2] = width;
    opt.region[3] = y1;
  }
  if (!a.sample_range.empty()) std::tie(opt.sample_begin, opt.sample_end) = parse_sample_range(a.sample_range);
  if (!a.sample_split.empty()) {
    const auto [k, n] = parse_split("--sample-split", a.sample_split);
    const int samples = a.samples > 0 ? a.samples : scene.integrator.samples;
    std::tie(opt.sample_begin, opt.sample_end) = split_range("--sample-split", k, n, samples);
  }
}

// `glimmer serve` keeps the last render's scene and renderer until the next renderer is prepared, so that tables
// its closures share process-wide (glint tables: plugin/tables/glint_tables.cpp acquire_table) are reused instead
// of being loaded and verified again at every change.
struct KeptRender {
  std::unique_ptr<scene::Scene> scene;
  std::unique_ptr<render::Renderer> renderer;  // refers to *scene
};

int render_one(CliContext &ctx, const RenderArgs &a, const std::string &scene_path, const std::string &output,
               int frame, KeptRender *keep = nullptr) {
  using Clock = std::chrono::steady_clock;
  auto since = [](Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); };
  try {
    render::check_output_path(output);  // before any work: a bad output must not cost a render
    render::check_output_folder_takes_files(output);
  } catch (const std::exception &e) {
    throw CliError(kExitBadInput, e.what());
  }
  auto t0 = Clock::now();
  auto loaded = std::make_unique<scene::Scene>();  // on the heap: a kept renderer refers to it
  scene::Scene &scene = *loaded;
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
  opt.aovs = !a.no_aovs;
  if (!a.display.empty()) opt.max_samples_per_pass = 1;  // a live display: an image after every sample
  opt.cancel = &g_interrupted;
  set_part(a, scene, opt);
  opt.scene_hash = render::scene_file_hash(scene_path);
  const std::string checkpoint = checkpoint_path(output);
  std::unique_ptr<render::Renderer> renderer;
  auto last_checkpoint = Clock::now(), last_display = Clock::now();
  // Readers (the Blender addon) load a checkpoint or display image as soon as its line is printed.
  auto announce = [&a](const char *what, int done, int total, const std::string &path) {
    if (a.quiet) return;
    std::printf("%s %d/%d %s\n", what, done, total, path.c_str());
    std::fflush(stdout);
  };
  opt.after_pass = [&](const render::Film &film) {
    const int total = renderer->part().sample_end - renderer->part().sample_begin;
    if (!a.display.empty() && (film.passes() == 1 || since(last_display) >= a.display_every)) {
      try {
        write_display(a.display, film, renderer->part(), scene.film.exposure);
        last_display = Clock::now();
        announce("Display", film.passes(), total, a.display);
      } catch (const std::exception &e) {  // the render goes on; only the viewer misses an update
        host::log_warning(std::string("display image not written: ") + e.what());
      }
    }
    if (a.checkpoint_every < 0.0 || since(last_checkpoint) < a.checkpoint_every || film.passes() == total) return;
    try {
      write_checkpoint(checkpoint, film, renderer->part());
    } catch (const std::exception &e) {  // the render goes on; only resumability is lost
      host::log_warning(std::string("checkpoint not written: ") + e.what());
      return;
    }
    last_checkpoint = Clock::now();
    announce("Checkpoint", film.passes(), total, checkpoint);
  };
  if (a.strategy == "light") opt.strategy = render::LightStrategy::LightOnly;
  else if (a.strategy == "bsdf") opt.strategy = render::LightStrategy::BsdfOnly;
  else if (a.strategy != "mis") throw CliError(kExitBadInput, "--strategy must be mis, light or bsdf");
  opt.exit_state_nee = !a.no_exit_state_nee;
  opt.bounce_limits_in_context = !a.no_bounce_limits_in_closures;

  try {
    renderer = std::make_unique<render::Renderer>(scene, plugin, opt);
  } catch (const scene::SceneError &e) {
    for (const auto &w : scene.warnings) std::fprintf(stderr, "%s\n", w.c_str());
    throw CliError(kExitBadInput, e.what());
  } catch (const std::invalid_argument &e) {
    throw CliError(kExitBadInput, e.what());
  } catch (const std::bad_alloc &) {
    throw CliError(kExitBadInput, "out of memory preparing '" + scene_path + "' (geometry, textures, tables)");
  }
  std::optional<render::Film> resumed;
  if (a.resume && std::filesystem::exists(checkpoint)) {
    resumed = read_checkpoint(checkpoint, renderer->part());
    if (resumed->aovs() && a.no_aovs)
      throw CliError(kExitBadInput, "--resume: checkpoint '" + checkpoint +
                                        "' has the Albedo, Normal and Depth passes; resume it without --no-aovs");
    if (!a.quiet)
      std::printf("Resuming %s from sample %d/%d\n", checkpoint.c_str(), resumed->passes(),
                  renderer->part().sample_end - renderer->part().sample_begin);
  }
  for (const auto &w : scene.warnings) std::fprintf(stderr, "%s\n", w.c_str());
  for (const auto &w : renderer->warnings()) std::fprintf(stderr, "%s\n", w.c_str());

  // The module that writes the output (render/image_io.h: OpenEXR's for .exr, OIIO's otherwise) is loaded
  // here, before a render is spent on an image it could not write: a missing or broken module is an
  // installation problem (exit 2). Loading OIIO's on a background thread earlier, to overlap the scene load,
  // the BVH or the render, made them slower by about the load's own wall time (docs/architecture.md "Start-up").
  t0 = Clock::now();
  try {
    render::load_output_module(output);
  } catch (const std::exception &e) {
    throw CliError(kExitPlugin, e.what());
  }
  const double module_seconds = since(t0);
  const bool tty = ::isatty(STDOUT_FILENO) != 0;
  const auto render_start = Clock::now();
  render::RenderResult result;
  try {
    result = renderer->render(
        [&](int done, int total) {
          print_progress(done, total, tty, a.quiet, a.progress_format, frame, since(render_start));
        },
        resumed ? &*resumed : nullptr);
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
  const bool complete = !result.interrupted && !result.time_limited;
  std::error_code ignored;
  if (complete) std::filesystem::remove(checkpoint, ignored);  // the finished image supersedes it
  if (result.nan_samples > 0)
    host::log_warning(std::to_string(result.nan_samples) + " non-finite sample contributions were dropped");
  for (const auto &w : result.warnings) std::fprintf(stderr, "%s\n", w.c_str());
  if (a.stats) {
    const auto &f = renderer->features();
    auto join = [](const std::set<std::string> &s) {
      std::string out;
      for (const auto &x : s) out += (out.empty() ? "" : ",") + x;
      return out.empty() ? std::string("none") : out;
    };
    std::printf("features: closures=%s lights=%s emissive_triangles=%d background=%s environment_map=%s "
                "textures=%s transparent=%s volumes=%s shaders_used=%d shaders_unused=%d world_sampling=%s\n",
                join(f.closures).c_str(), join(f.light_types).c_str(), f.emissive_triangles,
                f.background ? "yes" : "no", f.environment_map ? "yes" : "no", join(f.textures).c_str(),
                f.transparent ? "yes" : "no", f.volumes ? "ignored" : "no", f.used_shaders, f.unused_shaders,
                f.world_sampling.c_str());
    std::printf("time: load=%.3fs bvh=%.3fs prepare=%.3fs module=%.3fs render=%.3fs write=%.3fs\n", load_seconds,
                renderer->times().bvh, renderer->times().prepare, module_seconds, result.render_seconds,
                write_seconds);
    std::printf("render: %dx%d samples=%d/%d paths=%llu samples_per_second=%.0f nan_dropped=%llu\n", result.width,
                result.height, result.samples_done, result.samples_requested,
                static_cast<unsigned long long>(result.paths),
                result.render_seconds > 0 ? static_cast<double>(result.paths) / result.render_seconds : 0.0,
                static_cast<unsigned long long>(result.nan_samples));
  }
  std::fflush(stdout);
  if (keep != nullptr) {  // the previous render is released only now, after this one's closures were prepared
    keep->renderer = std::move(renderer);
    keep->scene = std::move(loaded);
  }
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

void add_render_options(CLI::App *cmd, RenderArgs &a) {
  cmd->add_option("scene", a.scene, "scene file (Cycles XML; #### is replaced by the frame number)")->required();
  cmd->add_option("-o,--output", a.output, "output image: .exr (float, multilayer AOVs) or .png (sRGB)")->required();
  cmd->add_option("--samples", a.samples, "samples per pixel (default: the scene's integrator samples)")
      ->check(CLI::Range(1, 1 << 24));
  cmd->add_option("--threads", a.threads, "worker threads (0 = all cores)")->check(CLI::Range(0, 4096));
  cmd->add_option("--width", a.width, "image width (default: the camera's)")->check(CLI::Range(1, 65536));
  cmd->add_option("--height", a.height, "image height (default: the camera's)")->check(CLI::Range(1, 65536));
  cmd->add_option("--seed", a.seed, "sampling seed (default: the scene's integrator seed)")
      ->check(CLI::Range(0, 2147483647));
  cmd->add_option("--region", a.region, "render only pixels x0,y0,x1,y1 (x1, y1 exclusive); an EXR holds just this crop (data window), a PNG the whole image with the rest black");
  auto *tile = cmd->add_option("--tile", a.tile, "render band k of N (rows k*H/N to (k+1)*H/N), k/N; for farms");
  cmd->get_option("--region")->excludes(tile);
  auto *range = cmd->add_option("--sample-range", a.sample_range,
                                "render samples a..b-1 of --samples, a,b (merge the parts with glimmer merge)");
  auto *split = cmd->add_option("--sample-split", a.sample_split,
                                "render sample part k of N (samples k*S/N to (k+1)*S/N), k/N");
  range->excludes(split);
  cmd->add_option("--checkpoint-every", a.checkpoint_every,
                  "write the film to <output>.checkpoint.exr after a sample pass once this many seconds have "
                  "passed since the last one (0: every pass)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_flag("--resume", a.resume, "continue from <output>.checkpoint.exr when it exists");
  cmd->add_option("--display", a.display,
                  "write the image so far to this .exr (plain R,G,B,A float, uncompressed) after the first sample "
                  "pass and then every --display-every seconds, announced by 'Display n/N <path>' lines (viewers)");
  cmd->add_option("--display-every", a.display_every, "seconds between --display images (default 0: every pass)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--progress-format", a.progress_format,
                  "progress lines: sample ('Sample n/N') or blender ('Fra:F Time:.. | Remaining:.. | Sample n/N')")
      ->check(CLI::IsMember({"sample", "blender"}));
  cmd->add_option("--frames", a.frames, "frames to render, e.g. 1-10,12; #### in scene/output names is the frame");
  cmd->add_option("--time-limit", a.time_limit, "stop after the sample pass that exceeds this many seconds")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--tile-size", a.tile_size, "tile edge in pixels (does not change the image)")
      ->check(CLI::Range(1, 4096));
  cmd->add_option("--strategy", a.strategy, "direct light estimator: mis (default), light (NEE only), bsdf");
  cmd->add_flag("--no-exit-state-nee", a.no_exit_state_nee,
                "no light sampling through a thin frosted pane's last interface (ABI 2.8; the estimator before, for "
                "comparisons)");
  cmd->add_flag("--no-bounce-limits-in-closures", a.no_bounce_limits_in_closures,
                "closures are not told the bounce limits (ABI 2.9: frosted glass sg's walk then keeps the light the "
                "path would have ended; the estimator before, for comparisons)");
  cmd->add_flag("--no-aovs", a.no_aovs,
                "write the Combined pass only (no Albedo, Normal, Depth; their first-hit work is skipped)");
  cmd->add_flag("--quiet", a.quiet, "no progress output");
  cmd->add_flag("--stats", a.stats, "print the feature set and the time per phase");
}

// One `glimmer render` command line: its frames in turn. Returns the exit code.
int run_render(CliContext &ctx, const RenderArgs &a, KeptRender *keep = nullptr) {
  if (g_interrupted.load())
    throw CliError(kExitInterrupted, "interrupted before loading; '" + a.output + "' left unchanged");
  std::unique_ptr<tbb::global_control> threads;
  if (a.threads > 0)
    threads = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                    static_cast<size_t>(a.threads));
  if (a.frames.empty()) return render_one(ctx, a, a.scene, a.output, 1, keep);
  const auto frames = parse_frames(a.frames);
  if (frames.size() > 1 && a.output.find('#') == std::string::npos)
    throw CliError(kExitBadInput, "rendering several frames needs #### in the output name");
  for (int f : frames) {
    const int code = render_one(ctx, a, render::frame_path(a.scene, f), render::frame_path(a.output, f), f, keep);
    if (code != kExitOk) return code;
  }
  return kExitOk;
}

// `glimmer serve`: a persistent renderer (the Blender viewport's). Each line on stdin holds the arguments of one
// `glimmer render`; a new line interrupts the render in progress and the newest waiting line runs next, so process
// start-up and plugin loading are paid once, and tables shared by the closures of consecutive renders (KeptRender)
// are built or loaded once. After each command: 'Finished <exit code> <output>', also for a line replaced before it
// started ('Finished 3 <output>', 3 = interrupted: a driver waiting for one answer per line never hangs). At the end
// of stdin the newest command finishes and the server exits 0; SIGTERM/SIGINT interrupt the render and end the
// server (exit 3).
int serve(CliContext &ctx) {
  // One stdin line as `glimmer render`'s arguments into `args` (throws CLI::ParseError).
  const auto parse_render_line = [](const std::string &line, RenderArgs &args) {
    CLI::App app{"render"};
    add_render_options(&app, args);
    app.parse(line);
  };
  install_render_interrupt_handlers();
  std::mutex mutex;
  std::condition_variable wake;
  std::deque<std::string> waiting;
  bool end_of_input = false;
  // Queued and cancelled under one lock, so a command is never cancelled by the line that started it.
  std::thread([&] {
    std::string line;
    while (std::getline(std::cin, line)) {
      std::lock_guard<std::mutex> lock(mutex);
      waiting.push_back(line);
      g_interrupted.store(true);
      wake.notify_one();
    }
    std::lock_guard<std::mutex> lock(mutex);
    end_of_input = true;  // the newest command still finishes
    wake.notify_one();
  }).detach();  // blocked in getline when the server ends: the process exit takes it
  KeptRender kept;
  for (;;) {
    std::string line;
    std::vector<std::string> skipped;
    {
      std::unique_lock<std::mutex> lock(mutex);
      wake.wait_for(lock, std::chrono::milliseconds(100), [&] { return !waiting.empty() || end_of_input; });
      if (g_signalled.load()) return kExitInterrupted;
      if (waiting.empty()) {
        if (end_of_input) return kExitOk;
        continue;
      }
      line = waiting.back();  // the newest command; older ones are stale
      skipped.assign(waiting.begin(), waiting.end() - 1);
      waiting.clear();
      g_interrupted.store(false);
    }
    for (const std::string &stale : skipped) {  // replaced before they started: answered as interrupted
      RenderArgs stale_args;
      try {
        parse_render_line(stale, stale_args);
      } catch (const CLI::ParseError &) {  // unparsable: its output is unknown ("")
      }
      std::printf("Finished %d %s\n", kExitInterrupted, stale_args.output.c_str());
    }
    std::fflush(stdout);
    RenderArgs args;
    int code = kExitOk;
    try {
      parse_render_line(line, args);
      code = run_render(ctx, args, &kept);
    } catch (const CLI::ParseError &e) {
      std::fprintf(stderr, "glimmer: error: %s\n", e.what());
      code = kExitBadInput;
    } catch (const CliError &e) {
      std::fprintf(stderr, "glimmer: error: %s\n", e.what());
      code = e.code();
    } catch (const std::exception &e) {  // a bad scene or closure: the next command may be fine
      std::fprintf(stderr, "glimmer: error: %s\n", e.what());
      code = kExitBadInput;
    }
    std::fflush(stderr);
    std::printf("Finished %d %s\n", code, args.output.c_str());
    std::fflush(stdout);
  }
}

}  // namespace

void add_render_command(CLI::App &app, CliContext &ctx) {
  auto args = std::make_shared<RenderArgs>();
  auto *cmd = app.add_subcommand("render", "render a Cycles XML scene to an image");
  add_render_options(cmd, *args);
  cmd->callback([&ctx, args] {
    install_render_interrupt_handlers();  // again: main() installs them only when it sees "render"
    ctx.exit_code = run_render(ctx, *args);
  });
  auto *serve_cmd = app.add_subcommand(
      "serve", "persistent renderer: one line of `glimmer render` arguments per stdin line; a new line interrupts "
               "the render in progress ('Finished <code> <output>' after each); exits at the end of stdin");
  serve_cmd->callback([&ctx] { ctx.exit_code = serve(ctx); });
}

}  // namespace glimmer::cli
