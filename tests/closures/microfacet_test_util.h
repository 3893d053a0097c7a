// Helpers for the microfacet closure tests: plugin access through the C ABI,
// a Mitsuba-style chi-square test with adaptive cell integration of the pdf.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "glimmer/rng.h"
#include "host/closure_instance.h"
#include "host/plugin_library.h"

namespace glimmer::mftest {

inline host::PluginLibrary &plugin() {
  static std::unique_ptr<host::PluginLibrary> library = host::PluginLibrary::load(GLIMMER_TEST_PLUGIN_PATH);
  return *library;
}

// Creates an instance from "name=value" assignments.
inline std::unique_ptr<host::ClosureInstance> make_closure(const std::string &name,
                                                           const std::vector<std::string> &assignments) {
  const GlimmerClosureType *type = plugin().find(name);
  if (type == nullptr) throw std::runtime_error("closure not found: " + name);
  host::ParamList params;
  for (const auto &a : assignments) params.set_assignment(*type, a);
  return std::make_unique<host::ClosureInstance>(*type, params);
}

inline Vec3 direction_from(float cos_theta, float phi) {
  const float s = std::sqrt(std::max(0.0f, 1.0f - cos_theta * cos_theta));
  return {s * std::cos(phi), s * std::sin(phi), cos_theta};
}

// Regularized upper incomplete gamma Q(a, x) (series / Lentz continued fraction).
inline double gamma_q(double a, double x) {
  if (x <= 0.0) return 1.0;
  const double gln = std::lgamma(a);
  if (x < a + 1.0) {
    double ap = a, sum = 1.0 / a, del = sum;
    for (int n = 0; n < 100000; ++n) {
      ap += 1.0;
      del *= x / ap;
      sum += del;
      if (std::fabs(del) < std::fabs(sum) * 1e-15) break;
    }
    return 1.0 - sum * std::exp(-x + a * std::log(x) - gln);
  }
  double b = x + 1.0 - a, c = 1.0 / 1e-300, d = 1.0 / b, h = d;
  for (int i = 1; i < 100000; ++i) {
    const double an = -i * (i - a);
    b += 2.0;
    d = an * d + b;
    if (std::fabs(d) < 1e-300) d = 1e-300;
    c = b + an / c;
    if (std::fabs(c) < 1e-300) c = 1e-300;
    d = 1.0 / d;
    const double del = d * c;
    h *= del;
    if (std::fabs(del - 1.0) < 1e-15) break;
  }
  return std::exp(-x + a * std::log(x) - gln) * h;
}

struct Chi2Result {
  double p_value = 0.0, chi2 = 0.0;
  int dof = 0;
  long samples_ok = 0;
  double expected_total = 0.0;  // integral of the pdf over the sphere
};

// Mitsuba 3 style chi2 (src/python/python/chi2.py): cells over the whole
// sphere in polar coordinates (t, phi) around `axis`, theta = pi t^k (k > 1
// refines the cells near the axis for near-delta lobes); expected counts from an
// adaptive 4x4 Gauss integration of the pdf per cell; cells with < 5 expected
// pooled into one.
inline Chi2Result chi2_test(const std::function<bool(const float rand[3], Vec3 &wo)> &sample,
                            const std::function<double(const Vec3 &wo)> &pdf, long n_samples, uint64_t seed,
                            Vec3 axis = Vec3(0, 0, 1), double k = 1.0, int n_t = 48, int n_phi = 96) {
  const Frame frame = Frame::from_normal(normalize(axis));
  std::vector<double> observed(size_t(n_t) * n_phi, 0.0), expected(size_t(n_t) * n_phi, 0.0);
  Pcg32 rng(seed);
  Chi2Result r;
  for (long i = 0; i < n_samples; ++i) {
    const float u[3] = {rng.next_float(), rng.next_float(), rng.next_float()};
    Vec3 wo;
    if (!sample(u, wo)) continue;
    ++r.samples_ok;
    const Vec3 l = frame.to_local(wo);
    // atan2, not acos: exact for the tiny angles of near-delta lobes.
    const double theta = std::atan2(std::sqrt(double(l.x) * l.x + double(l.y) * l.y), double(l.z));
    const double t = std::pow(theta / M_PI, 1.0 / k);
    double phi = std::atan2(double(l.y), double(l.x));
    if (phi < 0.0) phi += 2.0 * M_PI;
    const int it = std::min(int(t * n_t), n_t - 1);
    const int ip = std::min(int(phi / (2.0 * M_PI) * n_phi), n_phi - 1);
    observed[size_t(it) * n_phi + ip] += 1.0;
  }
  static const double gx[4] = {-0.8611363115940526, -0.3399810435848563, 0.3399810435848563, 0.8611363115940526};
  static const double gw[4] = {0.3478548451374538, 0.6521451548625461, 0.6521451548625461, 0.3478548451374538};
  // Cells are integrated in a variable x with theta = theta(x): for k = 1,
  // cos(theta) = x^3 (clusters nodes at the horizon, where grazing lobes
  // squeeze into a thin band), for k > 1 theta = pi t^k as binned.
  const bool cubic = k == 1.0;
  auto x_of_t = [&](double t) { return cubic ? std::cbrt(std::cos(M_PI * t)) : t; };
  auto density = [&](double x, double phi) {
    double theta, jac;
    if (cubic) {
      const double c = x * x * x;
      theta = std::acos(clamp(c, -1.0, 1.0));
      jac = 3.0 * x * x;
    } else {
      theta = M_PI * std::pow(x, k);
      jac = std::sin(theta) * M_PI * k * std::pow(x, k - 1.0);
    }
    const Vec3 l(float(std::sin(theta) * std::cos(phi)), float(std::sin(theta) * std::sin(phi)), float(std::cos(theta)));
    return jac > 0.0 ? pdf(frame.to_world(l)) * jac : 0.0;
  };
  auto gauss = [&](double t0, double t1, double p0, double p1) {
    double s = 0.0;
    for (int a = 0; a < 4; ++a)
      for (int b = 0; b < 4; ++b)
        s += gw[a] * gw[b] * density(0.5 * (t0 + t1) + 0.5 * (t1 - t0) * gx[a], 0.5 * (p0 + p1) + 0.5 * (p1 - p0) * gx[b]);
    return s * 0.25 * std::fabs(t1 - t0) * (p1 - p0);
  };
  std::function<double(double, double, double, double, double, int)> adapt =
      [&](double t0, double t1, double p0, double p1, double whole, int depth) -> double {
    const double tm = 0.5 * (t0 + t1), pm = 0.5 * (p0 + p1);
    const double q[4] = {gauss(t0, tm, p0, pm), gauss(tm, t1, p0, pm), gauss(t0, tm, pm, p1), gauss(tm, t1, pm, p1)};
    const double sum = q[0] + q[1] + q[2] + q[3];
    if (depth >= 7 || std::fabs(sum - whole) < 1e-9 * (1.0 + std::fabs(sum))) return sum;
    return adapt(t0, tm, p0, pm, q[0], depth + 1) + adapt(tm, t1, p0, pm, q[1], depth + 1) +
           adapt(t0, tm, pm, p1, q[2], depth + 1) + adapt(tm, t1, pm, p1, q[3], depth + 1);
  };
  for (int it = 0; it < n_t; ++it) {
    const double t0 = x_of_t(double(it) / n_t), t1 = x_of_t(double(it + 1) / n_t);
    for (int ip = 0; ip < n_phi; ++ip) {
      const double p0 = 2.0 * M_PI * ip / n_phi, p1 = 2.0 * M_PI * (ip + 1) / n_phi;
      expected[size_t(it) * n_phi + ip] = double(n_samples) * adapt(t0, t1, p0, p1, gauss(t0, t1, p0, p1), 0);
    }
  }
  double pooled_obs = 0.0, pooled_exp = 0.0, chi2 = 0.0, total_exp = 0.0;
  int bins = 0;
  for (size_t i = 0; i < observed.size(); ++i) {
    total_exp += expected[i];
    if (expected[i] < 5.0) {
      pooled_obs += observed[i];
      pooled_exp += expected[i];
    } else {
      chi2 += (observed[i] - expected[i]) * (observed[i] - expected[i]) / expected[i];
      ++bins;
    }
  }
  if (pooled_exp >= 5.0) {
    chi2 += (pooled_obs - pooled_exp) * (pooled_obs - pooled_exp) / pooled_exp;
    ++bins;
  } else if (pooled_obs > 0.0) {
    chi2 += (pooled_obs - pooled_exp) * (pooled_obs - pooled_exp) / std::max(pooled_exp, 1.0);
    ++bins;
  }
  r.chi2 = chi2;
  r.dof = std::max(bins - 1, 1);
  r.p_value = gamma_q(0.5 * r.dof, 0.5 * chi2);
  r.expected_total = total_exp / double(n_samples);
  return r;
}

// Mean sample weight f_cos / pdf per channel over strata^2 x (strata / 4)
// jittered 3D strata of the random numbers (the third one picks the lobe),
// split by the sampled lobe (reflection / transmission), and a conservative
// standard error of the total (that of independent samples), channel 0.
struct Albedo {
  Spectrum mean{0.0f}, reflect{0.0f}, transmit{0.0f};
  double std_error = 0.0;
};
inline Albedo sampled_albedo(const host::ClosureInstance &c, const Vec3 &wi, int strata, uint64_t seed) {
  const GlimmerShadingContext ctx = host::make_local_context(wi);
  Pcg32 rng(seed);
  double r[3] = {0, 0, 0}, t[3] = {0, 0, 0}, sum2 = 0.0;
  const int sz = std::max(strata / 4, 1), sxy = std::max(strata / 2, 1);
  const long n = long(sxy) * sxy * sz;
  for (int i = 0; i < sxy; ++i)
    for (int j = 0; j < sxy; ++j)
      for (int k = 0; k < sz; ++k) {
        const float u[3] = {(i + rng.next_float()) / sxy, (j + rng.next_float()) / sxy, (k + rng.next_float()) / sz};
        GlimmerSample s;
        const uint32_t label = c.sample(ctx, u, s);
        if (label == GLIMMER_LABEL_NONE) continue;
        double *acc = (label & GLIMMER_LABEL_TRANSMIT) ? t : r;
        for (int ch = 0; ch < 3; ++ch) acc[ch] += s.eval[ch] / s.pdf;
        sum2 += double(s.eval[0] / s.pdf) * (s.eval[0] / s.pdf);
      }
  Albedo a;
  a.reflect = Spectrum(float(r[0] / n), float(r[1] / n), float(r[2] / n));
  a.transmit = Spectrum(float(t[0] / n), float(t[1] / n), float(t[2] / n));
  a.mean = Spectrum(float((r[0] + t[0]) / n), float((r[1] + t[1]) / n), float((r[2] + t[2]) / n));
  const double mean = (r[0] + t[0]) / n;
  a.std_error = std::sqrt(std::max(0.0, sum2 / n - mean * mean) / n);
  return a;
}

// chi2 of a closure's sample() against the pdf of its eval() at `ctx`
// (binning as chi2_test with `axis`, `k`), plus the worst relative eval/pdf
// inconsistency (value in `channel`, pdf) at every 64th sampled direction.
struct ClosureChi2 {
  Chi2Result result;
  double inconsistency = 0.0;
};
inline ClosureChi2 closure_chi2(const host::ClosureInstance &closure, const GlimmerShadingContext &ctx, long n_samples,
                                uint64_t seed, Vec3 axis = Vec3(0, 0, 1), double k = 1.0, int channel = 0) {
  ClosureChi2 out;
  uint32_t calls = 0;
  auto sample = [&](const float u[3], Vec3 &wo) {
    GlimmerSample s;
    if (closure.sample(ctx, u, s) == GLIMMER_LABEL_NONE) return false;
    wo = Vec3(s.wo);
    if ((++calls & 63u) == 0u) {
      Spectrum f;
      float pdf;
      closure.eval(ctx, wo, f, pdf);
      const double rel_pdf = std::fabs(pdf - s.pdf) / std::max(double(s.pdf), 1e-30);
      const double rel_f = std::fabs(f[channel] - s.eval[channel]) / std::max(double(s.eval[channel]), 1e-30);
      if (s.pdf > 1e-3f && s.eval[channel] > 1e-6f)
        out.inconsistency = std::max(out.inconsistency, std::max(rel_pdf, rel_f));
    }
    return true;
  };
  auto pdf = [&](const Vec3 &wo) {
    Spectrum f;
    float p;
    closure.eval(ctx, wo, f, p);
    return double(p);
  };
  out.result = chi2_test(sample, pdf, n_samples, seed, axis, k);
  return out;
}

// Sidak-corrected per-test significance for `tests` tests at overall level `alpha`.
inline double sidak_threshold(int tests, double alpha = 0.01) { return 1.0 - std::pow(1.0 - alpha, 1.0 / tests); }

}  // namespace glimmer::mftest
