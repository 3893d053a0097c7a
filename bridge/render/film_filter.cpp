#include "render/film_filter.h"

#include <algorithm>
#include <cmath>

#include "glimmer/math.h"
#include "render/distribution.h"

namespace glimmer::render {

FilmFilter::FilmFilter(scene::FilterType type, float width) : type_(type), width_(width) {
  if (type == scene::FilterType::Box) return;
  // Cycles' filter functions over [-width/2, width/2] (film.cpp).
  const int n = 1024;
  std::vector<float> w(n);
  for (int i = 0; i < n; ++i) {
    const float x = ((i + 0.5f) / n - 0.5f) * width;  // offset in pixels
    if (type == scene::FilterType::Gaussian) {
      const float v = x * 6.0f / width;
      w[i] = std::exp(-2.0f * v * v);
    } else {
      const float v = kTwoPi * (x / width + 0.5f);
      w[i] = 0.35875f - 0.48829f * std::cos(v) + 0.14128f * std::cos(2.0f * v) - 0.01168f * std::cos(3.0f * v);
    }
  }
  Distribution1D d(w);
  inverse_cdf_.resize(n);
  for (int i = 0; i < n; ++i) {
    float r;
    const int bin = d.sample((i + 0.5f) / n, r);
    inverse_cdf_[i] = ((bin + r) / n - 0.5f) * width;
  }
}

float FilmFilter::offset(float u) const {
  if (type_ == scene::FilterType::Box) return (u - 0.5f) * width_;
  const float x = u * (inverse_cdf_.size() - 1);
  const int i = std::min(static_cast<int>(x), static_cast<int>(inverse_cdf_.size()) - 2);
  const float t = x - i;
  return inverse_cdf_[i] * (1 - t) + inverse_cdf_[i + 1] * t;
}

}  // namespace glimmer::render
