// C++ side of a closure: write a small class, register it with
// GLIMMER_REGISTER_CLOSURE, and ClosureAdapter produces the C ABI entry points.
//
// A closure class provides (see plugin/closures/diffuse.cpp for the shortest example):
//   static constexpr const char *kName, *kDoc;  static constexpr uint32_t kFlags;
//   static std::span<const GlimmerParamSpec> params();
//   static std::unique_ptr<T> create(const ParamReader &p);    // throws ParamError
//   LocalEval eval(const ShadingPoint &sp, const Vec3 &wo_local) const;
//   bool sample(const ShadingPoint &sp, const Vec3 &rand, LocalSample &out) const;
// and optionally
//   void prepare(const GlimmerHostServices *host);               // lazy tables; throws on failure
//   Spectrum albedo(const ShadingPoint &sp) const;
//   Spectrum emit(const ShadingPoint &sp) const;                 // with GLIMMER_CLOSURE_EMISSIVE
//   LocalEval eval_exit(const ShadingPoint &sp, const GlimmerExitState &state, const Vec3 &w_local) const;
//                                          // ABI 2.8: the last scatter of a sample that set LocalSample::exit_state
// Directions handed to eval/sample are in the local shading frame (z = N,
// x = tangent; for GLIMMER_CLOSURE_TRANSMISSIVE closures z = the outward
// normal, see LocalFrame); the adapter converts to and from world space.
// Parameters declared with GLIMMER_PARAM_VARYING may change per shading point
// (textures): eval/sample/albedo read them with sp.param_float(index, constant)
// / sp.param_color, index from ParamReader::index at create().
#pragma once

#include <atomic>
#include <concepts>
#include <cstdio>
#include <cstring>
#include <exception>
#include <limits>
#include <memory>
#include <new>
#include <span>
#include <type_traits>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "core/params.h"
#include "glimmer/closure_abi.h"
#include "glimmer/math.h"
#include "glimmer/rng.h"

namespace glimmer::plugin {

// The local frame of a closure. The host hands N turned toward wi and says with
// `backfacing` which medium wi is in (closure_abi.h, ABI 2.3). Reflection
// closures work in z = N. Transmissive closures work in the interface's own
// frame, z = the outward (front-face) normal, N turned back when backfacing: wi.z < 0
// exactly when wi is inside (so eta = backfacing ? 1 / ior : ior), and both media
// share the tangent plane's x and y.
enum class LocalFrame { TowardWi, Interface };

struct ShadingPoint {
  const GlimmerShadingContext *ctx;
  Frame frame;  // z = N (Interface: the outward normal), x = T
  Vec3 wi;      // local, toward the viewer
  std::span<const GlimmerParamSpec> schema;  // the closure's parameters (ranges of the varying values)

  explicit ShadingPoint(const GlimmerShadingContext *c, std::span<const GlimmerParamSpec> s = {},
                        LocalFrame kind = LocalFrame::TowardWi)
      : ctx(c), frame(Frame::from_normal_tangent(frame_normal(*c, kind), Vec3(c->T))), wi(frame.to_local(Vec3(c->wi))),
        schema(s) {}

  // Built for ABI <= 2.2 (test fixtures), the host hands transmissive closures the outward N itself.
  static Vec3 frame_normal(const GlimmerShadingContext &c, LocalFrame kind) {
#if GLIMMER_ABI_MINOR >= 3
    return kind == LocalFrame::Interface && c.backfacing ? -Vec3(c.N) : Vec3(c.N);
#else
    (void)kind;
    return Vec3(c.N);
#endif
  }
  // False where wi is below the N the host handed (a bent shading normal): a
  // transmissive closure scatters nothing there (as Cycles' glass).
  bool wi_above_n() const {
#if GLIMMER_ABI_MINOR >= 3
    return dot(Vec3(ctx->wi), Vec3(ctx->N)) > 0.0f;
#else
    return true;
#endif
  }

