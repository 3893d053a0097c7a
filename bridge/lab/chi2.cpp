// Chi-square goodness-of-fit test of a closure's sample() against its pdf,
// after Mitsuba 3's chi2.py: histogram the sampled directions over the sphere
// (cells refined toward an axis for near-delta lobes), integrate the pdf over
// the same cells adaptively, pool cells with fewer than 5 expected samples, and
// compare the statistic's p-value with a Sidak-corrected significance level.
// The one chi2 of the project: `glimmer lab chi2` and every closure test use it.
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

// Cells over the sphere in polar coordinates (theta, phi) about the binning
// axis: cells uniform in t with theta = pi t^k (k = theta_exponent; k > 1
// refines the cells near the axis for near-delta lobes) and in phi over
// [-pi, pi). theta is measured with atan2 (exact for tiny angles).
struct Grid {
  int theta_bins, phi_bins;
  double exponent;
  Frame binning;  // axis frame in the shading frame's coordinates (z = axis)

  double theta_of_t(double t) const { return M_PI * std::pow(t, exponent); }
  double phi_step() const { return 2.0 * M_PI / phi_bins; }
  int cell(const Vec3 &local) const {
    const Vec3 b = binning.to_local(local);
    const double x = b.x, y = b.y, z = b.z;
    const double theta = std::atan2(std::sqrt(x * x + y * y), z);
    const double t = std::pow(theta / M_PI, 1.0 / exponent);
    const int it = std::clamp(static_cast<int>(t * theta_bins), 0, theta_bins - 1);
    const int ip = std::clamp(static_cast<int>((std::atan2(y, x) + M_PI) / phi_step()), 0, phi_bins - 1);
    return it * phi_bins + ip;
  }
};

// The pdf integrated over cells, in a variable x along theta chosen so the
// Gauss nodes sit where lobes are narrow: for k = 1, cos(theta) = x^3 (nodes
// cluster at the horizon, where grazing lobes squeeze into a thin band); for
// k > 1, x = t (theta = pi t^k, as binned). Rectangles in (x, phi) are
// integrated by 4x4-point Gauss-Legendre and split in four (adaptively) until
// the split changes the estimate by at most the tolerance.
class CellIntegrator {
 public:
  CellIntegrator(const host::ClosureInstance &instance, const GlimmerShadingContext &ctx, const Grid &grid,
                 const Chi2Options &options)
      : instance_(instance), ctx_(ctx), grid_(grid), shading_(detail::shading_frame(ctx)),
        cubic_(grid.exponent == 1.0), max_depth_(std::max(0, options.max_depth)),
        tolerance_(options.integration_tolerance / std::max<double>(1.0, static_cast<double>(options.samples))) {}

  // Integral of the pdf over cell (theta_bin, phi_bin); `uniform_splits` > 0
  // integrates on a uniform grid of that many splits per axis instead.
  double cell(int theta_bin, int phi_bin, int uniform_splits = 0) const {
    const double x0 = x_of_t(double(theta_bin) / grid_.theta_bins), x1 = x_of_t(double(theta_bin + 1) / grid_.theta_bins);
    const double p0 = -M_PI + phi_bin * grid_.phi_step(), p1 = p0 + grid_.phi_step();
    if (uniform_splits > 0) {
      double sum = 0.0;
      for (int i = 0; i < uniform_splits; ++i)
        for (int j = 0; j < uniform_splits; ++j)
          sum += gauss(x0 + (x1 - x0) * i / uniform_splits, x0 + (x1 - x0) * (i + 1) / uniform_splits,
                       p0 + (p1 - p0) * j / uniform_splits, p0 + (p1 - p0) * (j + 1) / uniform_splits);
      return sum;
    }
    return adapt(x0, x1, p0, p1, gauss(x0, x1, p0, p1), 0);
  }

 private:
  double x_of_t(double t) const { return cubic_ ? std::cbrt(std::cos(M_PI * t)) : t; }

  // pdf(theta(x), phi) |d omega / (dx dphi)|.
  double density(double x, double phi) const {
    double theta, jacobian;
    if (cubic_) {
      theta = std::acos(std::clamp(x * x * x, -1.0, 1.0));
      jacobian = 3.0 * x * x;
    } else {
      theta = grid_.theta_of_t(x);
      jacobian = std::sin(theta) * M_PI * grid_.exponent * std::pow(x, grid_.exponent - 1.0);
    }
    if (!(jacobian > 0.0)) return 0.0;
    Spectrum f_cos;
    float pdf = 0.0f;
    const Vec3 wo = shading_.to_world(grid_.binning.to_world(detail::spherical_direction(theta, phi)));
    instance_.eval(ctx_, wo, f_cos, pdf);
    return std::isfinite(pdf) ? static_cast<double>(pdf) * jacobian : 0.0;
  }

