#include "host/closure_instance.h"

#include <cmath>
#include <pwd.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <limits>

#include "glimmer/atomic_file.h"
#include "host/log.h"
#include "scene/parse_number.h"

namespace glimmer::host {

const char *param_type_name(uint32_t type) {
  switch (type) {
    case GLIMMER_PARAM_FLOAT: return "float";
    case GLIMMER_PARAM_INT: return "int";
    case GLIMMER_PARAM_BOOL: return "bool";
    case GLIMMER_PARAM_COLOR: return "color";
    case GLIMMER_PARAM_VECTOR: return "vector";
    case GLIMMER_PARAM_ENUM: return "enum";
    case GLIMMER_PARAM_STRING: return "string";
  }
  return "unknown";
}

const GlimmerParamSpec &param_at(const GlimmerClosureType &type, uint32_t index) {
  return *reinterpret_cast<const GlimmerParamSpec *>(reinterpret_cast<const char *>(type.params) +
                                                     static_cast<size_t>(index) * type.param_spec_size);
}

uint32_t param_index(const GlimmerClosureType &type, const GlimmerParamSpec &spec) {
  const auto offset = reinterpret_cast<const char *>(&spec) - reinterpret_cast<const char *>(type.params);
  return static_cast<uint32_t>(offset / type.param_spec_size);
}

uint32_t param_flags(const GlimmerClosureType &type, const GlimmerParamSpec &spec) {
  return GLIMMER_HAS_FIELD(type.param_spec_size, GlimmerParamSpec, flags) ? spec.flags : 0u;
}

uint32_t closure_abi_version(const GlimmerClosureType &type) {
  return GLIMMER_HAS_FIELD(type.struct_size, GlimmerClosureType, abi_version) ? type.abi_version : 0u;
}

bool wants_front_normal(const GlimmerClosureType &type) {
  return (type.flags & GLIMMER_CLOSURE_TRANSMISSIVE) && closure_abi_version(type) < ((2u << 16) | 3u);
}

const GlimmerParamSpec *find_param(const GlimmerClosureType &type, const std::string &name) {
  for (uint32_t i = 0; i < type.param_count; ++i)
    if (name == param_at(type, i).name) return &param_at(type, i);
  return nullptr;
}

std::string validate_schema(const GlimmerClosureType &type) {
  const std::string closure = type.name ? type.name : "?";
  for (uint32_t i = 0; i < type.param_count; ++i) {
    const GlimmerParamSpec &p = param_at(type, i);
    if (p.name == nullptr || *p.name == '\0') return closure + ": parameter #" + std::to_string(i) + " has no name";
    const std::string prefix = closure + ": parameter '" + p.name + "'";
    for (uint32_t j = 0; j < i; ++j)
      if (std::string(param_at(type, j).name) == p.name) return prefix + " is declared twice";
    if (p.type > GLIMMER_PARAM_STRING) return prefix + " has an unknown type " + std::to_string(p.type);
    if (p.type == GLIMMER_PARAM_ENUM) {
      if (p.enum_choices == nullptr || p.default_string == nullptr) return prefix + ": enum without choices or default";
      bool found = false;
      std::string choice;
      for (const char *c = p.enum_choices;; ++c) {
        if (*c == '|' || *c == '\0') {
          found = found || choice == p.default_string;
          choice.clear();
          if (*c == '\0') break;
        } else {
          choice += *c;
        }
      }
      if (!found)
        return prefix + ": default '" + p.default_string + "' is not one of its choices '" + p.enum_choices + "'";
      continue;
    }
    if (p.type == GLIMMER_PARAM_STRING) continue;
    if (!std::isfinite(p.min_value) || !std::isfinite(p.max_value) || p.min_value > p.max_value)
      return prefix + ": invalid range [" + std::to_string(p.min_value) + ", " + std::to_string(p.max_value) + "]";
    const int n = (p.type == GLIMMER_PARAM_COLOR || p.type == GLIMMER_PARAM_VECTOR) ? 3 : 1;
    if (p.type == GLIMMER_PARAM_INT && (p.min_value != std::floor(p.min_value) || p.max_value != std::floor(p.max_value)))
      return prefix + ": integer range [" + std::to_string(p.min_value) + ", " + std::to_string(p.max_value) +
             "] has a bound that is not a whole number";
    for (int c = 0; c < n; ++c) {
      const float d = p.default_value[c];
      if (!std::isfinite(d) || d < p.min_value || d > p.max_value)
        return prefix + ": default " + std::to_string(d) + " is outside its range [" + std::to_string(p.min_value) +
               ", " + std::to_string(p.max_value) + "]";
      if ((p.type == GLIMMER_PARAM_INT || p.type == GLIMMER_PARAM_BOOL) && d != std::floor(d))
        return prefix + ": default " + std::to_string(d) + " is not a whole number";
    }
  }
  return "";
}

namespace {

std::vector<float> parse_numbers(const std::string &closure, const std::string &name, const std::string &text) {
  std::vector<float> out;
  for (const std::string_view token : scene::split_number_list(text)) {
    if (token == "true") { out.push_back(1.0f); continue; }
    if (token == "false") { out.push_back(0.0f); continue; }
    try {
      out.push_back(scene::parse_float(token));  // strict: junk, overflow, nan/inf are errors
    } catch (const scene::NumberError &e) {
      throw ClosureError(closure + ": parameter '" + name + "': " + e.what());
    }
  }
  return out;
}

// INT text: one integer, exact for decimal integers ("16777217"), or a whole
// number in another spelling ("1e3", "4.0").
int64_t parse_integer(const std::string &closure, const std::string &name, const std::string &text) {
  const auto tokens = scene::split_number_list(text);
  if (tokens.size() != 1)
    throw ClosureError(closure + ": parameter '" + name + "' (int) expects 1 number, got '" + text + "'");
  try {
    return scene::parse_integer(tokens[0], std::numeric_limits<int64_t>::min(), std::numeric_limits<int64_t>::max());
  } catch (const scene::NumberError &e) {
    throw ClosureError(closure + ": parameter '" + name + "' (int) needs a whole number: " + e.what());
  }
}

}  // namespace

void ParamList::set_from_text(const GlimmerClosureType &type, const std::string &name, const std::string &text) {
  const GlimmerParamSpec *spec = find_param(type, name);
  if (spec == nullptr) {
    std::string known;
    for (uint32_t i = 0; i < type.param_count; ++i) known += (i ? ", " : "") + std::string(param_at(type, i).name);
    throw ClosureError(std::string(type.name) + ": unknown parameter '" + name + "' (known: " + known + ")");
  }
  if (spec->type == GLIMMER_PARAM_ENUM || spec->type == GLIMMER_PARAM_STRING) {
    set_string(name, text);
    return;
  }
  if (spec->type == GLIMMER_PARAM_INT) {
    set_integer(name, parse_integer(type.name, name, text));
    return;
  }
  const auto numbers = parse_numbers(type.name, name, text);
  const size_t want = (spec->type == GLIMMER_PARAM_COLOR || spec->type == GLIMMER_PARAM_VECTOR) ? 3 : 1;
  if (numbers.size() == 1 && want == 3) {
    set_number(name, numbers[0], numbers[0], numbers[0]);
  } else if (numbers.size() == want) {
    set_number(name, numbers[0], want == 3 ? numbers[1] : 0.0f, want == 3 ? numbers[2] : 0.0f);
  } else {
    throw ClosureError(std::string(type.name) + ": parameter '" + name + "' (" + param_type_name(spec->type) +
                       ") expects " + std::to_string(want) + " number(s), got '" + text + "'");
  }
}

void ParamList::set_number(const std::string &name, float v0, float v1, float v2) {
  Entry &e = entries_[name];
  e.value[0] = v0;
  e.value[1] = v1;
  e.value[2] = v2;
  e.is_string = false;
}

void ParamList::set_integer(const std::string &name, int64_t value) {
  Entry &e = entries_[name];
  e.value[0] = static_cast<float>(value);
  e.value[1] = e.value[2] = 0.0f;
  e.string = std::to_string(value);
  e.is_string = false;
  e.is_integer = true;
  e.integer = value;
}

void ParamList::set_string(const std::string &name, const std::string &value) {
  Entry &e = entries_[name];
  e.string = value;
  e.is_string = true;
  e.is_integer = false;
}

void ParamList::set_assignment(const GlimmerClosureType &type, const std::string &assignment) {
  const auto eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0)
    throw ClosureError("parameter '" + assignment + "' must be written name=value");
  set_from_text(type, assignment.substr(0, eq), assignment.substr(eq + 1));
}

