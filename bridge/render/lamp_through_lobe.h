// A lamp seen from P through an exit lobe (frosted_glass sg, closure ABI 2.4; docs/frosted_glass.md "Lamps
// through the exit lobe"): Int p(w) L(w) dw over the lamp, p the lobe's density (glimmer/exit_lobe.h), estimated
// with kLampStrata^2 points of the lamp's own sampling and kLampStrata^2 directions of the lobe's vMF, each set
// stratified with one offset (u, v) (unbiased: every point is uniform within its stratum), combined by the
// power heuristic (multi-sample MIS: each point counts f pdf_own / (n (pdf_L^2 + v^2)), f = p L; the balance
// heuristic let the lobe's directions, which move together near its pole, add rare large shares where a small
// lamp's own points do the work: 3 % noise per estimate on a 0.05-wide lamp at 3, power 0.1 %). It covers both
// limits: a lamp small against the lobe (its own points find it) and a lobe sharp against the lamp (the lobe's
// directions find it). One point's visibility then stands for the lamp's: picked with probability a_i / sum(a)
// (a: the points' luminance shares), the estimate share_i sum(a) / a_i x V_i is unbiased for Int p L V.
// Used by LightSet::lamp_through_lobe; a header so that the tests can call it for one lamp.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <type_traits>

#include "glimmer/exit_lobe.h"
#include "render/light_area.h"
#include "render/light_common.h"
#include "render/light_distant.h"

