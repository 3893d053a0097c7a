// The dark test's count for a footprint of a few particle nodes (issue 10, session 24, glintdark24).
//
// glint.cpp's dark test counts a small footprint's reflecting particles at a
// bound P_max >= P (tables/glint_peak.h) and returns f = 0 when there are
// none; at footprint area 1e-8..1e-6 almost every eval ends there. Through
// the general route (locate_glints, then count_glints) such an eval built the
// node list (1 KB of NodeList, its level, the box path's AVX2 row keys), the
// FootprintFrame and the LitCountBounds before the first node, and hashed
// each node's four direction groups one scalar mix_u32 at a time: ~820
// instructions per eval at area 1e-8, for 1.06 nodes and ~1.6 drawn positions.
//
// small_footprint_dark_avx2 (glint_small_dark.cpp) answers the same
// question (is the count at P_max complete and 0?) for a footprint smaller
// than a node whose bounding box spans at most kBoxSpan x kBoxSpan particle
// nodes and holds at most `max_nodes` of them: the node list footprint_nodes
// gives such a footprint is the whole box. The level from the material's
// density (computed once; a textured density computes its own), the box by
// the same four floors, the nodes' keys by node_row_key + i W, the direction
// cells by direction_cell_seeds_avx2's body (inlined); pass 1: each node's
// four group hashes in one register (mix_u32x4_avx2: node_seed_hash's words)
// and the quick rejects as one compare, the passing pairs as bits (none: dark,
// ~20 % of the evals at area 1e-8); pass 2: count_reflecting_particles' node
// loop step for step over those pairs, in its order: the lit count K by
// LitCountBounds or the model, the steps' cap, the frame (made at the first
// lit pair) and the node's origin, the positions by particle_position and
// membership by FootprintFrame::particle_inside. The answer is a boolean, so
// it returns at the first counted particle (the count is then > 0 whatever
// follows). Everything else (footprints at least as large as a node, whose
// count takes the pair passes; boxes beyond kBoxSpan or beyond 2^51 node
// units; more than max_nodes nodes) is left to the general route (kGeneric),
// as is the SSE2 walk (GLIMMER_GLINT_WALK=sse2 runs the general route
// throughout). GlintParticles.SmallFootprintDarkMatchesTheCount compares it
// with the general route over random footprints, directions and bounds.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <optional>

#include "tables/glint_particles.h"

namespace glimmer::plugin::glint {

enum class SmallDark {
  kDark,     // the count at P is complete and 0 (site's cells are not filled)
  kNotDark,  // the count is > 0 or incomplete; site's cells (has_half_vector, cell_seeds, group_density) filled
  kGeneric,  // not decided here: the general route (locate_glints, count_glints) decides
};

// The per-material constants of small_footprint_dark_avx2: the direction cells' keys and cone, the dark test's
// node and step caps, and the particle level of the material's density (a textured density computes its own).
struct SmallDarkField {
  DirectionCellKeys keys{0};
  float gamma_rad = 0.0f;
  int max_nodes = 0, max_steps = 0;
  double density = -1.0;  // the density whose level is below (per unit area, all groups)
  double group_density = 0.0;
  int level = 0;
  SmallDarkField() = default;
  SmallDarkField(const DirectionCellKeys &k, float gamma, int nodes, int steps, double material_density);
};
// A new SmallDarkField. Out of line (glint_small_dark.cpp), as is the constructor, and held by pointer in
// GlintClosure: glint.cpp is at GCC's inlining budget (docs/history/glints_sessions.md, "Session 24 (glintdark24)").
std::unique_ptr<const SmallDarkField> make_small_dark_field(const DirectionCellKeys &k, float gamma, int nodes,
                                                            int steps, double material_density);

#if GLIMMER_GLINT_WALK_AVX2
// Whether count_glints(f, site, P, m.max_steps) would be complete and 0 after
// locate_glints(f, density, m.keys, wi, wo, m.gamma_rad, site), for a node list of at most m.max_nodes nodes (more:
// kGeneric); `area` is f.area(). See the header comment. Defined in glint_small_dark.cpp, out of glint.cpp's
// translation unit (glint.cpp sits at GCC's inline-unit-growth limit).
[[gnu::target("avx2")]] SmallDark small_footprint_dark_avx2(const SmallDarkField &m, const Footprint &f, double area,
                                                            double density, const Vec3 &wi, const Vec3 &wo, double P,
                                                            GlintSite &site);
#endif

}  // namespace glimmer::plugin::glint
