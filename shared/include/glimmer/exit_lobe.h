// The exit lobe of a moved sample (closure ABI 2.4, GLIMMER_SAMPLE_EXIT_LOBE): the direction in which light
// leaves a frosted object (frosted_glass method=sg, de Rousiers et al. 2012) is drawn from a normalised
// spherical Gaussian (a von Mises-Fisher distribution) about `axis` with sharpness kappa,
//   v(w) = kappa exp(kappa (axis . w - 1)) / (2 pi (1 - exp(-2 kappa))),
// restricted to the outside of the exit surface (normal n) by the rule the plugin samples with:
// draw; while the direction is below the surface (n . w <= 0) draw again, at most kRedraws times; a last
// direction still below is mirrored about the surface. Its exact density outside is
//   p(w) = v(w) (1 + q + ... + q^kRedraws) + q^kRedraws v(M w),   M w = w - 2 (n . w) n,
// with q the SG's fraction below the surface (fraction_below). Plugin and host share this code: the plugin
// samples with ExitLobe::sample, the host evaluates ExitLobe::pdf for next-event estimation and MIS at the
// exit point (eval = the sample's weight x p, so eval / pdf is the weight the singular sample carried).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>

#include "glimmer/horner.h"
#include "glimmer/math.h"

namespace glimmer {

// von Mises-Fisher density about `axis` (unit) with sharpness kappa > 0 at unit w. 1 - axis . w is
// computed as |axis - w|^2 / 2 (no cancellation: kappa reaches 1e7).
inline double vmf_density(const Vec3 &axis, double kappa, const Vec3 &w) {
  const double dx = double(axis.x) - w.x, dy = double(axis.y) - w.y, dz = double(axis.z) - w.z;
  const double one_minus_cos = 0.5 * (dx * dx + dy * dy + dz * dz);
  return kappa * std::exp(-kappa * one_minus_cos) / (2.0 * M_PI * -std::expm1(-2.0 * kappa));
}

// A draw from the vMF in its two halves, cos theta (vmf_cos) and phi (vmf_phi), joined by vmf_direction; a
// stratified set of draws that share their cos theta numbers and their phi numbers makes each half once (the
// host's lamp integral, render/lamp_through_lobe.h: n x n draws, n of each, n = kLampStrata). sample_vmf is the
// three in one.
struct VmfCos {
  double cos_t, sin_t;
};
inline VmfCos vmf_cos(double kappa, float u1) {
  const double k = std::max(kappa, 1e-6);
  const double u = std::clamp(double(u1), 0.0, 1.0);
  double cos_t = 1.0 + std::log(u + (1.0 - u) * std::exp(-2.0 * k)) / k;
  if (!std::isfinite(cos_t)) cos_t = 1.0;
  cos_t = std::clamp(cos_t, -1.0, 1.0);
  return {cos_t, std::sqrt(std::max(0.0, 1.0 - cos_t * cos_t))};
}
struct VmfPhi {
  double cos_phi, sin_phi;
};
inline VmfPhi vmf_phi(float u2) {
  const double phi = 2.0 * M_PI * double(u2);
  return {std::cos(phi), std::sin(phi)};
}
inline Vec3 vmf_direction(const Frame &f, const VmfCos &c, const VmfPhi &phi) {
  return normalize(
      f.to_world(Vec3(float(c.sin_t * phi.cos_phi), float(c.sin_t * phi.sin_phi), float(c.cos_t))));
}

// A direction from the vMF about `axis`: inverse CDF of cos theta for exp(kappa (cos theta - 1)) on [-1, 1],
// phi uniform.
inline Vec3 sample_vmf(const Vec3 &axis, double kappa, float u1, float u2) {
  return vmf_direction(Frame::from_normal(axis), vmf_cos(kappa, u1), vmf_phi(u2));
}

// I0(x) for 0 <= x <= 3.75 (Abramowitz & Stegun 9.8.1; relative error < 1.6e-7): bessel_i0_scaled's and
// exp_times_bessel_i0_scaled's polynomial below 3.75.
inline double bessel_i0_below_3_75(double x) {
  const double t = (x / 3.75) * (x / 3.75);
  return 1.0 + t * (3.5156229 + t * (3.0899424 + t * (1.2067492 + t * (0.2659732 + t * (0.0360768 + t * 0.0045813)))));
}

// exp(-x) I0(x), the exponentially scaled modified Bessel function of order 0 (Abramowitz & Stegun 9.8.1 and
// 9.8.2; relative error < 1e-6).
inline double bessel_i0_scaled(double x) {
  x = std::fabs(x);
  if (x <= 3.75) return std::exp(-x) * bessel_i0_below_3_75(x);
  const double t = 3.75 / x;
  const double s =
      0.39894228 +
      t * (0.01328592 +
           t * (0.00225319 +
                t * (-0.00157565 +
                     t * (0.00916281 + t * (-0.02057706 + t * (0.02635537 + t * (-0.01647633 + t * 0.00392377)))))));
  return s / std::sqrt(x);
}

// exp(y) inline: y = n ln 2 + r, |r| <= ln 2 / 2 (n rounded to nearest by the 1.5 x 2^52 shift; ln 2 split in two,
// fdlibm's ln2_hi / ln2_lo, so n ln2_hi is exact), exp(r) by its Taylor series to r^13 in Horner form (the next term
// is below 4.2e-18), times 2^n made in the exponent bits: within ~2 ulp of libm's. Outside [-708, 709] (where 2^n
// would leave the normal range), and for NaN: libm. vmf_fraction_below's exponentials (libm's ~51 instructions a
// call with its wrapper; session 32, frostedtime32).
inline double exp_inline(double y) {
  if (!(y >= -708.0 && y <= 709.0)) return std::exp(y);
  constexpr double kShift = 6755399441055744.0;  // 1.5 x 2^52: adding it rounds to an integer
  const double n = (y * 1.4426950408889634 + kShift) - kShift;
  const double r = (y - n * 6.93147180369123816490e-01) - n * 1.90821492927058770002e-10;
  // 1 / k!, k = 0 .. 13 (glimmer::horner: the chain from 1 / 13! down).
  static constexpr std::array<double, 14> kExp = {1.0,           1.0,           0.5,          1.0 / 6.0,
                                                  1.0 / 24.0,    1.0 / 120.0,   1.0 / 720.0,  1.0 / 5040.0,
                                                  1.0 / 40320.0, 1.0 / 362880.0, 1.0 / 3628800.0, 1.0 / 39916800.0,
                                                  1.0 / 479001600.0, 1.0 / 6227020800.0};
  const double p = horner(r, kExp);
  const uint64_t bits = uint64_t(int64_t(n) + 1023) << 52;  // 2^n, n in [-1022, 1023]
  double scale;
  std::memcpy(&scale, &bits, sizeof(scale));
  return p * scale;
}

// exp(e) x bessel_i0_scaled(x) with one exponential: below x = 3.75 the scaled function is exp(-x) times a
// polynomial, so the two exponentials are joined (exp(e - x)); above it the scaled series has none. The exponential
// by exp_inline (session 32).
inline double exp_times_bessel_i0_scaled(double e, double x) {
  x = std::fabs(x);
  if (x <= 3.75) return exp_inline(e - x) * bessel_i0_below_3_75(x);
  return exp_inline(e) * bessel_i0_scaled(x);
}

// sin x and cos x for |x| <= pi / 2 by their Taylor series in Horner form (sin to x^21, cos to x^22: the next terms
// are below 1.3e-18 there, so the result is within a few ulp of libm's). vmf_fraction_below's angles all lie in that
// range; libm's sincos (~95 instructions, with its general range reduction) took ~140 instructions per camera path
// of the caustic bench's host exit NEE (session 32, frostedtime32). Outside the range: libm.
inline void sincos_half_pi(double x, double &s, double &c) {
  if (!(std::fabs(x) <= 1.5707963267948968)) {
    s = std::sin(x), c = std::cos(x);
    return;
  }
  // (-1)^k / (2k + 3)!, k = 0 .. 9, and (-1)^k / (2k + 2)!, k = 0 .. 10, in powers of x^2 (glimmer::horner).
  static constexpr std::array<double, 10> kSin = {
      1.0 / 6.0,           -1.0 / 120.0,          1.0 / 5040.0,           -1.0 / 362880.0,
      1.0 / 39916800.0,    -1.0 / 6227020800.0,   1.0 / 1307674368000.0,  -1.0 / 355687428096000.0,
      1.0 / 121645100408832000.0, -1.0 / 51090942171709440000.0};
  static constexpr std::array<double, 11> kCos = {
      0.5,                 -1.0 / 24.0,           1.0 / 720.0,            -1.0 / 40320.0,
      1.0 / 3628800.0,     -1.0 / 479001600.0,    1.0 / 87178291200.0,    -1.0 / 20922789888000.0,
      1.0 / 6402373705728000.0, -1.0 / 2432902008176640000.0, 1.0 / 1124000727777607680000.0};
  const double x2 = x * x, ps = horner(x2, kSin), pc = horner(x2, kCos);
  s = x - x * x2 * ps;  // x - x^3 / 3! + x^5 / 5! - ...
  c = 1.0 - x2 * pc;    // 1 - x^2 / 2! + x^4 / 4! - ...
}

// The fraction q of the vMF (axis, kappa) below the plane with unit normal n. Around n, with beta the polar
// angle and alpha = angle(axis, n), the azimuthal integral is 2 pi I0(kappa sin alpha sin beta), so
//   q = kappa / (1 - exp(-2 kappa)) Int_{pi/2}^{pi} sin(beta) exp(kappa (cos(beta - alpha) - 1))
//       I0e(kappa sin alpha sin beta) d beta,
// a smooth integrand peaked at beta = alpha with width ~ 1 / sqrt(kappa): integrated by composite
// Gauss-Legendre over the window where exp(kappa (cos(beta - alpha) - 1)) > exp(-40), 4 panels of 8 nodes (16
// panels before the host evaluated 10-lobe mixtures, 8 until the twentieth session: over alpha 0..180 deg, kappa
// 0.01..1e7, against 64 plain panels, 8 panels differ by at most 7.2e-10, 4 by 2.1e-7, 3 by 3.2e-5; the host's density
// needs q far less precisely: it enters as 1 + q + ... + q^16, and 4 panels halve the exponentials of the host's
// exit NEE, FrostedExitLobe.FractionBelowQuadratureAgainstAFineOne). Session 27 (frostedcost27): the panels by the
// window's width in the integrand's own width 1 / sqrt(kappa), w = sqrt(kappa) (hi - lo): ceil(w / kPanelWidth), 1..4
// (the window is w <= 2 sqrt(80) = 17.9 wide; a wide lobe clipped by the horizon needs fewer nodes), and the
// integrand's two exponentials joined (exp_times_bessel_i0_scaled): max |difference| to 64 plain panels 2.1e-7 as
// before (the same test), ~half the exponentials of the caustic bench's exit NEE.
inline double vmf_fraction_below(const Vec3 &axis, double kappa, const Vec3 &n) {
  const double c = std::clamp(double(dot(axis, n)), -1.0, 1.0);
  const double alpha = std::acos(c), sin_alpha = std::sqrt(std::max(0.0, 1.0 - c * c));
  const double half_width = std::sqrt(80.0 / std::max(kappa, 1e-9));
  const double lo = std::max(0.5 * M_PI, alpha - half_width), hi = std::min(M_PI, alpha + half_width);
  if (!(hi > lo)) return 0.0;
  // 8-point Gauss-Legendre nodes and weights on [-1, 1] (positive half).
  static constexpr double kNode[4] = {0.1834346424956498, 0.5255324099163290, 0.7966664774136267, 0.9602898564975363};
  static constexpr double kWeight[4] = {0.3626837833783620, 0.3137066458778873, 0.2223810344533745, 0.1012285362903763};
  constexpr double kPanelWidth = 3.5;  // the widest panel in units of 1 / sqrt(kappa)
  const double width = std::sqrt(std::max(kappa, 1e-9)) * (hi - lo);
  const int panels = width <= kPanelWidth ? 1 : width <= 2 * kPanelWidth ? 2 : width <= 3 * kPanelWidth ? 3 : 4;
  const double panel = (hi - lo) / panels;
  // The panels are equal, so the nodes sit at the same offsets +-d_k from each panel's middle, and the middles step
  // by `panel`: sin(beta) and sin((beta - alpha) / 2) by angle addition. One sincos per offset's half angle (the
  // offset's own by the double angle; -d_k by symmetry), one for the half step (the step by the double angle), one
  // each for the first middle and its half angle off alpha, then rotations: 7 sincos per call (32 before).
  // Per node of a panel (the 4 offsets -d_k, then the 4 offsets +d_k), signed: sin and cos of the offset and of its
  // half, and the weight.
  double sin_d[8], cos_d[8], sin_h[8], cos_h[8], weight[8];
  for (int k = 0; k < 4; ++k) {
    const double half = 0.25 * kNode[k] * panel;  // d_k / 2, d_k = kNode[k] panel / 2
    double sh, ch;
    sincos_half_pi(half, sh, ch);
    const double sd = 2.0 * sh * ch, cd = 1.0 - 2.0 * sh * sh;
    sin_d[k] = -sd, sin_d[k + 4] = sd, cos_d[k] = cos_d[k + 4] = cd;
    sin_h[k] = -sh, sin_h[k + 4] = sh, cos_h[k] = cos_h[k + 4] = ch;
    weight[k] = weight[k + 4] = kWeight[k];
  }
  double sin_step_h = 0.0, cos_step_h = 1.0;  // the step to the next panel's middle (none after a single panel)
  if (panels > 1) sincos_half_pi(0.5 * panel, sin_step_h, cos_step_h);
  const double sin_step = 2.0 * sin_step_h * cos_step_h, cos_step = 1.0 - 2.0 * sin_step_h * sin_step_h;
  const double mid0 = lo + 0.5 * panel;
  // mid0 in [pi / 2, pi]: sin(mid0) = cos(mid0 - pi / 2), cos(mid0) = -sin(mid0 - pi / 2); (mid0 - alpha) / 2 in
  // [-pi / 4, pi / 2]. Every angle here within sincos_half_pi's range (session 32).
  double sin_r, cos_r, sin_mh, cos_mh;
  sincos_half_pi(mid0 - 0.5 * M_PI, sin_r, cos_r);
  double sin_m = cos_r, cos_m = -sin_r;
  sincos_half_pi(0.5 * (mid0 - alpha), sin_mh, cos_mh);
  const double minus_2k = -2.0 * kappa, k_sin_alpha = kappa * sin_alpha;
  double sum = 0.0;
  for (int p = 0; p < panels; ++p) {
    // The panel's 8 nodes: sin(beta) and the exponent first, then the integrand summed in node order.
    double sin_beta[8], exponent[8];
    for (int k = 0; k < 8; ++k) {
      sin_beta[k] = sin_m * cos_d[k] + cos_m * sin_d[k];
      const double s = sin_mh * cos_h[k] + cos_mh * sin_h[k];  // sin((beta - alpha) / 2)
      exponent[k] = minus_2k * s * s;
    }
    for (int k = 0; k < 8; ++k) {
      const double f = sin_beta[k] * exp_times_bessel_i0_scaled(exponent[k], k_sin_alpha * sin_beta[k]);
      sum += weight[k] * f;
    }
    const double sm = sin_m * cos_step + cos_m * sin_step, cm = cos_m * cos_step - sin_m * sin_step;
    const double smh = sin_mh * cos_step_h + cos_mh * sin_step_h, cmh = cos_mh * cos_step_h - sin_mh * sin_step_h;
    sin_m = sm, cos_m = cm, sin_mh = smh, cos_mh = cmh;
  }
  const double q = sum * 0.5 * panel * kappa / -std::expm1(-2.0 * kappa);
  return std::clamp(q, 0.0, 1.0);
}

// The half-angle of the spherical cap about the axis that holds `fraction` of the vMF (axis, kappa)'s energy:
//   1 - cos theta_c = -ln(1 - fraction (1 - e^(-2 kappa))) / kappa.
inline double vmf_cap_angle(double kappa, double fraction) {
  const double k = kappa > 1e-6 ? kappa : 1e-6;  // also NaN
  const double f = std::clamp(fraction, 0.0, 1.0);
  const double one_minus_cos = std::clamp(-std::log1p(f * std::expm1(-2.0 * k)) / k, 0.0, 2.0);
  return 2.0 * std::asin(std::sqrt(0.5 * one_minus_cos));
}

// The uniform cap that stands for the exit lobe in a pre-filtered environment lookup (the host's
// environment_lookup(direction, cone); docs/frosted_glass.md "The world behind the glass"): the cap holding
// kExitWorldConeEnergy of the lobe's energy. Chosen by measurement against the vMF-weighted mean of a checker
// world, kappa 4..3000 (tests/bridge/test_frosted_exit_world.cpp, FrostedExitWorld.ConeRule...).
inline constexpr double kExitWorldConeEnergy = 0.8;
inline double exit_world_cone(double kappa) { return vmf_cap_angle(kappa, kExitWorldConeEnergy); }

struct ExitLobe {
  static constexpr int kRedraws = 16;  // draws after the first while the direction is below the surface