  double gauss(double x0, double x1, double p0, double p1) const {
    static constexpr double node[4] = {-0.8611363115940526, -0.3399810435848563, 0.3399810435848563,
                                       0.8611363115940526};
    static constexpr double weight[4] = {0.3478548451374538, 0.6521451548625461, 0.6521451548625461,
                                         0.3478548451374538};
    double sum = 0.0;
    for (int a = 0; a < 4; ++a)
      for (int b = 0; b < 4; ++b)
        sum += weight[a] * weight[b] *
               density(0.5 * (x0 + x1) + 0.5 * (x1 - x0) * node[a], 0.5 * (p0 + p1) + 0.5 * (p1 - p0) * node[b]);
    return sum * 0.25 * std::fabs(x1 - x0) * (p1 - p0);
  }

  double adapt(double x0, double x1, double p0, double p1, double whole, int depth) const {
    const double xm = 0.5 * (x0 + x1), pm = 0.5 * (p0 + p1);
    const double q[4] = {gauss(x0, xm, p0, pm), gauss(xm, x1, p0, pm), gauss(x0, xm, pm, p1), gauss(xm, x1, pm, p1)};
    const double sum = q[0] + q[1] + q[2] + q[3];
    if (depth >= max_depth_ || std::fabs(sum - whole) <= tolerance_) return sum;
    return adapt(x0, xm, p0, pm, q[0], depth + 1) + adapt(xm, x1, p0, pm, q[1], depth + 1) +
           adapt(x0, xm, pm, p1, q[2], depth + 1) + adapt(xm, x1, pm, p1, q[3], depth + 1);
  }

  const host::ClosureInstance &instance_;
  const GlimmerShadingContext &ctx_;
  const Grid &grid_;
  Frame shading_;
  bool cubic_;
  int max_depth_;
  double tolerance_;  // on the pdf integral of a cell (options.integration_tolerance expected samples)
};

std::string describe_cell(const Grid &grid, const Chi2Cell &c) {
  char buffer[256];
  if (c.theta_bin < 0) {
    std::snprintf(buffer, sizeof(buffer), "[pooled: observed %.0f, expected %.2f]", c.observed, c.expected);
  } else {
    const double deg = 180.0 / M_PI;
    std::snprintf(buffer, sizeof(buffer), "[theta %.3g-%.3g deg, phi %.1f-%.1f deg: observed %.0f, expected %.2f]",
                  grid.theta_of_t(double(c.theta_bin) / grid.theta_bins) * deg,
                  grid.theta_of_t(double(c.theta_bin + 1) / grid.theta_bins) * deg,
                  (-M_PI + c.phi_bin * grid.phi_step()) * deg, (-M_PI + (c.phi_bin + 1) * grid.phi_step()) * deg,
                  c.observed, c.expected);
  }
  return buffer;
}

// The binning frame: the shading frame itself for the default axis (phi
// measured from T), else a frame about `axis` (given in shading coordinates).
Frame binning_frame(const Vec3 &axis) {
  const float length = std::sqrt(dot(axis, axis));
  if (!(length > 0.0f) || !std::isfinite(length)) throw std::invalid_argument("chi2: the binning axis must be a non-zero direction");
  const Vec3 n = axis / length;
  if (n.z == 1.0f) return Frame();
  return Frame::from_normal(n);
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
  if (!(options.theta_exponent >= 1.0) || !std::isfinite(options.theta_exponent))
    throw std::invalid_argument("chi2: theta_exponent must be >= 1 (cells refined toward the axis)");
  const Grid grid{std::max(2, options.theta_bins), std::max(1, options.phi_bins), options.theta_exponent,
                  binning_frame(options.axis)};
  const int cell_count = static_cast<int>(requested_cells);
  const Frame frame = detail::shading_frame(ctx);
  const CellIntegrator integrator(instance, ctx, grid, options);

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
      GlimmerSample s = glimmer_blank_sample();
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
    for (int c = r.begin(); c != r.end(); ++c) integral[c] = integrator.cell(c / grid.phi_bins, c % grid.phi_bins);
  });
  // Samples in a cell whose pdf integrated to zero (a lobe the adaptive
  // nodes missed): look again on a fine uniform grid of the cell.
  for (int c = 0; c < cell_count; ++c)
    if (observed[c] > 0.0 && !(integral[c] > 0.0))
      integral[c] = integrator.cell(c / grid.phi_bins, c % grid.phi_bins, 64);

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
