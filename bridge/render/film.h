// The film: per-pixel sums of path contributions, of alpha (coverage: 0 where a camera
// path escaped to a transparent film's background, Cycles' Film > Transparent) and of the
// Albedo/Normal/Depth AOVs, plus sample counts, in sample order. Keeping the raw sums is what makes a
// render resumable bit for bit (a checkpoint stores them, --resume continues the
// same additions) and splittable: a region is the same additions on fewer pixels,
// a sample range [a, b) the additions of samples a..b-1 (see docs/farm.md).
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "glimmer/math.h"
#include "render/clamped_parameters.h"

namespace glimmer::render {

struct RenderResult;
struct RenderOptions;

// Which part of which render an image holds; written as glimmer:* EXR metadata so
// that `glimmer merge` and `--resume` can check that parts belong together.
struct PartInfo {
  std::string scene_hash;                // scene_file_hash() of the scene file; empty = unknown
  std::string strategy = "mis";          // direct-light estimator (mis, light, bsdf)
  int seed = 0;
  int samples_total = 0;                 // N: samples per pixel of the whole render
  int sample_begin = 0, sample_end = 0;  // this part renders samples [begin, end) of N
  int full_width = 0, full_height = 0;   // resolution of the whole image
  int window[4] = {0, 0, 0, 0};          // rendered pixels x0, y0, x1, y1 (x1, y1 exclusive)
};

// The part a render with these options covers, for an image of width x height with
// `samples` per pixel: window from options.region (clamped; none = whole image), sample
// range from options.sample_begin/end (both 0 = all). Throws std::invalid_argument
// when the sample range is not inside [0, samples).
PartInfo describe_part(const RenderOptions &options, int width, int height, int samples, uint32_t seed);

// "0123456789abcdef": FNV-1a 64 of the file's bytes (what the scene hash records).
// Throws std::runtime_error when the file cannot be read.
std::string scene_file_hash(const std::string &path);

class Film {
 public:
  Film(int width, int height, bool aovs);

  int width() const { return width_; }
  int height() const { return height_; }
  // Sample passes completed over every pixel of the window (what a checkpoint records).
  int passes() const { return passes_; }
  // Whether the film keeps the Albedo, Normal and Depth passes.
  bool aovs() const { return aovs_; }

  // One sample of pixel i (row-major, full image): radiance L, alpha in [0, 1] (1 - the
  // throughput that escaped to a transparent background). Called concurrently for distinct pixels.
  // Returns false (the sample's radiance dropped, the count kept) when adding L would overflow
  // the pixel's sum to Inf: the caller counts it with the non-finite samples.
  bool add(size_t i, const Spectrum &L, float alpha, const Spectrum &albedo, const Vec3 &normal, float depth) {
    const Spectrum next = sum_[i] + L;
    const bool finite = is_finite(next);
    if (finite) sum_[i] = next;
    alpha_[i] += alpha;
    count_[i]++;
    if (aovs_) {
      albedo_[i] += albedo;
      normal_[i] += normal;
      depth_[i] += depth;
    }
    return finite;
  }
  void end_pass() { ++passes_; }

  // The out-of-range textured parameters counted over the samples in the film (the renderer sets them after each
  // pass, a resumed film's included); store() and restore() keep them, so a checkpoint carries them.
  const ClampedParameterRecords &clamped_parameters() const { return clamped_; }
  void set_clamped_parameters(ClampedParameterRecords records) { clamped_ = std::move(records); }

  // Per-pixel means into result.combined/albedo/normal/depth (RGB scaled by exposure; alpha = the
  // alpha sum / sample count, so exactly 0 or 1 where every sample agreed). RGB is premultiplied
  // (the transparent background adds nothing). A mean that exposure pushes past the float range
  // becomes 0 and counts in result.nan_samples.
  void resolve(float exposure, RenderResult &result) const;

  // Checkpoint image: channels hold the raw sums, Combined alpha the per-pixel sample count,
  // RenderResult::alpha_sum the alpha sums (RenderResult::film_sums set); restore() is its exact
  // inverse (a checkpoint without alpha sums, written before they existed, restores as opaque).
  void store(RenderResult &result) const;
  static Film restore(const RenderResult &checkpoint);

 private:
  int width_, height_;
  bool aovs_;
  int passes_ = 0;
  std::vector<Spectrum> sum_, albedo_, normal_;
  std::vector<float> alpha_, depth_;
  std::vector<uint32_t> count_;  // an interrupt stops a pass mid-way, so pixels can differ by one
  ClampedParameterRecords clamped_;
};

}  // namespace glimmer::render
