// Helpers for the microfacet closure tests: closures through the C ABI, the
// lab's chi-square test with their binning, sampled albedo split by lobe.
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
#include "lab/closure_lab.h"
#include "test_support.h"

namespace glimmer::mftest {

using test::plugin;
using test::stress_scale;

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

// A chi2 result as the microfacet tests report it (from lab::chi2_test).
struct Chi2Result {
  double p_value = 0.0, chi2 = 0.0;
  int dof = 0;
  long samples_ok = 0;          // samples histogrammed (not absorbed, not singular)
  double expected_total = 0.0;  // integral of the pdf over the sphere
  std::string message;          // lab::Chi2Result::message (worst cells)
};

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
        GlimmerSample s = glimmer_blank_sample();
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

// chi2 of a closure's sample() against the pdf of its eval() at `ctx`: the
// lab's test (bridge/lab/chi2.cpp) on 48 x 96 cells about `axis` (in the
// coordinates of ctx's vectors, i.e. the outward frame of
// host::make_local_context; the lab takes it in the shading frame z = ctx.N) with
// theta = pi t^k; plus the worst relative eval/pdf inconsistency (value in
// `channel`, pdf) at every 64th sampled direction.
struct ClosureChi2 {
  Chi2Result result;
  double inconsistency = 0.0;
};
inline ClosureChi2 closure_chi2(const host::ClosureInstance &closure, const GlimmerShadingContext &ctx, long n_samples,
                                uint64_t seed, Vec3 axis = Vec3(0, 0, 1), double k = 1.0, int channel = 0) {
  lab::Chi2Options options;
  options.theta_bins = 48;
  options.phi_bins = 96;
  options.samples = uint64_t(n_samples);
  options.seed = seed;
  options.axis = Frame::from_normal_tangent(Vec3(ctx.N), Vec3(ctx.T)).to_local(axis);
  options.theta_exponent = k;
  const lab::Chi2Result r = lab::chi2_test(closure, ctx, options);
  ClosureChi2 out;
  out.result = {r.p_value, r.chi2, r.dof, long(std::llround(r.sampled_fraction * double(n_samples))), r.pdf_integral,
                r.message};
  for (long i = 0; i < n_samples; i += 64) {
    float u[3];
    lab::sample_random3(seed, uint64_t(i), u);
    GlimmerSample s = glimmer_blank_sample();
    if (closure.sample(ctx, u, s) == GLIMMER_LABEL_NONE) continue;
    Spectrum f;
    float pdf;
    closure.eval(ctx, Vec3(s.wo), f, pdf);
    const double rel_pdf = std::fabs(pdf - s.pdf) / std::max(double(s.pdf), 1e-30);
    const double rel_f = std::fabs(f[channel] - s.eval[channel]) / std::max(double(s.eval[channel]), 1e-30);
    if (s.pdf > 1e-3f && s.eval[channel] > 1e-6f) out.inconsistency = std::max(out.inconsistency, std::max(rel_pdf, rel_f));
  }
  return out;
}

// Sidak-corrected per-test significance for `tests` tests at overall level `alpha`.
inline double sidak_threshold(int tests, double alpha = 0.01) { return lab::sidak_significance(alpha, tests); }

}  // namespace glimmer::mftest
