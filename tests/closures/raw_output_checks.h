// Stress checks on a closure class's raw outputs (before the C ABI's sanitising): no NaN, Inf or negative value
// in eval, and a successful sample has a positive finite pdf, a unit finite direction, a valid eta and roughness.
#pragma once

#include <algorithm>
#include <cmath>

#include "core/closure.h"
#include "glimmer/exit_lobe.h"
#include "glimmer/rng.h"

namespace glimmer::test {

// A stress test's direction: z exactly at the extremes (0, 1e-7 .. 1e-3, 1) one time in three (always when
// `grazing`), uniform otherwise; on the lower side when r's next word is a multiple of `lower_one_in` (2: either side
// of a pane; 4: mostly outside); phi uniform.
inline Vec3 stress_direction(Pcg32 &r, bool grazing, uint32_t lower_one_in) {
  const float zs[] = {0.0f, 1e-7f, 1e-6f, 1e-4f, 1e-3f, 0.01f, 0.5f, 1.0f - 1e-7f, 1.0f};
  float z = (grazing || r.next_u32() % 3 == 0) ? zs[r.next_u32() % 9] : r.next_float();
  if (r.next_u32() % lower_one_in == 0) z = -z;
  const float phi = 2.0f * float(M_PI) * r.next_float(), st = std::sqrt(std::max(0.0f, 1 - z * z));
  return Vec3(st * std::cos(phi), st * std::sin(phi), z);
}

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

// A sample as the host reads it through the C ABI (ClosureAdapter::sample into a 2.7 host's GlimmerSample whose
// exit_mixture points at `buffer`; bridge/render/renderer.cpp integrate_exit_lobe / exit_mixture_of): the number
// of bad results (0 when the label is NONE). A returned sample: finite non-negative eval, positive finite pdf, unit
// finite wo. MOVED: finite origin and unit origin_Ng, singular. EXIT_LOBE: unit finite lobe_axis, finite positive
// sharpness. EXIT_MIXTURE (the whole mixture, read only with the flag): count 1..GLIMMER_EXIT_MAX_LOBES, unit finite
// axes, finite sharpness > 0, finite weights >= 0 summing to 1, the picked lobe (lobe_axis / lobe_sharpness) among
// them, and the host's estimators' numbers finite: each lobe's below-surface fraction in [0, 1], the prepared
// mixture density (NEE / MIS) at wo finite and positive, a draw of the lamp integral (ExitLobeMixture::draw at
// (u1, u2)) unit and finite with finite pdf and draw density. `mixtures` counts the mixtures read.
inline long bad_host_sample(uint32_t label, const GlimmerSample &s, const GlimmerExitMixture &buffer, float u1,
                            float u2, long &mixtures) {
  if (label == GLIMMER_LABEL_NONE) return (s.flags != 0 || s.label != GLIMMER_LABEL_NONE) ? 1 : 0;
  const Vec3 wo(s.wo);
  long n = (bad(s.eval[0]) || bad(s.eval[1]) || bad(s.eval[2]) || !(s.pdf > 0.0f) || bad(s.pdf) || !is_finite(wo) ||
            std::fabs(length(wo) - 1.0f) > 1e-3f || s.label != label)
               ? 1
               : 0;
  const uint32_t lobe_flags = GLIMMER_SAMPLE_EXIT_LOBE | GLIMMER_SAMPLE_EXIT_MIXTURE;
  if (!(s.flags & GLIMMER_SAMPLE_MOVED)) return n + ((s.flags & lobe_flags) ? 1 : 0);
  const Vec3 Ng(s.origin_Ng);
  if (!is_finite(Vec3(s.origin)) || !is_finite(Ng) || std::fabs(length(Ng) - 1.0f) > 1e-3f ||
      !(s.label & GLIMMER_LABEL_SINGULAR))
    ++n;
  if (!(s.flags & GLIMMER_SAMPLE_EXIT_LOBE)) return n + ((s.flags & GLIMMER_SAMPLE_EXIT_MIXTURE) ? 1 : 0);
  const Vec3 lobe_axis(s.lobe_axis);
  if (!is_finite(lobe_axis) || std::fabs(length(lobe_axis) - 1.0f) > 1e-3f || !std::isfinite(s.lobe_sharpness) ||
      !(s.lobe_sharpness > 0.0f))
    ++n;
  if (!(s.flags & GLIMMER_SAMPLE_EXIT_MIXTURE)) return n;
  if (s.exit_mixture != &buffer) return n + 1;
  ++mixtures;
  if (!(buffer.count >= 1 && buffer.count <= GLIMMER_EXIT_MAX_LOBES)) return n + 1;
  ExitLobeMixture mix;
  double sum = 0.0;
  bool picked_listed = false;
  for (uint32_t k = 0; k < buffer.count; ++k) {
    const Vec3 axis(buffer.axis[k]);
    const float kappa = buffer.sharpness[k], w = buffer.weight[k];
    if (!is_finite(axis) || std::fabs(length(axis) - 1.0f) > 1e-3f || !std::isfinite(kappa) || !(kappa > 0.0f) ||
        !std::isfinite(w) || w < 0.0f)
      ++n;
    sum += w;
    picked_listed |=
        axis.x == lobe_axis.x && axis.y == lobe_axis.y && axis.z == lobe_axis.z && kappa == s.lobe_sharpness;
    mix.lobe[mix.count] = ExitLobe::make(axis, kappa, Ng);
    if (!(mix.lobe[mix.count].below >= 0.0 && mix.lobe[mix.count].below <= 1.0)) ++n;
    mix.weight[mix.count++] = w;
  }
  if (std::fabs(sum - 1.0) > 1e-4 || !picked_listed) ++n;
  mix.prepare();
  const double p = mix.pdf(wo);
  if (!(p > 0.0) || !std::isfinite(p)) ++n;
  const Vec3 d = mix.draw(u1, u2);
  double draw = 0.0;
  const double pd = mix.pdf_and_draw_density(d, draw);
  if (!is_finite(d) || std::fabs(length(d) - 1.0f) > 1e-3f || !std::isfinite(pd) || pd < 0.0 ||
      !std::isfinite(draw) || !(draw > 0.0))
    ++n;
  return n;
}

// The same query as the renderer makes it: the C entry point (ClosureAdapter<Closure>::sample) into a 2.7 host's
// GlimmerSample with its whole-mixture buffer, checked by bad_host_sample with the lamp-integral draw at (u1, u2).
// Returns the bad count; `flags` gets the sample's flags, `mixtures` counts the whole mixtures read.
template <class Closure>
long bad_host_query(const Closure &c, GlimmerShadingContext &ctx, const Vec3 &rand, float u1, float u2,
                    uint32_t &flags, long &mixtures) {
  GlimmerExitMixture buffer;
  GlimmerSample hs = glimmer_blank_sample();
  hs.exit_mixture = &buffer;
  const float r3[3] = {rand.x, rand.y, rand.z};
  const uint32_t label =
      plugin::ClosureAdapter<Closure>::sample(reinterpret_cast<const GlimmerInstance *>(&c), &ctx, r3, &hs);
  flags = hs.flags;
  return bad_host_sample(label, hs, buffer, u1, u2, mixtures);
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
