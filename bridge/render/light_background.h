// The world as a light (Cycles' kernel/light/background.h): radiance from the
// background shader; a constant world is sampled uniformly over the sphere, a
// textured one by an equirectangular importance map of the evaluated background
// (whatever its node graph: image, sky, mapping; 512 x 256 cells, 2x2 supersampled
// luminance times sin theta, plus a 1 % floor so every direction keeps a density).
// A sky texture's sun disc (one, with the sky reading the ray direction) is sampled
// uniformly within its cone instead (Cycles' background sun sampling): the map leaves
// the cone out and the two densities are mixed by their estimated powers. One pdf(d)
// for sample() and for BSDF rays that escape.
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
  // The probability that sample() draws from the sun's cone (0 without a sun disc).
  float sun_probability() const { return sun_pick_; }

 private:
  void build_map();
  void set_up_sun(const nodes::SunDisc &sun);
  bool in_sun(const Vec3 &d) const;
  float map_pdf(const Vec3 &d) const;

  const ShaderSystem *shaders_;
  int width_ = 0, height_ = 0;  // 0: uniform over the sphere
  Distribution2D map_;
  // The sun's cone: axis frame, half-angle, 1 - cos(half-angle) (computed as 2 sin^2(half / 2)),
  // the integral of its luminance and the probability of sampling it.
  Frame sun_frame_;
  float sun_half_angle_ = 0.0f;
  double sun_one_minus_cos_ = 0.0;
  float sun_power_ = 0.0f, sun_pick_ = 0.0f;
};

}  // namespace glimmer::render
