// Level 0 of the glint table as an analytic lobe times a smooth residual (issue 10, session 42).
//
// Level 0 (P_gamma at zero blur, glint_tables.h (1)) is what every unblurred eval reads. On its 1-degree grid it is
// 3 MB per table, and its lookups are random accesses that miss the caches: the GI scene's largest single stall.
// Subsampled to 2-degree nodes (385 KB, L2-resident) the glint render was 3.9 % faster (docs/glints.md, "Session 42")
// but P itself is not smooth on that scale where the lobe is narrow (errors of tens of %). So the lobe is factored
// out. P's small-cone limit is sigma q(wi, wo) (sigma the cone's solid angle); with the cone's spread folded into the
// lobe's width it is
//
//   A(wi, wo) = sigma D_a'(h) cos(theta_h) / (4 wi.h),   a'^2 = alpha^2 + (gamma / 2)^2 / (wi.h)^2,           (1)
//
// the cone of half-angle gamma around wo moving h by gamma / 2 along the plane of (wi, wo) and by gamma / (2 wi.h)
// across it (the scales of glint_tables.cpp's cone rule), so the widening grows toward grazing. The residual
// R = P / A is smooth where P is not; it is stored at 2-degree nodes of theta_i (0..80), theta_o and dphi (41 x 46 x
// 91 16-bit values, 343 KB) from level 0's fp32 nodes (so it carries level 0's energy cap), each theta_i slice scaled
// to level 0's W-weighted energy (the scales saved with the table), and a lookup at theta_i <= 80 is
//
//   P = A(wi, wo) R(theta_i, theta_o, dphi)   (R trilinear),                                                      (2)
//
// with A from the eval's own half vector. R is capped at kResidualCap where A -> 0 with P > 0 (theta_i = theta_o =
// 90 degrees, Beckmann's far tail where the cone's spread dominates D): a larger cap let single nodes reach 100 %+
// errors at 3-4 degree grids.
//
// Measured against the cone integral (benchmarks/glint_factored_level0_study.cpp, 40 000 queries per table over all
// azimuths and theta_i 0..85, where P > 1e-3 of its slice's peak; relative error mean / p99 / max):
//   GGX alpha 0.1225 gamma 2:    1-degree table 0.258 / 2.93 / 46.3 %, factored 0.074 / 1.48 / 54.5 %
//   Beckmann alpha 0.25 gamma 3: 0.277 / 2.35 / 39.4 %, factored 0.027 / 0.34 / 9.2 %
//   GGX alpha 0.16 gamma 2:      0.157 / 1.65 / 18.3 %, factored 0.039 / 0.60 / 15.6 %
// (the maxima of both forms at forward grazing, theta_i 82..85, theta_o 86..90, dphi 172..180); widening by a
// constant (no 1 / (wi.h)^2) left the p99 at 1.4..3.6 %. Lobes narrow against the cone (alpha <= 1.5 gamma, those
// that count particles by pseudo-normals, glint_pseudo_normals.h) keep the 1-degree level 0: there neither form is
// accurate (GGX alpha 0.04 gamma 2: 1.61 / 10.3 / 76.5 % against factored 1.16 / 18.1 / 98.6 %).
//
// Beyond theta_i 80 (forward grazing, where R varies faster than its 2-degree dphi nodes) and for narrow lobes,
// lookups read the 1-degree level 0, which the table keeps. The dark test's bounds (glint_peak.h) are taken over the
// 1-degree nodes; the closure clamps (2) to that bound wherever the test can apply (blur <= gamma), so the test stays
// exact for (2) (the clamp binds at ~1 query in 1000, by <= 2e-4: GlintFactoredLevel0 tests).
#pragma once

#include <cmath>

namespace glimmer::plugin::glint {

// A of (1) without its table: the base distribution, alpha^2, (gamma / 2)^2 and sigma / (4 pi).
struct Level0Lobe {
  bool ggx = true;
  float alpha2 = 0.0f;
  float widen2 = 0.0f;  // (gamma_rad / 2)^2
  float scale = 0.0f;   // sigma / (4 pi): D's 1 / pi and (1)'s 1 / 4 with the cone's solid angle
  double alpha2_d = 0.0, widen2_d = 0.0, scale_d = 0.0;  // the same in double (the residual's nodes)

  Level0Lobe() = default;
  Level0Lobe(bool is_ggx, double alpha, double gamma_rad, double sigma)
      : ggx(is_ggx),
        alpha2(static_cast<float>(alpha * alpha)),
        widen2(static_cast<float>(0.25 * gamma_rad * gamma_rad)),
        scale(static_cast<float>(sigma / (4.0 * 3.141592653589793))),
        alpha2_d(alpha * alpha),
        widen2_d(0.25 * gamma_rad * gamma_rad),
        scale_d(sigma / (4.0 * 3.141592653589793)) {}

  // A at wi.h and cos(theta_h). pi D = 1 / (a2 k^2) with k = (1 - c^2) / a2 + c^2 (GGX), exp(-(1 - c^2) / (c^2 a2)) /
  // (a2 c^4) (Beckmann, 0 beyond an exponent of 80 as mf::beckmann_D). 0 where wi.h or cos(theta_h) is below
  // kMinCosine (h at the horizon of wi or of the surface; lookups read A only where theta_i <= 80, where
  // both are above 0.08): no overflow of the 1 / (wi.h)^2 widening or of A's 1 / wi.h.
  static constexpr float kMinCosine = 1e-3f;
  float operator()(float wi_h, float cos_h) const { return lobe(wi_h, cos_h, alpha2, widen2, scale, ggx); }
  double at(double wi_h, double cos_h) const { return lobe(wi_h, cos_h, alpha2_d, widen2_d, scale_d, ggx); }
  // (1) in float (the eval) or double (the residual's nodes): the same operations.
  template <class T>
  static T lobe(T wi_h, T cos_h, T alpha2_, T widen2_, T scale_, bool is_ggx) {
    if (!(wi_h >= T(kMinCosine)) || !(cos_h >= T(kMinCosine))) return T(0);
    const T a2 = alpha2_ + widen2_ / (wi_h * wi_h);
    const T c2 = cos_h * cos_h;
    T pi_d;
    if (is_ggx) {
      const T k = (T(1) - c2) / a2 + c2;
      pi_d = T(1) / (a2 * k * k);
    } else {
      const T e = (T(1) - c2) / (c2 * a2);
      if (!(e < T(80))) return T(0);
      pi_d = std::exp(-e) / (a2 * c2 * c2);
    }
    return scale_ * pi_d * cos_h / wi_h;
  }
};

}  // namespace glimmer::plugin::glint
