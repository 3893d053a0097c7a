// The ray-scene acceleration structure: one Embree 3 scene of the meshes'
// triangles (geometry id = mesh index, primitive id = triangle index), with the
// closest-hit and any-hit (shadow) queries the path loop and trace_ray use.
#pragma once

#include <embree3/rtcore.h>

#include <cmath>
#include <limits>
#include <vector>

#include "glimmer/math.h"
#include "scene/scene.h"

namespace glimmer::render {

// The closest hit of a ray: mesh, triangle, barycentrics (b1, b2) and distance.
struct SurfaceHit {
  int mesh = -1;
  int prim = -1;
  float u = 0, v = 0, t = std::numeric_limits<float>::infinity();
};

class Accel {
 public:
  explicit Accel(const std::vector<scene::Mesh> &meshes);  // builds the BVH (RTC_BUILD_QUALITY_HIGH)
  ~Accel();
  Accel(const Accel &) = delete;
  Accel &operator=(const Accel &) = delete;

  // Closest hit of (o, d) in [tmin, tmax]; false when the ray escapes or cannot be traced.
  bool intersect(const Vec3 &o, const Vec3 &d, float tmin, float tmax, SurfaceHit &hit) const;
  // True when anything lies on (o, d) in [0, tmax] (or the ray cannot be traced: no light along it).
  bool occluded(const Vec3 &o, const Vec3 &d, float tmax) const;

  // Debian's Embree asserts ray.valid(): origin and direction components within +-1.844e18
  // (its FLT_LARGE; NaN and Inf fail too) and tnear/tfar not NaN. Other rays never reach it.
  static bool traceable_ray(const Vec3 &o, const Vec3 &d, float tmin, float tmax) {
    constexpr float kEmbreeLargest = 1.8e18f;
    auto bounded = [](const Vec3 &v) {
      return std::fabs(v.x) <= kEmbreeLargest && std::fabs(v.y) <= kEmbreeLargest && std::fabs(v.z) <= kEmbreeLargest;
    };
    return bounded(o) && bounded(d) && tmin >= 0.0f && tmin <= tmax;  // false for NaN
  }

 private:
  // An Embree ray (o, d) over [tmin, tmax] for all geometry.
  static void fill_ray(RTCRay &r, const Vec3 &o, const Vec3 &d, float tmin, float tmax);

  RTCDevice device_ = nullptr;
  RTCScene scene_ = nullptr;
};

// Inline (header): the path loop calls these on every ray segment and shadow ray.
inline void Accel::fill_ray(RTCRay &r, const Vec3 &o, const Vec3 &d, float tmin, float tmax) {
  r.org_x = o.x; r.org_y = o.y; r.org_z = o.z;
  r.dir_x = d.x; r.dir_y = d.y; r.dir_z = d.z;
  r.tnear = tmin;
  r.tfar = tmax;
  r.time = 0.0f;
  r.mask = 0xffffffffu;
  r.id = 0;
  r.flags = 0;
}

inline bool Accel::intersect(const Vec3 &o, const Vec3 &d, float tmin, float tmax, SurfaceHit &hit) const {
  if (!traceable_ray(o, d, tmin, tmax)) return false;
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRayHit rh;
  fill_ray(rh.ray, o, d, tmin, tmax);
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(scene_, &ctx, &rh);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return false;
  hit.mesh = static_cast<int>(rh.hit.geomID);
  hit.prim = static_cast<int>(rh.hit.primID);
  hit.u = rh.hit.u;
  hit.v = rh.hit.v;
  hit.t = rh.ray.tfar;
  return true;
}

inline bool Accel::occluded(const Vec3 &o, const Vec3 &d, float tmax) const {
  if (!traceable_ray(o, d, 0.0f, tmax)) return true;  // no light along a ray that cannot be traced
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRay r;
  fill_ray(r, o, d, 0.0f, tmax);
  rtcOccluded1(scene_, &ctx, &r);
  return r.tfar < 0.0f;
}

}  // namespace glimmer::render
