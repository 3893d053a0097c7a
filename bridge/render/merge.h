// `glimmer merge`: puts the parts of one render back together. Parts are images
// written by `glimmer render` with --region/--tile (a window of the image) and/or
// --sample-range/--sample-split (samples [a, b) of N). Per window, the sample ranges
// must tile [0, N) exactly; the windows must tile the whole image exactly.
//  - a window rendered by one part is copied: bit-identical to a one-machine render;
//  - a window split by samples is the sample-count-weighted mean of its parts
//    (sum_k n_k * mean_k / N in double): equal to the one-machine render within float
//    rounding (the sums were added in another order).
// The parts' out-of-range textured parameters (RenderResult::clamped_parameters) add up per parameter: the merged
// result holds them, and their warning lines, as a one-machine render would.
#pragma once

#include <string>
#include <vector>

#include "render/renderer.h"

namespace glimmer::render {

// Throws std::runtime_error naming the offending file(s) when the parts come from
// different renders (scene hash, resolution, seed, sample count, strategy, AOVs),
// overlap (pixels or samples), leave pixels or samples missing, or are incomplete.
RenderResult merge_parts(const std::vector<RenderResult> &parts, const std::vector<std::string> &names);

}  // namespace glimmer::render
