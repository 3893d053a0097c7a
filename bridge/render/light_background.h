// The world as a light (Cycles' kernel/light/background.h): radiance from the
// background shader; a constant world is sampled uniformly over the sphere, a
// textured one by an equirectangular importance map (512 x 256 cells, 2x2
// supersampled luminance times sin theta, plus a 1 % floor so every direction
// keeps a density). One pdf(d) for sample() and for BSDF rays that escape.
#pragma once

#include "render/distribution.h"
#include "render/light_common.h"
#include "render/shader_system.h"

namespace glimmer::render {

class BackgroundLight {
 public:
  explicit BackgroundLight(const ShaderSystem &shaders);  // builds the map when the world is not constant
  // Power through the scene's bounding disk of area `disk_area`.
  float power(float disk_area) const;
  bool sample(float u, float v, const Vec3 &P, float pick, LightSample &out) const;
  float pdf(const Vec3 &d) const;  // solid-angle density of direction d (without the pick probability)

 private:
  void build_map();

  const ShaderSystem *shaders_;
  int width_ = 0, height_ = 0;  // 0: uniform over the sphere
  Distribution2D map_;
};

}  // namespace glimmer::render
