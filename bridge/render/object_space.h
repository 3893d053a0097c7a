// Object space of a shading point (closure ABI 2.5: GlimmerShadingContext
// .P_object, .dPdx_object, .dPdy_object, .Ng_object). Meshes are stored in
// world space (scene.h); each keeps its object-to-world transform, whose
// inverse maps the point and its footprint back to the object's own space.
#pragma once

#include <cmath>

#include "glimmer/closure_abi.h"
#include "glimmer/math.h"
#include "scene/transform.h"

namespace glimmer::render {

// The world-to-object map of an object whose transform is `object_to_world`:
// its affine inverse (scene::Transform::inverse), and the transpose of the
// linear part, which takes a world normal back to the object's
// (n_world ~ M^-T n_object).
struct ObjectSpace {
  scene::Transform world_to_object;
  scene::Transform object_to_world;
  bool valid = false;  // false for a singular transform: the context's object fields stay zero

  explicit ObjectSpace(const scene::Transform &m)
      : object_to_world(m), valid(m.inverse(world_to_object, 1e-30f)) {}

  // Unit object-space normal of the world normal `n_world`.
  Vec3 normal(const Vec3 &n_world) const {
    const auto &m = object_to_world.m;
    const Vec3 n(m[0][0] * n_world.x + m[1][0] * n_world.y + m[2][0] * n_world.z,
                 m[0][1] * n_world.x + m[1][1] * n_world.y + m[2][1] * n_world.z,
                 m[0][2] * n_world.x + m[1][2] * n_world.y + m[2][2] * n_world.z);
    const float len = length(n);
    return len > 0.0f && std::isfinite(len) ? n / len : Vec3(0.0f);
  }

  // The point and its geometric normal (world, the mesh's outward side).
  void set_point(const Vec3 &P, const Vec3 &Ng, GlimmerShadingContext &ctx) const {
    if (!valid) return;
    ctx.P_object = world_to_object.point(P);
    ctx.Ng_object = normal(Ng);
  }
  // The footprint's world steps per pixel on the surface.
  void set_footprint(const Vec3 &dPdx, const Vec3 &dPdy, GlimmerShadingContext &ctx) const {
    if (!valid) return;
    const Vec3 x = world_to_object.vector(dPdx), y = world_to_object.vector(dPdy);
    ctx.dPdx_object = is_finite(x) ? x : Vec3(0.0f);
    ctx.dPdy_object = is_finite(y) ? y : Vec3(0.0f);
  }
};

}  // namespace glimmer::render
