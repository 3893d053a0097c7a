// Numerical stress: eval/sample/albedo/emit over extreme inputs, counting
// every NaN, Inf or negative number a closure hands back.
#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <mutex>

#include "glimmer/sampling.h"
#include "lab/closure_lab.h"
#include "lab/lab_internal.h"

namespace glimmer::lab {

namespace {

// The largest float below 1 (sample() takes numbers in [0, 1)).
constexpr float kOneMinusEpsilon = 0x1.fffffep-1f;

struct Inputs {
  GlimmerShadingContext ctx;
  Vec3 wo;
  float rand3[3];
};

// Builds the inputs of call `index` from (seed, index) alone.
Inputs make_inputs(uint64_t seed, uint64_t index, const GlimmerHostServices *host) {
  uint32_t dim = 0;
  auto u = [&] { return static_cast<float>(random_unit(seed, index, dim++)); };
  auto pick = [&](int n) { return std::min(n - 1, static_cast<int>(u() * static_cast<float>(n))); };

  // Shading frame: usually +z, sometimes random; the tangent sometimes
  // degenerate (zero or parallel to N) to exercise the frame fallback.
  Vec3 N(0, 0, 1);
  if (pick(2) == 1) N = sample_uniform_sphere(u(), u());
  Vec3 T;
  switch (pick(4)) {
    case 0: T = Frame::from_normal(N).s; break;
    case 1: T = normalize(cross(N, sample_uniform_sphere(u(), u()))); break;
    case 2: T = Vec3(0.0f); break;
    default: T = N; break;
  }
  const Frame frame = Frame::from_normal_tangent(N, T);

  Vec3 wi_local;
  switch (pick(9)) {
    case 0: wi_local = Vec3(std::sqrt(1.0f - 1e-12f), 0.0f, 1e-6f); break;  // grazing 1e-6
    case 1: wi_local = Vec3(std::sqrt(1.0f - 1e-6f), 0.0f, 1e-3f); break;   // grazing 1e-3
    case 2: wi_local = Vec3(0, 0, 1); break;                                // exactly normal
    case 3: wi_local = Vec3(1, 0, 0); break;                                // exactly tangent
    case 4: wi_local = Vec3(0, 0, -1); break;                               // straight below
    case 5: wi_local = Vec3(std::sqrt(1.0f - 1e-12f), 0.0f, -1e-6f); break; // just below the horizon
    case 6: {                                                               // anywhere below
      wi_local = sample_uniform_sphere(u(), u());
      wi_local.z = -std::fabs(wi_local.z);
      break;
    }
    default: {
      wi_local = sample_uniform_sphere(u(), u());
      wi_local.z = std::fabs(wi_local.z);
    }
  }
  // Rotate grazing directions around the normal.
  const float phi = kTwoPi * u();
  const float c = std::cos(phi), s = std::sin(phi);
  wi_local = Vec3(c * wi_local.x - s * wi_local.y, s * wi_local.x + c * wi_local.y, wi_local.z);

  Vec3 wo_local;
  switch (pick(8)) {
    case 0: wo_local = Vec3(-wi_local.x, -wi_local.y, wi_local.z); break;  // mirror direction
    case 1: wo_local = -wi_local; break;                                   // straight through
    case 2: wo_local = wi_local; break;                                    // back toward the viewer
    case 3: wo_local = Vec3(0, 0, 1); break;
    case 4: wo_local = Vec3(0, 1, 1e-6f); break;
    case 5: wo_local = Vec3(0, 1, 0); break;
    default: wo_local = sample_uniform_sphere(u(), u());
  }

  Inputs in;
  in.ctx = host::make_local_context(Vec3(0, 0, 1), host);
  in.ctx.N = N;
  in.ctx.Ng = N;
  in.ctx.T = T;
  in.ctx.wi = frame.to_world(normalize(wi_local));
  in.wo = frame.to_world(normalize(wo_local));

  // Footprint: zero (point query), tiny, huge, along one axis at the float range's ends (with the other
  // differential so, a thin footprint of moderate area, e.g. (0, 3e38) x (1e-44, 0)), random, or degenerate
  // (dx = dy).
  auto footprint = [&](float out[2]) {
    switch (pick(6)) {
      case 0: out[0] = out[1] = 0.0f; break;
      case 1: out[0] = 1e-12f; out[1] = -1e-12f; break;
      case 2: out[0] = 1e6f; out[1] = 1e6f; break;
      case 3: {
        const int axis = pick(2);
        out[axis] = (pick(2) == 0 ? 3e38f : 1e-44f) * (pick(2) == 0 ? 1.0f : -1.0f);
        out[1 - axis] = 0.0f;
        break;
      }
      default: {
        const float scale = std::pow(10.0f, -8.0f + 10.0f * u());
        out[0] = (2.0f * u() - 1.0f) * scale;
        out[1] = (2.0f * u() - 1.0f) * scale;
      }
    }
  };
  footprint(in.ctx.duv_dx);
  if (pick(6) == 0) {
    in.ctx.duv_dy[0] = in.ctx.duv_dx[0];
    in.ctx.duv_dy[1] = in.ctx.duv_dx[1];
  } else {
    footprint(in.ctx.duv_dy);
  }
  switch (pick(4)) {
    case 0: in.ctx.uv[0] = u(); in.ctx.uv[1] = u(); break;
    case 1: in.ctx.uv[0] = 1e5f * (2.0f * u() - 1.0f); in.ctx.uv[1] = 1e5f * (2.0f * u() - 1.0f); break;
    case 2: in.ctx.uv[0] = 0.0f; in.ctx.uv[1] = 1.0f; break;
    default: in.ctx.uv[0] = -u(); in.ctx.uv[1] = -u();
  }
  in.ctx.P = Vec3(1e3f * (2.0f * u() - 1.0f), 1e3f * (2.0f * u() - 1.0f), 1e3f * (2.0f * u() - 1.0f));
  const float spreads[4] = {0.0f, 1e-6f, kPi * u(), 10.0f};
  in.ctx.spread_angle = spreads[pick(4)];
  in.ctx.bounce = static_cast<uint32_t>(pick(64));
  in.ctx.glossy_bounce = in.ctx.bounce / 2;
  in.ctx.backfacing = wi_local.z < 0.0f ? 1u : 0u;
  in.ctx.path_seed = static_cast<uint32_t>(random_unit(seed, index, 1000) * 4294967296.0);

  for (float &r : in.rand3) {
    switch (pick(5)) {
      case 0: r = 0.0f; break;
      case 1: r = kOneMinusEpsilon; break;
      case 2: r = 0.5f; break;
      default: r = std::min(u(), kOneMinusEpsilon);
    }
  }
  return in;
}

void classify(float v, uint64_t &nan, uint64_t &inf, uint64_t &negative, bool &bad) {
  if (std::isnan(v)) { ++nan; bad = true; }
  else if (std::isinf(v)) { ++inf; bad = true; }
  else if (v < 0.0f) { ++negative; bad = true; }
}

std::string describe(const host::ClosureInstance &instance, const Inputs &in, const char *what) {
  char buffer[512];
  std::snprintf(buffer, sizeof(buffer),
                "%s: %s at wi=(%g,%g,%g) wo=(%g,%g,%g) N=(%g,%g,%g) T=(%g,%g,%g) rand=(%g,%g,%g) "
                "duv_dx=(%g,%g) duv_dy=(%g,%g) uv=(%g,%g) spread=%g",
                instance.type().name, what, in.ctx.wi.x, in.ctx.wi.y, in.ctx.wi.z, in.wo.x, in.wo.y, in.wo.z,
                in.ctx.N.x, in.ctx.N.y, in.ctx.N.z, in.ctx.T.x, in.ctx.T.y, in.ctx.T.z, in.rand3[0], in.rand3[1],
                in.rand3[2], in.ctx.duv_dx[0], in.ctx.duv_dx[1], in.ctx.duv_dy[0], in.ctx.duv_dy[1], in.ctx.uv[0],
                in.ctx.uv[1], in.ctx.spread_angle);
  return buffer;
}

}  // namespace

StressResult stress(std::span<const host::ClosureInstance *const> instances, const StressOptions &options) {
  StressResult total;
  std::mutex failure_mutex;
  uint64_t first_failure_index = std::numeric_limits<uint64_t>::max();

  for (size_t k = 0; k < instances.size(); ++k) {
    const host::ClosureInstance &instance = *instances[k];
    const uint64_t seed = options.seed * 0x9e3779b97f4a7c15ULL + k;
    tbb::enumerable_thread_specific<StressResult> per_thread;
    detail::for_each_block<char>(options.calls, [&](uint64_t begin, uint64_t end, char &) {
      StressResult &r = per_thread.local();
      for (uint64_t i = begin; i < end; ++i) {
        const Inputs in = make_inputs(seed, i, host::default_host_services());
        bool bad = false;
        const char *what = "";

        float rgb[3], pdf = 0.0f;
        instance.type().eval(instance.handle(), &in.ctx, in.wo, rgb, &pdf);
        for (float v : {rgb[0], rgb[1], rgb[2], pdf}) classify(v, r.eval_nan, r.eval_inf, r.eval_negative, bad);
        if (bad) what = "eval";

        GlimmerSample s{};
        const uint32_t label = instance.sample(in.ctx, in.rand3, s);
        bool sample_bad = false;
        for (float v : {s.eval[0], s.eval[1], s.eval[2], s.pdf, s.roughness, s.eta})
          classify(v, r.sample_nan, r.sample_inf, r.sample_negative, sample_bad);
        if (label != GLIMMER_LABEL_NONE && !detail::is_unit_direction(Vec3(s.wo))) {
          ++r.sample_bad_direction;
          sample_bad = true;
        }
        if (sample_bad && !bad) what = "sample";
        bad = bad || sample_bad;

        if (instance.type().albedo != nullptr || instance.type().emit != nullptr) {
          const Spectrum a = instance.albedo(in.ctx), e = instance.emit(in.ctx);
          bool other_bad = false;
          for (float v : {a.x, a.y, a.z, e.x, e.y, e.z}) other_bad = other_bad || is_invalid_value(v);
          if (other_bad) {
            ++r.other_invalid;
            if (!bad) what = "albedo/emit";
            bad = true;
          }
        }
        ++r.calls;
        if (bad) {
          const uint64_t global_index = k * options.calls + i;
          std::lock_guard<std::mutex> lock(failure_mutex);
          if (global_index < first_failure_index) {
            first_failure_index = global_index;
            total.first_failure = describe(instance, in, what);
          }
        }
      }
    });
    for (const StressResult &r : per_thread) {
      total.calls += r.calls;
      total.eval_nan += r.eval_nan;
      total.eval_inf += r.eval_inf;
      total.eval_negative += r.eval_negative;
      total.sample_nan += r.sample_nan;
      total.sample_inf += r.sample_inf;
      total.sample_negative += r.sample_negative;
      total.sample_bad_direction += r.sample_bad_direction;
      total.other_invalid += r.other_invalid;
    }
  }
  return total;
}

StressResult stress(const host::ClosureInstance &instance, const StressOptions &options) {
  const host::ClosureInstance *list[1] = {&instance};
  return stress(std::span<const host::ClosureInstance *const>(list, 1), options);
}

}  // namespace glimmer::lab
