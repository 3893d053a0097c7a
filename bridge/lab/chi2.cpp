// Chi-square goodness-of-fit test of a closure's sample() against its pdf,
// after Mitsuba 3's chi2.py: histogram the sampled directions over the sphere,
// integrate the pdf over the same cells numerically, pool cells with fewer
// than 5 expected samples, and compare the statistic's p-value with a
// Sidak-corrected significance level.
#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <stdexcept>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <sstream>

#include "lab/closure_lab.h"
#include "lab/lab_internal.h"

namespace glimmer::lab {

// ---- Statistics ------------------------------------------------------------

// Q(a, x) = Gamma(a, x) / Gamma(a): the series of P(a, x) for x < a + 1,
// else the continued fraction of Q evaluated with the modified Lentz method
// (Press et al., Numerical Recipes, sec. 6.2).
double regularized_gamma_q(double a, double x) {
  if (!(a > 0.0) || std::isnan(x)) return std::nan("");
  if (x <= 0.0) return 1.0;
  if (std::isinf(x)) return 0.0;
  const double log_prefix = a * std::log(x) - x - std::lgamma(a);
  if (x < a + 1.0) {
    double term = 1.0 / a, sum = term;
    for (int n = 1; n < 1000000; ++n) {
      term *= x / (a + n);
      sum += term;
      if (std::fabs(term) < std::fabs(sum) * 1e-16) break;
    }
    return std::clamp(1.0 - sum * std::exp(log_prefix), 0.0, 1.0);
  }
  constexpr double tiny = 1e-300;
  double b = x + 1.0 - a, c = 1.0 / tiny, d = 1.0 / b, h = d;
  for (int i = 1; i < 1000000; ++i) {
    const double an = -i * (i - a);
    b += 2.0;
    d = an * d + b;
    if (std::fabs(d) < tiny) d = tiny;
    c = b + an / c;
    if (std::fabs(c) < tiny) c = tiny;
    d = 1.0 / d;
    const double delta = d * c;
    h *= delta;
    if (std::fabs(delta - 1.0) < 1e-16) break;
  }
  return std::clamp(std::exp(log_prefix) * h, 0.0, 1.0);
}

double chi2_survival(double chi2, double dof) { return regularized_gamma_q(0.5 * dof, 0.5 * chi2); }

double sidak_significance(double alpha, int test_count) {
  return 1.0 - std::pow(1.0 - alpha, 1.0 / std::max(1, test_count));
}

// ---- The test ----------------------------------------------------------------

namespace {

struct Grid {
  int theta_bins, phi_bins;
  double theta_step, phi_step;
  int cell(const Vec3 &local) const {
    const double theta = std::acos(std::clamp(static_cast<double>(local.z), -1.0, 1.0));
    const double phi = std::atan2(static_cast<double>(local.y), static_cast<double>(local.x));
    const int t = std::clamp(static_cast<int>(theta / theta_step), 0, theta_bins - 1);
    const int p = std::clamp(static_cast<int>((phi + M_PI) / phi_step), 0, phi_bins - 1);
    return t * phi_bins + p;
  }
};

// Composite Simpson integral of pdf(theta, phi) sin(theta) over one cell with
// n (even) intervals per axis; returns the estimates with n/2 and n intervals.
struct SimpsonPair {
  double coarse, fine;
};
SimpsonPair simpson_cell(const host::ClosureInstance &instance, const GlimmerShadingContext &ctx, const Frame &frame,
                         const Grid &grid, int theta_bin, int phi_bin, int n) {
  const double theta0 = theta_bin * grid.theta_step, phi0 = -M_PI + phi_bin * grid.phi_step;
  const double h_theta = grid.theta_step / n, h_phi = grid.phi_step / n;
  auto weight = [](int i, int count) { return (i == 0 || i == count) ? 1.0 : (i % 2 ? 4.0 : 2.0); };
  double fine = 0.0, coarse = 0.0;
  for (int i = 0; i <= n; ++i) {
    const double theta = theta0 + i * h_theta;
    const double jacobian = std::sin(theta);
    for (int j = 0; j <= n; ++j) {
      const double phi = phi0 + j * h_phi;
      Spectrum f_cos;
      float pdf = 0.0f;
      instance.eval(ctx, frame.to_world(detail::spherical_direction(theta, phi)), f_cos, pdf);
      const double value = (std::isfinite(pdf) ? static_cast<double>(pdf) : 0.0) * jacobian;
      fine += weight(i, n) * weight(j, n) * value;
      if (i % 2 == 0 && j % 2 == 0) coarse += weight(i / 2, n / 2) * weight(j / 2, n / 2) * value;
    }
  }
  fine *= h_theta * h_phi / 9.0;
  coarse *= (2.0 * h_theta) * (2.0 * h_phi) / 9.0;
  return {coarse, fine};
}

// Integral of the pdf over one cell, refined until two successive Simpson
// estimates agree to 1e-4 relative or 1e-3 expected samples absolute.
double integrate_cell(const host::ClosureInstance &instance, const GlimmerShadingContext &ctx, const Frame &frame,
                      const Grid &grid, int theta_bin, int phi_bin, const Chi2Options &options, bool force_finest) {
  const double absolute_tolerance = 1e-3 / std::max<double>(1.0, static_cast<double>(options.samples));
  int n = std::max(2, options.initial_subdivisions & ~1) * 2;
  const int finest = std::max(n, options.max_subdivisions);
  if (force_finest) n = finest;
  for (;;) {
    const SimpsonPair s = simpson_cell(instance, ctx, frame, grid, theta_bin, phi_bin, n);
    if (n >= finest || std::fabs(s.fine - s.coarse) <= std::max(1e-4 * std::fabs(s.fine), absolute_tolerance))
      return s.fine;
    n *= 2;
  }
}

std::string describe_cell(const Grid &grid, const Chi2Cell &c) {
  char buffer[256];
  if (c.theta_bin < 0) {
    std::snprintf(buffer, sizeof(buffer), "[pooled: observed %.0f, expected %.2f]", c.observed, c.expected);
  } else {
    const double deg = 180.0 / M_PI;
    std::snprintf(buffer, sizeof(buffer), "[theta %.1f-%.1f deg, phi %.1f-%.1f deg: observed %.0f, expected %.2f]",
                  c.theta_bin * grid.theta_step * deg, (c.theta_bin + 1) * grid.theta_step * deg,
                  (-M_PI + c.phi_bin * grid.phi_step) * deg, (-M_PI + (c.phi_bin + 1) * grid.phi_step) * deg,
                  c.observed, c.expected);
  }
  return buffer;
}

}  // namespace

Chi2Result chi2_test(const host::ClosureInstance &instance, const GlimmerShadingContext &ctx,
                     const Chi2Options &options) {
  Chi2Result result;
  result.samples = options.samples;
  result.significance = sidak_significance(options.significance, options.test_count);
  // The cell count is computed in 64 bits: two large int bin counts must not wrap past the limit.
  const int64_t requested_cells =
      static_cast<int64_t>(std::max(2, options.theta_bins)) * static_cast<int64_t>(std::max(1, options.phi_bins));
  if (requested_cells > kMaxChi2Cells)
    throw std::invalid_argument("chi2: " + std::to_string(options.theta_bins) + " x " +
                                std::to_string(options.phi_bins) + " bins is more than " +
                                std::to_string(kMaxChi2Cells) + " cells");
  const Grid grid{std::max(2, options.theta_bins), std::max(1, options.phi_bins),
                  M_PI / std::max(2, options.theta_bins), 2.0 * M_PI / std::max(1, options.phi_bins)};
  const int cell_count = static_cast<int>(requested_cells);
  const Frame frame = detail::shading_frame(ctx);

  // 1. Histogram of sampled directions (integer counts: order-independent).
  struct Counts {
    std::vector<uint32_t> histogram;
    uint64_t singular = 0, invalid = 0, histogrammed = 0;
  };
  tbb::enumerable_thread_specific<Counts> per_thread([&] {
    Counts c;
    c.histogram.assign(cell_count, 0u);
    return c;
  });
  detail::for_each_block<char>(options.samples, [&](uint64_t begin, uint64_t end, char &) {
    Counts &counts = per_thread.local();
    for (uint64_t i = begin; i < end; ++i) {
      GlimmerSample s;
      const uint32_t label = detail::sample_at(instance, ctx, options.seed, i, s);
      if (label == GLIMMER_LABEL_NONE) continue;
      if (label & GLIMMER_LABEL_SINGULAR) {
        ++counts.singular;
        continue;
      }
      const Vec3 wo(s.wo);
      if (!detail::is_unit_direction(wo)) {
        ++counts.invalid;
        continue;
      }
      ++counts.histogram[grid.cell(frame.to_local(wo))];
      ++counts.histogrammed;
    }
  });
  std::vector<double> observed(cell_count, 0.0);
  uint64_t histogrammed = 0;
  for (const Counts &c : per_thread) {
    for (int i = 0; i < cell_count; ++i) observed[i] += c.histogram[i];
    result.singular_count += c.singular;
    result.invalid_count += c.invalid;
    histogrammed += c.histogrammed;
  }

  // 2. Expected counts from the pdf, integrated per cell.
  std::vector<double> integral(cell_count, 0.0);
  tbb::parallel_for(tbb::blocked_range<int>(0, cell_count, 16), [&](const tbb::blocked_range<int> &r) {
    for (int c = r.begin(); c != r.end(); ++c)
      integral[c] = integrate_cell(instance, ctx, frame, grid, c / grid.phi_bins, c % grid.phi_bins, options, false);
  });
  // Samples in a cell whose pdf integrated to zero: look again at the finest level.
  for (int c = 0; c < cell_count; ++c)
    if (observed[c] > 0.0 && !(integral[c] > 0.0))
      integral[c] = integrate_cell(instance, ctx, frame, grid, c / grid.phi_bins, c % grid.phi_bins, options, true);

  const double n = static_cast<double>(options.samples);
  std::vector<double> expected(cell_count);
  for (int c = 0; c < cell_count; ++c) {
    result.pdf_integral += integral[c];
    expected[c] = integral[c] * n;
  }
  result.sampled_fraction = n > 0.0 ? static_cast<double>(histogrammed) / n : 0.0;

  // 3. Pool cells with small expected counts (in increasing order of expected
  // count, as Mitsuba does) and accumulate the statistic.
  std::vector<int> order(cell_count);
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return expected[a] < expected[b]; });
  std::vector<Chi2Cell> cells;
  Chi2Cell pool{-1, -1, 0.0, 0.0, 0.0};
  int last_pool = -1;
  for (int c : order) {
    if (!(expected[c] > 0.0)) {
      result.samples_in_zero_pdf_cells += static_cast<uint64_t>(observed[c]);
      continue;
    }
    if (expected[c] < options.min_expected) {
      pool.observed += observed[c];
      pool.expected += expected[c];
      ++result.pooled_cells;
      if (pool.expected >= options.min_expected) {
        cells.push_back(pool);
        last_pool = static_cast<int>(cells.size()) - 1;
        pool = Chi2Cell{-1, -1, 0.0, 0.0, 0.0};
      }
    } else {
      cells.push_back(Chi2Cell{c / grid.phi_bins, c % grid.phi_bins, observed[c], expected[c], 0.0});
    }
  }
  if (pool.expected > 0.0) {
    if (last_pool >= 0) {
      cells[last_pool].observed += pool.observed;
      cells[last_pool].expected += pool.expected;
    } else {
      cells.push_back(pool);
    }
  }
  for (Chi2Cell &c : cells) {
    c.contribution = (c.observed - c.expected) * (c.observed - c.expected) / c.expected;
    result.chi2 += c.contribution;
  }
  result.cells = static_cast<int>(cells.size());
  result.dof = result.cells - 1;

  std::vector<Chi2Cell> worst = cells;
  const size_t keep = std::min<size_t>(8, worst.size());
  std::partial_sort(worst.begin(), worst.begin() + keep, worst.end(),
                    [](const Chi2Cell &a, const Chi2Cell &b) { return a.contribution > b.contribution; });
  worst.resize(keep);
  result.worst_cells = worst;

  // 4. Verdict.
  std::ostringstream msg;
  bool ok = true;
  if (result.dof < 1) {
    ok = false;
    msg << "fewer than 2 cells with expected counts (nothing to test: singular or empty sampler). ";
    result.p_value = 0.0;
  } else {
    result.p_value = chi2_survival(result.chi2, result.dof);
  }
  if (result.samples_in_zero_pdf_cells > 0) {
    ok = false;
    msg << result.samples_in_zero_pdf_cells << " samples landed in cells where the pdf integrates to 0. ";
  }
  if (result.invalid_count > 0) {
    ok = false;
    msg << result.invalid_count << " samples had a non-finite or non-unit direction. ";
  }
  if (result.pdf_integral > 1.0 + options.pdf_integral_tolerance) {
    ok = false;
    msg << "the pdf integrates to " << result.pdf_integral << " > 1 over the sphere. ";
  }
  // The sampler's non-absorbed fraction must match the pdf's total mass (the
  // chi2 statistic alone hardly sees a wrong normalisation): binomial noise
  // (5 sigma) plus the quadrature allowance.
  const double mass = std::clamp(result.pdf_integral, 0.0, 1.0);
  const double sigma = std::sqrt(std::max(mass * (1.0 - mass), 1.0 / std::max(n, 1.0)) / std::max(n, 1.0));
  if (std::fabs(result.sampled_fraction - result.pdf_integral) > 5.0 * sigma + options.pdf_integral_tolerance) {
    ok = false;
    msg << "the sampled fraction " << result.sampled_fraction << " does not match the pdf integral "
        << result.pdf_integral << " (5 sigma = " << 5.0 * sigma << "). ";
  }
  if (!(result.p_value >= result.significance)) ok = false;
  result.passed = ok;
  std::ostringstream head;
  head << (ok ? "passed" : "FAILED") << ": chi2 = " << result.chi2 << ", dof = " << result.dof
       << ", p = " << result.p_value << " (Sidak-corrected alpha = " << result.significance << ", "
       << options.test_count << " test(s)); pdf integral " << result.pdf_integral << ", sampled fraction "
       << result.sampled_fraction << "; " << result.cells << " cells (" << result.pooled_cells << " pooled). ";
  std::string text = head.str() + msg.str();
  if (!worst.empty()) {
    text += "Worst cells:";
    for (const auto &c : worst) {
      text += ' ';
      text += describe_cell(grid, c);
    }
  }
  result.message = text;
  return result;
}

}  // namespace glimmer::lab
