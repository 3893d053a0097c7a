// Configure and eval functions of the node families (one .cpp per family), listed
// in node_table.cpp.
#pragma once

#include "render/nodes/node.h"

namespace glimmer::render::nodes {

#define GLIMMER_NODE_FNS(name)                                 \
  void configure_##name(const SettingsReader &, NodeSettings &); \
  void eval_##name(const NodeSettings &, const ShadingPoint &, const Vec3 *, Vec3 *);

GLIMMER_NODE_FNS(noise)
GLIMMER_NODE_FNS(voronoi)
GLIMMER_NODE_FNS(musgrave)
GLIMMER_NODE_FNS(wave)
GLIMMER_NODE_FNS(color_ramp)
GLIMMER_NODE_FNS(math)
GLIMMER_NODE_FNS(vector_math)
GLIMMER_NODE_FNS(mix_rgb)
GLIMMER_NODE_FNS(mapping)
GLIMMER_NODE_FNS(value)
GLIMMER_NODE_FNS(clamp)
GLIMMER_NODE_FNS(map_range)
GLIMMER_NODE_FNS(gradient)
GLIMMER_NODE_FNS(white_noise)
GLIMMER_NODE_FNS(bump)
GLIMMER_NODE_FNS(normal_map)
GLIMMER_NODE_FNS(tangent)
GLIMMER_NODE_FNS(sky)
#undef GLIMMER_NODE_FNS

void eval_hsv(const NodeSettings &, const ShadingPoint &, const Vec3 *, Vec3 *);
void eval_texture_coordinate(const NodeSettings &, const ShadingPoint &, const Vec3 *, Vec3 *);
void eval_geometry(const NodeSettings &, const ShadingPoint &, const Vec3 *, Vec3 *);
void configure_displacement(const SettingsReader &, NodeSettings &);
void eval_displacement(const NodeSettings &, const ShadingPoint &, const Vec3 *, Vec3 *);
void eval_fresnel(const NodeSettings &, const ShadingPoint &, const Vec3 *, Vec3 *);
void eval_layer_weight(const NodeSettings &, const ShadingPoint &, const Vec3 *, Vec3 *);
void eval_light_path(const NodeSettings &, const ShadingPoint &, const Vec3 *, Vec3 *);
void eval_invert(const NodeSettings &, const ShadingPoint &, const Vec3 *, Vec3 *);
void eval_gamma(const NodeSettings &, const ShadingPoint &, const Vec3 *, Vec3 *);
void eval_brightness_contrast(const NodeSettings &, const ShadingPoint &, const Vec3 *, Vec3 *);
void eval_separate(const NodeSettings &, const ShadingPoint &, const Vec3 *, Vec3 *);
void eval_combine(const NodeSettings &, const ShadingPoint &, const Vec3 *, Vec3 *);
void eval_rgb_to_bw(const NodeSettings &, const ShadingPoint &, const Vec3 *, Vec3 *);

}  // namespace glimmer::render::nodes
