// Cycles' Principled BSDF (v1, Blender 3.x) as a composite of the closure nodes the
// host already maps (render/closure_nodes.cpp): the principled_bsdf node is expanded
// into diffuse, glossy, glass, mix/add, fresnel/math, emission and transparent nodes in
// a copy of its graph, which the shader system then compiles as any other graph, so a
// linked socket (base_color, roughness, metallic, ...) is evaluated per shading point
// exactly as it is on those nodes. The recipe is the one the Blender exporter writes
// (blender_addon/glimmer/exporter.py ShaderGraph.principled) plus clearcoat and alpha:
//   dielectric = diffuse(base_color) + glossy(0.08 * specular, roughness)     [Fresnel f0 of Disney's specular]
//   base       = mix(transmission, dielectric, glass(base_color, roughness, ior))
//   base       = mix(metallic, base, glossy(base_color, roughness))
//   coated     = mix(clearcoat * F_1.5(N.I), base, glossy(1, clearcoat_roughness, GGX))
//   surface    = mix(alpha, transparent(1), coated + emission * emission_strength)
// (the coat attenuates the base by 1 - clearcoat * F; Cycles 3.4's clearcoat is a GTR1
// lobe weighted 0.25 * clearcoat with Schlick f0 0.04: see docs/scene-format.md).
#pragma once

#include <functional>
#include <string>

#include "render/closure_nodes.h"
#include "scene/scene.h"

namespace glimmer::render {

// The principled_bsdf row of the closure-node table (sockets, defaults, unsupported notes).
ClosureNodeRow principled_row();

using PrincipledWarn = std::function<void(const scene::SourceLocation &, const std::string &)>;

// `expanded` = `g` plus the composite's nodes and links for node `n`; returns the
// name of a (virtual) node whose `surface` input the composite's result is linked
// to: compile it with ShaderSystem::compile_closure(expanded, name, "surface").
// Unsupported sockets set to non-default values or linked warn through `warn` (file:line).
std::string expand_principled(const scene::ShaderGraph &g, const scene::ShaderNode &n, scene::ShaderGraph &expanded,
                              const PrincipledWarn &warn);

}  // namespace glimmer::render
