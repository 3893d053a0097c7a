// Stress checks on a closure class's raw outputs (before the C ABI's sanitising): no NaN, Inf or negative value
// in eval, and a successful sample has a positive finite pdf, a unit finite direction, a valid eta and roughness.
#pragma once

#include <cmath>

#include "core/closure.h"
#include "glimmer/exit_lobe.h"

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

// A moved sample (frosted_glass sg: the path continues where the light leaves the glass): 1 when its origin or
// exit normal is not finite, it is not singular, or its exit lobe (ABI 2.4, the host's light sampling there) is
// missing or gives no positive finite density at the drawn direction (world space `wo_world`); else 0.
inline long bad_moved_sample(const plugin::LocalSample &s, const Vec3 &wo_world) {
  long n = (!is_finite(s.origin) || !is_finite(s.origin_Ng) || !(s.label & GLIMMER_LABEL_SINGULAR)) ? 1 : 0;
  const ExitLobe lobe = ExitLobe::make(s.lobe_axis, s.lobe_sharpness, s.origin_Ng);
  const double p = lobe.pdf(wo_world);
  if (!s.exit_lobe || !is_finite(s.lobe_axis) || !(s.lobe_sharpness > 0.0f) || !(p > 0.0) || !std::isfinite(p)) ++n;
  return n;
}

// ABI 2.7: the whole exit mixture a moved sample wrote into the host's buffer: 1..GLIMMER_EXIT_MAX_LOBES lobes,
// unit finite axes, finite positive sharpness, weights >= 0 summing to 1, and its density at wo (every lobe
// about origin_Ng) finite and positive. 0 when the sample did not write one.
inline long bad_exit_mixture(const plugin::LocalSample &s, const GlimmerExitMixture &m, const Vec3 &wo_world) {
  if (!s.exit_mixture) return 0;
  if (!(m.count >= 1 && m.count <= GLIMMER_EXIT_MAX_LOBES)) return 1;
  ExitLobeMixture mix;
  double sum = 0.0;
  long n = 0;
  for (uint32_t k = 0; k < m.count; ++k) {
    const Vec3 axis(m.axis[k]);
    if (!is_finite(axis) || std::fabs(length(axis) - 1.0f) > 1e-3f || !std::isfinite(m.sharpness[k]) ||
        !(m.sharpness[k] > 0.0f) || !std::isfinite(m.weight[k]) || m.weight[k] < 0.0f)
      ++n;
    sum += m.weight[k];
    mix.lobe[mix.count] = ExitLobe::make(axis, m.sharpness[k], s.origin_Ng);
    mix.weight[mix.count++] = m.weight[k];
  }
  if (std::fabs(sum - 1.0) > 1e-4) ++n;
  const double p = mix.pdf(wo_world);
  if (!(p > 0.0) || !std::isfinite(p)) ++n;
  return n;
}

// One eval and one sample call of a stress loop at (sp, wo): the bad outputs of both (a moved sample's exit checked
// too); counts the successful samples and the moved ones.
template <class Closure, class Counter>
long stress_eval_and_sample(const Closure &c, const plugin::ShadingPoint &sp, const Vec3 &wo, const Vec3 &rand,
                            Counter &samples, Counter &moved) {
  plugin::LocalSample s;
  const plugin::LocalEval e = c.eval(sp, wo);
  const bool ok = c.sample(sp, rand, s);
  long n_bad = bad_raw_outputs(e, ok, s);
  if (ok) {
    samples.fetch_add(1, std::memory_order_relaxed);
    if (s.moved) {
      moved.fetch_add(1, std::memory_order_relaxed);
      n_bad += bad_moved_sample(s, sp.frame.to_world(s.wo));
    }
  }
  return n_bad;
}

}  // namespace glimmer::test
