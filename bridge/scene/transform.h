// Affine transforms as Cycles' Transform: a 3x4 row-major matrix acting on
// column vectors, composed parent * M * T * R * S by the XML reader.
#pragma once

#include <cmath>

#include "glimmer/math.h"

namespace glimmer::scene {

struct Transform {
  float m[3][4] = {{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}};

  static Transform identity() { return {}; }
  static Transform translate(const Vec3 &t) {
    Transform r;
    r.m[0][3] = t.x; r.m[1][3] = t.y; r.m[2][3] = t.z;
    return r;
  }
  static Transform scale(const Vec3 &s) {
    Transform r;
    r.m[0][0] = s.x; r.m[1][1] = s.y; r.m[2][2] = s.z;
    return r;
  }
  // Rotation by `angle` radians about `axis` (right-handed, as transform_rotate in Cycles).
  static Transform rotate(float angle, Vec3 axis) {
    axis = normalize(axis);
    const float s = std::sin(angle), c = std::cos(angle), t = 1.0f - c;
    Transform r;
    r.m[0][0] = axis.x * axis.x * t + c;
    r.m[0][1] = axis.x * axis.y * t - s * axis.z;
    r.m[0][2] = axis.x * axis.z * t + s * axis.y;
    r.m[1][0] = axis.y * axis.x * t + s * axis.z;
    r.m[1][1] = axis.y * axis.y * t + c;
    r.m[1][2] = axis.y * axis.z * t - s * axis.x;
    r.m[2][0] = axis.z * axis.x * t - s * axis.y;
    r.m[2][1] = axis.z * axis.y * t + s * axis.x;
    r.m[2][2] = axis.z * axis.z * t + c;
    return r;
  }

  Transform operator*(const Transform &b) const {
    Transform r;
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 4; ++j) {
        float v = m[i][0] * b.m[0][j] + m[i][1] * b.m[1][j] + m[i][2] * b.m[2][j];
        if (j == 3) v += m[i][3];
        r.m[i][j] = v;
      }
    }
    return r;
  }
  Vec3 point(const Vec3 &p) const {
    return {m[0][0] * p.x + m[0][1] * p.y + m[0][2] * p.z + m[0][3],
            m[1][0] * p.x + m[1][1] * p.y + m[1][2] * p.z + m[1][3],
            m[2][0] * p.x + m[2][1] * p.y + m[2][2] * p.z + m[2][3]};
  }
  Vec3 vector(const Vec3 &v) const {
    return {m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z, m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z,
            m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z};
  }
  // Normals transform with the inverse transpose of the linear part.
  Vec3 normal(const Vec3 &n) const {
    const Vec3 c0(m[0][0], m[1][0], m[2][0]), c1(m[0][1], m[1][1], m[2][1]), c2(m[0][2], m[1][2], m[2][2]);
    // Rows of the inverse transpose are the cofactor vectors (up to 1/det).
    const Vec3 r0 = cross(c1, c2), r1 = cross(c2, c0), r2 = cross(c0, c1);
    const float det = dot(c0, r0);
    const Vec3 out = r0 * n.x + r1 * n.y + r2 * n.z;
    return det < 0.0f ? -out : out;
  }
  // The affine inverse: the linear part's inverse (its columns are the cross products of the rows over the
  // determinant), then the translation. False, `out` untouched, when |det| <= min_abs_det or det is not finite.
  bool inverse(Transform &out, float min_abs_det = 0.0f) const {
    const Vec3 r0(m[0][0], m[0][1], m[0][2]), r1(m[1][0], m[1][1], m[1][2]), r2(m[2][0], m[2][1], m[2][2]);
    const float det = dot(r0, cross(r1, r2));
    if (!(std::fabs(det) > min_abs_det) || !std::isfinite(det)) return false;
    const Vec3 c0 = cross(r1, r2) / det, c1 = cross(r2, r0) / det, c2 = cross(r0, r1) / det;
    const Vec3 rows[3] = {{c0.x, c1.x, c2.x}, {c0.y, c1.y, c2.y}, {c0.z, c1.z, c2.z}};
    const Vec3 t(m[0][3], m[1][3], m[2][3]);
    for (int r = 0; r < 3; ++r) {
      out.m[r][0] = rows[r].x;
      out.m[r][1] = rows[r].y;
      out.m[r][2] = rows[r].z;
      out.m[r][3] = -dot(rows[r], t);
    }
    return true;
  }
  float determinant() const {
    const Vec3 c0(m[0][0], m[1][0], m[2][0]), c1(m[0][1], m[1][1], m[2][1]), c2(m[0][2], m[1][2], m[2][2]);
    return dot(c0, cross(c1, c2));
  }
};

}  // namespace glimmer::scene