  // The seed of a closure's own random numbers here (stochastic walks, an exit lobe's numbers): a pure function of
  // the path's seed and v (the sampler's numbers for sample(), or wo for an estimate in eval()), so images are the
  // same for any thread count and tile size.
  uint32_t seed_for(const Vec3 &v) const {
    return hash_u32x4(ctx->path_seed, std::bit_cast<uint32_t>(v.x), std::bit_cast<uint32_t>(v.y),
                      std::bit_cast<uint32_t>(v.z));
  }

  // True when the host lists per-point values for any varying parameter (ABI 2.1 contexts).
  bool varies() const {
#if GLIMMER_ABI_MINOR >= 1
    return GLIMMER_HAS_FIELD(ctx->struct_size, GlimmerShadingContext, varying) && ctx->varying_count > 0 &&
           ctx->varying != nullptr;
#else
    return false;
#endif
  }

  // True when the host says no light strategy is MIS-combined with this vertex's BSDF samples (ABI 2.4
  // GLIMMER_SAMPLING_UNCOMBINED): a closure may then sample with the strategy that is best alone.
  bool uncombined() const {
#if GLIMMER_ABI_MINOR >= 4
    return GLIMMER_HAS_FIELD(ctx->struct_size, GlimmerShadingContext, sampling_flags) &&
           (ctx->sampling_flags & GLIMMER_SAMPLING_UNCOMBINED) != 0;
#else
    return false;
#endif
  }

  // The value of schema parameter `param` at this point: the host's per-point
  // value when it lists one (clamped to the spec's range; a non-finite value
  // keeps the constant), else `constant` (the value given at create()).
  float param_float(uint32_t param, float constant) const {
    const GlimmerVaryingValue *v = find_varying(param);
    return v ? clamp_to_spec(param, v->value[0], constant) : constant;
  }
  Spectrum param_color(uint32_t param, const Spectrum &constant) const {
    const GlimmerVaryingValue *v = find_varying(param);
    if (!v) return constant;
    return {clamp_to_spec(param, v->value[0], constant.x), clamp_to_spec(param, v->value[1], constant.y),
            clamp_to_spec(param, v->value[2], constant.z)};
  }

