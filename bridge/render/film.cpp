#include "render/film.h"

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <stdexcept>

#include "render/renderer.h"

namespace glimmer::render {

std::string scene_file_hash(const std::string &path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read scene '" + path + "' to hash it");
  // FNV-1a, 64 bit: offset basis 14695981039346656037, prime 1099511628211.
  uint64_t h = 14695981039346656037ull;
  char buffer[1 << 16];
  while (in.read(buffer, sizeof buffer) || in.gcount() > 0) {
    for (std::streamsize k = 0; k < in.gcount(); ++k) {
      h ^= static_cast<unsigned char>(buffer[k]);
      h *= 1099511628211ull;
    }
  }
  char text[17];
  std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(h));
  return text;
}

PartInfo describe_part(const RenderOptions &options, int width, int height, int samples, uint32_t seed) {
  PartInfo part;
  part.scene_hash = options.scene_hash;
  part.seed = static_cast<int>(seed);
  part.samples_total = samples;
  part.full_width = width;
  part.full_height = height;
  part.strategy = options.strategy == LightStrategy::LightOnly  ? "light"
                  : options.strategy == LightStrategy::BsdfOnly ? "bsdf"
                                                                : "mis";
  part.sample_begin = options.sample_begin;
  part.sample_end = options.sample_end;
  if (part.sample_begin == 0 && part.sample_end == 0) part.sample_end = samples;
  if (part.sample_begin < 0 || part.sample_end <= part.sample_begin || part.sample_end > samples)
    throw std::invalid_argument("sample range [" + std::to_string(part.sample_begin) + ", " +
                                std::to_string(part.sample_end) + ") is not inside the render's " +
                                std::to_string(samples) + " samples");
  int *w = part.window;
  const int *r = options.region;
  if (r[0] != 0 || r[1] != 0 || r[2] != 0 || r[3] != 0) {
    w[0] = std::clamp(r[0], 0, width);
    w[1] = std::clamp(r[1], 0, height);
    w[2] = std::clamp(r[2], w[0], width);
    w[3] = std::clamp(r[3], w[1], height);
  } else {
    w[2] = width;
    w[3] = height;
  }
  return part;
}

Film::Film(int width, int height, bool aovs) : width_(width), height_(height), aovs_(aovs) {
  const size_t npix = static_cast<size_t>(width) * height;
  sum_.assign(npix, Spectrum(0.0f));
  alpha_.assign(npix, 0.0f);
  count_.assign(npix, 0u);
  if (aovs) {
    albedo_.assign(npix, Spectrum(0.0f));
    normal_.assign(npix, Vec3(0.0f));
    depth_.assign(npix, 0.0f);
  }
}

void Film::resolve(float exposure, RenderResult &r) const {
  const size_t npix = sum_.size();
  r.combined.assign(npix * 4, 0.0f);
  // A film without AOVs gives none (the image then holds Combined only).
  r.albedo.assign(aovs_ ? npix * 3 : 0, 0.0f);
  r.normal.assign(aovs_ ? npix * 3 : 0, 0.0f);
  r.depth.assign(aovs_ ? npix : 0, 0.0f);
  for (size_t i = 0; i < npix; ++i) {
    const float inv = count_[i] > 0 ? 1.0f / static_cast<float>(count_[i]) : 0.0f;
    Spectrum c = sum_[i] * (inv * exposure);
    if (!is_finite(c)) {
      c = Spectrum(0.0f);
      ++r.nan_samples;
    }
    for (int k = 0; k < 3; ++k) r.combined[4 * i + k] = c[k];
    // Divided, not multiplied by inv: n of n opaque samples is exactly 1 for every n.
    r.combined[4 * i + 3] = count_[i] > 0 ? std::clamp(alpha_[i] / static_cast<float>(count_[i]), 0.0f, 1.0f) : 0.0f;
    if (!aovs_) continue;
    const Spectrum a = albedo_[i] * inv, n = normal_[i] * inv;
    for (int k = 0; k < 3; ++k) {
      r.albedo[3 * i + k] = a[k];
      r.normal[3 * i + k] = n[k];
    }
    r.depth[i] = depth_[i] * inv;
  }
}

void Film::store(RenderResult &r) const {
  const size_t npix = sum_.size();
  r.width = width_;
  r.height = height_;
  r.film_sums = true;
  r.combined.assign(npix * 4, 0.0f);
  for (size_t i = 0; i < npix; ++i) {
    for (int k = 0; k < 3; ++k) r.combined[4 * i + k] = sum_[i][k];
    r.combined[4 * i + 3] = static_cast<float>(count_[i]);  // exact below 2^24 samples
  }
  r.alpha_sum = alpha_;
  r.clamped_parameters = clamped_;
  r.albedo.clear();
  r.normal.clear();
  r.depth.clear();
  if (!aovs_) return;
  r.albedo.resize(npix * 3);
  r.normal.resize(npix * 3);
  r.depth = depth_;
  for (size_t i = 0; i < npix; ++i)
    for (int k = 0; k < 3; ++k) {
      r.albedo[3 * i + k] = albedo_[i][k];
      r.normal[3 * i + k] = normal_[i][k];
    }
}

Film Film::restore(const RenderResult &r) {
  if (!r.film_sums) throw std::runtime_error("not a checkpoint (no film sums)");
  const size_t npix = static_cast<size_t>(r.width) * r.height;
  if (r.combined.size() != 4 * npix) throw std::runtime_error("checkpoint has the wrong number of pixels");
  const bool aovs = r.albedo.size() == 3 * npix && r.normal.size() == 3 * npix && r.depth.size() == npix;
  if (!r.alpha_sum.empty() && r.alpha_sum.size() != npix)
    throw std::runtime_error("checkpoint has the wrong number of alpha sums");
  Film f(r.width, r.height, aovs);
  f.passes_ = r.samples_done;
  f.clamped_ = r.clamped_parameters;
  for (size_t i = 0; i < npix; ++i) {
    f.sum_[i] = Spectrum(r.combined[4 * i], r.combined[4 * i + 1], r.combined[4 * i + 2]);
    f.count_[i] = static_cast<uint32_t>(r.combined[4 * i + 3]);
    f.alpha_[i] = r.alpha_sum.empty() ? r.combined[4 * i + 3] : r.alpha_sum[i];
    if (!aovs) continue;
    f.albedo_[i] = Spectrum(r.albedo[3 * i], r.albedo[3 * i + 1], r.albedo[3 * i + 2]);
    f.normal_[i] = Vec3(r.normal[3 * i], r.normal[3 * i + 1], r.normal[3 * i + 2]);
    f.depth_[i] = r.depth[i];
  }
  return f;
}

}  // namespace glimmer::render
