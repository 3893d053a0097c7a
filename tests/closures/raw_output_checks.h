// Stress checks on a closure class's raw outputs (before the C ABI's sanitising): no NaN, Inf or negative value
// in eval, and a successful sample has a positive finite pdf, a unit finite direction, a valid eta and roughness.
#pragma once

#include <cmath>

#include "core/closure.h"

namespace glimmer::test {

inline bool bad(float v) { return !std::isfinite(v) || v < 0.0f; }
inline bool bad(const Spectrum &s) { return bad(s.x) || bad(s.y) || bad(s.z); }

// Number of bad results among eval `e` and, when `sampled`, sample `s` (0, 1 or 2).
inline long bad_raw_outputs(const plugin::LocalEval &e, bool sampled, const plugin::LocalSample &s) {
  long n = (bad(e.f_cos) || bad(e.pdf)) ? 1 : 0;
  if (sampled && (bad(s.f_cos) || !(s.pdf > 0.0f) || bad(s.pdf) || !is_finite(s.wo) ||
                  std::fabs(length(s.wo) - 1) > 1e-3f || !(s.eta > 0.0f) || !std::isfinite(s.eta) ||
                  bad(s.roughness)))
    ++n;
  return n;
}

}  // namespace glimmer::test
