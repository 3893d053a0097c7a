// The ray-scene acceleration structure: one Embree 3 scene of the meshes'
// triangles (geometry id = mesh index, primitive id = triangle index), with the
// closest-hit and any-hit (shadow) queries the path loop and trace_ray use.
#pragma once

#include <cmath>
#include <limits>
#include <vector>

#include "glimmer/math.h"
#include "scene/scene.h"

typedef struct RTCDeviceTy *RTCDevice;
typedef struct RTCSceneTy *RTCScene;

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
  RTCDevice device_ = nullptr;
  RTCScene scene_ = nullptr;
};

}  // namespace glimmer::render
