// Parameter validation against a closure's schema (GlimmerParamSpec array).
// A closure declares its parameters once; ParamReader checks names, types and
// ranges at create time and throws ParamError with a message naming the
// parameter and the reason.
#pragma once

#include <cstdint>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "glimmer/closure_abi.h"
#include "glimmer/math.h"

namespace glimmer::plugin {

class ParamError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class ParamReader {
 public:
  // Validates every given value against the schema (unknown name, range,
  // enum choice, integer-ness); throws ParamError on the first problem.
  ParamReader(std::string_view closure_name, std::span<const GlimmerParamSpec> schema,
              std::span<const GlimmerParamValue> values);

  float get_float(std::string_view name) const;
  // INT parameters: the exact value (ABI 2.2 hosts send integers beyond 2^24
  // exactly); get_int saturates it to int.
  int64_t get_int64(std::string_view name) const;
  int get_int(std::string_view name) const;
  bool get_bool(std::string_view name) const;
  Vec3 get_color(std::string_view name) const;
  Vec3 get_vector(std::string_view name) const { return get_color(name); }
  // Index of the chosen enum value in the '|'-separated choice list.
  int get_enum(std::string_view name) const;
  std::string get_string(std::string_view name) const;
  // Index of a declared parameter in the schema (for ShadingPoint::param_float
  // and param_color, which read varying values by index).
  uint32_t index(std::string_view name) const;
  // The closure's name, for the messages of errors create() finds across parameters.
  const std::string &closure_name() const { return closure_name_; }

 private:
  const GlimmerParamSpec &spec(std::string_view name) const;
  const GlimmerParamValue *given(std::string_view name) const;

  std::string closure_name_;
  std::span<const GlimmerParamSpec> schema_;
  std::span<const GlimmerParamValue> values_;
};

// Splits "a|b|c" into its choices.
std::vector<std::string> split_enum_choices(const char *choices);

}  // namespace glimmer::plugin
