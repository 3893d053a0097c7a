// Warping functions from the unit square, each with its density.
#pragma once

#include <cmath>

#include "glimmer/math.h"

namespace glimmer {

// Concentric square-to-disk map (Shirley & Chiu 1997).
inline void sample_uniform_disk_concentric(float u1, float u2, float &x, float &y) {
  const float a = 2.0f * u1 - 1.0f, b = 2.0f * u2 - 1.0f;
  if (a == 0.0f && b == 0.0f) { x = y = 0.0f; return; }
  float r, phi;
  if (std::fabs(a) > std::fabs(b)) { r = a; phi = (kPi / 4.0f) * (b / a); }
  else { r = b; phi = (kPi / 2.0f) - (kPi / 4.0f) * (a / b); }
  x = r * std::cos(phi);
  y = r * std::sin(phi);
}

// Cosine-weighted hemisphere around +z; pdf = cos(theta) / pi.
inline Vec3 sample_cosine_hemisphere(float u1, float u2) {
  float x, y;
  sample_uniform_disk_concentric(u1, u2, x, y);
  const float z = safe_sqrt(1.0f - x * x - y * y);
  return {x, y, z};
}
inline float cosine_hemisphere_pdf(float cos_theta_value) { return std::max(cos_theta_value, 0.0f) * kInvPi; }

// Uniform sphere; pdf = 1 / (4 pi).
inline Vec3 sample_uniform_sphere(float u1, float u2) {
  const float z = 1.0f - 2.0f * u1;
  const float r = safe_sqrt(1.0f - z * z);
  const float phi = kTwoPi * u2;
  return {r * std::cos(phi), r * std::sin(phi), z};
}

// Uniform cone around +z with cos of half-angle cos_max; pdf = 1 / (2 pi (1 - cos_max)).
inline Vec3 sample_uniform_cone(float u1, float u2, float cos_max) {
  const float cos_t = (1.0f - u1) + u1 * cos_max;
  const float sin_t = safe_sqrt(1.0f - cos_t * cos_t);
  const float phi = kTwoPi * u2;
  return {sin_t * std::cos(phi), sin_t * std::sin(phi), cos_t};
}

// A discrete choice that keeps the stratification of the sample it splits: the first branch is taken
// with probability p when u < p, and u becomes a fresh uniform number within the chosen branch
// (u / p or (u - p) / (1 - p)) for the warp that follows (the "sample reuse" of Cycles' closure pick and
// pbrt's SampleDiscrete). Returns true for the first branch.
inline bool choose_and_rescale(float p, float &u) {
  constexpr float kBelowOne = 0x1.fffffep-1f;
  if (u < p) {
    u = std::min(u / p, kBelowOne);
    return true;
  }
  u = p > 0.0f ? std::min((u - p) / (1.0f - p), kBelowOne) : u;
  return false;
}

inline float power_heuristic(float pdf_a, float pdf_b) {
  const float a2 = pdf_a * pdf_a, b2 = pdf_b * pdf_b;
  return (a2 + b2) > 0.0f ? a2 / (a2 + b2) : 0.0f;
}

}  // namespace glimmer
