// A shader's `displacement` output rendered as bump mapping, as Cycles does with its default
// displacement method (`bump`; Cycles 3.4 ShaderGraph::bump_from_displacement): the displacement
// vector D is evaluated at the point and one footprint step away along x and y, its height along the
// normal h = D . N drives a Bump node of distance 1, and the bumped normal replaces the shading normal
// of everything downstream (every closure and normal-reading node whose normal is not linked).
// A float linked to the output is the vector (f, f, f) (Cycles' implicit conversion), so its height is
// f (Nx + Ny + Nz). Cycles measures the bump in object space; meshes are stored in world space here,
// so the bump is measured in world space (the same for objects without a scale).
#pragma once

#include <functional>
#include <string>

#include "scene/scene.h"

namespace glimmer::render {

using DisplacementWarn = std::function<void(const scene::SourceLocation &, const std::string &)>;

// Whether `node` is the Bump node expand_displacement_as_bump added: its normal replaces the shading normal
// itself (Cycles' set_normal), so a closure reading it is not "perturbed" (no bump shadowing term).
bool is_displacement_bump(const std::string &node);

// `expanded` = `g` with the bump nodes added and linked, when `g` links its `output displacement`;
// returns false (and leaves `expanded` untouched) when it does not.
bool expand_displacement_as_bump(const scene::ShaderGraph &g, scene::ShaderGraph &expanded,
                                 const DisplacementWarn &warn);

}  // namespace glimmer::render
