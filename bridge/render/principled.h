// Cycles' Principled BSDF (v1, Blender 3.x) as a composite of the closure nodes the
// host already maps (render/closure_nodes.cpp): the principled_bsdf node is expanded
// into principled_diffuse, principled_specular, principled_sheen, glass, clearcoat, mix/add, math, emission and
// transparent nodes in
// a copy of its graph, which the shader system then compiles as any other graph, so a
// linked socket (base_color, roughness, metallic, ...) is evaluated per shading point
// exactly as it is on those nodes. The recipe (the Blender exporter writes Blender's
// Principled BSDF as this node):
//   specular   = principled_specular(base_color, metallic, specular, specular_tint, roughness)
//   dielectric = principled_diffuse(base_color, roughness) + specular
//                [+ principled_sheen(base_color, sheen, sheen_tint) when sheen > 0 or linked]
//   base       = mix(transmission, dielectric, glass(base_color, roughness, ior))
//   base       = mix(metallic, base, specular)
// (Cycles 3.4's weights: diffuse (1 - metallic)(1 - transmission), glass (1 - metallic) transmission, specular
// 1 - transmission (1 - metallic), sheen as the diffuse; the specular's Fresnel colour carries the metal, see
// plugin/closures/principled_specular.h)
//   coated     = base + clearcoat_bsdf(weight 0.25 * clearcoat, clearcoat_roughness)
//   surface    = mix(alpha, transparent(1), coated + emission * emission_strength)
// (the coat is Cycles 3.4's: the clearcoat closure, plugin/closures/clearcoat.h, on top of
// the base, which it does not attenuate; see docs/scene-format.md).
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
