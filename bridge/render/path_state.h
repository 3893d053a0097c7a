// The state of one path between bounces (Cycles' kernel/integrator/path_state.h):
// bounce counters by label, the MIS state of the last scatter and the
// footprint spread, with advance(label) as Cycles' path_state_next.
#pragma once

#include <algorithm>
#include <cstdint>
#include <limits>

#include "glimmer/closure_abi.h"
#include "scene/scene.h"

namespace glimmer::render {

// Cycles' kernel limits (scene/integrator.cpp): the settings plus one, "so that a
// bounce of 0 indicates no global illumination, only direct illumination";
// transparent_max_bounce is used as is.
struct BounceLimits {
  int min_bounce, bounce, diffuse, glossy, transmission, transparent;

  explicit BounceLimits(const scene::IntegratorSettings &integ)
      : min_bounce(plus_one(integ.min_bounce)),
        bounce(plus_one(integ.max_bounce)),
        diffuse(plus_one(integ.max_diffuse_bounce)),
        glossy(plus_one(integ.max_glossy_bounce)),
        transmission(plus_one(integ.max_transmission_bounce)),
        transparent(integ.transparent_max_bounce) {}

  static int plus_one(int v) { return v < std::numeric_limits<int>::max() ? v + 1 : v; }
};

struct PathState {
  int bounce = 0, diffuse_bounce = 0, glossy_bounce = 0, transmission_bounce = 0, transparent_bounce = 0;
  bool terminate_next = false;  // the next surface still adds emission, then the path ends
  bool last_singular = true;    // camera rays count as singular: no MIS on emission
  float mis_ray_pdf = 0.0f;     // mixture pdf of the last (non-singular) scatter
  float min_ray_pdf = std::numeric_limits<float>::max();  // filter_glossy
  float spread = 0.0f;          // accumulated angular spread (radians) of glossy bounces
  // Cycles' PATH_RAY_TRANSPARENT_BACKGROUND: the camera ray and its transparent pass-throughs see a
  // transparent film's background as alpha, not as light; the first scatter clears it.
  bool transparent_background = false;
  uint32_t last_label = GLIMMER_LABEL_NONE;  // the last scatter's label (Light Path node); none: camera ray

  // A scatter with `label` (Cycles' path_state_next): count it, and end the
  // path after the next surface when a limit is reached.
  void advance(uint32_t label, const BounceLimits &limits) {
    ++bounce;
    transparent_background = false;
    last_label = label;
    if (bounce >= limits.bounce) terminate_next = true;
    if (label & GLIMMER_LABEL_REFLECT) {
      if (label & GLIMMER_LABEL_DIFFUSE) {
        if (++diffuse_bounce >= limits.diffuse) terminate_next = true;
      } else if (++glossy_bounce >= limits.glossy) {
        terminate_next = true;
      }
    } else if (++transmission_bounce >= limits.transmission) {
      terminate_next = true;
    }
  }

  // A pass through a transparent closure: not a bounce, counted apart.
  void advance_transparent(const BounceLimits &limits) {
    if (++transparent_bounce >= limits.transparent) terminate_next = true;
  }

  // The path vertex whose sample sets (BSDF, light) the next surface uses: every surface the path has
  // left, transparent pass-throughs included (Cycles advances rng_offset for both), so the surface behind
  // a transparent one draws fresh numbers instead of the x < transparent-share that picked the pass-through.
  int sample_vertex() const { return bounce + transparent_bounce; }
};

}  // namespace glimmer::render
