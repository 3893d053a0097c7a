// Small float vector math shared by the plugin and the host.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "glimmer/closure_abi.h"

namespace glimmer {

inline constexpr float kPi = 3.14159265358979323846f;
inline constexpr float kInvPi = 0.31830988618379067154f;
inline constexpr float kTwoPi = 6.28318530717958647692f;
inline constexpr float kInv2Pi = 0.15915494309189533577f;
inline constexpr float kInv4Pi = 0.07957747154594766788f;

struct Vec3 {
  float x = 0.0f, y = 0.0f, z = 0.0f;

  constexpr Vec3() = default;
  constexpr Vec3(float x_, float y_, float z_) : x(x_), y(y_), z(z_) {}
  constexpr explicit Vec3(float s) : x(s), y(s), z(s) {}
  constexpr Vec3(const GlimmerVec3 &v) : x(v.x), y(v.y), z(v.z) {}  // NOLINT: implicit by design
  constexpr operator GlimmerVec3() const { return GlimmerVec3{x, y, z}; }

  constexpr float operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
  float &operator[](int i) { return i == 0 ? x : (i == 1 ? y : z); }

  constexpr Vec3 operator-() const { return {-x, -y, -z}; }
  constexpr Vec3 operator+(const Vec3 &b) const { return {x + b.x, y + b.y, z + b.z}; }
  constexpr Vec3 operator-(const Vec3 &b) const { return {x - b.x, y - b.y, z - b.z}; }
  constexpr Vec3 operator*(const Vec3 &b) const { return {x * b.x, y * b.y, z * b.z}; }
  constexpr Vec3 operator/(const Vec3 &b) const { return {x / b.x, y / b.y, z / b.z}; }
  constexpr Vec3 operator*(float s) const { return {x * s, y * s, z * s}; }
  constexpr Vec3 operator/(float s) const { return {x / s, y / s, z / s}; }
  Vec3 &operator+=(const Vec3 &b) { x += b.x; y += b.y; z += b.z; return *this; }
  Vec3 &operator-=(const Vec3 &b) { x -= b.x; y -= b.y; z -= b.z; return *this; }
  Vec3 &operator*=(const Vec3 &b) { x *= b.x; y *= b.y; z *= b.z; return *this; }
  Vec3 &operator*=(float s) { x *= s; y *= s; z *= s; return *this; }
  Vec3 &operator/=(float s) { x /= s; y /= s; z /= s; return *this; }
};

// RGB triples are Vec3 too; the name says which meaning a value has.
using Spectrum = Vec3;

constexpr Vec3 operator*(float s, const Vec3 &v) { return v * s; }
constexpr float dot(const Vec3 &a, const Vec3 &b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
constexpr Vec3 cross(const Vec3 &a, const Vec3 &b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline float length(const Vec3 &v) { return std::sqrt(dot(v, v)); }
inline float length_squared(const Vec3 &v) { return dot(v, v); }
inline Vec3 normalize(const Vec3 &v) {
  const float len = length(v);
  return len > 0.0f ? v / len : Vec3(0.0f);
}
inline Vec3 abs(const Vec3 &v) { return {std::fabs(v.x), std::fabs(v.y), std::fabs(v.z)}; }
inline Vec3 min(const Vec3 &a, const Vec3 &b) {
  return {std::min(a.x, b.x), std::min(a.y, b.y), std::min(a.z, b.z)};
}
inline Vec3 max(const Vec3 &a, const Vec3 &b) {
  return {std::max(a.x, b.x), std::max(a.y, b.y), std::max(a.z, b.z)};
}
inline float max_component(const Vec3 &v) { return std::max(v.x, std::max(v.y, v.z)); }
inline float min_component(const Vec3 &v) { return std::min(v.x, std::min(v.y, v.z)); }
inline float average(const Vec3 &v) { return (v.x + v.y + v.z) * (1.0f / 3.0f); }
// Rec.709 luminance of linear RGB (Cycles' colour -> float conversion with its default scene coefficients).
inline float luminance(const Vec3 &c) { return 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z; }
inline bool is_finite(const Vec3 &v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}
inline bool is_zero(const Vec3 &v) { return v.x == 0.0f && v.y == 0.0f && v.z == 0.0f; }
inline Vec3 reflect(const Vec3 &w, const Vec3 &n) { return 2.0f * dot(w, n) * n - w; }

template <typename T>
constexpr T clamp(T v, T lo, T hi) { return v < lo ? lo : (v > hi ? hi : v); }
inline float saturate(float v) { return clamp(v, 0.0f, 1.0f); }
inline float safe_sqrt(float v) { return std::sqrt(std::max(v, 0.0f)); }
inline float safe_acos(float v) { return std::acos(clamp(v, -1.0f, 1.0f)); }
inline float sqr(float v) { return v * v; }
inline float lerp(float a, float b, float t) { return a + (b - a) * t; }

// Orthonormal basis with z = n; built without branches on sign (Duff et al. 2017).
struct Frame {
  Vec3 s, t, n;

  Frame() : s(1, 0, 0), t(0, 1, 0), n(0, 0, 1) {}
  Frame(const Vec3 &s_, const Vec3 &t_, const Vec3 &n_) : s(s_), t(t_), n(n_) {}

  static Frame from_normal(const Vec3 &n) {
    const float sign = std::copysign(1.0f, n.z);
    const float a = -1.0f / (sign + n.z);
    const float b = n.x * n.y * a;
    return Frame(Vec3(1.0f + sign * n.x * n.x * a, sign * b, -sign * n.x), Vec3(b, sign + n.y * n.y * a, -n.y), n);
  }
  // Frame with z = n and x as close to `tangent` as possible (Gram-Schmidt);
  // falls back to from_normal() when the tangent is degenerate.
  static Frame from_normal_tangent(const Vec3 &n, const Vec3 &tangent) {
    const Vec3 t_proj = tangent - n * dot(n, tangent);
    const float len2 = dot(t_proj, t_proj);
    if (!(len2 > 1e-12f)) return from_normal(n);
    const Vec3 s = t_proj / std::sqrt(len2);
    return Frame(s, cross(n, s), n);
  }
  Vec3 to_local(const Vec3 &v) const { return {dot(v, s), dot(v, t), dot(v, n)}; }
  Vec3 to_world(const Vec3 &v) const { return s * v.x + t * v.y + n * v.z; }
};

// Local-frame trigonometry (z is the normal), as in pbrt.
inline float cos_theta(const Vec3 &w) { return w.z; }
inline float abs_cos_theta(const Vec3 &w) { return std::fabs(w.z); }
inline float cos2_theta(const Vec3 &w) { return w.z * w.z; }
inline float sin2_theta(const Vec3 &w) { return std::max(0.0f, 1.0f - cos2_theta(w)); }
inline float sin_theta(const Vec3 &w) { return std::sqrt(sin2_theta(w)); }
inline float tan2_theta(const Vec3 &w) { return sin2_theta(w) / cos2_theta(w); }
inline bool same_hemisphere(const Vec3 &a, const Vec3 &b) { return a.z * b.z > 0.0f; }

}  // namespace glimmer
