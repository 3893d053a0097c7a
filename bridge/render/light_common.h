// What every light kind (render/light_<kind>.h) hands the path loop: a light
// sample for next-event estimation and a light hit for a BSDF-sampled ray.
// Pick probabilities are the LightSet's; each kind multiplies its own solid-angle
// density by the one it is given, in one pdf formula shared by sample and hit, so
// the MIS weights of NEE and of BSDF-hit emission come from the same code.
#pragma once

#include "glimmer/math.h"

namespace glimmer::render {

struct LightSample {
  Vec3 wi;            // toward the light
  float dist = 0.0f;  // to the light point (infinite for distant lights)
  Spectrum radiance{0.0f};  // incident radiance (delta lights: irradiance-like term, pdf = pick probability)
  float pdf = 0.0f;   // solid angle density including the pick probability
  bool delta = false;
  bool world = false;  // drawn from the world (the background light)
  bool lamp = false;   // drawn from a lamp (point, spot, area, sun), not an emissive triangle or the world
};

struct LightHit {
  Spectrum radiance{0.0f};
  float pdf = 0.0f;  // what sample() would give for this direction
  float t = 0.0f;
  bool delta = false;
};

// Every lamp a ray segment passes through: Cycles' lamps do not block rays
// (shade_light adds the emission and the ray continues past the lamp).
struct LightHits {
  static constexpr int kMax = 16;
  LightHit hits[kMax];
  int count = 0;
  void add(const LightHit &h) {
    if (count < kMax) hits[count++] = h;
  }
};

// Solid-angle density of a point sampled uniformly by area on a surface of `area`, seen at squared
// distance dist2 under cosine cos_l to the surface normal (pdf_A * d^2 / cos), times the pick probability.
inline float area_to_solid_angle_pdf(float pick, float dist2, float cos_l, float area) {
  return pick * dist2 / (cos_l * area);
}

}  // namespace glimmer::render
