// Math node (Cycles 3.4 svm_math): every operation of the node with Cycles' safe
// conventions (division, modulo, logarithm, power, square roots and arc functions
// return 0 or clamp instead of producing NaN/Inf), optional clamp to [0, 1].
#include "render/nodes/families.h"
#include "render/nodes/math_util.h"

namespace glimmer::render::nodes {

namespace {
// Operation names in Cycles' order (NodeMathType).
constexpr std::initializer_list<const char *> kOperations = {
    "add",         "subtract",   "multiply",  "divide",    "multiply_add", "sine",       "cosine",     "tangent",
    "sinh",        "cosh",       "tanh",      "arcsine",   "arccosine",    "arctangent", "power",      "logarithm",
    "minimum",     "maximum",    "round",     "less_than", "greater_than", "modulo",     "absolute",   "arctan2",
    "floor",       "ceil",       "fraction",  "sqrt",      "inversesqrt",  "sign",       "exponent",   "radians",
    "degrees",     "trunc",      "snap",      "wrap",      "pingpong",     "compare",    "smoothmin",  "smoothmax"};
}  // namespace

float math_operation(int op, float a, float b, float c) {
  using namespace safe;
  switch (op) {
    case 0: return a + b;
    case 1: return a - b;
    case 2: return a * b;
    case 3: return divide(a, b);
    case 4: return a * b + c;
    case 5: return std::sin(a);
    case 6: return std::cos(a);
    case 7: return std::tan(a);
    case 8: return std::sinh(a);
    case 9: return std::cosh(a);
    case 10: return std::tanh(a);
    case 11: return std::asin(clamp(a, -1.0f, 1.0f));
    case 12: return std::acos(clamp(a, -1.0f, 1.0f));
    case 13: return std::atan(a);
    case 14: return power(a, b);
    case 15: return logarithm(a, b);
    case 16: return std::fmin(a, b);
    case 17: return std::fmax(a, b);
    case 18: return std::floor(a + 0.5f);
    case 19: return a < b ? 1.0f : 0.0f;
    case 20: return a > b ? 1.0f : 0.0f;
    case 21: return modulo(a, b);
    case 22: return std::fabs(a);
    case 23: return std::atan2(a, b);
    case 24: return std::floor(a);
    case 25: return std::ceil(a);
    case 26: return a - std::floor(a);
    case 27: return safe_sqrt(a);
    case 28: return a > 0.0f ? 1.0f / std::sqrt(a) : 0.0f;
    case 29: return a == 0.0f ? 0.0f : (a > 0.0f ? 1.0f : -1.0f);
    case 30: return std::exp(a);
    case 31: return a * (kPi / 180.0f);
    case 32: return a * (180.0f / kPi);
    case 33: return a >= 0.0f ? std::floor(a) : std::ceil(a);
    case 34: return snap(a, b);
    case 35: return wrap(a, b, c);
    case 36: return pingpong(a, b);
    case 37: return std::fabs(a - b) <= std::fmax(c, 1e-5f) ? 1.0f : 0.0f;
    case 38: return smooth_min(a, b, c);
    default: return -smooth_min(-a, -b, c);
  }
}

void configure_math(const SettingsReader &r, NodeSettings &s) {
  s.mode[0] = r.choice("math_type", kOperations, 0);
  s.flag = r.boolean("use_clamp", false);
}

// in: value1, value2, value3; out: value.
void eval_math(const NodeSettings &s, const ShadingPoint &, const Vec3 *in, Vec3 *out) {
  float v = math_operation(s.mode[0], in[0].x, in[1].x, in[2].x);
  if (s.flag) v = saturate(v);
  out[0] = Vec3(finite_or_zero(v));
}

}  // namespace glimmer::render::nodes
