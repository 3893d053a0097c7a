// Host-side handle on one closure instance: parameter parsing from text,
// create + prepare with clear errors, RAII destroy, typed eval/sample calls.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "glimmer/closure_abi.h"
#include "glimmer/math.h"

namespace glimmer::host {

// Bad closure parameters or a failed create/prepare (message names the closure
// and the parameter).
class ClosureError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Parameter values for create(), owning their strings.
class ParamList {
 public:
  // Parses `text` according to the closure's schema: FLOAT/INT/BOOL one number
  // (BOOL also true/false), COLOR/VECTOR "r,g,b" or "r g b" (one number = grey),
  // ENUM/STRING verbatim. Throws ClosureError for unknown names or bad numbers.
  void set_from_text(const GlimmerClosureType &type, const std::string &name, const std::string &text);
  void set_number(const std::string &name, float v0, float v1, float v2);
  // An INT parameter's exact value (ABI 2.2: reaches a 2.2 plugin exactly).
  void set_integer(const std::string &name, int64_t value);
  void set_string(const std::string &name, const std::string &value);
  // "name=value" as given on the command line.
  void set_assignment(const GlimmerClosureType &type, const std::string &assignment);

  // The values for `type`'s create(), valid while *this lives. INT values
  // carry their decimal text for ABI 2.2 plugins; for older ones an integer a
  // float cannot hold exactly (beyond 2^24) throws ClosureError.
  std::vector<GlimmerParamValue> values(const GlimmerClosureType &type) const;
  bool has(const std::string &name) const { return entries_.count(name) != 0; }

 private:
  struct Entry {
    float value[3] = {0, 0, 0};
    std::string string;  // ENUM/STRING value, or an integer's decimal text
    bool is_string = false;
    bool is_integer = false;
    int64_t integer = 0;
  };
  std::map<std::string, Entry> entries_;
};

// Schema access honouring the plugin's GlimmerParamSpec size (an ABI 2.0
// plugin's specs have no flags field): use these, never type.params[i].
const GlimmerParamSpec &param_at(const GlimmerClosureType &type, uint32_t index);
uint32_t param_index(const GlimmerClosureType &type, const GlimmerParamSpec &spec);
uint32_t param_flags(const GlimmerClosureType &type, const GlimmerParamSpec &spec);  // 0 for ABI 2.0 plugins
// The ABI version a closure type's plugin was built with (GlimmerClosureType
// .abi_version, ABI 2.2); 0 for an older plugin, whose types do not say.
uint32_t closure_abi_version(const GlimmerClosureType &type);
const GlimmerParamSpec *find_param(const GlimmerClosureType &type, const std::string &name);
const char *param_type_name(uint32_t type);
// Checks a closure type's schema (names, types, ranges, defaults in range,
// enum defaults among the choices); returns "" or the first problem.
std::string validate_schema(const GlimmerClosureType &type);

// Default host services for tools without a scene (lab, tests): log to
// stderr, cache in $GLIMMER_CACHE_DIR or ~/.cache/glimmer, no ray tracing.
const GlimmerHostServices *default_host_services();

class ClosureInstance {
 public:
  // create + prepare; throws ClosureError with the plugin's message.
  ClosureInstance(const GlimmerClosureType &type, const ParamList &params,
                  const GlimmerHostServices *host = default_host_services());
  ~ClosureInstance();
  ClosureInstance(const ClosureInstance &) = delete;
  ClosureInstance &operator=(const ClosureInstance &) = delete;

  const GlimmerClosureType &type() const { return type_; }
  const GlimmerInstance *handle() const { return instance_; }

  // Contexts follow the ABI 2.3 normal convention (N toward wi, `backfacing` names the medium).
  void eval(const GlimmerShadingContext &ctx, const Vec3 &wo, Spectrum &f_cos, float &pdf) const {
    float rgb[3];
    GlimmerShadingContext scratch;
    type_.eval(instance_, &as_expected(ctx, scratch), wo, rgb, &pdf);
    f_cos = Spectrum(rgb[0], rgb[1], rgb[2]);
  }
  uint32_t sample(const GlimmerShadingContext &ctx, const float rand3[3], GlimmerSample &out) const {
    GlimmerShadingContext scratch;
    return type_.sample(instance_, &as_expected(ctx, scratch), rand3, &out);
  }
#if GLIMMER_ABI_MINOR >= 8
  // ABI 2.8: whether the type has eval_exit, and f cos / pdf toward wo of the exit state a sample wrote.
  bool has_eval_exit() const {
    return GLIMMER_HAS_FIELD(type_.struct_size, GlimmerClosureType, eval_exit) && type_.eval_exit != nullptr;
  }
  void eval_exit(const GlimmerShadingContext &ctx, const GlimmerExitState &state, const Vec3 &wo, Spectrum &f_cos,
                 float &pdf) const {
    float rgb[3] = {0.0f, 0.0f, 0.0f};
    pdf = 0.0f;
    GlimmerShadingContext scratch;
    if (has_eval_exit()) type_.eval_exit(instance_, &as_expected(ctx, scratch), &state, wo, rgb, &pdf);
    f_cos = Spectrum(rgb[0], rgb[1], rgb[2]);
  }
#endif
#if GLIMMER_ABI_MINOR >= 10
  // ABI 2.10: whether the type has prefetch (read once at construction: NULL or a type too old to hold the field
  // reads as none), and the hint itself (no result).
  bool has_prefetch() const { return prefetch_ != nullptr; }
  void prefetch(const GlimmerShadingContext &ctx, const Vec3 &wo) const {
    if (prefetch_ != nullptr) prefetch_(instance_, &ctx, wo);
  }
#endif
  Spectrum albedo(const GlimmerShadingContext &ctx) const;
  Spectrum emit(const GlimmerShadingContext &ctx) const;

 private:
  // The context in the convention the closure was built for: a TRANSMISSIVE
  // closure of a plugin older than ABI 2.3 gets the front-face N and Ng
  // (turned back when backfacing, a copy in `scratch`); every other closure `ctx` itself.
  const GlimmerShadingContext &as_expected(const GlimmerShadingContext &ctx, GlimmerShadingContext &scratch) const {
    if (!wants_front_normal_ || !ctx.backfacing) return ctx;
    scratch = ctx;
    scratch.N = -Vec3(ctx.N);
    scratch.Ng = -Vec3(ctx.Ng);
    return scratch;
  }

  const GlimmerClosureType &type_;
  GlimmerInstance *instance_ = nullptr;
  bool wants_front_normal_ = false;
#if GLIMMER_ABI_MINOR >= 10
  decltype(GlimmerClosureType::prefetch) prefetch_ = nullptr;
#endif
};

// True for a TRANSMISSIVE closure built for ABI <= 2.2, which takes the side
// from dot(wi, N) and so expects the front-face normal (closure_abi.h).
bool wants_front_normal(const GlimmerClosureType &type);

// A shading context at the origin for the laboratory and tests, in the
// renderer's convention: the surface's outward normal is +z and T = +x; a wi
// below it arrives from the back, so N and Ng are turned to -z and `backfacing`
// is set. Empty (point) footprint.
GlimmerShadingContext make_local_context(const Vec3 &wi, const GlimmerHostServices *host = default_host_services());

}  // namespace glimmer::host
