// Grid of the multiple-scattering energy tables (GGX), shared by the
// generator (`glimmer precompute energy`) and the lookups in the plugin
// (plugin/tables/microfacet_energy.h).
//
// Axes (node i of n at t = i / (n - 1)):
//  - mu = cos(theta_i): mu = t^2. Non-uniform: the first steps near grazing are
//    1e-3, 4e-3, 9e-3, ... (Cycles' linear 32-node grid steps 1/31 = 0.032).
//  - alpha: sqrt(alpha) = t, alpha clamped to >= 1e-4 (Cycles uses sqrt(alpha) too).
//  - eta (relative IOR >= 1): z = sqrt((eta - 1) / (eta + 1)) in [0, 1/sqrt(2)]
//    linear (Cycles' parameter; eta in [1, 3]), eta = (1 + z^2) / (1 - z^2).
//    The node eta = 1 is evaluated at 1 + 1e-4. 32 nodes: near eta = 1, where the
//    grazing albedo of the inside (1/eta) changes fastest, nodes sit at 1.001, 1.004, 1.009, ...
#pragma once

#include <algorithm>
#include <cmath>

namespace glimmer::microfacet::energy_grid {

inline constexpr int kMuCount = 32;
inline constexpr int kAlphaCount = 32;
inline constexpr int kEtaCount = 32;
inline constexpr float kEtaMax = 3.0f;
inline constexpr float kZMax = 0.70710678118654752f;  // z(eta = 3)

inline float mu_of_node(int i) { return std::max(float(i * i) / float((kMuCount - 1) * (kMuCount - 1)), 1e-4f); }
inline float alpha_of_node(int j) {
  const float t = float(j) / float(kAlphaCount - 1);
  return std::max(t * t, 1e-4f);
}
inline float eta_of_node(int k) {
  const float z = kZMax * float(k) / float(kEtaCount - 1);
  return std::max((1.0f + z * z) / (1.0f - z * z), 1.0f + 1e-4f);
}

// Multiple-scattering energies (E_Fms in F0, bounce tint in c) are stored per
// node as a cubic P divided by the bounce-series factor (glimmer/microfacet_walk.h):
//   energy(x) = P(x) / (1 - tail (1 - E) x),  E = the node's single-scatter albedo.
// The generator fits P with these tails and the lookups evaluate it here.
inline constexpr double kFresnelSplitTail = 0.5;
inline constexpr double kBounceTintTail = 0.6;
template <typename T>
inline T tail_cubic(const T *c, T E, T x, T tail) {
  return (c[0] + x * (c[1] + x * (c[2] + x * c[3]))) / (T(1) - tail * (T(1) - E) * x);
}

// Continuous node coordinates in [0, n - 1] for interpolation.
inline float mu_coord(float mu) { return std::sqrt(std::clamp(mu, 0.0f, 1.0f)) * float(kMuCount - 1); }
inline float alpha_coord(float alpha) { return std::sqrt(std::clamp(alpha, 0.0f, 1.0f)) * float(kAlphaCount - 1); }
inline float eta_coord(float eta) {
  const float e = std::clamp(eta, 1.0f, kEtaMax);
  return std::sqrt((e - 1.0f) / (e + 1.0f)) / kZMax * float(kEtaCount - 1);
}

// Linear interpolation weights along one axis.
struct Lerp {
  int i0, i1;
  float t;
};
inline Lerp lerp_axis(float coord, int n) {
  const float c = std::clamp(coord, 0.0f, float(n - 1));
  const int i0 = std::min(int(c), n - 2);
  return {i0, i0 + 1, c - float(i0)};
}

}  // namespace glimmer::microfacet::energy_grid