  Vec3 axis{0.0f, 0.0f, 1.0f};  // unit
  double kappa = 1.0;           // > 0
  Vec3 n{0.0f, 0.0f, 1.0f};     // unit exit surface normal, outward (toward where the light goes)
  double below = 0.0;           // q: the SG's fraction below the surface

  static ExitLobe make(const Vec3 &axis, double kappa, const Vec3 &n) {
    ExitLobe l;
    l.axis = axis;
    l.kappa = std::max(kappa, 1e-6);
    l.n = n;
    l.below = vmf_fraction_below(axis, l.kappa, n);
    return l;
  }

  // The plugin's sampling rule; `uniform()` returns numbers in [0, 1). The result can be on the surface
  // (n . w = 0, measure zero): the caller rejects it.
  template <class Uniform>
  Vec3 sample(Uniform &&uniform) const {
    const auto draw = [&] {
      const float u_phi = uniform();  // the order of frosted sg's draws since its first version
      const float u_cos = uniform();
      return sample_vmf(axis, kappa, u_cos, u_phi);
    };
    Vec3 w = draw();
    for (int k = 0; k < kRedraws && dot(w, n) <= 0.0f; ++k) w = draw();
    const float height = dot(w, n);
    return height <= 0.0f ? normalize(w - n * (2.0f * height)) : w;
  }

