// Vector Math node (Cycles 3.4 svm_vector_math): every operation, with Cycles' safe
// division/modulo/normalisation; a zero vector normalises to zero (no NaN).
#include "render/nodes/families.h"
#include "render/nodes/math_util.h"

namespace glimmer::render::nodes {

namespace {

enum Op {
  kAdd, kSubtract, kMultiply, kDivide, kMultiplyAdd, kCross, kProject, kReflect, kRefract, kFaceforward, kDot,
  kDistance, kLength, kScale, kNormalize, kSnap, kFloor, kCeil, kModulo, kWrap, kFraction, kAbsolute, kMinimum,
  kMaximum, kSine, kCosine, kTangent
};

constexpr std::initializer_list<const char *> kOperations = {
    "add",         "subtract", "multiply", "divide",   "multiply_add", "cross_product", "project",
    "reflect",     "refract",  "faceforward", "dot_product", "distance", "length",      "scale",
    "normalize",   "snap",     "floor",    "ceil",     "modulo",       "wrap",          "fraction",
    "absolute",    "minimum",  "maximum",  "sine",     "cosine",       "tangent"};

Vec3 per_component(const Vec3 &a, float (*f)(float)) { return {f(a.x), f(a.y), f(a.z)}; }

}  // namespace

void configure_vector_math(const SettingsReader &r, NodeSettings &s) { s.mode[0] = r.choice("math_type", kOperations, 0); }

// in: vector1, vector2, vector3, scale; out: vector, value.
void eval_vector_math(const NodeSettings &s, const ShadingPoint &, const Vec3 *in, Vec3 *out) {
  const Vec3 &a = in[0], &b = in[1], &c = in[2];
  const float scale = in[3].x;
  Vec3 vector(0.0f);
  float value = 0.0f;
  switch (s.mode[0]) {
    case kAdd: vector = a + b; break;
    case kSubtract: vector = a - b; break;
    case kMultiply: vector = a * b; break;
    case kDivide: vector = safe::divide(a, b); break;
    case kMultiplyAdd: vector = a * b + c; break;
    case kCross: vector = cross(a, b); break;
    case kProject: {
      const float b2 = dot(b, b);
      vector = b2 != 0.0f ? b * (dot(a, b) / b2) : Vec3(0.0f);
      break;
    }
    case kReflect: {
      const Vec3 n = safe::normalize(b);
      vector = a - 2.0f * dot(n, a) * n;
      break;
    }
    case kRefract: {  // eta = scale
      const Vec3 n = safe::normalize(b);
      const float cos_i = dot(n, a);
      const float k = 1.0f - scale * scale * (1.0f - cos_i * cos_i);
      vector = k < 0.0f ? Vec3(0.0f) : scale * a - (scale * cos_i + std::sqrt(k)) * n;
      break;
    }
    case kFaceforward: vector = dot(c, b) < 0.0f ? a : -a; break;
    case kDot: value = dot(a, b); break;
    case kDistance: value = length(a - b); break;
    case kLength: value = length(a); break;
    case kScale: vector = a * scale; break;
    case kNormalize: vector = safe::normalize(a); break;
    case kSnap: vector = per_component(safe::divide(a, b), std::floor) * b; break;
    case kFloor: vector = per_component(a, std::floor); break;
    case kCeil: vector = per_component(a, std::ceil); break;
    case kModulo: vector = {safe::modulo(a.x, b.x), safe::modulo(a.y, b.y), safe::modulo(a.z, b.z)}; break;
    case kWrap: vector = {safe::wrap(a.x, b.x, c.x), safe::wrap(a.y, b.y, c.y), safe::wrap(a.z, b.z, c.z)}; break;
    case kFraction: vector = a - per_component(a, std::floor); break;
    case kAbsolute: vector = abs(a); break;
    case kMinimum: vector = min(a, b); break;
    case kMaximum: vector = max(a, b); break;
    case kSine: vector = per_component(a, std::sin); break;
    case kCosine: vector = per_component(a, std::cos); break;
    default: vector = per_component(a, std::tan); break;
  }
  out[0] = finite_or_zero(vector);
  out[1] = Vec3(finite_or_zero(value));
}

}  // namespace glimmer::render::nodes
