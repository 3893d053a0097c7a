// Nodes that perturb the shading normal or give a tangent (Cycles 3.4 svm_node_set_bump,
// svm_node_normal_map, svm_node_tangent), and the shading-normal helpers of shading_normal.h.
// Their outputs feed a closure's `normal` / `tangent` socket (ShaderSystem::shading_frame).
#include <cmath>

#include "render/nodes/families.h"
#include "render/nodes/shading_normal.h"

namespace glimmer::render::nodes {

namespace {

Vec3 safe_normalize(const Vec3 &v) {
  const float len2 = length_squared(v);
  return len2 > 0.0f && std::isfinite(len2) ? v / std::sqrt(len2) : Vec3(0.0f);
}

enum NormalMapSpace { kTangent, kObject, kWorld, kBlenderObject, kBlenderWorld };
enum TangentDirection { kRadial, kUvMap };

}  // namespace

Vec3 ensure_valid_reflection(const Vec3 &Ng, const Vec3 &I, const Vec3 &N) {
  const Vec3 R = 2.0f * dot(N, I) * N - I;
  const float Iz = dot(I, Ng);
  const float t = std::fmin(0.9f * Iz, 0.01f);  // reflections at least as shallow as the incoming ray
  if (dot(Ng, R) >= t) return N;
  // Frame: z = Ng, x = N's part orthogonal to Ng (N' stays in that plane: N' = sqrt(1 - s) X + sqrt(s) Ng).
  Vec3 X = safe_normalize(N - dot(N, Ng) * Ng);
  if (is_zero(X)) X = safe_normalize(I - Iz * Ng);
  if (is_zero(X)) return Ng;
  const float Ix = dot(I, X);
  // dot(R', Ng) = 2 (x Ix + z Iz) z - Iz = t with x = sqrt(1 - s), z = sqrt(s); squared:
  // 4 a s^2 - 4 (a + Iz t) s + (t + Iz)^2 = 0, a = Ix^2 + Iz^2, discriminant 16 Ix^2 (a - t^2).
  const float a = Ix * Ix + Iz * Iz;
  if (!(a > 0.0f)) return Ng;
  const float c = a + Iz * t;
  const float root = std::fabs(Ix) * std::sqrt(std::fmax(a - t * t, 0.0f));
  // Of the two roots, the one that solves the unsquared equation (the other is its mirror image).
  auto normal_for = [&](float s) {
    s = std::fmin(std::fmax(s, 0.0f), 1.0f);
    return std::sqrt(1.0f - s) * X + std::sqrt(s) * Ng;
  };
  auto residual = [&](const Vec3 &n) { return std::fabs(dot(2.0f * dot(n, I) * n - I, Ng) - t); };
  const Vec3 n1 = normal_for((c + root) / (2.0f * a)), n2 = normal_for((c - root) / (2.0f * a));
  return residual(n1) <= residual(n2) ? n1 : n2;
}

Vec3 radial_tangent(const Vec3 &g, int axis) {
  if (axis == 0) return {0.0f, -(g.z - 0.5f), g.y - 0.5f};
  if (axis == 1) return {-(g.z - 0.5f), 0.0f, g.x - 0.5f};
  return {-(g.y - 0.5f), g.x - 0.5f, 0.0f};
}

Vec3 tangent_in_plane(const Vec3 &N, const Vec3 &t) { return cross(N, safe_normalize(cross(t, N))); }

// out: position, normal, tangent, true_normal, incoming, parametric, backfacing, pointiness,
// random_per_island (Cycles 3.4 svm_node_geometry). The tangent is Cycles' primitive_tangent with the generated
// coordinates every mesh has here: radial about z in object space, then made perpendicular to N.
void eval_geometry(const NodeSettings &, const ShadingPoint &sp, const Vec3 *, Vec3 *out) {
  out[0] = sp.P;
  out[1] = sp.N;
  out[2] = tangent_in_plane(sp.N, sp.object_normal_to_world(radial_tangent(sp.generated, 2)));
  out[3] = sp.Ng;
  out[4] = sp.I();
  out[5] = Vec3(0.0f);
  out[6] = Vec3(sp.backfacing ? 1.0f : 0.0f);
  out[7] = Vec3(0.0f);
  out[8] = Vec3(0.0f);
}

void configure_displacement(const SettingsReader &r, NodeSettings &s) { s.mode[0] = r.choice("space", {"object", "world"}, 0); }

// in: height, midlevel, scale, normal; out: displacement = (height - midlevel) scale N (svm_node_displacement).
void eval_displacement(const NodeSettings &, const ShadingPoint &, const Vec3 *in, Vec3 *out) {
  out[0] = (in[0].x - in[1].x) * in[2].x * in[3];
}

void configure_bump(const SettingsReader &r, NodeSettings &s) {
  s.flag = r.boolean("invert", false);
  if (r.boolean("use_object_space", false))
    r.warn("use_object_space: the distance is measured in world space (meshes are stored in world space)");
}

// in: strength, distance, height, normal, then the height one footprint step along x and along y.
// The surface gradient of the height over the footprint (Mikkelsen 2010, "Bump Mapping Unparametrized
// Surfaces on the GPU", eq. 2-4): R1 = dPdy x N, R2 = N x dPdx, det = dPdx . R1,
// grad = (h_x - h) R1 + (h_y - h) R2, N' = normalize(|det| N - distance sign(det) grad), blended with N by
// strength; then Cycles' terminator fix.
void eval_bump(const NodeSettings &s, const ShadingPoint &sp, const Vec3 *in, Vec3 *out) {
  Vec3 N = safe_normalize(in[3]);
  if (is_zero(N)) N = sp.N;
  const float h = in[2].x, h_x = in[4].x, h_y = in[5].x;
  const Vec3 r1 = cross(sp.bump_dPdy, N), r2 = cross(N, sp.bump_dPdx);
  const float det = dot(sp.bump_dPdx, r1);
  const Vec3 surface_gradient = (h_x - h) * r1 + (h_y - h) * r2;
  const float distance = s.flag ? -in[1].x : in[1].x;
  const float strength = std::fmax(in[0].x, 0.0f);
  const Vec3 bumped = safe_normalize(std::fabs(det) * N - distance * (det < 0.0f ? -1.0f : 1.0f) * surface_gradient);
  Vec3 result = is_zero(bumped) ? N : safe_normalize(strength * bumped + (1.0f - strength) * N);
  if (is_zero(result)) result = N;
  out[0] = ensure_valid_reflection(sp.Ng, sp.I(), result);
}

void configure_normal_map(const SettingsReader &r, NodeSettings &s) {
  s.mode[0] = r.choice("space", {"tangent", "object", "world", "blender_object", "blender_world"}, kTangent);
  r.text("attribute");  // the UV map's name: a mesh has one UV map
}

// in: strength, color. Tangent space: the colour (2 c - 1) in the frame of the UV map's tangent T,
// the bitangent sign * N x T and the (unflipped) normal N (without a UV map: the unperturbed normal, as
// Cycles without its tangent attribute); object/world: the colour is the normal (Blender's own spaces
// negate y and z). Then flipped to N's side, blended by strength, terminator fix.
void eval_normal_map(const NodeSettings &s, const ShadingPoint &sp, const Vec3 *in, Vec3 *out) {
  Vec3 c = 2.0f * (in[1] - Vec3(0.5f));
  Vec3 N;
  if (s.mode[0] == kTangent) {
    if (is_zero(sp.tangent)) {
      out[0] = sp.N;
      return;
    }
    const Vec3 normal = sp.backfacing ? -sp.N : sp.N;  // the mesh's own orientation
    const Vec3 B = sp.tangent_sign * cross(normal, sp.tangent);
    N = safe_normalize(c.x * sp.tangent + c.y * B + c.z * normal);
  } else {
    if (s.mode[0] == kBlenderObject || s.mode[0] == kBlenderWorld) c = Vec3(c.x, -c.y, -c.z);
    N = safe_normalize(s.mode[0] == kObject || s.mode[0] == kBlenderObject ? sp.object_normal_to_world(c) : c);
  }
  if (sp.backfacing) N = -N;
  const float strength = in[0].x;
  if (strength != 1.0f) N = safe_normalize(sp.N + (N - sp.N) * std::fmax(strength, 0.0f));
  out[0] = is_zero(N) ? sp.N : ensure_valid_reflection(sp.Ng, sp.I(), N);
}

void configure_tangent(const SettingsReader &r, NodeSettings &s) {
  s.mode[0] = r.choice("direction_type", {"radial", "uv_map"}, kRadial);
  s.mode[1] = r.choice("axis", {"x", "y", "z"}, 2);
  r.text("attribute");  // the UV map's name: a mesh has one UV map
}

// out: tangent, in N's plane: the UV map's tangent (dP/du without a UV map), or radial about an axis of the
// generated coordinates (object space, turned with the object as a normal, as Cycles).
void eval_tangent(const NodeSettings &s, const ShadingPoint &sp, const Vec3 *, Vec3 *out) {
  const Vec3 uv_tangent = is_zero(sp.tangent) ? sp.dPdu : sp.tangent;
  const Vec3 t = s.mode[0] == kUvMap ? uv_tangent : sp.object_normal_to_world(radial_tangent(sp.generated, s.mode[1]));
  out[0] = tangent_in_plane(sp.N, t);
}

}  // namespace glimmer::render::nodes