namespace glimmer::render {

// Session 31 (frostedcost31): 3 (9 + 9 points; 4 before, 16 + 16). On the caustic bench (64x40, 4 seeds x 1024 spp)
// the pixels' variance per sample moved within its noise (all 0.10230 -> 0.10265, glass 0.9101 -> 0.9096, lit 0.00882
// -> 0.00885, shadow 0.2931 -> 0.2966: the lamp integral's own noise is a small part of a pixel's) while sg lost 4.5
// % of its instructions per camera path (10582.8 -> 10105.6): docs/history/frosted_glass_sessions.md "Session 31".
inline constexpr int kLampStrata = 3;

struct LampEstimate {
  Spectrum value{0.0f};       // the estimate of Int p(w) L(w) dw over the lamp, to be multiplied by V(wi, dist)
  Vec3 wi{0.0f, 0.0f, 1.0f};  // toward the point whose visibility stands for the lamp's
  float dist = 0.0f;          // to that point (infinite for the sun)
};

// A lamp's radiance toward P along unit d and its solid-angle density of sampling that point (pick 1).
template <class Kind>
inline bool lamp_hit(const Kind &light, const Vec3 &P, const Vec3 &d, LightHit &h) {
  if constexpr (std::is_same_v<Kind, DistantLight>)
    return light.intersect(P, d, std::numeric_limits<float>::infinity(), false, 1.0f, h);
  else
    return light.intersect(P, d, std::numeric_limits<float>::infinity(), 1.0f, h);
}

// An exit lobe whose value is not its density (session 24, frostedpane24: method=sg's rough pane hands the exact
// exit's value q(w) through the closure's eval_exit): the integral is Int q(w) L(w) dw, the vMF mixture stays the
// proposal of the lobe's directions (and its draw density the MIS weights'), so every point's weight is as for the
// mixture itself and the estimate is unbiased for q wherever the lamp's own points cover it.
struct ValuedExitLobe {
  const ExitLobeMixture *proposal = nullptr;
  double (*value)(const void *context, const Vec3 &w) = nullptr;
  const void *context = nullptr;
  // The value first: where it is not > 0 the point does not count (lamp_through_lobe reads `draw` only after a p > 0),
  // so the proposal's density (an exp per lobe) is made only where it does (session 29, frostedcost29: the pane's
  // exits then left by one face, and its lamp points on the other side, most of the bench's, had value 0; since
  // session 33's frostedface33 the split's state holds both faces' ends by default, so both sides have value).
  double pdf_and_draw_density(const Vec3 &w, double &draw) const {
    const double v = value(context, w);
    draw = 0.0;
    if (v > 0.0) proposal->pdf_and_draw_density(w, draw);
    return v;
  }
  double pdf(const Vec3 &w) const { return value(context, w); }  // the value (the tests' brute force reads it)
  using DrawCos = ExitLobeMixture::DrawCos;
  DrawCos draw_cos(float uc) const { return proposal->draw_cos(uc); }
  static Vec3 draw_at(const DrawCos &d, const VmfPhi &phi) { return ExitLobeMixture::draw_at(d, phi); }
};

// An area lamp wholly below every exit lobe's surface (AreaLight::wholly_below; session 28, frostedcost28): an
// ExitLobe's or ExitLobeMixture's density is 0 at and below its surface, so none of lamp_through_lobe's points would
// count (its lamp points lie below, and a lobe direction that hits the lamp goes below) and its estimate is false:
// known before the 32 points are made. The exit lobes of the sphere seen through from the camera leave toward the
// floor, often with the lamp below their horizon. Other lamps and lobes (the pane's exact exit, ValuedExitLobe,
// valued by the closure): false (no skip).
template <class Kind, class Lobe>
inline bool lamp_below_exit(const Kind &light, const Vec3 &P, const Lobe &lobe) {
  if constexpr (std::is_same_v<Kind, AreaLight> && std::is_same_v<Lobe, ExitLobe>) {
    return light.wholly_below(P, lobe.n);
  } else if constexpr (std::is_same_v<Kind, AreaLight> && std::is_same_v<Lobe, ExitLobeMixture>) {
    for (int k = 0; k < lobe.count; ++k)
      if (lobe.weight[k] > 0.0 && !light.wholly_below(P, lobe.lobe[k].n)) return false;
    return true;
  } else {
    (void)light, (void)P, (void)lobe;
    return false;
  }
}

// Session 32 (frostedtime32): the lobe's directions are left out where they cannot carry weight. Where the lobe's
// largest draw density is at most kLobeSetRatio x the lamp's smallest sampling density (an area lamp's t^2 / (A cos_l)
// >= h^2 / A, h the distance from P to its plane: AreaLight::min_pdf), a lobe direction that hits the lamp has the
// power heuristic's weight draw^2 / (draw^2 + own^2) <= 1 %, and it rarely hits (the lamp covers a small part of the
// lobe); the lamp's own points alone, each with weight 1 / own (one strategy), are unbiased for the same integral.
// The choice depends on P, the lamp and the lobe only (not on the numbers), so the estimate stays unbiased whatever
// the bound's rounding. The caustic bench's roughness-0.5 lobes (draw density <= ~2 / sr) against its 0.25-wide lamp
// (>= ~60 / sr) skip it almost always (LampThroughLobe.SkippedLobeSetStaysUnbiased).
inline constexpr double kLobeSetRatio = 0.1;

// The largest value of a lobe's draw density over all directions (a bound: the sum of the lobes' vMF peaks).
inline double lobe_peak_draw_density(const ExitLobe &lobe) {
  return lobe.kappa / (2.0 * M_PI * -std::expm1(-2.0 * lobe.kappa));
}
inline double lobe_peak_draw_density(const ExitLobeMixture &m) {
  double peak = 0.0;
  for (int k = 0; k < m.count; ++k)
    if (m.weight[k] > 0.0) peak += m.weight[k] * (m.prepared ? m.constants[k].norm : lobe_peak_draw_density(m.lobe[k]));
  return peak;
}

// Whether lamp_through_lobe leaves the lobe's directions out (area lamps only: other kinds always keep them).
template <class Kind, class Lobe>
inline bool lobe_set_negligible(const Kind &light, const Vec3 &P, const Lobe &lobe, double ratio) {
  if constexpr (std::is_same_v<Kind, AreaLight>) {
    double peak;
    if constexpr (std::is_base_of_v<ValuedExitLobe, Lobe>)  // the proposal draws the directions
      peak = lobe.proposal != nullptr ? lobe_peak_draw_density(*lobe.proposal) : HUGE_VAL;
    else
      peak = lobe_peak_draw_density(lobe);
    return peak <= ratio * double(light.min_pdf(P));
  } else {
    (void)light, (void)P, (void)lobe, (void)ratio;
    return false;
  }
}

// One point of lamp_through_lobe's two sets, and its storage, not initialised (a slot is read only after the point was
// written into it: Vec3's zeroing constructor made 7 stores per slot per call; session 31, frostedcost31).
struct LampPoint {
  Vec3 wi;
  float dist;
  Spectrum share;
};
union LampPointSlot {
  LampPoint point;
  LampPointSlot() {}
};

// The estimate for one lamp (a point, spot, area or distant light); false when none of its light reaches P
// through the lobe.
// `lobe`: an ExitLobe, or an ExitLobeMixture (ABI 2.7: the whole mixture; p its density, the lobe's directions
// drawn from the vMF mixture).
template <class Kind, class Lobe>
inline bool lamp_through_lobe(const Kind &light, const Vec3 &P, const Lobe &lobe, float u, float v, float pick,
                              LampEstimate &out, double lobe_set_ratio = kLobeSetRatio) {
  if (lamp_below_exit(light, P, lobe)) return false;
  const bool lobe_set = !lobe_set_negligible(light, P, lobe, lobe_set_ratio);  // the lobe's directions drawn
  constexpr int n = kLampStrata, count = n * n;
  LampPointSlot points[2 * count];
  int used = 0;
  Spectrum total(0.0f);
  const auto add = [&](const Vec3 &wi, float dist, const Spectrum &share) {
    if (is_zero(share) || !is_finite(share)) return;
    points[used++].point = {wi, dist, share};
    total += share;
  };
  // A point of one set (density `own`, the other set's `other` there) counts f x own / (count (own^2 + other^2)):
  // the power heuristic over the two sets of `count` points each (multi-sample MIS, Veach 1997 sec. 9.2).
  const auto power_weight = [](double own, double other) { return own / (count * (own * own + other * other)); };
  bool delta = false;
  for (int k = 0; k < count && !delta; ++k) {  // the lamp's own sampling
    LightSample ls;
    const float lu = (float(k % n) + u) / n, lv = (float(k / n) + v) / n;
    if (!light.sample(std::min(lu, 0x1.fffffep-1f), std::min(lv, 0x1.fffffep-1f), P, 1.0f, ls)) continue;
    double draw_density = 0.0;
    const double p = lobe.pdf_and_draw_density(ls.wi, draw_density);
    if (!(p > 0.0)) continue;
    if (ls.delta) {  // one point carries it all (the lobe cannot find it)
      delta = true;
      used = 0;
      total = Spectrum(0.0f);
      add(ls.wi, ls.dist, ls.radiance * float(p));
      break;
    }
    add(ls.wi, ls.dist, ls.radiance * float(p * power_weight(ls.pdf, lobe_set ? draw_density : 0.0)));
  }
  // The lobe's directions (its vMF, stratified): the n x n draws share n cos theta numbers and n phi numbers, so
  // each half of the draw is made n times, not n^2 (the same directions bit for bit as lobe.draw(uc, up)).
  typename Lobe::DrawCos cos_part[n];
  VmfPhi phi_part[n];
  if (!delta && lobe_set)
    for (int i = 0; i < n; ++i) {
      const float uc = (float(i) + v) / n, up = (float(i) + u) / n;
      cos_part[i] = lobe.draw_cos(std::min(uc, 0x1.fffffep-1f));
      phi_part[i] = vmf_phi(std::min(up, 0x1.fffffep-1f));
    }
  for (int k = 0; k < count && !delta && lobe_set; ++k) {
    const Vec3 wi = Lobe::draw_at(cos_part[k % n], phi_part[k / n]);
    LightHit h;
    if (!lamp_hit(light, P, wi, h)) continue;
    double draw_density = 0.0;
    const double p = lobe.pdf_and_draw_density(wi, draw_density);
    if (!(p > 0.0)) continue;
    add(wi, h.delta ? std::numeric_limits<float>::infinity() : h.t,
        h.radiance * float(p * power_weight(draw_density, h.pdf)));
  }
  if (used == 0) return false;
  // The point whose visibility stands for the lamp's, picked with probability a_i / sum(a) (a: the shares'
  // luminance); returning share_i sum(a) / a_i x V_i is unbiased for sum_i share_i V_i, the estimate of Int p L V.
  const float sum = average(total);
  float target = std::clamp(pick, 0.0f, 0x1.fffffep-1f) * sum;
  int chosen = used - 1;
  for (int i = 0; i < used; ++i) {
    target -= average(points[i].point.share);
    if (target < 0.0f) {
      chosen = i;
      break;
    }
  }
  const LampPoint &c = points[chosen].point;
  out.wi = c.wi;
  out.dist = c.dist;
  const float a = average(c.share);
  out.value = a > 0.0f ? c.share * (sum / a) : Spectrum(0.0f);
  return !is_zero(out.value);
}


}  // namespace glimmer::render
