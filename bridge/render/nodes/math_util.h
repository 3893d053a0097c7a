// Cycles' safe arithmetic (kernel/svm/math_util.h, util/math_float.h conventions)
// shared by the Math and Vector Math nodes, and the colour-model conversions the
// Mix and HSV nodes share.
#pragma once

#include <cmath>

#include "glimmer/math.h"

namespace glimmer::render::nodes {

inline float finite_or_zero(float v) { return std::isfinite(v) ? v : 0.0f; }
inline Vec3 finite_or_zero(const Vec3 &v) { return {finite_or_zero(v.x), finite_or_zero(v.y), finite_or_zero(v.z)}; }

// One Math node operation (index in Cycles' NodeMathType order), unclamped.
float math_operation(int op, float a, float b, float c);

namespace safe {
inline float divide(float a, float b) { return b != 0.0f ? a / b : 0.0f; }
inline float modulo(float a, float b) { return b != 0.0f ? std::fmod(a, b) : 0.0f; }
// Cycles' safe_powf: 0 for a negative base with a fractional exponent, else powf (on
// the CPU); the node's output turns the Inf of 0^negative into 0 (finite_or_zero).
inline float power(float a, float b) {
  if (a < 0.0f && std::trunc(b) != b) return 0.0f;
  return std::pow(a, b);
}
inline float logarithm(float a, float b) {
  if (a <= 0.0f || b <= 0.0f) return 0.0f;
  return divide(std::log(a), std::log(b));
}
inline float snap(float a, float b) { return b != 0.0f ? std::floor(a / b) * b : 0.0f; }
// Wraps a into [min, max) (Cycles' wrapf(value, max, min)).
inline float wrap(float a, float max, float min) {
  const float range = max - min;
  return range != 0.0f ? a - range * std::floor((a - min) / range) : min;
}
inline float pingpong(float a, float b) {
  if (b == 0.0f) return 0.0f;
  const float x = (a - b) / (b * 2.0f);
  return std::fabs((x - std::floor(x)) * b * 2.0f - b);
}
// Polynomial smooth minimum (Inigo Quilez), c the blend distance.
inline float smooth_min(float a, float b, float c) {
  if (c == 0.0f) return std::fmin(a, b);
  const float h = std::fmax(c - std::fabs(a - b), 0.0f) / c;
  return std::fmin(a, b) - h * h * h * c * (1.0f / 6.0f);
}
inline Vec3 divide(const Vec3 &a, const Vec3 &b) { return {divide(a.x, b.x), divide(a.y, b.y), divide(a.z, b.z)}; }
inline Vec3 normalize(const Vec3 &v) { return glimmer::normalize(v); }  // zero stays zero
}  // namespace safe

// One Mix node blend mode (index in the mix_type list of mix_rgb.cpp), factor t in [0, 1].
Vec3 mix_colors(int mode, float t, const Vec3 &c1, const Vec3 &c2);

// Cycles' rgb_to_hsv / hsv_to_rgb (hue in [0, 1)).
Vec3 rgb_to_hsv(const Vec3 &rgb);
Vec3 hsv_to_rgb(const Vec3 &hsv);

}  // namespace glimmer::render::nodes