 private:
  const GlimmerVaryingValue *find_varying(uint32_t param) const {
#if GLIMMER_ABI_MINOR >= 1
    if (!varies() || param >= schema.size() || !(schema[param].flags & GLIMMER_PARAM_VARYING)) return nullptr;
    for (uint32_t i = 0; i < ctx->varying_count; ++i)
      if (ctx->varying[i].param == param) return &ctx->varying[i];
#else
    (void)param;
#endif
    return nullptr;
  }
  float clamp_to_spec(uint32_t param, float v, float constant) const {
    if (!std::isfinite(v)) return constant;
    return std::min(std::max(v, schema[param].min_value), schema[param].max_value);
  }
};

struct LocalEval {
  Spectrum f_cos{0.0f};  // f * |cos(wo)|
  float pdf = 0.0f;
};

struct LocalSample {
  Vec3 wo;               // local
  Spectrum f_cos{0.0f};  // f * |cos(wo)| (singular: delta weight)
  float pdf = 0.0f;
  float roughness = 0.0f;
  float eta = 1.0f;
  uint32_t label = GLIMMER_LABEL_NONE;
  // ABI 2.3: the path continues from `origin` (world space, offset by the host along origin_Ng toward wo).
  bool moved = false;
  Vec3 origin{0.0f}, origin_Ng{0.0f};
  // ABI 2.4: a moved sample drawn from an exit lobe (glimmer/exit_lobe.h) about lobe_axis (world space).
  bool exit_lobe = false;
  Vec3 lobe_axis{0.0f};
  float lobe_sharpness = 0.0f;
#if GLIMMER_ABI_MINOR >= 7
  // ABI 2.7: the host's buffer for an exit lobe mixture (NULL: the host does not take one). A closure that
  // writes it (world space, every lobe leaving from `origin`, restricted to origin_Ng) sets exit_mixture.
  GlimmerExitMixture *mixture_out = nullptr;
  bool exit_mixture = false;
#endif
#if GLIMMER_ABI_MINOR >= 8
  // ABI 2.8: the host's buffer for an exit state (NULL: the host does not take one). A closure that writes it (a
  // singular sample that is not moved) sets exit_state; the host then calls the closure's eval_exit with it.
  GlimmerExitState *state_out = nullptr;
  bool exit_state = false;
#endif
};

// The number of fields of aggregate T (T{f1, .., fn} well-formed for n of them, each from a value of any type).
namespace detail {
struct AnyField {
  template <typename U>
  operator U() const;  // NOLINT: implicit by design (declared only, for the requires-expression)
};
template <typename T, typename... Fields>
consteval std::size_t aggregate_field_count() {
  if constexpr (requires { T{Fields{}..., AnyField{}}; })
    return aggregate_field_count<T, Fields..., AnyField>();
  else
    return sizeof...(Fields);
}
}  // namespace detail

// LocalSample{}'s values, written field by field into a LocalSample that was not initialised (the adapter's sample
// wrapper where the closure asks for it, WritesSampleDefaults; session 33): GCC clears a LocalSample{} (120 bytes,
// nearly all zeros) by a `rep stos`, whose start-up costs tens of cycles on every sample; these are a dozen stores.
// Every field is written, so a closure that leaves one unwritten hands the wrapper LocalSample{}'s value, as before.
// A new field must be added here (the static_assert).
[[gnu::always_inline]] inline void write_local_sample_defaults(LocalSample &s) {
  static_assert(std::is_aggregate_v<LocalSample> && std::is_trivially_destructible_v<LocalSample>,
                "the wrapper's storage holds a LocalSample without a constructor call (an implicit-lifetime type)");
  static_assert(detail::aggregate_field_count<LocalSample>() ==
                    12 + (GLIMMER_ABI_MINOR >= 7 ? 2 : 0) + (GLIMMER_ABI_MINOR >= 8 ? 2 : 0),
                "a new LocalSample field needs its default here");
  s.wo = Vec3(0.0f);
  s.f_cos = Spectrum(0.0f);
  s.pdf = 0.0f;
  s.roughness = 0.0f;
  s.eta = 1.0f;
  s.label = GLIMMER_LABEL_NONE;
  s.moved = false;
  s.origin = Vec3(0.0f);
  s.origin_Ng = Vec3(0.0f);
  s.exit_lobe = false;
  s.lobe_axis = Vec3(0.0f);
  s.lobe_sharpness = 0.0f;
#if GLIMMER_ABI_MINOR >= 7
  s.mixture_out = nullptr;
  s.exit_mixture = false;
#endif
#if GLIMMER_ABI_MINOR >= 8
  s.state_out = nullptr;
  s.exit_state = false;
#endif
}

// Keeps only finite, non-negative values: a closure must never hand NaN/Inf or
// negative numbers to the host. Finite and > 0 is 0 < v < inf (NaN fails both), taken as SSE compare masks where
// the target has SSE2 (session 43, issue 10: a glint's f is 0 or not by the particles it counts, which no branch
// predictor follows; the branches of the scalar form mispredicted there); the same values. (The ordered compares
// raise the invalid flag on a quiet NaN, which isfinite did not: only a host that traps FP exceptions would see it.)
#if defined(__SSE2__)
inline __m128 sanitize_lanes(__m128 v) {
  const __m128 ok = _mm_and_ps(_mm_cmpgt_ps(v, _mm_setzero_ps()),
                               _mm_cmplt_ps(v, _mm_set1_ps(std::numeric_limits<float>::infinity())));
  return _mm_and_ps(ok, v);
}
inline Spectrum sanitize(const Spectrum &s) {
  alignas(16) float r[4];
  _mm_store_ps(r, sanitize_lanes(_mm_setr_ps(s.x, s.y, s.z, 0.0f)));
  return {r[0], r[1], r[2]};
}
inline float sanitize(float v) { return _mm_cvtss_f32(sanitize_lanes(_mm_set_ss(v))); }
#else
inline Spectrum sanitize(const Spectrum &s) {
  auto fix = [](float v) { return (std::isfinite(v) && v > 0.0f) ? v : 0.0f; };
  return {fix(s.x), fix(s.y), fix(s.z)};
}
inline float sanitize(float v) { return (std::isfinite(v) && v > 0.0f) ? v : 0.0f; }
#endif

inline void write_error(char *error, size_t size, const char *message) {
  if (error != nullptr && size > 0) std::snprintf(error, size, "%s", message);
}

template <typename T>
concept HasPrepare = requires(T &t, const GlimmerHostServices *h) { t.prepare(h); };
template <typename T>
concept HasAlbedo = requires(const T &t, const ShadingPoint &sp) { t.albedo(sp); };
// A reflection closure whose albedo does not depend on the shading point and is sanitized once (at create):
// `const Spectrum &sanitized_albedo() const`. The adapter then builds no ShadingPoint (its frame) and sanitizes
// nothing per call (glint, session 30: 62 -> ~8 instructions per albedo call).
template <typename T>
concept HasSanitizedConstantAlbedo = (T::kFlags & GLIMMER_CLOSURE_TRANSMISSIVE) == 0 && requires(const T &t) {
  { t.sanitized_albedo() } -> std::same_as<const Spectrum &>;
};
template <typename T>
concept HasEmit = requires(const T &t, const ShadingPoint &sp) { t.emit(sp); };
#if GLIMMER_ABI_MINOR >= 8
template <typename T>
concept HasEvalExit = requires(const T &t, const ShadingPoint &sp, const GlimmerExitState &st, const Vec3 &w) {
  t.eval_exit(sp, st, w);
};
#endif

// A closure whose adapter calls clear() out of line (ClosureAdapter::kClearOutOfLine).
template <typename T>
concept ClearsOutOfLine = T::kAdapterClearOutOfLine;
// A closure whose adapter writes LocalSample{}'s values by stores (write_local_sample_defaults) instead of
// value-initialising the wrapper's LocalSample: one whose sample() keeps it in memory (glint hands out.pdf to an
// out-of-line eval). Where sample() inlines whole, GCC keeps the fields in registers instead, which the storage of
// write_local_sample_defaults would prevent (DiffuseClosure: a 128-byte larger frame, loads and stores).
template <typename T>
concept WritesSampleDefaults = T::kAdapterSampleDefaultsByStores;

// The shading point closure class T sees: its schema and local frame
// (LocalFrame::Interface for GLIMMER_CLOSURE_TRANSMISSIVE closures).
template <typename T>
ShadingPoint shading_point_for(const GlimmerShadingContext *ctx) {
  constexpr bool transmissive = (T::kFlags & GLIMMER_CLOSURE_TRANSMISSIVE) != 0;
  return ShadingPoint(ctx, T::params(), transmissive ? LocalFrame::Interface : LocalFrame::TowardWi);
}

template <typename T>
struct ClosureAdapter {
  static const T &self(const GlimmerInstance *inst) { return *reinterpret_cast<const T *>(inst); }

