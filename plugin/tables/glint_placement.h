// Where the glint particles live (issue 10): in the scaled uv plane
// (placement="uv", the default) or in the object's own space
// (placement="object"), for meshes whose UVs are stretched or shared
// (overlapping islands, mirrored halves): there the uv density per unit
// surface area follows the stretch, and shared islands repeat the glints.
//
// Object placement is a triplanar projection of the object-space point
// (ABI 2.5: GlimmerShadingContext.P_object, dPdx_object, dPdy_object,
// Ng_object). The projection axis is the dominant component of the
// object-space geometric normal n (flat per triangle, so a face never
// switches axis inside); the point and its footprint (dP/dx, dP/dy, on the
// surface) are projected onto the other two coordinates, which shrinks
// areas on the surface by |n_axis| (>= 1/sqrt(3)), and then scaled by
// uv_scale / sqrt(|n_axis|), which restores them: the particle density per
// unit of object-space surface area is exactly `density` on planar faces
// (on curved faces up to the change of n across one footprint, which the
// footprint's Jacobian ignores). Each axis's plane is offset so the three
// projections show independent fields. The result is a pure function of the
// object-space point and footprint, so the glints stay on the object when
// it moves.
//
// Without the ABI 2.5 fields (an older host) or with a zero Ng_object (no
// object space, e.g. the closure laboratory) the uv footprint is used.
#pragma once

#include <cmath>

#include "glimmer/closure_abi.h"
#include "tables/glint_common.h"

namespace glimmer::plugin::glint {

enum class Placement { UV = 0, Object = 1 };

// Offset of projection axis a's plane (scaled units): far apart, so the
// three projections use disjoint parts of the particle field.
inline constexpr double kAxisPlaneOffset = 4099.37;

// The footprint of `ctx` in the particles' plane for the given placement, and its area (f.area(), computed once).
// Inlining pinned (session 25): with the area passed out, GCC made this a function of its own in glint.cpp.
[[gnu::always_inline]] inline Footprint placed_footprint(const ParticleField &field, Placement placement,
                                                        const GlimmerShadingContext *ctx, double &area) {
#if GLIMMER_ABI_MINOR >= 4
  if (placement == Placement::Object && GLIMMER_HAS_FIELD(ctx->struct_size, GlimmerShadingContext, Ng_object)) {
    const float n[3] = {std::fabs(ctx->Ng_object.x), std::fabs(ctx->Ng_object.y), std::fabs(ctx->Ng_object.z)};
    const int axis = n[0] >= n[1] && n[0] >= n[2] ? 0 : (n[1] >= n[2] ? 1 : 2);
    const float n_len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (n_len > 0.0f && std::isfinite(n_len)) {
      const int a = (axis + 1) % 3, b = (axis + 2) % 3;  // the projection plane's coordinates
      const double scale = field.uv_scale / std::sqrt(static_cast<double>(n[axis] / n_len));
      auto coord = [](const GlimmerVec3 &v, int k) { return static_cast<double>(k == 0 ? v.x : k == 1 ? v.y : v.z); };
      Footprint f;
      const double offset = kAxisPlaneOffset * (axis + 1);
      f.cx = coord(ctx->P_object, a) * scale + offset;
      f.cy = coord(ctx->P_object, b) * scale + offset;
      f.ax = coord(ctx->dPdx_object, a) * scale;
      f.ay = coord(ctx->dPdx_object, b) * scale;
      f.bx = coord(ctx->dPdy_object, a) * scale;
      f.by = coord(ctx->dPdy_object, b) * scale;
      return field.valid_footprint(f, area);
    }
  }
#else
  (void)placement;
#endif
  return field.footprint(ctx, area);
}

}  // namespace glimmer::plugin::glint
