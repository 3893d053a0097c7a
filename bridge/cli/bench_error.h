// The error estimator of `glimmer bench error-vs-time` (header-only, tested in
// tests/bridge/test_bench_error_estimator.cpp).
//
// N >= 1 converged reference renders r_1..r_N of one scene on different seeds.
// Their mean R = (1/N) sum r_k is the reference; it still carries noise, whose
// variance per pixel value is estimated from the references' spread,
//     s^2 = sum_k (r_k - R)^2 / (N - 1)     (unbiased),   var(R) = s^2 / N,
// and averaged over the pixels of a region: var_ref_mean. A method's image m is
// independent of the references, so E[(m - R)^2] = E[(m - truth)^2] + var(R):
//     MSE = mean((m - R)^2) - var_ref_mean
// is an unbiased estimate of the method's own mean squared error (its noise +
// bias^2), and RMSE = sqrt(max(MSE, 0)). With N = 1 nothing is subtracted
// (var_ref_mean = 0: the raw RMSE against the one reference).
//
// Regions: a per-pixel region index (a mask or id image); every figure is
// computed per region as well as over all pixels.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <stdexcept>
#include <string>
#include <vector>

namespace glimmer::cli::bench {

// The mean of N references and the variance of that mean per value (0 with N = 1).
struct Reference {
  std::vector<float> mean;
  std::vector<double> var_of_mean;
  int count = 0;
};

inline Reference combine_references(const std::vector<std::vector<float>> &refs) {
  if (refs.empty()) throw std::invalid_argument("no reference images");
  const size_t n = refs[0].size();
  for (const auto &r : refs)
    if (r.size() != n) throw std::invalid_argument("the reference images differ in size");
  Reference out;
  out.count = static_cast<int>(refs.size());
  out.mean.assign(n, 0.0f);
  out.var_of_mean.assign(n, 0.0);
  const double k = static_cast<double>(refs.size());
  for (size_t i = 0; i < n; ++i) {
    double s = 0.0;
    for (const auto &r : refs) s += r[i];
    const double m = s / k;
    out.mean[i] = static_cast<float>(m);
    if (refs.size() < 2) continue;
    double ss = 0.0;
    for (const auto &r : refs) ss += (r[i] - m) * (r[i] - m);
    out.var_of_mean[i] = ss / (k - 1.0) / k;
  }
  return out;
}

// One region's error of an image against a reference.
struct RegionError {
  double mse_raw = 0.0;       // mean((m - R)^2)
  double var_ref_mean = 0.0;  // mean over the region of var(R)
  size_t pixels = 0;
  double mse() const { return mse_raw - var_ref_mean; }            // the method's own MSE (unbiased; may be < 0)
  double rmse() const { return std::sqrt(std::max(mse(), 0.0)); }  // reported
  double rmse_raw() const { return std::sqrt(mse_raw); }
};

// `pixels` values per pixel (3: RGB); region[p] is pixel p's region index, and region_count the number of regions;
// the returned vector has one entry per region plus a last one over all pixels.
inline std::vector<RegionError> region_errors(const std::vector<float> &image, const Reference &ref,
                                              const std::vector<int> &region, int region_count, int channels = 3) {
  if (image.size() != ref.mean.size()) throw std::invalid_argument("the image and the reference differ in size");
  const size_t pixel_count = image.size() / static_cast<size_t>(channels);
  if (!region.empty() && region.size() != pixel_count)
    throw std::invalid_argument("the region image and the render differ in size");
  std::vector<RegionError> out(static_cast<size_t>(region_count) + 1);
  std::vector<double> sq(out.size(), 0.0), var(out.size(), 0.0);
  for (size_t p = 0; p < pixel_count; ++p) {
    const int r = region.empty() ? -1 : region[p];
    for (int c = 0; c < channels; ++c) {
      const size_t i = p * static_cast<size_t>(channels) + static_cast<size_t>(c);
      const double d = double(image[i]) - double(ref.mean[i]);
      sq.back() += d * d;
      var.back() += ref.var_of_mean[i];
      if (r >= 0 && r < region_count) {
        sq[static_cast<size_t>(r)] += d * d;
        var[static_cast<size_t>(r)] += ref.var_of_mean[i];
      }
    }
    if (r >= 0 && r < region_count) ++out[static_cast<size_t>(r)].pixels;
  }
  out.back().pixels = pixel_count;
  for (size_t k = 0; k < out.size(); ++k) {
    if (out[k].pixels == 0) continue;
    const double values = static_cast<double>(out[k].pixels) * channels;
    out[k].mse_raw = sq[k] / values;
    out[k].var_ref_mean = var[k] / values;
  }
  return out;
}

// N >= 1 images of one method on independent seeds (one rung of the ladder) against a reference, per region (the
// last entry: all pixels). The rung's MSE is the mean of the images' own MSEs (each as region_errors: the expected
// MSE of ONE image, estimated from N of them). With N >= 2 it splits into the images' noise and their bias: with
// M the images' mean and s^2 their unbiased spread per value (combine_references),
//     variance = mean(s^2)                                  (one image's noise variance),
//     bias2    = mean((M - R)^2) - mean(s^2) / N - var_ref_mean    (the mean squared bias; unbiased, may be < 0),
// and since mean_k (m_k - R)^2 = (M - R)^2 + (N - 1) / N s^2 per value, mse() = bias2 + variance exactly.
struct SeedErrors {
  std::vector<RegionError> errors;    // mse_raw: the mean of the images' mse_raw; var_ref_mean: the reference's
  std::vector<double> variance, bias2;  // per region as `errors`; empty with N = 1
  int count = 0;
};

inline SeedErrors seed_errors(const std::vector<std::vector<float>> &images, const Reference &ref,
                              const std::vector<int> &region, int region_count, int channels = 3) {
  if (images.empty()) throw std::invalid_argument("no images");
  SeedErrors out;
  out.count = static_cast<int>(images.size());
  for (const auto &image : images) {
    const std::vector<RegionError> e = region_errors(image, ref, region, region_count, channels);
    if (out.errors.empty()) out.errors.assign(e.size(), RegionError{});
    for (size_t k = 0; k < e.size(); ++k) {
      out.errors[k].mse_raw += e[k].mse_raw / static_cast<double>(images.size());
      out.errors[k].var_ref_mean = e[k].var_ref_mean;
      out.errors[k].pixels = e[k].pixels;
    }
  }
  if (images.size() < 2) return out;
  const Reference spread = combine_references(images);  // M and s^2 / N per value
  const std::vector<RegionError> of_mean = region_errors(spread.mean, ref, region, region_count, channels);
  const std::vector<RegionError> noise = region_errors(spread.mean, spread, region, region_count, channels);
  const double n = static_cast<double>(images.size());
  for (size_t k = 0; k < of_mean.size(); ++k) {
    out.variance.push_back(noise[k].var_ref_mean * n);
    out.bias2.push_back(of_mean[k].mse_raw - noise[k].var_ref_mean - of_mean[k].var_ref_mean);
  }
  return out;
}

// Regions of an id image (RGB per pixel, rendered with box-filtered samples): a pixel whose channels are each
// within 1e-3 of 0 or 1 gets the index bits(R) + 2 bits(G) + 4 bits(B) (0 = black .. 7 = white); any other pixel
// (a mix of ids at an edge, or a grey mask value) gets 8, "edges".
inline std::vector<int> binary_id_regions(const std::vector<float> &ids) {
  std::vector<int> out(ids.size() / 3);
  for (size_t p = 0; p < out.size(); ++p) {
    int index = 0;
    for (int c = 0; c < 3; ++c) {
      const float v = ids[3 * p + static_cast<size_t>(c)];
      if (std::fabs(v - 1.0f) <= 1e-3f) index |= 1 << c;
      else if (!(std::fabs(v) <= 1e-3f)) index = 8;
      if (index == 8) break;
    }
    out[p] = index;
  }
  return out;
}

}  // namespace glimmer::cli::bench