  static constexpr bool kTransmissive = (T::kFlags & GLIMMER_CLOSURE_TRANSMISSIVE) != 0;
  static ShadingPoint shading_point(const GlimmerShadingContext *ctx) { return shading_point_for<T>(ctx); }
  // Whether the closure scatters at all here (transmissive: not with wi below N).
  static bool scatters(const ShadingPoint &sp) { return !kTransmissive || sp.wi_above_n(); }

  // The C entry points: noexcept, every exception stops at this boundary.
  static int create(const GlimmerParamValue *values, uint32_t count, const GlimmerHostServices *,
                    GlimmerInstance **out, char *error, size_t error_size) noexcept {
    try {
      const auto schema = T::params();
      ParamReader reader(T::kName, schema, std::span<const GlimmerParamValue>(values, values ? count : 0));
      std::unique_ptr<T> instance = T::create(reader);
      *out = reinterpret_cast<GlimmerInstance *>(instance.release());
      return 1;
    } catch (const std::exception &e) {
      write_error(error, error_size, e.what());
    } catch (...) {
      write_error(error, error_size, "unknown error while creating closure");
    }
    *out = nullptr;
    return 0;
  }

  static int prepare(GlimmerInstance *inst, const GlimmerHostServices *host, char *error,
                     size_t error_size) noexcept {
    if constexpr (HasPrepare<T>) {
      try {
        reinterpret_cast<T *>(inst)->prepare(host);
      } catch (const std::exception &e) {
        write_error(error, error_size, e.what());
        return 0;
      } catch (...) {
        write_error(error, error_size, "unknown error while preparing closure");
        return 0;
      }
    }
    return 1;
  }