std::vector<GlimmerParamValue> ParamList::values(const GlimmerClosureType &type) const {
  const bool exact_integers = closure_abi_version(type) >= ((2u << 16) | 2u);
  std::vector<GlimmerParamValue> out;
  for (const auto &[name, e] : entries_) {
    GlimmerParamValue v{};
    v.name = name.c_str();
    v.value[0] = e.value[0];
    v.value[1] = e.value[1];
    v.value[2] = e.value[2];
    v.string = e.is_string ? e.string.c_str() : nullptr;
    if (e.is_integer && exact_integers) v.string = e.string.c_str();
    // long double holds every int64 and every float exactly: unequal exactly when the float lost digits.
    if (e.is_integer && !exact_integers && static_cast<long double>(e.value[0]) != static_cast<long double>(e.integer))
      throw ClosureError(std::string(type.name) + ": parameter '" + name + "' = " + e.string +
                         " cannot reach this plugin exactly (built for ABI 2.1 or older: integers travel as floats, "
                         "exact up to 2^24); rebuild the plugin against ABI 2.2");
    out.push_back(v);
  }
  return out;
}

namespace {


// $GLIMMER_CACHE_DIR, else $XDG_CACHE_HOME/glimmer, else ~/.cache/glimmer
// (home from $HOME or the password database); never a shared /tmp folder.
// The folder is made private (0700, ours); "" disables the cache with a warning.
std::string default_cache_dir() {
  std::string dir;
  if (const char *d = std::getenv("GLIMMER_CACHE_DIR"); d && *d) dir = d;
  else if (const char *x = std::getenv("XDG_CACHE_HOME"); x && *x == '/') dir = std::string(x) + "/glimmer";
  else if (const char *h = std::getenv("HOME"); h && *h == '/') dir = std::string(h) + "/.cache/glimmer";
  else if (const passwd *pw = ::getpwuid(::geteuid()); pw && pw->pw_dir && *pw->pw_dir == '/')
    dir = std::string(pw->pw_dir) + "/.cache/glimmer";
  if (dir.empty()) {
    log_warning("no cache folder (no XDG_CACHE_HOME, HOME or home directory); precomputed tables are not cached");
    return {};
  }
  if (const std::string problem = ensure_private_directory(dir); !problem.empty()) {
    log_warning("cache folder unusable (" + problem + "); precomputed tables are not cached");
    return {};
  }
  return dir;
}

}  // namespace

