// The camera ray with its ray differentials (Igehy 1999) and their specular
// propagation: Cycles' perspective camera (fov across the shorter image side,
// thin lens), used by the path loop and probe().
#pragma once

#include "glimmer/math.h"
#include "scene/scene.h"

namespace glimmer::render {

// Ray differentials: position and direction per pixel step in x and y.
struct Differentials {
  Vec3 dPdx{0.0f}, dPdy{0.0f}, dDdx{0.0f}, dDdy{0.0f};
};

// Camera ray through film position (x, y) of a width x height image; (lens_u,
// lens_v) picks the point on the thin-lens aperture. dir_z is the cosine to the
// view axis (depth = t * dir_z).
void camera_ray(const scene::Camera &cam, int width, int height, float x, float y, Vec3 &org, Vec3 &dir,
                Differentials &rd, float &dir_z, float lens_u = 0.5f, float lens_v = 0.5f);

// Reflect or refract the direction differentials at a singular scatter (Igehy
// 1999, eq. 14-15, 18-19): N shading normal and Ng geometric normal (both facing
// the incoming side), dn1/dn2 the normal's per-pixel derivatives.
void propagate_specular(Differentials &rd, const Vec3 &D, const Vec3 &wo, const Vec3 &N, const Vec3 &Ng,
                        const Vec3 &dn1, const Vec3 &dn2, float eta);

}  // namespace glimmer::render