  static void destroy(GlimmerInstance *inst) noexcept { delete reinterpret_cast<T *>(inst); }

  static void eval(const GlimmerInstance *inst, const GlimmerShadingContext *ctx, GlimmerVec3 wo,
                   float out_eval[3], float *out_pdf) noexcept {
    LocalEval e;
    try {
      const ShadingPoint sp = shading_point(ctx);
      if (scatters(sp)) e = self(inst).eval(sp, sp.frame.to_local(Vec3(wo)));
    } catch (...) {
      e = LocalEval{};  // a closure that throws contributes nothing
    }
    const Spectrum f = sanitize(e.f_cos);
    out_eval[0] = f.x;
    out_eval[1] = f.y;
    out_eval[2] = f.z;
    *out_pdf = sanitize(e.pdf);
  }

  static uint32_t sample(const GlimmerInstance *inst, const GlimmerShadingContext *ctx, const float rand3[3],
                         GlimmerSample *out) noexcept {
    try {
      return sample_unguarded(inst, ctx, rand3, out);
    } catch (...) {
      no_sample(out);
      return GLIMMER_LABEL_NONE;
    }
  }

  // clear() where sample() and sample_unguarded() give no sample: out of line for a closure that asks for it
  // (`static constexpr bool kAdapterClearOutOfLine = true;`: glint, whose translation unit sits at GCC's inlining
  // budget; session 30: inlined, the wrappers' prologues cost +0.23 M in the GI scene). The call sites test it with
  // `if constexpr`, so every other closure's code is the same as with clear() alone.
  static constexpr bool kClearOutOfLine = ClearsOutOfLine<T>;
  // sample_unguarded's LocalSample{} by stores (write_local_sample_defaults) where T asks for it.
  static constexpr bool kSampleDefaultsByStores = WritesSampleDefaults<T>;
  [[gnu::noinline]] static void clear_out_of_line(GlimmerSample *out) { clear(out); }
  // The three "no sample" exits: clear(), out of line where T asks for it.
  [[gnu::always_inline]] static void no_sample(GlimmerSample *out) {
    if constexpr (kClearOutOfLine)
      clear_out_of_line(out);
    else
      clear(out);
  }

  // "No sample", keeping the host's struct_size.
  // Only the host's struct_size bytes are written (an older host's buffer is smaller), and the host's
  // exit_mixture buffer pointer (ABI 2.7) is kept.
  static void clear(GlimmerSample *out) {
    const uint32_t size = out->struct_size;
#if GLIMMER_ABI_MINOR >= 7
    GlimmerExitMixture *const buffer =
        GLIMMER_HAS_FIELD(size, GlimmerSample, exit_mixture) ? out->exit_mixture : nullptr;
#endif
#if GLIMMER_ABI_MINOR >= 8
    GlimmerExitState *const state_buffer =
        GLIMMER_HAS_FIELD(size, GlimmerSample, exit_state) ? out->exit_state : nullptr;
#endif
    const GlimmerSample zero{};
    std::memcpy(static_cast<void *>(out), &zero,
                size == 0 ? offsetof(GlimmerSample, label) + sizeof(uint32_t) : std::min<size_t>(size, sizeof zero));
    out->struct_size = size;
#if GLIMMER_ABI_MINOR >= 7
    if (GLIMMER_HAS_FIELD(size, GlimmerSample, exit_mixture)) out->exit_mixture = buffer;
#endif
#if GLIMMER_ABI_MINOR >= 8
    if (GLIMMER_HAS_FIELD(size, GlimmerSample, exit_state)) out->exit_state = state_buffer;
#endif
  }

