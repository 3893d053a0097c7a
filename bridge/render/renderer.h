// The path tracer: Embree 3 BVH, TBB tiles, Cycles-style shade_surface per
// bounce (Russian roulette, NEE with power-heuristic MIS, one-sample MIS over
// closure mixtures, bounce counters by label, sample clamps) and ray
// differentials turned into the uv footprint handed to the closures.
#pragma once

#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "host/plugin_library.h"
#include "render/film.h"
#include "render/shader_system.h"
#include "scene/scene.h"

namespace glimmer::render {

// Which estimators feed direct lighting (tests compare them; renders use MIS).
enum class LightStrategy { MIS, LightOnly, BsdfOnly };

struct RenderOptions {
  int samples = 0;        // 0: the scene's integrator samples
  int width = 0, height = 0;  // 0: the camera's
  int seed = -1;          // -1: the scene's integrator seed
  int region[4] = {0, 0, 0, 0};  // x0, y0, x1, y1 (pixels, x1/y1 exclusive); all 0 = whole image
  double time_limit = 0.0;  // seconds, 0 = none: stops after the sample pass that exceeds it
  int tile_size = 32;
  LightStrategy strategy = LightStrategy::MIS;
  // Light sampling (NEE + MIS) at exit lobes of moved samples (frosted_glass sg, ABI 2.4); off: they stay
  // singular (the estimator before; tests and benchmarks compare the two).
  bool exit_lobe_nee = true;
  // Where the path continued from an exit lobe escapes, the world seen through the lobe is one pre-filtered cone
  // lookup along its axis (EnvironmentCone) instead of the background at the ray's direction; off: the point
  // lookup (the estimator before; tests and benchmarks compare the two).
  bool exit_lobe_environment = true;
  bool aovs = true;       // Albedo, Normal, Depth (false: not computed, the film keeps Combined only)
  // The lamps seen through an exit lobe (with exit_lobe_nee): each lamp integrated against the lobe at the exit
  // point (LightSet::lamp_through_lobe, stratified, one shadow ray per lamp) instead of one light sample there, and
  // the continued path's lamp hits not counted; off: the lamps are light-sampled there (the estimator before).
  bool exit_lobe_lamps = true;
  // Light sampling (NEE + MIS) through the last interface of a singular sample that hands over an exit state (ABI
  // 2.8: frosted_glass method=path's thin pane, at the shading point); off: the host passes no buffer and the
  // sample stays singular, MIS weight 1 (the estimator before; tests and benchmarks compare the two).
  bool exit_state_nee = true;
  // The path's bounce limits in every shading context (ABI 2.9: GlimmerShadingContext.max_bounce ...), so that a
  // closure whose one sample stands for several scatters (frosted_glass sg's walk through a solid) drops the light
  // the path would have ended; off: 0 there, no limits (the estimator before; tests and benchmarks compare the two).
  bool bounce_limits_in_context = true;
  // Samples per pixel per parallel pass at most (after_pass runs after each pass): 1 = after every sample (a live
  // display); larger batches spare small images a barrier per sample (Renderer::render).
  int max_samples_per_pass = 16;
  const std::atomic<bool> *cancel = nullptr;  // set from a signal handler: stop after the current pass
  int sample_begin = 0, sample_end = 0;  // render samples [begin, end) of `samples`; both 0 = all of them
  std::string scene_hash;                // recorded in the part's metadata (render::scene_file_hash)
  // Called after every complete sample pass with the film so far (checkpoints).
  std::function<void(const Film &)> after_pass;
};

struct RenderResult {
  int width = 0, height = 0;
  int samples_requested = 0, samples_done = 0;  // of this part's sample range
  PartInfo part;                 // what this image covers (EXR metadata)
  bool film_sums = false;        // a checkpoint: raw sums, alpha = sample count (Film::store)
  std::vector<float> alpha_sum;  // a checkpoint's per-pixel alpha sums (empty otherwise)
  bool interrupted = false;
  bool time_limited = false;
  uint64_t nan_samples = 0;      // non-finite contributions dropped
  std::vector<float> combined;   // RGBA (premultiplied), row 0 = top, exposure applied
  std::vector<float> albedo;     // RGB
  std::vector<float> normal;     // XYZ (world space, first hit)
  std::vector<float> depth;      // Z (camera-space depth of the first hit, 1e10 for background)
  double render_seconds = 0.0;
  uint64_t paths = 0;            // pixels x samples traced
  // The textured parameters whose values fell outside their range (the closures clamped them): the shading points
  // of the whole render, a resumed checkpoint's included, or of all the parts `glimmer merge` joined; kept in the
  // EXR (render/clamped_parameters.h).
  ClampedParameterRecords clamped_parameters;
  // "file:line: warning: ..." found while rendering: the records above (render::clamped_parameter_warnings).
  std::vector<std::string> warnings;
};

struct PhaseTimes {
  double prepare = 0.0;  // shader compile + closure create/prepare + textures + lights
  double bvh = 0.0;
};

class Renderer {
 public:
  Renderer(const scene::Scene &scene, const host::PluginLibrary &plugin, const RenderOptions &options);
  ~Renderer();
  Renderer(const Renderer &) = delete;
  Renderer &operator=(const Renderer &) = delete;

  // Progress callback: (samples done, samples total) after every sample pass.
  // `resume`: continue this film (a checkpoint of the same part, Film::restore) instead of a new one.
  RenderResult render(const std::function<void(int, int)> &progress = {}, const Film *resume = nullptr);

  // The pixels and samples this render covers (resolution, seed, sample range, window).
  const PartInfo &part() const;

  // Follows the ray through film position (x, y) (pixels, no jitter, seed path 0) across
  // singular bounces and returns the shading context at the first non-singular hit, with
  // its ray-differential footprint. False when the ray escapes. For tests and debugging.
  bool probe(float x, float y, GlimmerShadingContext &out) const;
  // The services closures get (trace_ray, trace_ray_closure, environment, log, cache): for tests and tools.
  const GlimmerHostServices &host_services() const;
  // For tests: host_services().trace_ray_closure, but always evaluating the hit's shader there (never the
  // per-mesh description of a constant shader that trace_ray_closure copies).
  int trace_ray_closure_shaded(const GlimmerRay &ray, GlimmerRayHit &hit, GlimmerHitClosure &out) const;

  const FeatureSet &features() const { return features_; }
  const std::vector<std::string> &warnings() const { return warnings_; }
  const PhaseTimes &times() const { return times_; }

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
  FeatureSet features_;
  std::vector<std::string> warnings_;
  PhaseTimes times_;
};

}  // namespace glimmer::render
