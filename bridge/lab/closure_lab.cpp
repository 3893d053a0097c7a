// Closure laboratory: random numbers, white furnace, eval/pdf consistency and
// reciprocity. (chi2.cpp, stress.cpp, bench.cpp and plot.cpp hold the rest.)
#include "lab/closure_lab.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "glimmer/sampling.h"
#include "lab/lab_internal.h"

namespace glimmer::lab {

namespace {

// splitmix64 finalizer (Steele, Lea & Flood 2014): a strong 64-bit mix.
constexpr uint64_t mix64(uint64_t z) {
  z += 0x9e3779b97f4a7c15ULL;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

constexpr uint64_t random_word(uint64_t seed, uint64_t index, uint32_t dimension) {
  return mix64(mix64(mix64(seed) ^ index) + 0x632be59bd9b4e019ULL * (dimension + 1));
}

}  // namespace

void sample_random3(uint64_t seed, uint64_t index, float out[3]) {
  for (uint32_t d = 0; d < 3; ++d)
    out[d] = static_cast<float>(random_word(seed, index, d) >> 40) * (1.0f / 16777216.0f);
}

double random_unit(uint64_t seed, uint64_t index, uint32_t dimension) {
  return static_cast<double>(random_word(seed, index, dimension) >> 11) * (1.0 / 9007199254740992.0);
}

double relative_difference(double a, double b) {
  const double scale = std::max(std::fabs(a), std::fabs(b));
  return scale > 0.0 ? std::fabs(a - b) / scale : 0.0;
}

// ---- White furnace ---------------------------------------------------------

FurnaceResult furnace(const host::ClosureInstance &instance, const GlimmerShadingContext &ctx, uint64_t samples,
                      uint64_t seed) {
  struct Accumulator {
    double sum[3] = {0, 0, 0}, sum_sq[3] = {0, 0, 0};
    uint64_t absorbed = 0, invalid = 0, singular = 0, transmission = 0;
  };
  const auto partial = detail::for_each_block<Accumulator>(samples, [&](uint64_t begin, uint64_t end, Accumulator &acc) {
    for (uint64_t i = begin; i < end; ++i) {
      GlimmerSample s = glimmer_blank_sample();
      const uint32_t label = detail::sample_at(instance, ctx, seed, i, s);
      if (label == GLIMMER_LABEL_NONE) {
        ++acc.absorbed;
        continue;
      }
      if (detail::spectrum_invalid(s.eval) || is_invalid_value(s.pdf) || !(s.pdf > 0.0f) ||
          !detail::is_unit_direction(Vec3(s.wo))) {
        ++acc.invalid;
        continue;
      }
      const bool singular = (label & GLIMMER_LABEL_SINGULAR) != 0;
      acc.singular += singular;
      acc.transmission += (label & GLIMMER_LABEL_TRANSMIT) != 0;
      const double inv_pdf = singular ? 1.0 : 1.0 / static_cast<double>(s.pdf);
      for (int c = 0; c < 3; ++c) {
        const double w = static_cast<double>(s.eval[c]) * inv_pdf;
        acc.sum[c] += w;
        acc.sum_sq[c] += w * w;
      }
    }
  });

  FurnaceResult result;
  result.samples = samples;
  double sum[3] = {0, 0, 0}, sum_sq[3] = {0, 0, 0};
  for (const auto &a : partial) {
    for (int c = 0; c < 3; ++c) {
      sum[c] += a.sum[c];
      sum_sq[c] += a.sum_sq[c];
    }
    result.absorbed_count += a.absorbed;
    result.invalid_count += a.invalid;
    result.singular_count += a.singular;
    result.transmission_count += a.transmission;
  }
  if (samples == 0) return result;
  const double n = static_cast<double>(samples);
  for (int c = 0; c < 3; ++c) {
    const double mean = sum[c] / n;
    const double variance = samples > 1 ? std::max(0.0, (sum_sq[c] - n * mean * mean) / (n - 1.0)) : 0.0;
    result.albedo[c] = static_cast<float>(mean);
    result.standard_error[c] = static_cast<float>(std::sqrt(variance / n));
  }
  return result;
}

Spectrum albedo_quadrature(const host::ClosureInstance &instance, const GlimmerShadingContext &ctx, int theta_steps,
                           int phi_steps) {
  const int nt = std::max(2, theta_steps + (theta_steps & 1)), np = std::max(2, phi_steps + (phi_steps & 1));
  const double h_theta = M_PI / nt, h_phi = 2.0 * M_PI / np;
  const Frame frame = detail::shading_frame(ctx);
  auto weight = [](int i, int n) { return (i == 0 || i == n) ? 1.0 : (i % 2 ? 4.0 : 2.0); };
  // One partial sum per theta row, added in row order (deterministic).
  std::vector<std::array<double, 3>> rows(nt + 1);
  tbb::parallel_for(tbb::blocked_range<int>(0, nt + 1), [&](const tbb::blocked_range<int> &r) {
    for (int i = r.begin(); i != r.end(); ++i) {
      const double theta = i * h_theta, jacobian = std::sin(theta);
      std::array<double, 3> sum{0.0, 0.0, 0.0};
      for (int j = 0; j <= np; ++j) {
        Spectrum f_cos;
        float pdf = 0.0f;
        instance.eval(ctx, frame.to_world(detail::spherical_direction(theta, -M_PI + j * h_phi)), f_cos, pdf);
        for (int c = 0; c < 3; ++c)
          if (std::isfinite(f_cos[c])) sum[c] += weight(j, np) * f_cos[c];
      }
      for (int c = 0; c < 3; ++c) rows[i][c] = weight(i, nt) * jacobian * sum[c];
    }
  });
  Spectrum result;
  for (int c = 0; c < 3; ++c) {
    double total = 0.0;
    for (const auto &row : rows) total += row[c];
    result[c] = static_cast<float>(total * h_theta * h_phi / 9.0);
  }
  return result;
}

// ---- eval/pdf consistency ----------------------------------------------------

ConsistencyResult consistency(const host::ClosureInstance &instance, const GlimmerShadingContext &ctx,
                              uint64_t samples, uint64_t seed, double tolerance) {
  struct Accumulator {
    uint64_t checked = 0, mismatches = 0;
    double max_eval = 0.0, max_pdf = 0.0, worst = -1.0;
    Vec3 worst_wo{0.0f};
  };
  const auto partial = detail::for_each_block<Accumulator>(samples, [&](uint64_t begin, uint64_t end, Accumulator &acc) {
    for (uint64_t i = begin; i < end; ++i) {
      GlimmerSample s = glimmer_blank_sample();
      const uint32_t label = detail::sample_at(instance, ctx, seed, i, s);
      if (label == GLIMMER_LABEL_NONE || (label & GLIMMER_LABEL_SINGULAR)) continue;
      Spectrum f_cos;
      float pdf = 0.0f;
      instance.eval(ctx, Vec3(s.wo), f_cos, pdf);
      ++acc.checked;
      double eval_difference = 0.0;
      for (int c = 0; c < 3; ++c)
        eval_difference = std::max(eval_difference, relative_difference(s.eval[c], f_cos[c]));
      // NaN never compares greater: treat it as a total mismatch.
      if (std::isnan(eval_difference)) eval_difference = 1.0;
      double pdf_difference = relative_difference(s.pdf, pdf);
      if (std::isnan(pdf_difference)) pdf_difference = 1.0;
      acc.max_eval = std::max(acc.max_eval, eval_difference);
      acc.max_pdf = std::max(acc.max_pdf, pdf_difference);
      const double worst = std::max(eval_difference, pdf_difference);
      if (worst > tolerance) ++acc.mismatches;
      if (worst > acc.worst) {
        acc.worst = worst;
        acc.worst_wo = Vec3(s.wo);
      }
    }
  });
  ConsistencyResult result;
  result.samples = samples;
  double worst = -1.0;
  for (const auto &a : partial) {
    result.checked += a.checked;
    result.mismatches += a.mismatches;
    result.max_relative_eval_difference = std::max(result.max_relative_eval_difference, a.max_eval);
    result.max_relative_pdf_difference = std::max(result.max_relative_pdf_difference, a.max_pdf);
    if (a.worst > worst) {
      worst = a.worst;
      result.worst_wo = a.worst_wo;
    }
  }
  return result;
}

// ---- Reciprocity -------------------------------------------------------------

ReciprocityResult reciprocity(const host::ClosureInstance &instance, const ContextBuilder &builder,
                              const ReciprocityOptions &options) {
  struct Accumulator {
    uint64_t compared = 0, failures = 0;
    double max_error = -1.0;
    Vec3 worst_wi{0.0f}, worst_wo{0.0f};
  };
  // Directions are drawn in the local frame of the context built for +z and
  // mapped to world space with it.
  const Frame frame = detail::shading_frame(builder(Vec3(0, 0, 1)));
  const auto partial = detail::for_each_block<Accumulator>(options.pairs, [&](uint64_t begin, uint64_t end,
                                                                                Accumulator &acc) {
    for (uint64_t i = begin; i < end; ++i) {
      // wi uniform over the upper hemisphere, wo over the upper hemisphere or
      // the whole sphere.
      const float u[4] = {static_cast<float>(random_unit(options.seed, i, 0)),
                          static_cast<float>(random_unit(options.seed, i, 1)),
                          static_cast<float>(random_unit(options.seed, i, 2)),
                          static_cast<float>(random_unit(options.seed, i, 3))};
      Vec3 wi_local = sample_uniform_sphere(u[0], u[1]);
      wi_local.z = std::fabs(wi_local.z);
      Vec3 wo_local = sample_uniform_sphere(u[2], u[3]);
      if (!options.transmission) wo_local.z = std::fabs(wo_local.z);
      if (std::fabs(wi_local.z) < options.min_abs_cos || std::fabs(wo_local.z) < options.min_abs_cos) continue;
      const Vec3 wi = frame.to_world(wi_local), wo = frame.to_world(wo_local);

      Spectrum forward, backward;
      float pdf_unused = 0.0f;
      instance.eval(builder(wi), wo, forward, pdf_unused);
      instance.eval(builder(wo), wi, backward, pdf_unused);
      const double eta_wi = wi_local.z > 0.0f ? 1.0 : options.eta;
      const double eta_wo = wo_local.z > 0.0f ? 1.0 : options.eta;
      double error = 0.0;
      bool any = false;
      for (int c = 0; c < 3; ++c) {
        const double f_forward = forward[c] / std::fabs(wo_local.z) / (eta_wi * eta_wi);
        const double f_backward = backward[c] / std::fabs(wi_local.z) / (eta_wo * eta_wo);
        any = any || f_forward != 0.0 || f_backward != 0.0;
        double e = relative_difference(f_forward, f_backward);
        if (std::isnan(e)) e = 1.0;
        error = std::max(error, e);
      }
      if (!any) continue;
      ++acc.compared;
      if (error > options.tolerance) ++acc.failures;
      if (error > acc.max_error) {
        acc.max_error = error;
        acc.worst_wi = wi;
        acc.worst_wo = wo;
      }
    }
  });
  ReciprocityResult result;
  result.pairs = options.pairs;
  double worst = -1.0;
  for (const auto &a : partial) {
    result.compared += a.compared;
    result.failures += a.failures;
    if (a.max_error > worst) {
      worst = a.max_error;
      result.worst_wi = a.worst_wi;
      result.worst_wo = a.worst_wo;
    }
  }
  result.max_relative_error = std::max(0.0, worst);
  return result;
}

ReciprocityResult reciprocity(const host::ClosureInstance &instance, const ReciprocityOptions &options) {
  return reciprocity(instance, [](const Vec3 &wi) { return host::make_local_context(wi); }, options);
}

}  // namespace glimmer::lab