  static uint32_t sample_unguarded(const GlimmerInstance *inst, const GlimmerShadingContext *ctx,
                                   const float rand3[3], GlimmerSample *out) {
    const ShadingPoint sp = shading_point(ctx);
    if constexpr (kSampleDefaultsByStores) {
      // LocalSample{}'s values without its `rep stos` (write_local_sample_defaults): the storage of an unsigned char
      // array implicitly holds the LocalSample (C++20: an implicit-lifetime type), then every field is written.
      alignas(LocalSample) unsigned char storage[sizeof(LocalSample)];
      LocalSample &s = *std::launder(reinterpret_cast<LocalSample *>(storage));
      write_local_sample_defaults(s);
      return sample_into(inst, sp, rand3, out, s);
    } else {
      LocalSample s;
      return sample_into(inst, sp, rand3, out, s);
    }
  }
  // sample_unguarded's body, given LocalSample{}'s values in s.
  [[gnu::always_inline]] static uint32_t sample_into(const GlimmerInstance *inst, const ShadingPoint &sp,
                                                     const float rand3[3], GlimmerSample *out, LocalSample &s) {
#if GLIMMER_ABI_MINOR >= 7
    if (GLIMMER_HAS_FIELD(out->struct_size, GlimmerSample, exit_mixture)) s.mixture_out = out->exit_mixture;
#endif
#if GLIMMER_ABI_MINOR >= 8
    if constexpr (HasEvalExit<T>)
      if (GLIMMER_HAS_FIELD(out->struct_size, GlimmerSample, exit_state)) s.state_out = out->exit_state;
#endif
    const bool ok = scatters(sp) && self(inst).sample(sp, Vec3(rand3[0], rand3[1], rand3[2]), s);
    const Vec3 wo = sp.frame.to_world(s.wo);
    const float pdf = sanitize(s.pdf);
    if (!ok || s.label == GLIMMER_LABEL_NONE || !(pdf > 0.0f) || !is_finite(wo)) {
      no_sample(out);
      return GLIMMER_LABEL_NONE;
    }
    const Spectrum f = sanitize(s.f_cos);
    out->wo = wo;
    out->eval[0] = f.x;
    out->eval[1] = f.y;
    out->eval[2] = f.z;
    out->pdf = pdf;
    out->roughness = sanitize(s.roughness);
    out->eta = (std::isfinite(s.eta) && s.eta > 0.0f) ? s.eta : 1.0f;
    out->label = s.label;
#if GLIMMER_ABI_MINOR >= 3
    if (GLIMMER_HAS_FIELD(out->struct_size, GlimmerSample, flags)) out->flags = 0;
#endif
    if (s.moved && !write_origin(s, out)) {  // a host that cannot move the path gets no sample
      no_sample(out);
      return GLIMMER_LABEL_NONE;
    }
#if GLIMMER_ABI_MINOR >= 8
    // An exit state only on a singular sample that stays at the shading point, or on a moved exit-lobe sample
    // (frosted_glass sg's rough pane: the exact exit for the lamps through the lobe), in the host's own buffer.
    if (s.exit_state && s.state_out != nullptr && (!s.moved || s.exit_lobe) && (s.label & GLIMMER_LABEL_SINGULAR) &&
        GLIMMER_HAS_FIELD(out->struct_size, GlimmerSample, flags))
      out->flags |= GLIMMER_SAMPLE_EXIT_STATE;
#endif
    return s.label;
  }

