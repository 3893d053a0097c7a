// Shading-normal helpers shared by the Bump, Normal Map and Tangent nodes
// (render/nodes/normal_nodes.cpp) and the closures' own frames (ShaderSystem).
#pragma once

#include "glimmer/math.h"

namespace glimmer::render::nodes {

// Cycles 3.4's terminator fix for perturbed normals (kernel/closure/bsdf_util.h, ensure_valid_reflection):
// when the mirror reflection of I about N points below the surface (dot(R, Ng) under
// t = min(0.9 dot(Ng, I), 0.01)), N is tilted toward Ng, in the plane of N and Ng, just enough that
// dot(R', Ng) = t. Ng and I unit, on the same side (I toward the viewer); returns a unit normal.
Vec3 ensure_valid_reflection(const Vec3 &Ng, const Vec3 &I, const Vec3 &N);

// The Tangent node's radial tangent about `axis` (0 = X, 1 = Y, 2 = Z) from generated coordinates
// (Cycles' svm_node_tangent, before the projection onto the normal's plane).
Vec3 radial_tangent(const Vec3 &generated, int axis);

// `t` made orthogonal to unit N (Cycles: cross(N, normalize(cross(t, N)))); zero when t is along N.
Vec3 tangent_in_plane(const Vec3 &N, const Vec3 &t);

}  // namespace glimmer::render::nodes
