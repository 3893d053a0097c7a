// The exit lobe of an sg sample as the host sees it, shared by the frosted glass tests
// (tests/closures/test_frosted_sg.cpp, tests/closures/test_frosted_sampled_reflection.cpp).
#pragma once

#include <algorithm>
#include <cstdint>

#include "core/closure.h"
#include "glimmer/closure_abi.h"
#include "glimmer/exit_lobe.h"

namespace glimmer::test {

// The whole mixture the closure wrote into `buffer` (ABI 2.7), or the sample's single lobe, restricted to the
// side of origin_Ng, normalised.
inline ExitLobeMixture exit_mixture_of(const plugin::LocalSample &s, const GlimmerExitMixture &buffer) {
  ExitLobeMixture m;
  const Vec3 n = normalize(s.origin_Ng);
  if (s.exit_mixture) {
    m.count = int(std::min<uint32_t>(buffer.count, GLIMMER_EXIT_MAX_LOBES));
    for (int k = 0; k < m.count; ++k) {
      m.lobe[k] = ExitLobe::make(Vec3(buffer.axis[k]), double(buffer.sharpness[k]), n);
      m.weight[k] = double(buffer.weight[k]);
    }
  } else {
    m.count = 1;
    m.lobe[0] = ExitLobe::make(s.lobe_axis, double(s.lobe_sharpness), n);
    m.weight[0] = 1.0;
  }
  m.normalize();
  return m;
}

}  // namespace glimmer::test
