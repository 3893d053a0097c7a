// The camera ray with its ray differentials (Igehy 1999) and their specular
// propagation: Cycles' perspective camera (fov across the shorter image side,
// thin lens), used by the path loop and probe().
#pragma once

#include <cmath>

#include "glimmer/math.h"
#include "scene/scene.h"

namespace glimmer::render {

// Ray differentials: position and direction per pixel step in x and y.
// With depth of field the camera adds the aperture's share (lens = true): the ray's derivative with
// respect to the point on the lens, scaled to the aperture radius A, along camera x (dPdlx, dDdlx) and
// y. At distance t it spans A |1 - t / t_focus| (zero on the focal plane: the circle of confusion's
// radius); fold_lens_differentials adds it to the pixel's share at the first hit.
struct Differentials {
  Vec3 dPdx{0.0f}, dPdy{0.0f}, dDdx{0.0f}, dDdy{0.0f};
  Vec3 dPdlx{0.0f}, dPdly{0.0f}, dDdlx{0.0f}, dDdly{0.0f};
  bool lens = false;
};

// What every camera ray of one image shares (computed once per render: the tangent and the transformed
// axes were 3 % of a one-thread profile when computed per ray).
struct CameraFrame {
  int width = 1, height = 1;
  float half_w = 1.0f, half_h = 1.0f;  // the film's half extents in units of the shorter side
  float tan_half_fov = 1.0f;
  Vec3 dvx{0.0f}, dvy{0.0f};            // camera-space film step per pixel in x and y
  Vec3 dvx_world{0.0f}, dvy_world{0.0f};
  Vec3 origin{0.0f}, view_axis{0.0f, 0.0f, 1.0f};  // world space
};
CameraFrame camera_frame(const scene::Camera &cam, int width, int height);

// Camera ray through film position (x, y) of the frame's image; (lens_u,
// lens_v) picks the point on the thin-lens aperture. dir_z is the cosine to the
// view axis (depth = t * dir_z).
void camera_ray(const scene::Camera &cam, const CameraFrame &frame, float x, float y, Vec3 &org, Vec3 &dir,
                Differentials &rd, float &dir_z, float lens_u = 0.5f, float lens_v = 0.5f);

// A differential (dP, dD) of the ray (origin + t D) carried to the tangent plane of the hit at distance t with
// geometric normal Ng (Igehy 1999, eq. 10): the footprint one step makes on the surface.
inline Vec3 footprint_on_plane(const Vec3 &dP, const Vec3 &dD, const Vec3 &D, float t, const Vec3 &Ng) {
  const Vec3 p = dP + dD * t;
  const float dn = dot(D, Ng);
  const float dt = std::fabs(dn) > 1e-8f ? -dot(p, Ng) / dn : 0.0f;
  return p + D * dt;
}

// At the first hit (distance t along D, geometric normal Ng): adds the aperture's share to the pixel's, per
// axis with the sign that makes the two footprints on the surface add up (|pixel| + A |1 - t / t_focus| for
// parallel ones), so the footprint covers the circle of confusion as the lens blurs it; then clears `lens`.
// The result is one linear differential that reflections and refractions propagate as usual.
void fold_lens_differentials(Differentials &rd, const Vec3 &D, float t, const Vec3 &Ng);

// Reflect or refract the direction differentials at a singular scatter (Igehy
// 1999, eq. 14-15, 18-19): N shading normal and Ng geometric normal (both facing
// the incoming side), dn1/dn2 the normal's per-pixel derivatives.
void propagate_specular(Differentials &rd, const Vec3 &D, const Vec3 &wo, const Vec3 &N, const Vec3 &Ng,
                        const Vec3 &dn1, const Vec3 &dn2, float eta);

}  // namespace glimmer::render