  // The redraw factor 1 + q + ... + q^kRedraws of the density for below-surface fraction q; power ends as
  // q^kRedraws (the mirrored part's weight).
  static double redraw_series(double q, double &power) {
    double redraws = 0.0;
    power = 1.0;
    for (int k = 0; k <= kRedraws; ++k) {
      redraws += power;
      if (k < kRedraws) power *= q;
    }
    return redraws;
  }

  // The density of sample() at unit w (solid angle); 0 at and below the surface.
  double pdf(const Vec3 &w) const {
    const float height = dot(w, n);
    if (!(height > 0.0f)) return 0.0;
    double power;
    const double redraws = redraw_series(below, power);
    const double outside = vmf_density(axis, kappa, w) * redraws;
    if (!(power > 0.0)) return outside;  // q = 0 (the lobe far above its surface): no mirrored part, exactly
    const Vec3 mirrored = w - n * (2.0f * height);
    return outside + power * vmf_density(axis, kappa, mirrored);
  }

  // One unrestricted draw from the lobe's vMF (uc: cos theta, up: phi) and that draw's density: the direction
  // set of the host's lamp integral (render/lamp_through_lobe.h), shared with ExitLobeMixture.
  Vec3 draw(float uc, float up) const { return sample_vmf(axis, kappa, uc, up); }
  double draw_density(const Vec3 &w) const { return vmf_density(axis, kappa, w); }
  // draw(uc, up) in two halves: draw_at(draw_cos(uc), vmf_phi(up)) == draw(uc, up) bit for bit.
  struct DrawCos {
    Frame frame;
    VmfCos c;
  };
  DrawCos draw_cos(float uc) const { return {Frame::from_normal(axis), vmf_cos(kappa, uc)}; }
  static Vec3 draw_at(const DrawCos &d, const VmfPhi &phi) { return vmf_direction(d.frame, d.c, phi); }
  // pdf(w) and draw_density(w) together (one vMF evaluation for both).
  double pdf_and_draw_density(const Vec3 &w, double &draw) const {
    draw = vmf_density(axis, kappa, w);
    const float height = dot(w, n);
    if (!(height > 0.0f)) return 0.0;
    double power;
    const double redraws = redraw_series(below, power);
    const double outside = draw * redraws;
    if (!(power > 0.0)) return outside;
    return outside + power * vmf_density(axis, kappa, w - n * (2.0f * height));
  }
};

// The lobe the number u in [0, 1) picks from `count` weights (>= 0, summing to 1) by their cumulative sums; never
// one of weight 0 unless all are.
template <class W>
inline int pick_mixture_lobe(const W *weight, int count, double u) {
  double c = 0.0;
  int last = 0;
  for (int k = 0; k < count; ++k) {
    if (!(weight[k] > W(0))) continue;
    last = k;
    c += double(weight[k]);
    if (u < c) return k;
  }
  return last;
}

// A mixture of exit lobes (frosted_glass method=sg's exit lobe mixture, issue 12: one lobe per traced ray, each
// with its own axis, sharpness and share of the energy, all leaving from one exit point; a lobe's surface `n`
// may differ in the tests). Sampling picks lobe k with probability weight[k] (the first uniform number), then
// draws from it by ExitLobe::sample; the density is sum_k weight[k] ExitLobe::pdf_k(w), which integrates to
// sum_k weight[k] = 1 (each lobe over its own outside). The plugin hands the host the whole mixture (ABI 2.7,
// GlimmerExitMixture), and the host's estimators at the exit (NEE with MIS against this density, the lamps
// through the lobe, the world's cone lookup) evaluate it whole; a 2.6 host gets the picked lobe alone (its
// expectation is the mixture's, with more variance). Only the first `count` entries are set.
struct ExitLobeMixture {
  static constexpr int kMaxLobes = 10;
  int count = 0;
  ExitLobe lobe[kMaxLobes];
  double weight[kMaxLobes];  // >= 0, sum 1 (normalize()); entries from `count` on are not read
  // Per-lobe constants of the density (prepare(), after the lobes with their `below` and the weights are set):
  // the vMF's normalisation, the redraw factor 1 + q + ... + q^kRedraws and the mirrored part's q^kRedraws. The
  // host's lamp integral evaluates the density ~32 times per lamp per exit; pdf() without prepare() computes them
  // per call (same values up to rounding).
  struct Constants {
    double norm, redraws, mirror;
  };
  Constants constants[kMaxLobes];
  bool prepared = false;
  void prepare() {
    for (int k = 0; k < count; ++k) {
      const ExitLobe &l = lobe[k];
      double power;
      const double redraws = ExitLobe::redraw_series(l.below, power);
      constants[k] = {l.kappa / (2.0 * M_PI * -std::expm1(-2.0 * l.kappa)), redraws, power};
    }
    prepared = true;
  }
  // The prepared vMF density of lobe k at w (as vmf_density).
  double prepared_vmf(int k, const Vec3 &w) const {
    const Vec3 &a = lobe[k].axis;
    const double dx = double(a.x) - w.x, dy = double(a.y) - w.y, dz = double(a.z) - w.z;
    return constants[k].norm * std::exp(-lobe[k].kappa * 0.5 * (dx * dx + dy * dy + dz * dz));
  }
  // The mirrored part of lobe k's density (mirror x its vMF at the mirrored direction, at most mirror x norm: the
  // exponential of a number <= 0 is <= 1) cannot change the outside part pk in the sum pk + mirror part when
  // mirror x norm < 2^-54 pk: a term below half an ulp of pk (pk normal, >= 2^-960 so that 2^-54 pk is exact)
  // rounds away, so the sum is pk bit for bit and its exponential need not be made
  // (LampThroughLobe.SkippedMirrorPartsCannotChangeTheDensity).
  bool mirror_negligible(int k, double pk) const {
    return constants[k].mirror * constants[k].norm < 0x1p-54 * pk && pk >= 0x1p-960;
  }
  // pdf(w) and draw_density(w) together; prepared: one exponential per lobe (two where q^kRedraws > 0 and the
  // mirrored part is not negligible).
  double pdf_and_draw_density(const Vec3 &w, double &draw) const {
    draw = 0.0;
    double p = 0.0;
    for (int k = 0; k < count; ++k) {
      if (!(weight[k] > 0.0)) continue;
      if (!prepared) {
        double d = 0.0;
        p += weight[k] * lobe[k].pdf_and_draw_density(w, d);
        draw += weight[k] * d;
        continue;
      }
      const double v = prepared_vmf(k, w);
      draw += weight[k] * v;
      const float height = dot(w, lobe[k].n);
      if (!(height > 0.0f)) continue;
      double pk = v * constants[k].redraws;
      if (constants[k].mirror > 0.0 && !mirror_negligible(k, pk))
        pk += constants[k].mirror * prepared_vmf(k, w - lobe[k].n * (2.0f * height));
      p += weight[k] * pk;
    }
    return p;
  }

