// Per-corner UV tangents of a mesh (what Cycles' Normal Map and Tangent nodes read as the UV map's
// tangent attribute, which Blender computes with MikkTSpace). Glimmer's version, written from
// MikkTSpace's description (Mikkelsen 2008, "Simulation of Wrinkled Surfaces Revisited", sec. 4):
//  - a triangle's tangent is dP/du of its UV map, its handedness the sign of (n x dP/du) . dP/dv;
//  - at a corner it is projected onto the plane of the corner's normal (the vertex normal on smooth
//    meshes, the face normal on flat ones) and normalized;
//  - corners that share a vertex, its UV coordinates, its normal and the handedness (smooth meshes:
//    same vertex index and UV; flat meshes share nothing) average their projected tangents weighted
//    by the corner angle, and the sum is projected and normalized again.
// MikkTSpace itself additionally splits groups whose tangents differ by more than an angle threshold
// and orders its averaging differently; on meshes with smooth UV maps the results agree to float
// rounding, not bit for bit.
#pragma once

#include "scene/scene.h"

namespace glimmer::scene {

// Fills m.tangent / m.tangent_sign (3 per triangle) when the mesh has a UV map; leaves them empty otherwise.
void compute_uv_tangents(Mesh &m);

}  // namespace glimmer::scene
