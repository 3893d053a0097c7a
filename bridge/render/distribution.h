// Piecewise-constant distributions for importance sampling (pbrt's
// Distribution1D / 2D): the light pick by power, the environment map, the film
// filter's inverse CDF.
#pragma once

#include <vector>

namespace glimmer::render {

// Piecewise-constant 1D distribution over n bins.
struct Distribution1D {
  std::vector<float> cdf;  // size n + 1
  float total = 0.0f;      // sum of the (non-negative, finite) weights
  explicit Distribution1D(const std::vector<float> &weights = {});
  int count() const { return static_cast<int>(cdf.size()) - 1; }
  // Returns the bin and rescales u to [0, 1) within it.
  int sample(float u, float &u_remapped) const;
  float probability(int i) const { return total > 0.0f ? (cdf[i + 1] - cdf[i]) : 0.0f; }
};

// Piecewise-constant 2D distribution over width x height cells: a marginal over rows, then a row.
struct Distribution2D {
  std::vector<Distribution1D> rows;
  Distribution1D marginal;
  Distribution2D() = default;
  explicit Distribution2D(const std::vector<std::vector<float>> &weights);  // weights[y][x]
  // The cell (x, y) for (u, v), with (u, v) rescaled to [0, 1) within it.
  void sample(float u, float v, int &x, int &y, float &u_remapped, float &v_remapped) const;
  // Probability of cell (x, y) (sums to 1 over the cells).
  float probability(int x, int y) const { return marginal.probability(y) * rows[y].probability(x); }
};

}  // namespace glimmer::render
