#include "render/accel.h"

#include <embree3/rtcore.h>

#include <cmath>
#include <stdexcept>

namespace glimmer::render {

namespace {

// One triangle geometry of a mesh's vertices and index triples.
RTCGeometry triangle_geometry(RTCDevice device, const scene::Mesh &m) {
  RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto *vb = static_cast<float *>(
      rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), m.P.size()));
  for (size_t k = 0; k < m.P.size(); ++k) {
    vb[3 * k] = m.P[k].x;
    vb[3 * k + 1] = m.P[k].y;
    vb[3 * k + 2] = m.P[k].z;
  }
  auto *ib = static_cast<uint32_t *>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                             3 * sizeof(uint32_t), m.triangles.size()));
  for (size_t k = 0; k < m.triangles.size(); ++k)
    for (int c = 0; c < 3; ++c) ib[3 * k + c] = m.triangles[k][c];
  rtcCommitGeometry(g);
  return g;
}

// An Embree ray (o, d) over [tmin, tmax] for all geometry.
void fill_ray(RTCRay &r, const Vec3 &o, const Vec3 &d, float tmin, float tmax) {
  r.org_x = o.x; r.org_y = o.y; r.org_z = o.z;
  r.dir_x = d.x; r.dir_y = d.y; r.dir_z = d.z;
  r.tnear = tmin;
  r.tfar = tmax;
  r.time = 0.0f;
  r.mask = 0xffffffffu;
  r.id = 0;
  r.flags = 0;
}

}  // namespace

Accel::Accel(const std::vector<scene::Mesh> &meshes) {
  device_ = rtcNewDevice("threads=0");
  if (!device_) throw std::runtime_error("Embree: cannot create a device");
  scene_ = rtcNewScene(device_);
  rtcSetSceneBuildQuality(scene_, RTC_BUILD_QUALITY_HIGH);
  for (size_t i = 0; i < meshes.size(); ++i) {
    RTCGeometry g = triangle_geometry(device_, meshes[i]);
    rtcAttachGeometryByID(scene_, g, static_cast<unsigned>(i));
    rtcReleaseGeometry(g);
  }
  rtcCommitScene(scene_);
}

Accel::~Accel() {
  if (scene_) rtcReleaseScene(scene_);
  if (device_) rtcReleaseDevice(device_);
}

bool Accel::intersect(const Vec3 &o, const Vec3 &d, float tmin, float tmax, SurfaceHit &hit) const {
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

bool Accel::occluded(const Vec3 &o, const Vec3 &d, float tmax) const {
  if (!traceable_ray(o, d, 0.0f, tmax)) return true;  // no light along a ray that cannot be traced
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRay r;
  fill_ray(r, o, d, 0.0f, tmax);
  rtcOccluded1(scene_, &ctx, &r);
  return r.tfar < 0.0f;
}

}  // namespace glimmer::render
