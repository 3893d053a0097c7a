#include "render/accel.h"

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

}  // namespace glimmer::render