const GlimmerHostServices *default_host_services() {
  static const std::string cache_dir = default_cache_dir();
  static const GlimmerHostServices services = [] {
    GlimmerHostServices s{};
    s.struct_size = sizeof(GlimmerHostServices);
    s.abi_version = GLIMMER_ABI_VERSION;
    s.host_data = nullptr;
    s.trace_ray = nullptr;
    s.environment_lookup = nullptr;
    s.log = &log_callback;
    s.resolve_asset = nullptr;
    s.cache_dir = cache_dir.c_str();
    return s;
  }();
  return &services;
}

ClosureInstance::ClosureInstance(const GlimmerClosureType &type, const ParamList &params,
                                 const GlimmerHostServices *host)
    : type_(type), wants_front_normal_(wants_front_normal(type)) {
  const auto values = params.values(type);
  char error[1024] = {0};
  if (!type.create(values.data(), static_cast<uint32_t>(values.size()), host, &instance_, error, sizeof(error)) ||
      instance_ == nullptr)
    throw ClosureError(error[0] ? error : (std::string(type.name) + ": create failed"));
  if (type.prepare != nullptr && !type.prepare(instance_, host, error, sizeof(error))) {
    type.destroy(instance_);
    instance_ = nullptr;
    throw ClosureError(std::string(type.name) + ": prepare failed: " + error);
  }
#if GLIMMER_ABI_MINOR >= 10
  // ABI 2.10: only a type whose struct_size holds the field has one (an older plugin's type ends before it).
  if (GLIMMER_HAS_FIELD(type.struct_size, GlimmerClosureType, prefetch)) prefetch_ = type.prefetch;
#endif
}

ClosureInstance::~ClosureInstance() {
  if (instance_ != nullptr) type_.destroy(instance_);
}

Spectrum ClosureInstance::albedo(const GlimmerShadingContext &ctx) const {
  if (type_.albedo == nullptr) return Spectrum(1.0f);
  float rgb[3];
  GlimmerShadingContext scratch;
  type_.albedo(instance_, &as_expected(ctx, scratch), rgb);
  return {rgb[0], rgb[1], rgb[2]};
}

Spectrum ClosureInstance::emit(const GlimmerShadingContext &ctx) const {
  if (type_.emit == nullptr) return Spectrum(0.0f);
  float rgb[3];
  GlimmerShadingContext scratch;
  type_.emit(instance_, &as_expected(ctx, scratch), rgb);
  return {rgb[0], rgb[1], rgb[2]};
}

GlimmerShadingContext make_local_context(const Vec3 &wi, const GlimmerHostServices *host) {
  GlimmerShadingContext ctx{};
  ctx.struct_size = sizeof(GlimmerShadingContext);
  ctx.wi = normalize(wi);
  ctx.P = Vec3(0.0f);
  ctx.backfacing = wi.z < 0.0f ? 1u : 0u;
  ctx.N = Vec3(0, 0, ctx.backfacing ? -1.0f : 1.0f);
  ctx.Ng = ctx.N;
  ctx.T = Vec3(1, 0, 0);
  ctx.dPdu = Vec3(1, 0, 0);
  ctx.dPdv = Vec3(0, 1, 0);
  ctx.host = host;
  return ctx;
}

}  // namespace glimmer::host
