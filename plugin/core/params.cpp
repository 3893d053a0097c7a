#include "core/params.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <limits>
#include <sstream>

namespace glimmer::plugin {

std::vector<std::string> split_enum_choices(const char *choices) {
  std::vector<std::string> out;
  if (choices == nullptr) return out;
  std::string current;
  for (const char *c = choices; *c != '\0'; ++c) {
    if (*c == '|') {
      out.push_back(current);
      current.clear();
    } else {
      current += *c;
    }
  }
  out.push_back(current);
  return out;
}

namespace {

int components(uint32_t type) {
  return (type == GLIMMER_PARAM_COLOR || type == GLIMMER_PARAM_VECTOR) ? 3 : 1;
}

std::string format_value(const GlimmerParamValue &v, int n) {
  std::ostringstream s;
  for (int i = 0; i < n; ++i) s << (i ? "," : "") << v.value[i];
  return s.str();
}

// An INT bound or default (a whole float) as an integer, saturated to int64.
int64_t whole_to_int64(float x) {
  constexpr float kLimit = 9.2233720368547758e18f;  // 2^63
  if (x >= kLimit) return std::numeric_limits<int64_t>::max();
  if (x < -kLimit) return std::numeric_limits<int64_t>::min();
  return static_cast<int64_t>(x);
}

// The exact value of an INT parameter: the decimal text of an ABI 2.2 host
// (GlimmerParamValue.string), else value[0] (whole, checked by the caller).
int64_t integer_value(const GlimmerParamValue &v, const std::string &prefix) {
#if GLIMMER_ABI_MINOR >= 2
  if (v.string != nullptr) {
    const std::string_view text(v.string);
    int64_t out = 0;
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), out);
    if (text.empty() || ec != std::errc() || end != text.data() + text.size())
      throw ParamError(prefix + " = '" + std::string(text) + "' is not a whole number (64-bit)");
    return out;
  }
#else
  (void)prefix;
#endif
  return whole_to_int64(v.value[0]);
}

}  // namespace

ParamReader::ParamReader(std::string_view closure_name, std::span<const GlimmerParamSpec> schema,
                         std::span<const GlimmerParamValue> values)
    : closure_name_(closure_name), schema_(schema), values_(values) {
  for (size_t i = 0; i < values_.size(); ++i) {
    const GlimmerParamValue &v = values_[i];
    if (v.name == nullptr) throw ParamError(closure_name_ + ": parameter with no name");
    const GlimmerParamSpec *match = nullptr;
    for (const auto &s : schema_)
      if (std::string_view(s.name) == v.name) match = &s;
    if (match == nullptr) {
      std::string known;
      for (const auto &s : schema_) known += (known.empty() ? "" : ", ") + std::string(s.name);
      throw ParamError(closure_name_ + ": unknown parameter '" + v.name + "' (known: " + known + ")");
    }
    for (size_t j = 0; j < i; ++j)
      if (std::string_view(values_[j].name) == v.name)
        throw ParamError(closure_name_ + ": parameter '" + v.name + "' given twice");
    const std::string prefix = closure_name_ + ": parameter '" + v.name + "'";
    switch (match->type) {
      case GLIMMER_PARAM_ENUM: {
        if (v.string == nullptr) throw ParamError(prefix + " needs one of: " + match->enum_choices);
        bool ok = false;
        for (const auto &c : split_enum_choices(match->enum_choices)) ok = ok || c == v.string;
        if (!ok)
          throw ParamError(prefix + " = '" + v.string + "' is not one of: " + match->enum_choices);
        break;
      }
      case GLIMMER_PARAM_STRING:
        if (v.string == nullptr) throw ParamError(prefix + " needs a string value");
        break;
      case GLIMMER_PARAM_INT: {
        if (!std::isfinite(v.value[0]))
          throw ParamError(prefix + " = " + format_value(v, 1) + " is not a finite number");
        if (v.string == nullptr && v.value[0] != std::floor(v.value[0]))
          throw ParamError(prefix + " = " + format_value(v, 1) + " must be a whole number");
        const int64_t x = integer_value(v, prefix);
        if (x < whole_to_int64(match->min_value) || x > whole_to_int64(match->max_value)) {
          std::ostringstream s;
          s << prefix << " = " << x << " is outside [" << whole_to_int64(match->min_value) << ", "
            << whole_to_int64(match->max_value) << "]";
          if (match->doc) s << " (" << match->doc << ")";
          throw ParamError(s.str());
        }
        break;
      }
      default: {
        const int n = components(match->type);
        for (int c = 0; c < n; ++c) {
          const float x = v.value[c];
          if (!std::isfinite(x))
            throw ParamError(prefix + " = " + format_value(v, n) + " is not a finite number");
          if (x < match->min_value || x > match->max_value) {
            std::ostringstream s;
            s << prefix << " = " << format_value(v, n) << " is outside [" << match->min_value << ", "
              << match->max_value << "]";
            if (match->doc) s << " (" << match->doc << ")";
            throw ParamError(s.str());
          }
          if (match->type == GLIMMER_PARAM_BOOL && x != std::floor(x))
            throw ParamError(prefix + " = " + format_value(v, n) + " must be a whole number");
        }
      }
    }
  }
}

const GlimmerParamSpec &ParamReader::spec(std::string_view name) const {
  for (const auto &s : schema_)
    if (name == s.name) return s;
  // A closure asking for a parameter it did not declare is a programming error.
  throw ParamError(closure_name_ + ": internal error: undeclared parameter '" + std::string(name) + "'");
}

uint32_t ParamReader::index(std::string_view name) const {
  return static_cast<uint32_t>(&spec(name) - schema_.data());
}

const GlimmerParamValue *ParamReader::given(std::string_view name) const {
  for (const auto &v : values_)
    if (name == v.name) return &v;
  return nullptr;
}

float ParamReader::get_float(std::string_view name) const {
  const auto &s = spec(name);
  const auto *v = given(name);
  return v ? v->value[0] : s.default_value[0];
}
int64_t ParamReader::get_int64(std::string_view name) const {
  const auto &s = spec(name);
  const auto *v = given(name);
  return v ? integer_value(*v, closure_name_ + ": parameter '" + std::string(name) + "'")
           : whole_to_int64(s.default_value[0]);
}
int ParamReader::get_int(std::string_view name) const {
  const int64_t x = get_int64(name);
  return static_cast<int>(std::clamp<int64_t>(x, std::numeric_limits<int>::min(), std::numeric_limits<int>::max()));
}
bool ParamReader::get_bool(std::string_view name) const { return get_float(name) != 0.0f; }
Vec3 ParamReader::get_color(std::string_view name) const {
  const auto &s = spec(name);
  const auto *v = given(name);
  const float *src = v ? v->value : s.default_value;
  return {src[0], src[1], src[2]};
}
int ParamReader::get_enum(std::string_view name) const {
  const auto &s = spec(name);
  const auto *v = given(name);
  const std::string chosen = v ? v->string : (s.default_string ? s.default_string : "");
  const auto choices = split_enum_choices(s.enum_choices);
  for (size_t i = 0; i < choices.size(); ++i)
    if (choices[i] == chosen) return static_cast<int>(i);
  return 0;
}
std::string ParamReader::get_string(std::string_view name) const {
  const auto &s = spec(name);
  const auto *v = given(name);
  if (v && v->string) return v->string;
  return s.default_string ? s.default_string : "";
}

}  // namespace glimmer::plugin