  static bool write_origin(const LocalSample &s, GlimmerSample *out) {
#if GLIMMER_ABI_MINOR >= 3
    if (!GLIMMER_HAS_FIELD(out->struct_size, GlimmerSample, origin_Ng) || !is_finite(s.origin) ||
        !is_finite(s.origin_Ng))
      return false;
    out->flags = GLIMMER_SAMPLE_MOVED;
    out->origin = s.origin;
    out->origin_Ng = s.origin_Ng;
#if GLIMMER_ABI_MINOR >= 4
    // A 2.3 host does not hold the lobe: it gets the moved singular sample alone.
    if (s.exit_lobe && GLIMMER_HAS_FIELD(out->struct_size, GlimmerSample, lobe_sharpness) &&
        is_finite(s.lobe_axis) && std::isfinite(s.lobe_sharpness) && s.lobe_sharpness > 0.0f) {
      out->flags |= GLIMMER_SAMPLE_EXIT_LOBE;
      out->lobe_axis = s.lobe_axis;
      out->lobe_sharpness = s.lobe_sharpness;
#if GLIMMER_ABI_MINOR >= 7
      if (s.exit_mixture && s.mixture_out != nullptr) out->flags |= GLIMMER_SAMPLE_EXIT_MIXTURE;
#endif
    }
#endif
    return true;
#else
    (void)s;
    (void)out;
    return false;
#endif
  }

  static void albedo(const GlimmerInstance *inst, const GlimmerShadingContext *ctx, float out_rgb[3]) noexcept {
    Spectrum a(1.0f);
    if constexpr (HasSanitizedConstantAlbedo<T>) {  // no frame, no sanitize (reflection: scatters() is true)
      a = self(inst).sanitized_albedo();
    } else {
      try {
        const ShadingPoint sp = shading_point(ctx);
        if (!scatters(sp)) {
          a = Spectrum(0.0f);
        } else if constexpr (HasAlbedo<T>) {
          a = sanitize(self(inst).albedo(sp));
        }
      } catch (...) {
        a = Spectrum(1.0f);
      }
    }
    out_rgb[0] = a.x;
    out_rgb[1] = a.y;
    out_rgb[2] = a.z;
  }

  static void emit(const GlimmerInstance *inst, const GlimmerShadingContext *ctx, float out_rgb[3]) noexcept {
    Spectrum e(0.0f);
    try {
      if constexpr (HasEmit<T>) e = sanitize(self(inst).emit(shading_point(ctx)));
    } catch (...) {
      e = Spectrum(0.0f);
    }
    out_rgb[0] = e.x;
    out_rgb[1] = e.y;
    out_rgb[2] = e.z;
  }

#if GLIMMER_ABI_MINOR >= 8
  static void eval_exit(const GlimmerInstance *inst, const GlimmerShadingContext *ctx, const GlimmerExitState *state,
                        GlimmerVec3 w, float out_eval[3], float *out_pdf) noexcept {
    LocalEval e;
    if constexpr (HasEvalExit<T>) {
      try {
        const ShadingPoint sp = shading_point(ctx);
        if (state != nullptr && scatters(sp)) e = self(inst).eval_exit(sp, *state, sp.frame.to_local(Vec3(w)));
      } catch (...) {
        e = LocalEval{};
      }
    }
    const Spectrum f = sanitize(e.f_cos);
    out_eval[0] = f.x;
    out_eval[1] = f.y;
    out_eval[2] = f.z;
    *out_pdf = sanitize(e.pdf);
  }
#endif

  static GlimmerClosureType make_type() {
    const auto schema = T::params();
    GlimmerClosureType type{};
    type.struct_size = sizeof(GlimmerClosureType);
    type.param_spec_size = sizeof(GlimmerParamSpec);
    type.name = T::kName;
    type.doc = T::kDoc;
    type.flags = T::kFlags;
    type.param_count = static_cast<uint32_t>(schema.size());
    type.params = schema.data();
    type.create = &create;
    type.prepare = &prepare;
    type.destroy = &destroy;
    type.eval = &eval;
    type.sample = &sample;
    type.albedo = HasAlbedo<T> || HasSanitizedConstantAlbedo<T> ? &albedo : nullptr;
    type.emit = HasEmit<T> ? &emit : nullptr;
#if GLIMMER_ABI_MINOR >= 2
    type.abi_version = GLIMMER_ABI_VERSION;
#endif
#if GLIMMER_ABI_MINOR >= 8
    if constexpr (HasEvalExit<T>) type.eval_exit = &eval_exit;
#endif
    return type;
  }
};

// Adds a closure type to the plugin's list (called from static initializers).
bool register_closure_type(const GlimmerClosureType *type);

// The set-up of a lobe at one shading point, kept for the next calls with the same per-point values: the
// host calls albedo, eval (next-event estimation), sample and eval (MIS) at a shading point with the same
// varying values, so the lobe (alphas, energy-table rows, the multiple-scattering CDF) is built once per point
// instead of once per call. One entry per thread and closure class, keyed by the instance and the values.
#if GLIMMER_ABI_MINOR >= 1  // varying parameters exist from ABI 2.1
template <class Lobe>
struct PointLobeCache {
  static constexpr uint32_t kMaxValues = 8;  // more varying values than this are rebuilt every call
  uint64_t instance = 0;                     // OneLobeClosure serial; 0 = empty
  uint32_t count = 0;
  GlimmerVaryingValue values[kMaxValues];
  Lobe lobe;

