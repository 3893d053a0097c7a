// The exit lobe of frosted_glass method=sg (glimmer/exit_lobe.h, closure ABI 2.4): the density with which the
// plugin draws the direction leaving the object (a vMF about the exit axis, redrawn below the exit surface up
// to 16 times, then mirrored), which the host uses as the BSDF for light sampling and MIS at the exit point.
//  - the SG's fraction below the surface q (a 1D Bessel quadrature) equals its closed forms (axis along n, along
//    -n, in the plane) and a brute-force count of vMF samples, kappa 0.5..1e4;
//  - the density integrates to 1 over the outside (deterministic quadrature over the hemisphere, sharp lobes
//    included), so the host's eval = weight x pdf integrates to the weight the sample carried; negative
//    control: the SG restricted to the outside without the redraw factor integrates to 1 - q;
//  - chi2 of 1e6 draws by the plugin's rule against the density (Sidak over the family); negative control: the
//    density of an endless redraw (v / (1 - q), no mirrored tail) is rejected where q is large.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <vector>

#include "closures/microfacet_test_util.h"
#include "glimmer/exit_lobe.h"
#include "glimmer/rng.h"
#include "lab/closure_lab.h"

namespace {

using namespace glimmer;

// A unit axis at polar angle alpha (degrees) from n = +z.
Vec3 axis_at(double alpha_deg) {
  const double a = alpha_deg * M_PI / 180.0;
  return normalize(Vec3(float(std::sin(a)), 0.0f, float(std::cos(a))));
}

struct LobeConfig {
  double alpha_deg, kappa;
};

TEST(FrostedExitLobe, FractionBelowMatchesClosedFormsAndBruteForce) {
  const Vec3 n(0, 0, 1);
  for (double kappa : {0.5, 3.0, 40.0, 1e3, 1e4}) {
    // Axis along n: q = P(cos < 0) = e^-k / (1 + e^-k); along -n: 1 / (1 + e^-k); in the plane: 1/2.
    const double e = std::exp(-kappa);
    EXPECT_NEAR(vmf_fraction_below(axis_at(0), kappa, n), e / (1 + e), 1e-6) << "kappa " << kappa;
    EXPECT_NEAR(vmf_fraction_below(axis_at(180), kappa, n), 1 / (1 + e), 1e-6) << "kappa " << kappa;
    EXPECT_NEAR(vmf_fraction_below(axis_at(90), kappa, n), 0.5, 1e-6) << "kappa " << kappa;
  }
  // Brute force: the fraction of 1e6 vMF draws below the surface (5 binomial sigmas).
  const LobeConfig configs[] = {{30, 2}, {70, 5}, {85, 40}, {95, 40}, {89.5, 1e4}, {120, 3}, {60, 0.5}};
  double worst = 0.0;
  for (const LobeConfig &c : configs) {
    Pcg32 rng(7);
    const long n_draws = 1000000;
    long below = 0;
    for (long i = 0; i < n_draws; ++i) {
      const float u1 = rng.next_float(), u2 = rng.next_float();
      below += dot(sample_vmf(axis_at(c.alpha_deg), c.kappa, u1, u2), n) <= 0.0f;
    }
    const double measured = double(below) / n_draws, q = vmf_fraction_below(axis_at(c.alpha_deg), c.kappa, n);
    const double sigma = std::sqrt(std::max(q * (1 - q), 1e-6) / n_draws);
    worst = std::max(worst, std::fabs(measured - q) / sigma);
    EXPECT_LT(std::fabs(measured - q), 5 * sigma)
        << "alpha " << c.alpha_deg << " kappa " << c.kappa << ": q " << q << " vs counted " << measured;
  }
  std::printf("[exit lobe] fraction below: closed forms within 1e-6; vs 1e6 counted draws, worst %.2f sigma\n", worst);
}

// The fraction below by a plain fine quadrature (the same integrand as vmf_fraction_below, written out: 8-point
// Gauss-Legendre on `panels` equal panels over the same window, every sin and exp evaluated directly).
double fraction_below_reference(double alpha, double kappa, int panels) {
  static constexpr double kNode[4] = {0.1834346424956498, 0.5255324099163290, 0.7966664774136267, 0.9602898564975363};
  static constexpr double kWeight[4] = {0.3626837833783620, 0.3137066458778873, 0.2223810344533745, 0.1012285362903763};
  const double half_width = std::sqrt(80.0 / std::max(kappa, 1e-9));
  const double lo = std::max(0.5 * M_PI, alpha - half_width), hi = std::min(M_PI, alpha + half_width);
  if (!(hi > lo)) return 0.0;
  const double panel = (hi - lo) / panels;
  double sum = 0.0;
  for (int p = 0; p < panels; ++p)
    for (int k = 0; k < 8; ++k) {
      const double beta = lo + (p + 0.5) * panel + (k < 4 ? -1.0 : 1.0) * kNode[k % 4] * 0.5 * panel;
      const double s = std::sin(0.5 * (beta - alpha));
      sum += kWeight[k % 4] * std::sin(beta) * std::exp(-2.0 * kappa * s * s) *
             bessel_i0_scaled(kappa * std::sin(alpha) * std::sin(beta));
    }
  return std::clamp(sum * 0.5 * panel * kappa / -std::expm1(-2.0 * kappa), 0.0, 1.0);
}

// vmf_fraction_below's quadrature (panels and nodes stepped by angle addition) against the fine plain one (64
// panels) over random alpha 0..180 deg and kappa 1e-2..1e7: within 5e-7 (the host's density needs q far less
// precisely: it enters as 1 + q + ... + q^16). Negative control: 2 panels of the plain quadrature miss by > 1e-5.
TEST(FrostedExitLobe, FractionBelowQuadratureAgainstAFineOne) {
  Pcg32 rng(2026, 20);
  const Vec3 n(0, 0, 1);
  double worst = 0.0, control_worst = 0.0;
  for (int t = 0; t < 100000; ++t) {
    const double alpha = M_PI * rng.next_float(), kappa = std::pow(10.0, -2.0 + 9.0 * rng.next_float());
    const Vec3 axis = normalize(Vec3(float(std::sin(alpha)), 0.0f, float(std::cos(alpha))));
    const double a = std::acos(std::clamp(double(dot(axis, n)), -1.0, 1.0));  // the axis' angle as the code sees it
    const double fine = fraction_below_reference(a, kappa, 64);
    worst = std::max(worst, std::fabs(vmf_fraction_below(axis, kappa, n) - fine));
    control_worst = std::max(control_worst, std::fabs(fraction_below_reference(a, kappa, 2) - fine));
  }
  std::printf("[exit lobe] fraction below vs 64 panels: max |difference| %.3g; control (2 panels) %.3g\n", worst,
              control_worst);
  EXPECT_LT(worst, 5e-7);
  EXPECT_GT(control_worst, 1e-5);
}

// Int of f over the polar cap beta <= beta_max about +z, midpoint rule on a (beta, phi) grid.
double integrate_cap(const std::function<double(const Vec3 &)> &f, double beta_max, int n_beta, int n_phi) {
  double sum = 0.0;
  const double d_beta = beta_max / n_beta, d_phi = 2.0 * M_PI / n_phi;
  for (int i = 0; i < n_beta; ++i) {
    const double beta = (i + 0.5) * d_beta, sb = std::sin(beta), cb = std::cos(beta);
    double row = 0.0;
    for (int j = 0; j < n_phi; ++j) {
      const double phi = (j + 0.5) * d_phi;
      row += f(Vec3(float(sb * std::cos(phi)), float(sb * std::sin(phi)), float(cb)));
    }
    sum += row * sb;
  }
  return sum * d_beta * d_phi;
}

// Int over the outside hemisphere of f (n = +z).
double integrate_outside(const std::function<double(const Vec3 &)> &f, int n_beta, int n_phi) {
  return integrate_cap(f, 0.5 * M_PI, n_beta, n_phi);
}

TEST(FrostedExitLobe, DensityIntegratesToOneOutside) {
  const Vec3 n(0, 0, 1);
  // Above, grazing, below the surface (q large: redraws and the mirrored tail carry the mass), sharp.
  const LobeConfig configs[] = {{20, 4}, {80, 30}, {100, 30}, {150, 3}, {88, 1e3}, {91, 1e4}};
  double worst = 0.0;
  for (const LobeConfig &c : configs) {
    const ExitLobe lobe = ExitLobe::make(axis_at(c.alpha_deg), c.kappa, n);
    // Fine in beta: the midpoint rule's error at the horizon, where a grazing sharp lobe is cut, is
    // ~ (step / width)^2 / 24 of its mass.
    const double integral = integrate_outside([&](const Vec3 &w) { return lobe.pdf(w); }, 8192, 2048);
    worst = std::max(worst, std::fabs(integral - 1.0));
    EXPECT_NEAR(integral, 1.0, 2e-4) << "alpha " << c.alpha_deg << " kappa " << c.kappa << " q " << lobe.below;
    // Negative control: the SG restricted to the outside without the redraw factor loses its part below.
    if (lobe.below > 0.01) {
      const double plain =
          integrate_outside([&](const Vec3 &w) { return vmf_density(lobe.axis, lobe.kappa, w); }, 2048, 4096);
      EXPECT_GT(std::fabs(plain - 1.0), 50 * 2e-4) << "alpha " << c.alpha_deg;
      EXPECT_NEAR(plain, 1.0 - lobe.below, 2e-4);
    }
  }
  std::printf(
      "[exit lobe] Int pdf over the outside, 6 lobes (kappa 3..1e4, axis 20..150 deg from n): worst "
      "|1 - Int| = %.2e\n",
      worst);
}

// chi2 of draws by ExitLobe::sample against `pdf`, on an equal-area (cos beta, phi) grid of the outside;
// expected counts by a 12 x 12 midpoint sub-grid per cell, cells below 5 expected pooled.
double exit_lobe_chi2_p(const std::function<Vec3(Pcg32 &)> &draw, const std::function<double(const Vec3 &)> &pdf,
                        long n_draws) {
  constexpr int kMu = 64, kPhi = 128, kSub = 12;
  std::vector<double> observed(kMu * kPhi, 0.0), expected(kMu * kPhi, 0.0);
  Pcg32 rng(12345);
  for (long i = 0; i < n_draws; ++i) {
    const Vec3 w = draw(rng);
    if (!(w.z > 0.0f)) continue;
    const int mu = std::min(int(w.z * kMu), kMu - 1);
    double phi = std::atan2(double(w.y), double(w.x));
    if (phi < 0) phi += 2 * M_PI;
    const int ph = std::min(int(phi / (2 * M_PI) * kPhi), kPhi - 1);
    observed[mu * kPhi + ph] += 1;
  }
  for (int i = 0; i < kMu; ++i)
    for (int j = 0; j < kPhi; ++j) {
      double sum = 0.0;
      for (int a = 0; a < kSub; ++a)
        for (int b = 0; b < kSub; ++b) {
          const double mu = (i + (a + 0.5) / kSub) / kMu, phi = 2 * M_PI * (j + (b + 0.5) / kSub) / kPhi;
          const double s = std::sqrt(std::max(0.0, 1 - mu * mu));
          sum += pdf(Vec3(float(s * std::cos(phi)), float(s * std::sin(phi)), float(mu)));
        }
      expected[i * kPhi + j] = sum / (kSub * kSub) * (1.0 / kMu) * (2 * M_PI / kPhi) * double(n_draws);
    }
  double chi2 = 0.0, pool_o = 0.0, pool_e = 0.0;
  int cells = 0;
  for (size_t k = 0; k < observed.size(); ++k) {
    if (expected[k] < 5.0) {
      pool_o += observed[k];
      pool_e += expected[k];
      continue;
    }
    chi2 += (observed[k] - expected[k]) * (observed[k] - expected[k]) / expected[k];
    ++cells;
  }
  if (pool_e > 0.0) {
    chi2 += (pool_o - pool_e) * (pool_o - pool_e) / std::max(pool_e, 1.0);
    ++cells;
  }
  return lab::chi2_survival(chi2, std::max(cells - 1, 1));
}
double exit_lobe_chi2_p(const ExitLobe &lobe, const std::function<double(const Vec3 &)> &pdf, long n_draws) {
  return exit_lobe_chi2_p([&lobe](Pcg32 &rng) { return lobe.sample([&rng] { return rng.next_float(); }); }, pdf,
                          n_draws);
}

TEST(FrostedExitLobe, SamplingMatchesTheDensityChi2) {
  const Vec3 n(0, 0, 1);
  const LobeConfig configs[] = {{20, 4}, {60, 150}, {85, 40}, {100, 30}, {130, 10}, {150, 3}};
  const double threshold = glimmer::mftest::sidak_threshold(int(std::size(configs)));
  double min_p = 1.0;
  for (const LobeConfig &c : configs) {
    const ExitLobe lobe = ExitLobe::make(axis_at(c.alpha_deg), c.kappa, n);
    const double p = exit_lobe_chi2_p(
        lobe, [&](const Vec3 &w) { return lobe.pdf(w); }, 1000000);
    min_p = std::min(min_p, p);
    EXPECT_GT(p, threshold) << "alpha " << c.alpha_deg << " kappa " << c.kappa << " q " << lobe.below;
    // Negative control where the mirrored tail matters (q^16 >= 1e-3): an endless redraw's density.
    if (std::pow(lobe.below, ExitLobe::kRedraws) > 1e-3) {
      const double p_wrong = exit_lobe_chi2_p(
          lobe, [&](const Vec3 &w) { return w.z > 0 ? vmf_density(lobe.axis, lobe.kappa, w) / (1 - lobe.below) : 0.0; },
          1000000);
      EXPECT_LT(p_wrong, threshold) << "alpha " << c.alpha_deg << " kappa " << c.kappa;
      std::printf("[exit lobe] negative control (no mirrored tail), alpha %.0f kappa %.0f q %.3f: p %.2e\n",
                  c.alpha_deg, c.kappa, lobe.below, p_wrong);
    }
  }
  std::printf("[exit lobe] chi2, %zu lobes x 1e6 draws: min p %.4f (Sidak threshold %.2e)\n", std::size(configs), min_p,
              threshold);
}

// ---- The exit lobe mixture (ExitLobeMixture, frosted sg's kMixture exit, issue 12) ----------------------------
// Mixtures like the ones the plugin builds: 5 lobes (an axis and 4 around it at the bounding angle's image),
// weights 1 - s, s / 4 (times unequal energies), some split into a core and a tail (sharper and 4x wider), some with
// the exit surface tilted per lobe (each lobe leaves at its own exit point).
ExitLobeMixture test_mixture(int which) {
  ExitLobeMixture m;
  const double tilt = which == 2 ? 12.0 : 0.0;  // per-lobe exit normals tilted by up to this (degrees)
  const double base_alpha[3] = {20.0, 70.0, 40.0}, base_kappa[3] = {40.0, 25.0, 200.0};
  const double spread = 9.0;  // degrees between the axis and the others
  for (int k = 0; k < 5; ++k) {
    const double phi = k == 0 ? 0.0 : (k - 1) * 0.5 * M_PI;
    const double off = k == 0 ? 0.0 : spread * M_PI / 180.0;
    const Vec3 a = axis_at(base_alpha[which]);
    const Frame f = Frame::from_normal(a);
    const Vec3 axis = normalize(f.to_world(Vec3(float(std::sin(off) * std::cos(phi)),
                                                float(std::sin(off) * std::sin(phi)), float(std::cos(off)))));
    const double t = tilt * M_PI / 180.0 * (k == 0 ? 0.0 : 1.0);
    const Vec3 n = normalize(Vec3(float(std::sin(t) * std::cos(phi)), float(std::sin(t) * std::sin(phi)),
                                  float(std::cos(t))));
    m.lobe[m.count] = ExitLobe::make(axis, base_kappa[which] * (1.0 + 0.3 * k), n);
    m.weight[m.count++] = (k == 0 ? 0.6 : 0.1) * (1.0 - 0.05 * k);
  }
  if (which == 1) {  // core (0.9, kappa x 1.5) + tail (0.1, kappa / 4) per lobe
    const int n = m.count;
    for (int k = 0; k < n; ++k) {
      m.lobe[n + k] = ExitLobe::make(m.lobe[k].axis, m.lobe[k].kappa * 0.25, m.lobe[k].n);
      m.weight[n + k] = 0.1 * m.weight[k];
      m.lobe[k] = ExitLobe::make(m.lobe[k].axis, m.lobe[k].kappa * 1.5, m.lobe[k].n);
      m.weight[k] *= 0.9;
    }
    m.count = 2 * n;
  }
  m.normalize();
  return m;
}

// Int over the whole sphere of f.
double integrate_sphere(const std::function<double(const Vec3 &)> &f, int n_beta, int n_phi) {
  return integrate_cap(f, M_PI, n_beta, n_phi);
}

TEST(FrostedExitLobe, MixtureDensityIntegratesToOne) {
  double worst = 0.0;
  for (int which = 0; which < 3; ++which) {
    const ExitLobeMixture m = test_mixture(which);
    double wsum = 0.0;
    for (int k = 0; k < m.count; ++k) wsum += m.weight[k];
    EXPECT_NEAR(wsum, 1.0, 1e-12);
    const double integral = integrate_sphere([&](const Vec3 &w) { return m.pdf(w); }, 8192, 2048);
    worst = std::max(worst, std::fabs(integral - 1.0));
    EXPECT_NEAR(integral, 1.0, 2e-4) << "mixture " << which;
    // Negative control: the weights left unnormalised (the energies' sum, not 1) integrate to that sum.
    ExitLobeMixture raw = test_mixture(which);
    double raw_sum = 0.0;
    for (int k = 0; k < raw.count; ++k) raw_sum += (raw.weight[k] *= 0.9 + 0.02 * k);
    const double raw_integral = integrate_sphere([&](const Vec3 &w) { return raw.pdf(w); }, 2048, 1024);
    EXPECT_GT(std::fabs(raw_integral - 1.0), 50 * 2e-4) << "mixture " << which;
    EXPECT_NEAR(raw_integral, raw_sum, 1e-3) << "mixture " << which;
  }
  std::printf("[exit lobe] mixture Int pdf over the sphere, 3 mixtures (5 lobes; core + tail; tilted exit normals): "
              "worst |1 - Int| = %.2e\n", worst);
}

TEST(FrostedExitLobe, MixtureSamplingMatchesTheDensityChi2) {
  const double threshold = glimmer::mftest::sidak_threshold(3);
  double min_p = 1.0;
  for (int which = 0; which < 3; ++which) {
    const ExitLobeMixture m = test_mixture(which);
    const auto draw = [&m](Pcg32 &rng) { return m.sample([&rng] { return rng.next_float(); }); };
    const double p = exit_lobe_chi2_p(draw, [&](const Vec3 &w) { return m.pdf(w); }, 1000000);
    min_p = std::min(min_p, p);
    EXPECT_GT(p, threshold) << "mixture " << which;
    // Negative control: the density with equal weights (the picking rule ignored) is rejected.
    ExitLobeMixture equal = m;
    for (int k = 0; k < equal.count; ++k) equal.weight[k] = 1.0 / equal.count;
    const double p_wrong = exit_lobe_chi2_p(draw, [&](const Vec3 &w) { return equal.pdf(w); }, 1000000);
    EXPECT_LT(p_wrong, threshold) << "mixture " << which;
    std::printf("[exit lobe] mixture %d: chi2 p %.4f; equal-weights density p %.2e\n", which, p, p_wrong);
  }
  std::printf("[exit lobe] mixture chi2, 3 mixtures x 1e6 draws: min p %.4f (Sidak threshold %.2e)\n", min_p,
              threshold);
}

}  // namespace
