// Light binned by its angle off an axis: the exit-lobe shape tests of frosted_glass (solids and panes) compare the
// fraction of the transmitted energy per band of angle, sg against the exact walk.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <span>

#include "glimmer/math.h"

namespace glimmer::test {

// Angle between unit vectors a and b, in degrees.
inline double degrees_between(const Vec3 &a, const Vec3 &b) {
  return std::acos(std::clamp(double(dot(a, b)), -1.0, 1.0)) * 180.0 / M_PI;
}

// The band of `deg` given ascending edges (edges[0] = 0; the last band also takes anything beyond the last edge).
inline int angle_band(std::span<const double> edges, double deg) {
  const int bands = int(edges.size()) - 1;
  int b = 0;
  while (b + 1 < bands && deg >= edges[size_t(b) + 1]) ++b;
  return b;
}

// Sums over paths of the weight per band, its square and the total (each path adds at most once).
template <int N>
struct BandSums {
  std::array<double, N> w{}, w2{};
  double total = 0.0;

  void add(int band, double weight) {
    w[size_t(band)] += weight;
    w2[size_t(band)] += weight * weight;
    total += weight;
  }
  BandSums &operator+=(const BandSums &o) {
    for (int b = 0; b < N; ++b) w[size_t(b)] += o.w[size_t(b)], w2[size_t(b)] += o.w2[size_t(b)];
    total += o.total;
    return *this;
  }
  // The fraction of the total per band and its standard error over n paths.
  void fractions(double n, double (&mass)[N], double (&se)[N]) const {
    for (int b = 0; b < N; ++b) {
      mass[b] = w[size_t(b)] / total;
      const double m = w[size_t(b)] / n;
      se[b] = std::sqrt(std::max(0.0, w2[size_t(b)] / n - m * m) / n) * n / total;
    }
  }
};

}  // namespace glimmer::test
