#include "render/distribution.h"

#include <algorithm>
#include <cmath>

namespace glimmer::render {

Distribution1D::Distribution1D(const std::vector<float> &weights) {
  cdf.assign(weights.size() + 1, 0.0f);
  double acc = 0.0;
  for (size_t i = 0; i < weights.size(); ++i) {
    acc += std::max(0.0f, std::isfinite(weights[i]) ? weights[i] : 0.0f);
    cdf[i + 1] = static_cast<float>(acc);
  }
  total = static_cast<float>(acc);
  if (acc > 0.0)
    for (auto &c : cdf) c = static_cast<float>(c / acc);
}

int Distribution1D::sample(float u, float &u_remapped) const {
  const int n = count();
  int i = static_cast<int>(std::upper_bound(cdf.begin(), cdf.end(), u) - cdf.begin()) - 1;
  i = std::clamp(i, 0, n - 1);
  while (i > 0 && cdf[i + 1] - cdf[i] <= 0.0f) --i;  // never land on an empty bin
  while (i < n - 1 && cdf[i + 1] - cdf[i] <= 0.0f) ++i;
  const float width = cdf[i + 1] - cdf[i];
  u_remapped = width > 0.0f ? std::clamp((u - cdf[i]) / width, 0.0f, 0.99999994f) : 0.5f;
  return i;
}

Distribution2D::Distribution2D(const std::vector<std::vector<float>> &weights) {
  std::vector<float> row_totals(weights.size());
  rows.reserve(weights.size());
  for (size_t y = 0; y < weights.size(); ++y) {
    rows.emplace_back(weights[y]);
    row_totals[y] = rows.back().total;
  }
  marginal = Distribution1D(row_totals);
}

void Distribution2D::sample(float u, float v, int &x, int &y, float &u_remapped, float &v_remapped) const {
  y = marginal.sample(v, v_remapped);
  x = rows[y].sample(u, u_remapped);
}

}  // namespace glimmer::render
