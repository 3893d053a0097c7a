#include "scene/uv_tangents.h"

#include <cmath>
#include <map>
#include <tuple>

namespace glimmer::scene {

namespace {

Vec3 project_normalized(const Vec3 &t, const Vec3 &n) {
  const Vec3 p = t - n * dot(n, t);
  const float len2 = length_squared(p);
  return len2 > 0.0f && std::isfinite(len2) ? p / std::sqrt(len2) : Vec3(0.0f);
}

float corner_angle(const Vec3 &a, const Vec3 &b) {
  const float la = length(a), lb = length(b);
  if (!(la > 0.0f) || !(lb > 0.0f)) return 0.0f;
  return std::acos(std::fmax(-1.0f, std::fmin(1.0f, dot(a, b) / (la * lb))));
}

}  // namespace

void compute_uv_tangents(Mesh &m) {
  m.tangent.clear();
  m.tangent_sign.clear();
  if (m.uv.size() != 3 * m.triangles.size()) return;
  const size_t corners = m.uv.size();
  std::vector<Vec3> projected(corners, Vec3(0.0f));
  std::vector<float> weight(corners, 0.0f), sign(corners, 1.0f);
  std::vector<Vec3> normal(corners, Vec3(0.0f));
  for (size_t f = 0; f < m.triangles.size(); ++f) {
    const SurfacePoint s = m.surface_at(f, 1.0f / 3.0f, 1.0f / 3.0f);  // dP/du, dP/dv of the triangle
    const float handedness = dot(cross(s.Ng, s.dPdu), s.dPdv) < 0.0f ? -1.0f : 1.0f;
    for (int k = 0; k < 3; ++k) {
      const size_t c = 3 * f + k;
      const uint32_t v = m.triangles[f][k];
      normal[c] = m.smooth && !m.N.empty() ? m.N[v] : s.Ng;
      projected[c] = project_normalized(s.dPdu, normal[c]);
      const Vec3 p = m.P[v];
      weight[c] = corner_angle(m.P[m.triangles[f][(k + 1) % 3]] - p, m.P[m.triangles[f][(k + 2) % 3]] - p);
      sign[c] = handedness;
    }
  }
  // Groups of corners sharing vertex, UV and handedness (smooth meshes); flat meshes keep their own.
  using Key = std::tuple<uint32_t, float, float, float>;
  std::map<Key, Vec3> sums;
  const bool shared = m.smooth && !m.N.empty();
  if (shared)
    for (size_t c = 0; c < corners; ++c)
      sums[{m.triangles[c / 3][c % 3], m.uv[c][0], m.uv[c][1], sign[c]}] += projected[c] * weight[c];
  m.tangent.resize(corners);
  m.tangent_sign = sign;
  for (size_t c = 0; c < corners; ++c) {
    const Vec3 sum = shared ? sums[{m.triangles[c / 3][c % 3], m.uv[c][0], m.uv[c][1], sign[c]}] : projected[c];
    const Vec3 t = project_normalized(sum, normal[c]);
    m.tangent[c] = is_zero(t) ? projected[c] : t;
  }
}

}  // namespace glimmer::scene