  bool holds(uint64_t serial, const ShadingPoint &sp) const {
    return instance == serial && count == sp.ctx->varying_count &&
           std::memcmp(values, sp.ctx->varying, count * sizeof(GlimmerVaryingValue)) == 0;
  }
  void remember(uint64_t serial, const ShadingPoint &sp) {
    const bool fits = sp.ctx->varying_count <= kMaxValues;
    instance = fits ? serial : 0;
    count = fits ? sp.ctx->varying_count : 0;
    if (fits) std::memcpy(values, sp.ctx->varying, count * sizeof(GlimmerVaryingValue));
  }
};
#endif

// eval / sample / albedo of a closure that is one lobe (Derived::Lobe with eval(wi, wo), sample(wi, rand, out)
// and albedo(wi)): the instance's lobe (Derived::constant_lobe()), or, when the host gives per-point values of
// varying parameters, the lobe Derived::build_lobe_at(sp, lobe) builds from them, once per shading point
// (PointLobeCache).
template <class Derived>
class OneLobeClosure {
 public:
  LocalEval eval(const ShadingPoint &sp, const Vec3 &wo) const { return lobe_at(sp).eval(sp.wi, wo); }
  bool sample(const ShadingPoint &sp, const Vec3 &rand, LocalSample &out) const {
    return lobe_at(sp).sample(sp.wi, rand, out);
  }
  Spectrum albedo(const ShadingPoint &sp) const { return lobe_at(sp).albedo(sp.wi); }

  // The lobe at this shading point.
  const auto &lobe_at(const ShadingPoint &sp) const {
#if GLIMMER_ABI_MINOR >= 1
    if (!sp.varies()) return derived().constant_lobe();
    static thread_local PointLobeCache<typename Derived::Lobe> cache;
    if (!cache.holds(serial_, sp)) {
      derived().build_lobe_at(sp, cache.lobe);
      cache.remember(serial_, sp);
    }
    return cache.lobe;
#else
    (void)sp;
    return derived().constant_lobe();
#endif
  }

 private:
  static uint64_t next_serial() {
    static std::atomic<uint64_t> counter{0};
    return ++counter;
  }
  const Derived &derived() const { return static_cast<const Derived &>(*this); }
  const uint64_t serial_ = next_serial();  // unique per instance, so a cache entry never outlives its instance's identity
};

}  // namespace glimmer::plugin

#define GLIMMER_CONCAT_INNER(a, b) a##b
#define GLIMMER_CONCAT(a, b) GLIMMER_CONCAT_INNER(a, b)
// Registers closure class T with the plugin entry point.
#define GLIMMER_REGISTER_CLOSURE(T)                                                               \
  namespace {                                                                                     \
  const GlimmerClosureType GLIMMER_CONCAT(glimmer_type_, __LINE__) =                              \
      ::glimmer::plugin::ClosureAdapter<T>::make_type();                                          \
  const bool GLIMMER_CONCAT(glimmer_registered_, __LINE__) =                                      \
      ::glimmer::plugin::register_closure_type(&GLIMMER_CONCAT(glimmer_type_, __LINE__));         \
  }
