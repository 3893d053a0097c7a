// Strict number parsing for every text number the host reads (XML attributes,
// OBJ/PLY meshes, command-line vectors): one token is one whole number.
//  - junk after a number is an error ("1abc", "2.5x");
//  - a value that overflows its target type is an error ("1e39" as a float,
//    "1e10" as an int), never Inf or a wrapped integer;
//  - an integer must be integral and within the caller's range ("2.9" is not
//    an index); "3", "3.0" and "3e0" are the same integer.
// Failures throw NumberError with a message naming the token and the reason;
// callers prefix where it came from (file:line, option name).
#pragma once

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace glimmer::scene {

class NumberError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Separators between numbers in a list: white space and commas.
inline bool is_number_separator(char c) { return c == ' ' || c == ',' || c == '\t' || c == '\n' || c == '\r'; }

// The tokens of a whitespace/comma separated list.
inline std::vector<std::string_view> split_number_list(std::string_view text) {
  std::vector<std::string_view> tokens;
  size_t i = 0;
  while (i < text.size()) {
    while (i < text.size() && is_number_separator(text[i])) ++i;
    const size_t start = i;
    while (i < text.size() && !is_number_separator(text[i])) ++i;
    if (i > start) tokens.push_back(text.substr(start, i - start));
  }
  return tokens;
}

// One finite double; the whole token must be the number.
inline double parse_double(std::string_view token) {
  const std::string s(token);  // strtod needs a terminated string
  if (s.empty()) throw NumberError("empty value is not a number");
  errno = 0;
  char *end = nullptr;
  const double v = std::strtod(s.c_str(), &end);
  if (end == s.c_str() || *end != '\0') throw NumberError("'" + s + "' is not a number");
  if (!std::isfinite(v)) throw NumberError("'" + s + "' is not a finite number");  // nan, inf, overflow
  return v;  // underflow to a denormal or zero is accepted
}

// One finite float: a double that does not overflow float.
inline float parse_float(std::string_view token) {
  const double v = parse_double(token);
  if (std::fabs(v) > static_cast<double>(std::numeric_limits<float>::max()))
    throw NumberError("'" + std::string(token) + "' overflows a 32-bit float");
  return static_cast<float>(v);
}

// One integer in [lo, hi]: exact for decimal integers ("16777217", "-3", any
// long long); other spellings ("3.0", "1e3") through parse_double.
inline long long parse_integer(std::string_view token, long long lo, long long hi) {
  long long exact = 0;
  const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), exact);
  if (!token.empty() && end == token.data() + token.size()) {
    if (ec == std::errc::result_out_of_range || (ec == std::errc() && (exact < lo || exact > hi)))
      throw NumberError("'" + std::string(token) + "' is out of range [" + std::to_string(lo) + ", " +
                        std::to_string(hi) + "]");
    if (ec == std::errc()) return exact;
  }
  const double v = parse_double(token);
  if (v != std::floor(v)) throw NumberError("'" + std::string(token) + "' is not an integer");
  // (2^63 bounds the conversion: a double of hi = 2^63 - 1 rounds up to 2^63.)
  if (v < static_cast<double>(lo) || v > static_cast<double>(hi) || !(std::fabs(v) < 9223372036854775808.0))
    throw NumberError("'" + std::string(token) + "' is out of range [" + std::to_string(lo) + ", " +
                      std::to_string(hi) + "]");
  return static_cast<long long>(v);
}

inline int parse_int(std::string_view token, int lo = std::numeric_limits<int>::min(),
                     int hi = std::numeric_limits<int>::max()) {
  return static_cast<int>(parse_integer(token, lo, hi));
}

inline std::vector<float> parse_float_list(std::string_view text) {
  std::vector<float> out;
  for (std::string_view t : split_number_list(text)) out.push_back(parse_float(t));
  return out;
}

inline std::vector<int> parse_int_list(std::string_view text, int lo = std::numeric_limits<int>::min(),
                                       int hi = std::numeric_limits<int>::max()) {
  std::vector<int> out;
  for (std::string_view t : split_number_list(text)) out.push_back(parse_int(t, lo, hi));
  return out;
}

}  // namespace glimmer::scene