  void normalize() {
    double sum = 0.0;
    for (int k = 0; k < count; ++k) sum += weight[k] > 0.0 ? weight[k] : 0.0;
    for (int k = 0; k < count; ++k) weight[k] = sum > 0.0 && weight[k] > 0.0 ? weight[k] / sum : 0.0;
  }
  // The lobe the number u in [0, 1) picks (by the cumulative weights; never one of weight 0 unless all are).
  int pick(double u) const { return pick_mixture_lobe(weight, count, u); }
  template <class Uniform>
  Vec3 sample(Uniform &&uniform, int *picked = nullptr) const {
    const int k = pick(double(uniform()));
    if (picked) *picked = k;
    return lobe[k].sample(uniform);
  }
  double pdf(const Vec3 &w) const {
    if (prepared) {
      double unused;
      return pdf_and_draw_density(w, unused);
    }
    double p = 0.0;
    for (int k = 0; k < count; ++k)
      if (weight[k] > 0.0) p += weight[k] * lobe[k].pdf(w);
    return p;
  }
  // One unrestricted draw from the vMF mixture: uc picks the lobe by the cumulative weights and, rescaled within
  // the lobe's interval, is its cos theta number (stratified sets of uc stay stratified within each lobe); one
  // lobe of weight 1 draws exactly as ExitLobe::draw. draw_density is the mixture of the vMF densities.
  Vec3 draw(float uc, float up) const {
    float u;
    const int picked = pick_for_draw(uc, u);
    return lobe[picked].draw(u, up);
  }
  // The lobe uc picks by the cumulative weights, and uc rescaled within its interval (u in [0, 1)).
  int pick_for_draw(float uc, float &u) const {
    double lo = 0.0;
    int picked = 0;
    for (int k = 0; k < count; ++k) {
      if (!(weight[k] > 0.0)) continue;
      picked = k;
      if (double(uc) < lo + weight[k]) break;
      lo += weight[k];
    }
    u = float(std::clamp((double(uc) - lo) / weight[picked], 0.0, double(0x1.fffffep-1f)));
    return picked;
  }
  // draw(uc, up) in two halves (as ExitLobe's): draw_at(draw_cos(uc), vmf_phi(up)) == draw(uc, up) bit for bit.
  using DrawCos = ExitLobe::DrawCos;
  DrawCos draw_cos(float uc) const {
    float u;
    const int picked = pick_for_draw(uc, u);
    return lobe[picked].draw_cos(u);
  }
  static Vec3 draw_at(const DrawCos &d, const VmfPhi &phi) { return ExitLobe::draw_at(d, phi); }
  double draw_density(const Vec3 &w) const {
    double p = 0.0;
    for (int k = 0; k < count; ++k)
      if (weight[k] > 0.0) p += weight[k] * (prepared ? prepared_vmf(k, w) : lobe[k].draw_density(w));
    return p;
  }
};

}  // namespace glimmer
