// JSON numbers for float values: nlohmann::json stores numbers as double, so a
// float such as 0.8f would print as 0.800000011920929. These helpers convert
// through the float's shortest round-trip decimal form (std::to_chars), so it
// prints as 0.8 and still parses back to the same float.
#pragma once

#include <charconv>
#include <cmath>
#include <cstdlib>
#include <nlohmann/json.hpp>

#include "glimmer/math.h"

namespace glimmer::cli {

inline double shortest_double(float value) {
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer) - 1, value);
  *result.ptr = '\0';
  return std::strtod(buffer, nullptr);
}

// A float as a JSON number (null for NaN/Inf, which JSON cannot represent).
inline nlohmann::json json_float(float value) {
  if (!std::isfinite(value)) return nullptr;
  return shortest_double(value);
}

inline nlohmann::json json_vec3(const Vec3 &v) { return {json_float(v.x), json_float(v.y), json_float(v.z)}; }
inline nlohmann::json json_floats(const float *v, int n) {
  nlohmann::json a = nlohmann::json::array();
  for (int i = 0; i < n; ++i) a.push_back(json_float(v[i]));
  return a;
}

}  // namespace glimmer::cli
