// frosted_glass method=sg (de Rousiers et al. 2012, in a ray tracer): see frosted_glass_sg.h.
#include "closures/frosted_glass_sg.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdlib>
#include <initializer_list>
#include <limits>
#include <string_view>

#include "glimmer/exit_lobe.h"
#include "glimmer/microfacet_walk.h"
#include "glimmer/rng.h"

namespace glimmer::plugin::frosted {

namespace {

constexpr float kTableRoughnessMax = 1.0f;

// The solid seen directly (no diffuse or glossy bounce before the entry): where kSampledReflection, the stratified
// first roulette and kCurvedExitWaist apply.
bool seen_directly(const GlimmerShadingContext &ctx) { return ctx.diffuse_bounce + ctx.glossy_bounce == 0; }
// Fraction of an SG's energy inside the bounding cone (the paper's 75 %).
constexpr double kBoundingEnergy = 0.75;

// One ray through the object: the hit and the closure found there.
struct InteriorHit {
  GlimmerRayHit hit{};
  GlimmerHitClosure closure{};
  bool same_material = false;
  Vec3 normal{0.0f};  // unit shading normal at the hit, oriented along the ray (outward for a ray leaving)
};

bool host_can_trace_closures(const GlimmerHostServices *host) {
#if GLIMMER_ABI_MINOR >= 3
  return host != nullptr && GLIMMER_HAS_FIELD(host->struct_size, GlimmerHostServices, trace_ray_closure) &&
         host->trace_ray_closure != nullptr;
#else
  (void)host;
  return false;
#endif
}

bool trace_interior(const GlimmerHostServices *host, const SgInputs &in, const Vec3 &origin, const Vec3 &dir,
                    InteriorHit &out) {
  const GlimmerRay ray = unbounded_ray(origin, dir);
  out.hit = GlimmerRayHit{};
  out.hit.struct_size = sizeof(GlimmerRayHit);
  out.closure = GlimmerHitClosure{};
  out.closure.struct_size = sizeof(GlimmerHitClosure);
  if (!host->trace_ray_closure(host->host_data, &ray, &out.hit, &out.closure)) return false;
  if (!(std::isfinite(out.hit.t) && out.hit.t >= 0.0f) || !is_finite(Vec3(out.hit.P))) return false;
  out.same_material = out.closure.instance == in.self && in.self != nullptr;
  Vec3 n(out.hit.N);
  if (!is_finite(n) || !(dot(n, n) > 1e-12f)) n = Vec3(out.hit.Ng);
  if (!is_finite(n) || !(dot(n, n) > 1e-12f)) return false;
  n = normalize(n);
  out.normal = dot(n, dir) >= 0.0f ? n : -n;
  return true;
}

// The value of a varying parameter at a hit (clamped to its spec), else `constant`.
const GlimmerVaryingValue *hit_value(const SgInputs &in, const GlimmerHitClosure &c, uint32_t param) {
  const uint32_t count = std::min<uint32_t>(c.varying_count, GLIMMER_HIT_MAX_VARYING);
  if (param >= in.schema.size()) return nullptr;
  for (uint32_t i = 0; i < count; ++i)
    if (c.varying[i].param == param) return &c.varying[i];
  return nullptr;
}
float clamp_to(const GlimmerParamSpec &spec, float v, float constant) {
  return std::isfinite(v) ? std::clamp(v, spec.min_value, spec.max_value) : constant;
}
float hit_roughness(const SgInputs &in, const GlimmerHitClosure &c) {
  const GlimmerVaryingValue *v = hit_value(in, c, in.roughness_param);
  return v ? clamp_to(in.schema[in.roughness_param], v->value[0], in.constant_roughness) : in.constant_roughness;
}
Spectrum hit_color(const SgInputs &in, const GlimmerHitClosure &c) {
  const GlimmerVaryingValue *v = hit_value(in, c, in.color_param);
  if (!v) return in.constant_color;
  const GlimmerParamSpec &s = in.schema[in.color_param];
  return {clamp_to(s, v->value[0], in.constant_color.x), clamp_to(s, v->value[1], in.constant_color.y),
          clamp_to(s, v->value[2], in.constant_color.z)};
}

// The table's SG for incidence `wi_dir` (unit, on the +z side of the frame) turned into world space: the
// table's frame has wi = (sin theta, 0, cos theta); x here is wi's tangential direction.
// `axes`: the table's axes of (eta, roughness) (table_axes), made once for the lookups that share them.
// table_lobe in two steps (session 38): the lookup (TableLookup: the energy, and the lobe kept), then the SG in world
// space (table_lobe_sg) only where it is used; the solid walk's exit events that reflect need the energy alone.
struct TableLookup {
  TransmissionLobe lobe;
  Vec3 w{0.0f};  // wi_dir in the frame
  float cos_i = 1.0f;
};
bool table_lookup(const TransmissionSgTable &table, const TransmissionSgTable::Axes &axes, const Frame &frame,
                  const Vec3 &wi_dir, TableLookup &out) {
  out.w = frame.to_local(wi_dir);
  out.cos_i = std::clamp(out.w.z, 1e-4f, 1.0f);
  return table.lookup(out.cos_i, axes, out.lobe);
}
bool table_lobe_sg(const TableLookup &l, const TransmissionSgTable::Axes &axes, const Frame &frame,
                   SphericalGaussian &sg, float &energy) {
  const TransmissionLobe &lobe = l.lobe;
  const float cos_i = l.cos_i;
  const float tx = l.w.x, ty = l.w.y, tl = std::sqrt(tx * tx + ty * ty);
  const Vec3 x_dir = tl > 1e-7f ? frame.to_world(Vec3(tx / tl, ty / tl, 0.0f)) : frame.s;
  const SphericalGaussian local = lobe.sg(cos_i, axes.eta);
  sg.axis = normalize(x_dir * local.axis.x + frame.n * local.axis.z);
  sg.sharpness = std::clamp(local.sharpness, 1e-3f, 1e7f);
  sg.amplitude = local.amplitude;
  energy = std::clamp(lobe.energy, 0.0f, 1.0f);
  return is_finite(sg.axis);
}
bool table_lobe(const TransmissionSgTable &table, const TransmissionSgTable::Axes &axes, const Frame &frame,
                const Vec3 &wi_dir, SphericalGaussian &sg, float &energy) {
  TableLookup l;
  return table_lookup(table, axes, frame, wi_dir, l) && table_lobe_sg(l, axes, frame, sg, energy);
}
// The table's axes for relative IOR eta and `roughness` as the lookups read it (clamped to the table's range): the
// roughness and IOR taps, the same for every incidence (issue 12, session 22: made once per shading point, or once
// per exit event, instead of once per lookup). Session 28 (frostedcost28): this thread's last two (eta, roughness)
// and their axes kept (a solid's entry and exits, a pane's front samples and exits: one entering and one leaving
// pair per material; ~330 instructions each made): returned when eta and the clamped roughness compare equal (the
// same inputs, so the same bits; NaN never equal).
TransmissionSgTable::Axes table_axes(float eta, float roughness) {
  struct Kept {
    float eta = std::numeric_limits<float>::quiet_NaN(), roughness = 0.0f;
    TransmissionSgTable::Axes axes;
  };
  thread_local Kept kept[2];
  thread_local int oldest = 0;
  const float r = std::clamp(roughness, TransmissionSgTable::kRoughnessMin, kTableRoughnessMax);
  for (const Kept &k : kept)
    if (k.eta == eta && k.roughness == r) return k.axes;
  Kept &k = kept[oldest];
  oldest ^= 1;
  k.axes = TransmissionSgTable::axes(eta, r);
  k.eta = eta, k.roughness = r;
  return k.axes;
}
bool table_lobe(const TransmissionSgTable &table, const Frame &frame, const Vec3 &wi_dir, float eta, float roughness,
                SphericalGaussian &sg, float &energy) {
  return table_lobe(table, table_axes(eta, roughness), frame, wi_dir, sg, energy);
}

// Polar angle of the cone around an SG's axis holding kBoundingEnergy of its energy (de Rousiers eq. 9).
float bounding_angle(float kappa) {
  return std::acos(float(std::pow(1.0 - kBoundingEnergy, 1.0 / (double(kappa) + 1.0))));
}

// Toksvig: the length of the mean of unit normals gives the NDF's slope variance alpha^2 = 2 (1 - |n|) / |n|.
float toksvig_alpha2(float mean_length) {
  const float len = std::clamp(mean_length, 1e-4f, 1.0f);
  return 2.0f * (1.0f - len) / len;
}

// One segment inside: the axis and 4 bounding rays from `origin` along `axis` (cone of the internal lobe,
// sharpness kappa_in). Returns the axis hit and the mean exit normal.
struct Segment {
  InteriorHit axis;
  Vec3 mean_normal{0.0f};
  float mean_length = 1.0f;
  int bounding_count = 0;  // bounding rays that left through the same material
  Vec3 bounding_dir[4], bounding_normal[4], bounding_P[4];
  // exit_curvature below kPlanarExitCurvature over all bounding rays and over the facing ones (trace_segment; a
  // pane's flat face: unset).
  bool planar = false, planar_facing = false;
};
constexpr float kPlanarExitCurvature = 0.1f;  // exit_curvature below it: a planar exit (a slab's back face)
// How much the exit surface turns under the traced rays: the mean over the bounding rays of the angle between
// their exit normal and the axis ray's, over the angle between their direction and the axis (0: a planar exit;
// the unit sphere's 1-2). Not measured (no bounding ray left through the material): infinite, treated as curved.
// `curvature_facing`: only the bounding rays whose exit normal faces the axis ray's (a wide lobe's ray that turns back
// to a slab's entry face is left out; reflected_axis' planarity test); none of them: infinite. Both in one pass, once
// per segment (session 28: the roulette, the reflection and the exit mixture each made one before; the same sums).
// Only their comparisons with kPlanarExitCurvature are used: exit_planarity (session 38: the acos only where bounds on
// it do not decide; the same decisions).
void exit_curvature(Segment &seg, const Vec3 &axis) {
  float c[4], d[4];
  for (int i = 0; i < seg.bounding_count; ++i)
    c[i] = dot(seg.bounding_normal[i], seg.axis.normal), d[i] = dot(seg.bounding_dir[i], axis);
  const ExitPlanarity p = exit_planarity(c, d, seg.bounding_count, kPlanarExitCurvature);
  seg.planar = p.planar, seg.planar_facing = p.planar_facing;
}
// The bounding cone's cos and sin for sharpness kappa (bounding_angle): this thread's last kappa and its pair kept
// (session 38: a pow, an acos and a sincos per segment; the camera-seen walk's kappa is kEntryKappa at nearly every
// segment). Returned when kappa compares equal (the same input, so the same bits; NaN never equal).
struct BoundingCone {
  float kappa = std::numeric_limits<float>::quiet_NaN(), cos_theta = 1.0f, sin_theta = 0.0f;
};
BoundingCone bounding_cone(float kappa) {
  thread_local BoundingCone kept;
  if (kept.kappa == kappa) return kept;
  const float theta_b = bounding_angle(kappa);
  kept.cos_theta = std::cos(theta_b), kept.sin_theta = std::sin(theta_b);
  kept.kappa = kappa;
  return kept;
}
// The solid walk's exit lookup (session 38): table_lobe's energy and its success, with the SG left for table_lobe_sg
// (`deferred`) where it can be: a leaving lookup (eta < 1), whose local axis is (-s, 0, -sqrt(1 - s^2)) with s =
// clamp(sin theta_i / eta + axis_offset, -1, 1) (TransmissionLobe::sg): finite unless axis_offset is NaN (an infinite
// offset clamps to +-1), then turned by the finite unit frame into a unit vector, so table_lobe's is_finite(sg.axis)
// is !isnan(axis_offset) there and table_lobe's result is decided here. Otherwise (eta >= 1) the SG is made at once.
bool exit_lookup_energy(const TransmissionSgTable &table, const TransmissionSgTable::Axes &axes, const Frame &frame,
                        const Vec3 &wi_dir, TableLookup &l, SphericalGaussian &sg, float &energy, bool &deferred) {
  if (!table_lookup(table, axes, frame, wi_dir, l)) return false;
  deferred = axes.eta < 1.0f;
  if (!deferred) return table_lobe_sg(l, axes, frame, sg, energy);
  if (std::isnan(l.lobe.axis_offset)) return false;
  energy = std::clamp(l.lobe.energy, 0.0f, 1.0f);
  return true;
}

// `rays`: the bounding rays traced, the first `rays` of (+s, -s, +t, -t) (4: the paper's; bounding_rays' rule).
bool trace_segment(const GlimmerHostServices *host, const SgInputs &in, const Vec3 &origin, const Vec3 &axis,
                   float kappa_in, Segment &seg, int rays = 4) {
  if (!trace_interior(host, in, origin, axis, seg.axis) || !seg.axis.same_material) return false;
  Vec3 sum = seg.axis.normal;
  int count = 1;
  const BoundingCone cone = bounding_cone(kappa_in);
  const float c = cone.cos_theta, s = cone.sin_theta;
  const Frame f = Frame::from_normal(axis);
  const Vec3 offsets[4] = {f.s, -f.s, f.t, -f.t};
  for (int i = 0; i < rays; ++i) {
    const Vec3 &o = offsets[i];
    InteriorHit h;
    const Vec3 dir = normalize(axis * c + o * s);
    if (trace_interior(host, in, origin, dir, h) && h.same_material) {
      sum += h.normal;
      ++count;
      seg.bounding_dir[seg.bounding_count] = dir;
      seg.bounding_P[seg.bounding_count] = Vec3(h.hit.P);
      seg.bounding_normal[seg.bounding_count++] = h.normal;
    }
  }
  sum /= float(count);
  seg.mean_length = length(sum);
  seg.mean_normal = seg.mean_length > 1e-6f ? sum / seg.mean_length : seg.axis.normal;
  exit_curvature(seg, axis);
  return true;
}

// Direction d (inside, unit) leaving through the smooth interface with outward normal n; beyond the critical
// angle the incident ray is clamped to it (Wyman 2005), which leaves at grazing.
Vec3 refract_out(const Vec3 &d, const Vec3 &n, float ior) {
  Vec3 out;
  if (mf::refract(-d, -n, 1.0f / ior, out)) return out;
  const Vec3 tangential = d - n * dot(d, n);
  const float len = length(tangential);
  return len > 1e-7f ? normalize(tangential / len + n * 1e-3f) : n;
}

// Sharpness of the SG whose kBoundingEnergy cone has half-angle theta (inverse of bounding_angle).
float sharpness_of_cone(float cos_theta) {
  const double c = std::clamp(double(cos_theta), -1.0, 1.0 - 1e-9);
  if (c <= 0.0) return 1e-3f;
  return float(std::clamp(std::log(1.0 - kBoundingEnergy) / std::log(c) - 1.0, 1e-3, 1e7));
}

// The geometric spread of the transmitted lobe outside, traced: each bounding ray refracted through its own
// exit normal (smooth), its angle to the axis refracted through the mean normal -> the cone's sharpness. It holds
// the internal lobe's width, the magnification by Snell's law and the curvature of the exit surface together (a
// sphere focuses: the exit normals turn with the rays). Infinite (no spread) without bounding hits.
float traced_cone_sharpness(const Segment &seg, const Vec3 &axis_out, float ior) {
  if (seg.bounding_count == 0) return 1e7f;
  float cos_sum = 0.0f;
  for (int i = 0; i < seg.bounding_count; ++i)
    cos_sum += dot(refract_out(seg.bounding_dir[i], seg.bounding_normal[i], ior), axis_out);
  return sharpness_of_cone(cos_sum / float(seg.bounding_count));
}

// The leaving interface's energy at the axis (`axis_energy`) and at each bounding ray, each at its incidence on its
// own exit normal (`ray` 0 where the table has no lobe: counted as reflected by `reflected_axis`, left out of `mean`).
struct ExitEnergies {
  float axis = 0.0f, ray[4] = {};
  bool valid[4] = {};
  int count = 0;  // bounding rays
  // E_x averaged over the axis and the bounding rays that the table covers.
  float mean() const {
    float sum = axis;
    int n = 1;
    for (int i = 0; i < count; ++i)
      if (valid[i]) sum += ray[i], ++n;
    return sum / float(n);
  }
};
// `exit_axes`: the leaving table's axes, table_axes(1 / ior, roughness).
ExitEnergies exit_energies(const TransmissionSgTable &table, const Segment &seg, float axis_energy,
                           const TransmissionSgTable::Axes &exit_axes) {
  ExitEnergies e;
  e.axis = axis_energy;
  e.count = seg.bounding_count;
  // The 4 lookups share (1 / ior, r): one batch (the same energies as 4 lookup() calls, bit for bit).
  static_assert(4 <= TransmissionSgTable::kMaxEnergyBatch);
  float cos_i[4], energy[4];
  bool valid[4];
  for (int i = 0; i < seg.bounding_count; ++i)
    cos_i[i] = std::clamp(dot(seg.bounding_dir[i], seg.bounding_normal[i]), 1e-4f, 1.0f);
  table.lookup_energies(cos_i, seg.bounding_count, exit_axes, energy, valid);
  for (int i = 0; i < seg.bounding_count; ++i) {
    if (!valid[i]) continue;
    e.ray[i] = std::clamp(energy[i], 0.0f, 1.0f);
    e.valid[i] = true;
  }
  return e;
}
float mean_exit_energy(const TransmissionSgTable &table, const Segment &seg, float axis_energy,
                       const TransmissionSgTable::Axes &exit_axes) {
  return exit_energies(table, seg, axis_energy, exit_axes).mean();
}

// The part of the internal lobe that the exit reflects (issue 12, fourteenth session; docs/frosted_glass.md "The
// reflected remainder's own axis"): the axis and the bounding rays weighted by their reflectance 1 - E_i. At an
// oblique exit the rays toward grazing (beyond the critical angle) reflect and the rays toward the normal leave, so
// the reflected light travels further from the normal than the whole lobe's axis. Before, the reflected lobe kept the
// whole lobe's axis; between parallel faces (a slab: mirrored twice, the same incidence again) it came back to the
// exit and left through its normal side, the part that had already left (slab r 0.3, the small light seen 50 deg off
// axis toward the exit normal at 70 deg incidence: 3.6x the exact light). Used at planar exits only (trace_exit_lobe:
// on the sphere it helped, 0.0424 -> 0.0391, but the textured sphere went 0.0114 -> 0.0133 at 16384 sg paths).
// Unchanged when nothing reflects.
Vec3 reflected_axis(const Segment &seg, const Vec3 &axis, const ExitEnergies &e) {
  Vec3 sum = axis * (1.0f - std::clamp(e.axis, 0.0f, 1.0f));
  float weight = 1.0f - std::clamp(e.axis, 0.0f, 1.0f);
  for (int i = 0; i < e.count; ++i) {
    sum += seg.bounding_dir[i] * (1.0f - e.ray[i]);
    weight += 1.0f - e.ray[i];
  }
  if (!(weight > 1e-6f) || !(dot(sum, sum) > 1e-12f)) return axis;
  const Vec3 m = normalize(sum);
  return is_finite(m) ? m : axis;
}

void add_tail_ladder(const PaneLadder &ladder, ExitLobe &m);  // the pane's ladder (below), reused for planar exits

// kSampledReflection (frosted_glass_sg.h): direction d (inside) reflected at hit h (h.normal outward) by the interface
// lobe at `roughness` (SgInputs::lobe when it is the lobe's, else built), drawn until one draw reflects (at most 64,
// from numbers of their own); d becomes it. False: no reflection within 64 draws, or one that does not go back in.
bool sample_reflection(const SgInputs &in, const InteriorHit &h, float roughness, uint32_t seed, Vec3 &d,
                       float first_u = -1.0f) {
  if (in.lobe == nullptr) return false;
  DielectricLobe scratch;
  if (roughness != in.lobe_roughness)
    scratch.build(MicrofacetLobeParams::make(kMultiGgx, roughness, 0.0f), in.ior, false, false);
  const DielectricLobe &lobe = roughness == in.lobe_roughness ? *in.lobe : scratch;
  const Frame f = Frame::from_normal(h.normal);  // +z outward: d arrives from below
  const Vec3 wi = f.to_local(-d);
  mf::WalkRng rng(hash_u32x2(seed, 0x7265666cu));
  Vec3 wo;
  for (int k = 0; k < 64; ++k) {
    // The numbers in the order GCC evaluated the former Vec3(rng.next(), rng.next(), rng.next()) (right to left:
    // the same draws as before bit for bit); the first draw's x is first_u when given. sample_reflection: sample()'s
    // reflections bit for bit, without the transmitted draws' refraction and every draw's weight (session 38).
    const float u2 = rng.next(), u1 = rng.next(), u0 = rng.next();
    const Vec3 numbers(k == 0 && first_u >= 0.0f ? first_u : u0, u1, u2);
    if (!lobe.sample_reflection(wi, numbers, wo)) continue;
    const Vec3 r = normalize(f.to_world(wo));
    if (!(dot(r, h.normal) < 0.0f) || !is_finite(r)) return false;
    d = r;
    return true;
  }
  return false;
}

// Step 5's internal reflection of the lobe (axis, sharpness kappa_in) at the exit segment `seg` (mean normal n, the
// exit's alpha^2): kSampledReflection at a curved exit draws the axis (`seed` its numbers) and keeps the width (at a
// planar exit, a slab's, it made the accuracy set's slab worse: 0.0187 -> 0.0217); otherwise the axis is
// mirrored about the mean normal (at a planar exit the reflected part's axis first, reflected_axis) and the lobe
// widened by the rough reflection. False: no reflection drawn.
bool reflect_internal(const SgInputs &in, const Segment &seg, const ExitEnergies &energies, const Vec3 &n,
                      float alpha2, uint32_t seed, Vec3 &axis, float &kappa_in, float first_u) {
  const bool planar = seg.planar_facing;
  if (in.sampled_reflection && !planar)
    return sample_reflection(in, seg.axis, hit_roughness(in, seg.axis.closure), seed, axis, first_u);
  const float kappa_reflect = 2.0f / std::max(alpha2, 1e-7f);  // NDF sharpness; reflected lobe: kappa / 4
  if (planar) axis = reflected_axis(seg, axis, energies);
  kappa_in = 1.0f / (1.0f / kappa_in + 4.0f / kappa_reflect);
  axis = normalize(axis - n * (2.0f * dot(axis, n)));
  return true;
}

float roulette(uint32_t seed, int event) {
  return float(hash_u32x3(seed, uint32_t(event), 0x5bd1e995u) >> 8) * 0x1p-24f;
}
// Step 5's roulette number at `event`: stratified_first_roulette's `first_u` at event 0 when given (>= 0), else the
// hashed one; the walk leaves when u < E_x. `rest`: what is left of a stratified number given the outcome (level 2),
// u / E_x given the exit, (u - E_x) / (1 - E_x) given a reflection (uniform on [0, 1) either way); -1: none.
struct RouletteNumber {
  float u = 0.0f, rest = -1.0f;
  bool leaves = false;
};
RouletteNumber roulette_number(const SgInputs &in, uint32_t seed, int event, float first_u, float transmitted) {
  RouletteNumber r;
  const bool stratified = event == 0 && first_u >= 0.0f;
  r.u = stratified ? first_u : roulette(seed, event);
  r.leaves = !(r.u >= transmitted);
  const int level = stratified_roulette_level(in);
  if (stratified && (level == 2 || level == kStratifiedDrawControl)) {
    const float rest = r.leaves ? r.u / transmitted : (r.u - transmitted) / (1.0f - transmitted);
    if (std::isfinite(rest)) r.rest = std::clamp(rest, 0.0f, 0x1.fffffep-1f);
  }
  return r;
}

// SgVariant::kMixture (frosted_glass_sg.h, "exit lobe mixture"): one lobe per traced ray that left, each refracted
// through its own exit normal by the leaving table, weights (1 - s, s / 4 ...) x E_i, each lobe's width its exit
// roughness convolved with the residual (1 - v) of the traced geometric spread. False: no lobe has energy.
bool build_exit_mixture(const TransmissionSgTable &table, const Segment &seg, const Vec3 &axis, float kappa_in,
                        float kappa_geometric, float ior, float roughness_exit, float variance, float tail,
                        ExitLobe &out) {
  const float v = std::clamp(std::isfinite(variance) ? variance : 0.0f, 0.0f, 1.0f);
  const float theta_b = bounding_angle(kappa_in);
  const float point_var = 0.5f * std::max(kappa_in, 1e-6f) * theta_b * theta_b;  // the variance share at s = 1
  const float s = seg.bounding_count > 0 ? std::clamp(v / std::max(point_var, 1e-6f), 0.0f, 1.0f) : 0.0f;
  const float residual = 1.0f - std::min(1.0f, s * point_var);  // the variance the points do not carry
  const TransmissionSgTable::Axes exit_axes = table_axes(1.0f / ior, roughness_exit);  // the lobes' (1 / ior, r)
  out.lobe_count = 0;
  float total = 0.0f;
  for (int i = -1; i < seg.bounding_count; ++i) {
    const Vec3 d = i < 0 ? axis : seg.bounding_dir[i];
    const Vec3 n = i < 0 ? seg.axis.normal : seg.bounding_normal[i];
    SphericalGaussian lobe;
    float energy = 0.0f;
    if (!table_lobe(table, exit_axes, Frame::from_normal(-n), -d, lobe, energy)) continue;
    const float share = i < 0 ? 1.0f - s * float(seg.bounding_count) / 4.0f : s / 4.0f;
    const float w = share * energy;
    if (!(w > 0.0f) || !is_finite(lobe.axis)) continue;
    ExitLobe::MixtureLobe &l = out.lobe[out.lobe_count++];
    l.axis = lobe.axis;
    l.sharpness =
        std::clamp(1.0f / (1.0f / lobe.sharpness + residual / std::max(kappa_geometric, 1e-6f)), 1e-3f, 1e7f);
    l.weight = w;
    total += w;
  }
  if (!(total > 0.0f)) return false;
  for (int k = 0; k < out.lobe_count; ++k) out.lobe[k].weight /= total;
  const float t = std::clamp(std::isfinite(tail) ? tail : 0.0f, 0.0f, 0.2f);
  if (t > 0.0f) {  // core (1 - t, kappa (1 - t) / (1 - 4 t)) + tail (t, kappa / 4): the same variance
    const int n = out.lobe_count;
    for (int k = 0; k < n; ++k) {
      out.lobe[n + k].axis = out.lobe[k].axis;
      out.lobe[n + k].sharpness = std::max(out.lobe[k].sharpness * 0.25f, 1e-3f);
      out.lobe[n + k].weight = out.lobe[k].weight * t;
      out.lobe[k].sharpness = std::min(out.lobe[k].sharpness * (1.0f - t) / (1.0f - 4.0f * t), 1e7f);
      out.lobe[k].weight *= 1.0f - t;
    }
    out.lobe_count = 2 * n;
  }
  return true;
}

// A measurement knob (docs/frosted_glass.md's before / after runs): the environment variable `name` as a float clamped
// to [lo, hi]; `fallback` (the default) when unset, empty or not finite. Each caller reads it once (a static).
float measurement_knob(const char *name, float fallback, float lo, float hi) {
  const char *e = std::getenv(name);
  if (e == nullptr || *e == '\0') return fallback;
  const float v = std::strtof(e, nullptr);
  return std::isfinite(v) ? std::clamp(v, lo, hi) : fallback;
}
// Its int form (the switches: levels, on / off): `name` read as atoi does (no number: 0), clamped to [lo, hi].
int measurement_knob(const char *name, int fallback, int lo, int hi) {
  const char *e = std::getenv(name);
  if (e == nullptr || *e == '\0') return fallback;
  return std::clamp(std::atoi(e), lo, hi);
}
// Its form for a level set with gaps (a test-only control beside the levels): `name` exactly one of `levels` (a whole
// decimal number, nothing after it), else `fallback`: not clamped, so a typo cannot select a neighbouring level.
int measurement_level(const char *name, int fallback, std::initializer_list<int> levels) {
  const char *e = std::getenv(name);
  if (e == nullptr || *e == '\0') return fallback;
  char *end = nullptr;
  const long l = std::strtol(e, &end, 10);
  if (*end != '\0') return fallback;
  return std::find(levels.begin(), levels.end(), l) != levels.end() ? int(l) : fallback;
}

// A tail for solids (issue 12, twelfth session; docs/frosted_glass.md "A tail for solids"). The exit mixture of
// method=sg's rule (SgInputs::mixture_tail < 0) by what the traced rays measured:
//  - a planar exit (exit_curvature < kPlanarExitCurvature: a slab's back face) above kMixtureRoughnessMax: the
//    per-ray lobes as cores (sharpness x 2; x 3 until the thirteenth session) plus the pane's heavy-tail ladder about
//    the axis lobe (add_tail_ladder, kPlanarSolidTail), where the rule had the single SG (slab 0.5 / 0.8: 0.087 / 0.095
//    -> 0.039 / 0.031);
//  - a curved exit (a sphere focuses) below kCurvedSingleSgBelow: no tail, the single SG (exit harness, sphere
//    r 0.1: 9.4 -> 7.7 %); above kMixtureRoughnessMax the single SG as before (the pane's ladder made the sphere
//    worse: accuracy set 0.0424 -> 0.0534);
//  - otherwise (0.2..0.4 curved, <= 0.4 planar) the per-ray kappa / 4 tails as before.
// An explicit mixture_tail (>= 0, the tests' variants) is the per-ray mixture with that tail. lobe_count 0: the
// single SG (out.sg). False: no lobe has energy.
// kCurvedTail, or for measurements only (docs/history/frosted_glass_sessions.md "Eighteenth / nineteenth session": the
// bench's before / after with one build) the environment's GLIMMER_FROSTED_CURVED_TAIL (0: the unsplit single SG), read
// once. Session 22: the default is kCurvedExitShape (below); the split with t is the nineteenth session's, still
// reachable for before / after runs; unset: -1.
float curved_tail() {
  static const float t = measurement_knob("GLIMMER_FROSTED_CURVED_TAIL", -1.0f, 0.0f, 0.2f);
  return t;
}
// The single SG (out.sg) as a core (1 - t, kappa (1 - t) / (1 - 4 t)) and a tail (t, kappa / 4) of the same axis
// and variance (frosted_glass_sg.h, kCurvedTail); t <= 0 (or not finite): the single SG (lobe_count 0).
void split_single_sg(float t, ExitLobe &out) {
  out.lobe_count = 0;
  if (!(t > 0.0f)) return;
  t = std::min(t, 0.2f);
  ExitLobe::MixtureLobe &core = out.lobe[0], &tail = out.lobe[1];
  core.axis = out.sg.axis;
  core.sharpness = std::min(out.sg.sharpness * (1.0f - t) / (1.0f - 4.0f * t), 1e7f);
  core.weight = 1.0f - t;
  tail.axis = out.sg.axis;
  tail.sharpness = std::max(out.sg.sharpness * 0.25f, 1e-3f);
  tail.weight = t;
  out.lobe_count = 2;
}
// A CurvedShape applied to the single SG (out.sg): its lobes about the SG's axis; false (lobe_count 0) when the
// shape has no lobe with a positive share and a finite positive factor.
bool apply_curved_shape(const CurvedShape &shape, ExitLobe &out) {
  out.lobe_count = 0;
  float total = 0.0f;
  for (int k = 0; k < std::min(shape.count, kCurvedShapeLobes); ++k) {
    const float w = shape.weight[k], f = shape.factor[k];
    if (!(w > 0.0f && f > 0.0f && std::isfinite(w) && std::isfinite(f))) continue;
    ExitLobe::MixtureLobe &l = out.lobe[out.lobe_count++];
    l.axis = out.sg.axis;
    l.sharpness = std::clamp(out.sg.sharpness * f, 1e-3f, 1e7f);
    l.weight = w;
    total += w;
  }
  if (!(total > 0.0f)) return out.lobe_count = 0, false;
  for (int k = 0; k < out.lobe_count; ++k) out.lobe[k].weight /= total;
  return true;
}
// For measurements only: the environment's GLIMMER_FROSTED_CURVED_SHAPE = "w:f,w:f[,w:f]" (shares and sharpness
// factors of the curved exit's lobes, CurvedShape) replaces the split, read once; unset or unparsable: nullptr.
const CurvedShape *curved_shape_override() {
  static const CurvedShape shape = [] {
    CurvedShape c;
    const char *e = std::getenv("GLIMMER_FROSTED_CURVED_SHAPE");
    while (e != nullptr && *e != '\0' && c.count < kCurvedShapeLobes) {
      char *end = nullptr;
      const float w = std::strtof(e, &end);
      if (end == e || *end != ':') return CurvedShape{};
      e = end + 1;
      const float f = std::strtof(e, &end);
      if (end == e) return CurvedShape{};
      c.weight[c.count] = w;
      c.factor[c.count++] = f;
      e = *end == ',' ? end + 1 : nullptr;
    }
    return c;
  }();
  return shape.count > 0 ? &shape : nullptr;
}
// The curved exit's axis shift (session 22, frostedexit22): refracting the internal lobe's axis alone maps the
// lobe's mean through a nonlinear map (Snell's law bends the rays further from the normal more): the exact walk's
// mean exit direction leans outward of it on the sphere (~1.5 deg at roughness 0.5, IOR 1.5;
// FrostedGlassSg.ExitOfTheSphereAroundTheCausticBench). The mean of the smooth refractions of the axis and the 4
// bounding rays, each through its own exit normal, as a quadrature of the internal lobe (the points' second moment
// the vMF's: weight 1 - 1 / ln 4 on the bounding rays, theta_b^2 = 2 ln 4 / kappa), minus the axis' own refraction:
// the shift. Zero unless all 4 bounding rays left through the material.
Vec3 refracted_mean_shift(const Segment &seg, const Vec3 &axis, float ior) {
  if (seg.bounding_count != 4) return Vec3(0.0f);
  constexpr float kBoundingShare = 1.0f - 0.72134752f;  // 1 - 1 / ln 4 on the axis
  const Vec3 r0 = refract_out(axis, seg.axis.normal, ior);
  Vec3 sum = r0 * kBoundingShare;
  for (int i = 0; i < 4; ++i)
    sum += refract_out(seg.bounding_dir[i], seg.bounding_normal[i], ior) * ((1.0f - kBoundingShare) * 0.25f);
  if (!(dot(sum, sum) > 1e-12f)) return Vec3(0.0f);
  const Vec3 shift = normalize(sum) - r0;
  return is_finite(shift) ? shift : Vec3(0.0f);
}
// kCurvedAxisShift, or for measurements only GLIMMER_FROSTED_CURVED_SHIFT = k (0: none), read once.
float curved_shift() {
  static const float k = measurement_knob("GLIMMER_FROSTED_CURVED_SHIFT", kCurvedAxisShift, -4.0f, 4.0f);
  return k;
}
constexpr float kCurvedSingleSgBelow = 0.2f;
// kCurvedExitCentroid, or for measurements only GLIMMER_FROSTED_EXIT_CENTROID = s (0: the axis' exit point), read once.
float exit_centroid_scale() {
  static const float s = measurement_knob("GLIMMER_FROSTED_EXIT_CENTROID", kCurvedExitCentroid, -4.0f, 4.0f);
  return s;
}
// The leaving bundle of a segment (session 28, frostedcost28: built once per segment for both of session 27's origin
// rules, the exit-point centroid and the waist, which made it each): the internal lobe's 5 quadrature rays
// (refracted_mean_shift's weights: 1 - 1 / ln 4 on the axis, 1 / (4 ln 4) on each bounding ray), each carried along
// its own smooth exit direction d_i (refract_out) from its exit point P_i to the plane through the axis' exit point P0
// normal to the axis' own smooth exit direction d0: per bounding ray its lateral slope theta_i = (d_i - d0 (d_i . d0))
// / (d_i . d0) and its lateral offset A_i in that plane (the axis' 0), and their mean E[A]. Not valid unless all 4
// bounding rays left through the material, every d_i . d0 > 0.05, and the exit is convex there (every exit point on or
// below P0's tangent plane, normal n0, to a slope of 1e-3 for a mesh's facets; at a concave exit, the shell's cavity,
// the plane lies inside the glass: without this check the accuracy set's shell went 0.0647 -> 0.0734).
struct ExitBundle {
  bool valid = false;
  Vec3 d0{0.0f}, mean_A{0.0f};
  Vec3 A[4], theta[4];
};
constexpr float kBundleRayShare = 0.72134752f * 0.25f;  // 1 / (4 ln 4): refracted_mean_shift's bounding weight
ExitBundle exit_bundle(const Segment &seg, const Vec3 &axis, float ior, const Vec3 &n0) {
  ExitBundle b;
  if (seg.bounding_count != 4) return b;
  const Vec3 P0(seg.axis.hit.P);
  for (int i = 0; i < 4; ++i)
    if (!(dot(seg.bounding_P[i] - P0, n0) <= 1e-3f * length(seg.bounding_P[i] - P0))) return b;
  b.d0 = refract_out(axis, seg.axis.normal, ior);
  for (int i = 0; i < 4; ++i) {
    const Vec3 d = refract_out(seg.bounding_dir[i], seg.bounding_normal[i], ior), r = seg.bounding_P[i] - P0;
    const float along = dot(d, b.d0);
    if (!(along > 0.05f)) return b;
    b.theta[i] = (d - b.d0 * along) / along;
    const float c = dot(r, b.d0);
    b.A[i] = (r - b.d0 * c) - b.theta[i] * c;
    b.mean_A += b.A[i] * kBundleRayShare;
  }
  b.valid = true;
  return b;
}
// kCurvedExitCentroid's offset: the bundle's E[A] slid along d0 back to P0's tangent plane (normal n0, the exit lobe's
// surface), which leaves the bundle's lateral position at every distance along d0 unchanged. Zero unless the bundle is
// valid and d0 leaves the plane by more than 0.1.
Vec3 exit_centroid_offset(const ExitBundle &b, const Vec3 &n0) {
  if (!b.valid) return Vec3(0.0f);
  const float dn = dot(b.d0, n0);
  if (!(dn > 0.1f)) return Vec3(0.0f);
  const Vec3 offset = b.mean_A - b.d0 * (dot(b.mean_A, n0) / dn);
  return is_finite(offset) ? offset : Vec3(0.0f);
}
// kCurvedExitWaist, or for measurements only GLIMMER_FROSTED_EXIT_WAIST = w (0: none), read once.
float exit_waist_scale() {
  static const float w = measurement_knob("GLIMMER_FROSTED_EXIT_WAIST", kCurvedExitWaist, 0.0f, 4.0f);
  return w;
}
// kCurvedExitWaist's t* (frosted_glass_sg.h; frostedorigin26's curved_lamp_origin, its waist only) from the bundle's
// A_i and theta_i: t* = -Cov(A, theta) / (Var(theta) + v_r), v_r = 2 (1 / kappa_out - 1 / kappa_geometric) the exit's
// rough scatter (kappa_out the single SG's sharpness before the shape). 0 unless the bundle is valid and the waist lies
// behind the exit.
float bundle_waist(const ExitBundle &b, float kappa_out, float kappa_geometric) {
  if (!b.valid) return 0.0f;
  constexpr float kAxisShare = 1.0f - 0.72134752f;
  Vec3 mean_th(0.0f);
  for (int i = 0; i < 4; ++i) mean_th += b.theta[i] * kBundleRayShare;
  float cov = 0.0f, var = 0.0f;
  for (int i = 0; i < 4; ++i) {
    cov += kBundleRayShare * dot(b.A[i] - b.mean_A, b.theta[i] - mean_th);
    var += kBundleRayShare * dot(b.theta[i] - mean_th, b.theta[i] - mean_th);
  }
  cov += kAxisShare * dot(b.mean_A, mean_th), var += kAxisShare * dot(mean_th, mean_th);
  const float v_r = 2.0f * std::max(0.0f, 1.0f / std::max(kappa_out, 1e-3f) - 1.0f / std::max(kappa_geometric, 1e-3f));
  if (!(var + v_r > 1e-12f)) return 0.0f;
  const float t = -cov / (var + v_r);
  return std::isfinite(t) ? std::min(t, 0.0f) : 0.0f;
}
// Thirteenth session: cores x 3 -> x 2, measured with exit light sampling in the small light's test (its former
// 4096 / 1024 figures, which chose x 3, were mostly sg's noise): small light r 0.5 0.139 -> 0.085, slab band L1 r 0.5
// 0.169 -> 0.086, 2D band L1 0.773 -> 0.601, slab r 0.5 absorbing 0.0281 -> 0.0250, r 0.8 0.0314 -> 0.0308; slab r 0.5
// 0.0386 -> 0.0419 (docs/frosted_glass.md "A skewed exit lobe").
constexpr PaneTail kPlanarSolidTail{0.06f, 4, 0.18f, 2.0f};
constexpr PaneLadder kPlanarSolidLadder = make_pane_ladder(kPlanarSolidTail);  // validated once, at compile time
static_assert(kPlanarSolidLadder.valid, "the planar-solid tail must be a valid ladder");
// kDrawnExitShape (frosted_glass_sg.h), or for measurements only GLIMMER_FROSTED_DRAWN_SHAPE = 0 (the front SG's
// shape, curved_exit_shape's, on the drawn entry axis too: sessions 28's images), read once.
bool drawn_exit_shape() {
  static const bool on = measurement_knob("GLIMMER_FROSTED_DRAWN_SHAPE", int(kDrawnExitShape), 0, 1) != 0;
  return on;
}
// kFloorViewShift, or for measurements only GLIMMER_FROSTED_FLOOR_SHIFT = k, read once.
float floor_view_shift() {
  static const float k = measurement_knob("GLIMMER_FROSTED_FLOOR_SHIFT", kFloorViewShift, -4.0f, 4.0f);
  return k;
}
// kFloorViewExit (frosted_glass_sg.h, 0: main's floor view; SgInputs::floor_exit a test's), or for measurements only
// GLIMMER_FROSTED_FLOOR_EXIT = 1 (session 30's fit) / 2 (session 31's shift and origin rule), read once: where the
// solid is seen from the floor
// (not seen directly, the front SG's axis), the entry roughness at most kCurvedShapeRoughness[0], by the rule (no
// test's shape or tail, no measurement shape or tail). 0: not there.
int floor_view_exit(const SgInputs &in, bool seen_directly, bool drawn) {
  static const int by_rule = measurement_knob("GLIMMER_FROSTED_FLOOR_EXIT", kFloorViewExit, 0, 2);
  const int mode = in.floor_exit >= 0 ? std::min(in.floor_exit, 2) : by_rule;
  const bool there = !seen_directly && !drawn && !(in.roughness > kCurvedShapeRoughness[0]) &&
                     in.curved_shape == nullptr && in.curved_tail < 0.0f && curved_shape_override() == nullptr &&
                     curved_tail() < 0.0f;
  return there ? mode : 0;
}
// kFloorViewOrigin / kFloorViewOriginScale, or for measurements only GLIMMER_FROSTED_FLOOR_ORIGIN = m (0: none) and
// GLIMMER_FROSTED_FLOOR_ORIGIN_SCALE = s, read once.
int floor_view_origin() {
  static const int m = measurement_knob("GLIMMER_FROSTED_FLOOR_ORIGIN", kFloorViewOrigin, 0, 3);
  return m;
}
float floor_view_origin_scale() {
  static const float s = measurement_knob("GLIMMER_FROSTED_FLOOR_ORIGIN_SCALE", kFloorViewOriginScale, 0.0f, 8.0f);
  return s;
}
// kFloorViewOrigin 2 / 3's jitter axes: the principal axes of the bundle's exit points' lateral covariance (the axis'
// point at 0 and the 4 A_i, refracted_mean_shift's weights), each x the square root of its variance x `scale` (3:
// the major one only), slid along d0 to P0's tangent plane (normal n0) as exit_centroid_offset; zero unless the bundle
// is valid and d0 leaves the plane by more than 0.1.
void origin_jitter_axes(const ExitBundle &b, const Vec3 &n0, float scale, bool major_only, Vec3 (&out)[2]) {
  out[0] = out[1] = Vec3(0.0f);
  const float dn = b.valid ? dot(b.d0, n0) : 0.0f;
  if (!(dn > 0.1f) || !(scale > 0.0f)) return;
  const Frame f = Frame::from_normal(b.d0);
  const float mx = dot(b.mean_A, f.s), my = dot(b.mean_A, f.t);
  float cxx = -mx * mx, cxy = -mx * my, cyy = -my * my;
  for (int i = 0; i < 4; ++i) {
    const float x = dot(b.A[i], f.s), y = dot(b.A[i], f.t);
    cxx += kBundleRayShare * x * x, cxy += kBundleRayShare * x * y, cyy += kBundleRayShare * y * y;
  }
  const float half = 0.5f * (cxx + cyy), root = std::sqrt(std::max(0.0f, 0.25f * sqr(cxx - cyy) + cxy * cxy));
  const float l1 = std::max(0.0f, half + root), l2 = std::max(0.0f, half - root);
  // The major axis' direction in (s, t): (cxy, l1 - cxx) or (l1 - cyy, cxy), whichever is longer (an isotropic
  // covariance: s).
  float ex = cxy, ey = l1 - cxx;
  if (ex * ex + ey * ey < sqr(l1 - cyy) + cxy * cxy) ex = l1 - cyy, ey = cxy;
  const float el = std::sqrt(ex * ex + ey * ey);
  if (el > 1e-12f) ex /= el, ey /= el;
  else ex = 1.0f, ey = 0.0f;
  const Vec3 u = f.s * ex + f.t * ey, v = f.t * ex - f.s * ey;
  const auto onto_plane = [&](const Vec3 &a) { return a - b.d0 * (dot(a, n0) / dn); };
  out[0] = onto_plane(u * (std::sqrt(l1) * scale));
  if (!major_only) out[1] = onto_plane(v * (std::sqrt(l2) * scale));
  if (!is_finite(out[0]) || !is_finite(out[1])) out[0] = out[1] = Vec3(0.0f);
}
// `seen_directly`: the waist (applied only there, sample_sg_transmission) is made only then. `drawn`: the walk's
// internal lobe is about the drawn entry axis (kEntryAxis, drawn_entry_axis): the curved exit's shape is then the
// drawn entry's (curved_exit_shape, session 29).
bool solid_exit_mixture(const SgInputs &in, const Segment &seg, const Vec3 &axis, float kappa_in,
                        float kappa_geometric, float ior, float roughness_exit, bool seen_directly, bool drawn,
                        ExitLobe &out) {
  out.lobe_count = 0;
  const bool by_rule = in.mixture_tail < 0.0f;
  const bool wide = in.roughness > kMixtureRoughnessMax, narrow = in.roughness < kCurvedSingleSgBelow;
  const bool planar = seg.planar;
  const bool ladder = by_rule && wide && planar;
  if (by_rule && !planar && (wide || narrow)) {  // the single SG, split into a core and a tail when wide
    if (wide && in.roughness <= kCurvedSplitMax) {
      // The axis moved by the smooth refractions' mean shift (kCurvedAxisShift; session 23's first-moment rules were
      // measured and not kept, docs/history/frosted_glass_sessions.md "Session 23 (frostedexit23)"; removed in session
      // 24). The floor's view (floor_view_exit; off by default): kFloorViewShift, and session 30's
      // kCurvedExitShapeFloor (1) or session 31's origin rule (2: kFloorViewOrigin).
      const int floor_exit = floor_view_exit(in, seen_directly, drawn);
      if (const float k = floor_exit != 0 ? floor_view_shift() : curved_shift(); k != 0.0f) {
        const Vec3 shifted = normalize(out.sg.axis + refracted_mean_shift(seg, axis, ior) * k);
        if (is_finite(shifted)) out.sg.axis = shifted;
      }
      // Session 27's origin rules from one bundle (exit_bundle); the waist only where it is applied (seen_directly),
      // or session 31's floor-view origin (floor_exit 2).
      const int floor_origin = floor_exit == 2 ? floor_view_origin() : 0;
      const float floor_scale =
          floor_origin == 0 ? 0.0f : (in.floor_origin >= 0.0f ? in.floor_origin : floor_view_origin_scale());
      const float w = seen_directly ? (in.exit_waist >= 0.0f ? in.exit_waist : exit_waist_scale())
                                    : (floor_origin == 1 ? floor_scale : 0.0f);
      const float c = in.exit_centroid >= 0.0f ? in.exit_centroid : exit_centroid_scale();
      if (w != 0.0f || c != 0.0f || floor_origin >= 2) {
        const ExitBundle bundle = exit_bundle(seg, axis, ior, out.origin_Ng);
        if (w != 0.0f) out.waist_t = bundle_waist(bundle, out.sg.sharpness, kappa_geometric) * w;
        if (floor_origin >= 2) origin_jitter_axes(bundle, out.origin_Ng, floor_scale, floor_origin == 3, out.jitter);
        if (c != 0.0f) {
          const Vec3 moved = out.origin + exit_centroid_offset(bundle, out.origin_Ng) * c;
          if (is_finite(moved)) out.origin = moved;
        }
      }
      // The shape about out.sg.axis: a test's (curved_shape, or curved_tail: the nineteenth session's split, 0 the
      // single SG), else the environment's (measurements: a shape, or the split's t), else curved_exit_shape
      // (kCurvedExitShape up to 0.5; kCurvedExitShapeDrawn about a drawn entry axis, session 29).
      const CurvedShape *shape = in.curved_shape;
      float t = in.curved_tail;
      if (shape == nullptr && t < 0.0f) {
        shape = curved_shape_override();
        t = curved_tail();
      }
      if (shape != nullptr)
        apply_curved_shape(*shape, out);
      else if (t >= 0.0f)
        split_single_sg(t, out);
      else
        apply_curved_shape(floor_exit == 1 ? kCurvedExitShapeFloor
                                           : curved_exit_shape(in.roughness, drawn && drawn_exit_shape()),
                           out);
    }
    return true;
  }
  const float tail = ladder ? 0.0f : (by_rule ? mixture_tail_for(in.roughness) : in.mixture_tail);
  if (!build_exit_mixture(*in.table, seg, axis, kappa_in, kappa_geometric, ior, roughness_exit, in.mixture_variance,
                          tail, out))
    return false;
  if (ladder) add_tail_ladder(kPlanarSolidLadder, out);
  return true;
}

}  // namespace

ExitPlanarity exit_planarity_exact(const float *c, const float *d, int n, float threshold) {
  float sum = 0.0f, sum_facing = 0.0f;
  int count = 0, count_facing = 0;
  for (int i = 0; i < n; ++i) {
    const float dn = std::acos(std::clamp(c[i], -1.0f, 1.0f));
    const float dd = std::acos(std::clamp(d[i], -1.0f, 1.0f));
    const float turn = dn / std::max(dd, 1e-6f);
    sum += turn;
    ++count;
    if (c[i] > 0.0f) sum_facing += turn, ++count_facing;
  }
  constexpr float kInf = std::numeric_limits<float>::infinity();
  ExitPlanarity p;
  p.planar = (count > 0 ? sum / float(count) : kInf) < threshold;
  p.planar_facing = (count_facing > 0 ? sum_facing / float(count_facing) : kInf) < threshold;
  return p;
}

ExitPlanarity exit_planarity(const float *c, const float *d, int n, float threshold, float hi_scale) {
  // Bounds on each turn from t = sqrt((1 - x) / 2): acos in [2 t, pi t], each widened by 1e-4 (acosf's and t's
  // roundings are ~1e-7 relative); the sums' roundings and the division's are covered by the decision's 1e-3.
  float lo = 0.0f, hi = 0.0f, lo_facing = 0.0f, hi_facing = 0.0f;
  int count = 0, count_facing = 0;
  for (int i = 0; i < n; ++i) {
    const float tn = std::sqrt(0.5f * (1.0f - std::clamp(c[i], -1.0f, 1.0f)));
    const float td = std::sqrt(0.5f * (1.0f - std::clamp(d[i], -1.0f, 1.0f)));
    const float turn_lo = 2.0f * tn * (1.0f - 1e-4f) / std::max(hi_scale * td * (1.0f + 1e-4f), 1e-6f);
    const float turn_hi = hi_scale * tn * (1.0f + 1e-4f) / std::max(2.0f * td * (1.0f - 1e-4f), 1e-6f);
    lo += turn_lo, hi += turn_hi, ++count;
    if (c[i] > 0.0f) lo_facing += turn_lo, hi_facing += turn_hi, ++count_facing;
  }
  // true and `planar` set where the bounds decide (mean < threshold); NaN decides nothing.
  const auto decide = [threshold](float sum_lo, float sum_hi, int k, bool &planar) {
    if (k == 0) return planar = false, true;  // infinite: not below
    const float limit = threshold * float(k);
    if (sum_hi * 1.001f < limit) return planar = true, true;
    if (sum_lo > limit * 1.001f) return planar = false, true;
    return false;
  };
  ExitPlanarity p;
  if (decide(lo, hi, count, p.planar) && decide(lo_facing, hi_facing, count_facing, p.planar_facing)) return p;
  return exit_planarity_exact(c, d, n, threshold);
}

Vec3 offset_origin(const Vec3 &P, const Vec3 &Ng, const Vec3 &dir) {
  const float scale = 1.0f + std::max(std::fabs(P.x), std::max(std::fabs(P.y), std::fabs(P.z)));
  const float eps = 3e-5f * scale;
  return dot(dir, Ng) >= 0.0f ? P + Ng * eps : P - Ng * eps;
}

GlimmerRay unbounded_ray(const Vec3 &origin, const Vec3 &dir) {
  GlimmerRay ray{};
  ray.struct_size = sizeof(GlimmerRay);
  ray.origin = origin;
  ray.direction = dir;
  ray.t_min = 0.0f;
  ray.t_max = std::numeric_limits<float>::infinity();
  return ray;
}

Vec3 sample_sg_direction(const SphericalGaussian &sg, float u1, float u2) {
  return sample_vmf(sg.axis, sg.sharpness, u1, u2);
}

int reflections_allowed(const GlimmerShadingContext &ctx) {
#if GLIMMER_ABI_MINOR >= 9
  if (!GLIMMER_HAS_FIELD(ctx.struct_size, GlimmerShadingContext, max_transmission_bounce))
    return kMaxInternalReflections;
  // PathState::advance: a scatter after which a count reaches its limit ends the path at the next surface.
  const int64_t bounce = int64_t(ctx.bounce) + 1, glossy = ctx.glossy_bounce;  // after the entry
  if ((ctx.max_bounce > 0 && bounce >= ctx.max_bounce) ||
      (ctx.max_transmission_bounce > 0 && int64_t(ctx.transmission_bounce) + 1 >= ctx.max_transmission_bounce))
    return -1;
  int64_t allowed = kMaxInternalReflections;
  if (ctx.max_bounce > 0) allowed = std::min<int64_t>(allowed, int64_t(ctx.max_bounce) - bounce - 1);
  if (ctx.max_glossy_bounce > 0) allowed = std::min<int64_t>(allowed, int64_t(ctx.max_glossy_bounce) - glossy - 1);
  return int(std::max<int64_t>(allowed, 0));
#else
  (void)ctx;
  return kMaxInternalReflections;
#endif
}

namespace {
// Step 5: the roulette between the exit (E_x) and the internal reflection (1 - E_x) at a segment whose axis leaves with
// the leaving table's energy `axis_energy`. E_x is averaged over the axis and the bounding rays, each at its own
// incidence on its own exit normal: the directions of a wide lobe far from its axis reach the exit beyond the
// critical angle and reflect, which the axis alone does not see. The last event always exits: no roulette, so the
// bounding rays' energies are not looked up there. The number: roulette_number.
struct ExitRoulette : RouletteNumber {
  ExitEnergies energies;
};
ExitRoulette exit_roulette(const SgInputs &in, const Segment &seg, float axis_energy,
                           const TransmissionSgTable::Axes &exit_axes, uint32_t seed, int event, bool last,
                           float first_u) {
  ExitRoulette r;
  // The stratified number at curved exits only (a planar one, a slab's back face, keeps the hashed route: unmeasured on
  // the bench there; the exit harness' slab moved by its noise; docs/history/frosted_glass_sessions.md "Session 27").
  if (event == 0 && first_u >= 0.0f && seg.planar_facing) first_u = -1.0f;
  if (!last) r.energies = exit_energies(*in.table, seg, axis_energy, exit_axes);
  static_cast<RouletteNumber &>(r) =
      roulette_number(in, seed, event, first_u, last ? axis_energy : r.energies.mean());
  return r;
}
}  // namespace

namespace {
// kEntryAxis, or for measurements only GLIMMER_FROSTED_ENTRY_AXIS = m (0: the front SG's axis and width), read once;
// kEntryKappa or GLIMMER_FROSTED_ENTRY_KAPPA the internal lobe's sharpness about a drawn axis.
int entry_axis_mode(const SgInputs &in) {
  static const int m = measurement_knob("GLIMMER_FROSTED_ENTRY_AXIS", kEntryAxis, 0, 2);
  return in.entry_axis >= 0 ? in.entry_axis : m;
}
float entry_kappa() {
  static const float k = measurement_knob("GLIMMER_FROSTED_ENTRY_KAPPA", kEntryKappa, 1.0f, 1e7f);
  return k;
}
// kFloorView, or for measurements only GLIMMER_FROSTED_FLOOR_VIEW = s (0: the front SG, main's images) and
// GLIMMER_FROSTED_FLOOR_VIEW_SG (1: the drawn part from the front SG), read once.
float floor_view_share() {
  static const float s = measurement_knob("GLIMMER_FROSTED_FLOOR_VIEW", kFloorView, 0.0f, 1.0f);
  return s;
}
// kFloorView (frosted_glass_sg.h) where the solid is not seen directly (the floor's view), a partial draw: the
// internal axis turned from the front SG's axis towards the front sample's refracted direction `entry` by the share
// s of their angle (or, GLIMMER_FROSTED_FLOOR_VIEW_SG, drawn from a vMF about the front axis of sharpness
// kappa_front / s^2), the drawn part's angular variance s^2 of the front lobe's; the internal lobe about it keeps the
// rest, kappa_in = kappa_front / (1 - s^2) (a vMF's angular variance ~ 2 / kappa), at most drawn_entry_axis' cap.
// Called for s > 0 only (drawn_entry_axis); false (the front SG kept) without a usable entry. Measured, not kept.
[[gnu::noinline]] bool floor_view_axis(const ShadingPoint &sp, const Vec3 *entry, uint32_t seed,
                                       const SphericalGaussian &front, Vec3 &axis, float &kappa_in) {
  const float s = floor_view_share();
  if (entry == nullptr || !is_finite(*entry)) return false;
  static const bool from_sg = measurement_knob("GLIMMER_FROSTED_FLOOR_VIEW_SG", 0, 0, 1) != 0;
  const Vec3 a = normalize(Vec3(front.axis)), d = normalize(*entry);
  Vec3 turned = a;
  if (from_sg) {
    mf::WalkRng rng(hash_u32x2(seed, 0x7f4a7c15u));
    const float u1 = rng.next(), u2 = rng.next();
    turned = glimmer::sample_vmf(a, double(front.sharpness / (s * s)), u1, u2);
  } else if (const float c = std::clamp(dot(a, d), -1.0f, 1.0f); 1.0f - c > 1e-9f) {
    const Vec3 t = d - a * c;
    const float angle = s * std::acos(c), tl = length(t);
    if (tl > 1e-6f) turned = a * std::cos(angle) + t * (std::sin(angle) / tl);
  }
  if (!is_finite(turned) || !(dot(turned, Vec3(sp.ctx->Ng)) < 0.0f)) return false;
  axis = normalize(turned);
  const float cap = std::max(entry_kappa(), front.sharpness * 100.0f);
  kappa_in = s >= 1.0f ? cap : std::min(cap, front.sharpness / (1.0f - s * s));
  return true;
}
// kEntryAxis (frosted_glass_sg.h) where the solid is seen directly (sampled_reflection_at's test): the internal axis
// is the front sample's own refracted direction (m 1, `entry`) or a draw from the front SG (m 2), the internal lobe
// about it of sharpness entry_kappa or 100 x the front SG's (the shell's roughness 0.1: its front SG is narrower
// than kEntryKappa); false (the front SG kept) otherwise. The floor's view: floor_view_axis.
bool drawn_entry_axis(const ShadingPoint &sp, const SgInputs &in, const Vec3 *entry, uint32_t seed,
                      const SphericalGaussian &front, Vec3 &axis, float &kappa_in) {
  if (!seen_directly(*sp.ctx))  // the floor's view: main's front SG unless kFloorView (a call only then)
    return floor_view_share() > 0.0f && floor_view_axis(sp, entry, seed, front, axis, kappa_in);
  const int mode = entry_axis_mode(in);
  if (mode == 0) return false;
  Vec3 d;
  if (mode == 1) {
    if (entry == nullptr) return false;
    d = *entry;
  } else {
    mf::WalkRng rng(hash_u32x2(seed, 0x7f4a7c15u));
    const float u1 = rng.next(), u2 = rng.next();
    d = glimmer::sample_vmf(Vec3(front.axis), double(front.sharpness), u1, u2);
  }
  if (!is_finite(d) || !(dot(d, Vec3(sp.ctx->Ng)) < 0.0f)) return false;
  axis = normalize(d);
  kappa_in = std::max(entry_kappa(), front.sharpness * 100.0f);  // at most 1 % of the front lobe's variance
  return true;
}

// A narrow internal lobe's segment (session 29, frostedcost29): where kappa_in >= kNarrowPairKappa (the camera-seen
// solid's drawn entry axis, kappa >= kEntryKappa, and the sampled reflections after it, which keep that width) the
// bounding cone is ~1 deg wide (theta_b = sqrt(2 ln 4 / kappa) = 0.017 at 1e4) and its 4 rays see the axis' exit
// again: only the +-s pair is traced (the mean normal, curvature, energies and traced cone from 2 rays; the exit
// bundle and the axis shift, which need all 4, are ~theta_b^2 there). For measurements only
// GLIMMER_FROSTED_NARROW_PAIR_KAPPA = k (0: always 4 rays, main's images), read once.
constexpr float kNarrowPairKappa = 1e3f;
float narrow_pair_kappa() {
  static const float k = measurement_knob("GLIMMER_FROSTED_NARROW_PAIR_KAPPA", kNarrowPairKappa, 0.0f, 1e30f);
  return k;
}
int bounding_rays(float kappa_in) {
  const float k = narrow_pair_kappa();
  return k > 0.0f && kappa_in >= k ? 2 : 4;
}

// The next segment inside (trace_segment; bounding_rays); after a drawn entry axis (`drawn`: drawn_entry_axis, the
// first segment) only where its exit is curved: at a planar one (a slab's back face) the front SG's axis and width
// again (kEntryAxis).
bool next_segment(const GlimmerShadingContext &ctx, const SgInputs &in, const SphericalGaussian &front, bool drawn,
                  Vec3 &axis, float &kappa_in, Vec3 &origin, Segment &seg) {
  if (!trace_segment(ctx.host, in, origin, axis, kappa_in, seg, bounding_rays(kappa_in))) return false;
  if (!drawn || !seg.planar) return true;
  axis = front.axis, kappa_in = front.sharpness;
  origin = offset_origin(Vec3(ctx.P), Vec3(ctx.Ng), axis);
  seg = Segment{};  // trace_segment appends the bounding rays
  return trace_segment(ctx.host, in, origin, axis, kappa_in, seg, bounding_rays(kappa_in));
}

// Step 4's incident axis at the exit: -axis, or at the last event, beyond the critical angle (sin_crit = 1 / ior),
// clamped to it (Wyman 2005: it leaves at grazing).
Vec3 exit_incident(const Vec3 &axis, const Vec3 &n, float cos_in, float sin_crit, bool last) {
  if (!last || !(std::sqrt(std::max(0.0f, 1.0f - cos_in * cos_in)) > sin_crit)) return -axis;
  const Vec3 tangential = normalize(-axis - (-n) * dot(-axis, -n));
  return normalize(tangential * sin_crit + (-n) * std::sqrt(1.0f - sin_crit * sin_crit));
}

}  // namespace

bool trace_exit_lobe(const ShadingPoint &sp, const SgInputs &in, uint32_t seed, ExitLobe &out, float first_u,
                     const Vec3 *entry) {
  const GlimmerShadingContext &ctx = *sp.ctx;
  if (in.table == nullptr || !host_can_trace_closures(ctx.host) || !(sp.wi.z > 0.0f)) return false;
  const float ior = in.ior;
  if (!(ior >= TransmissionSgTable::kIorMin && ior <= TransmissionSgTable::kIorMax)) return false;
  // 1. The front BTDF as an SG (entering: eta = ior), in world space.
  SphericalGaussian front;
  float front_energy = 0.0f;
  if (!table_lobe(*in.table, sp.frame, Vec3(ctx.wi), ior, in.roughness, front, front_energy)) return false;

  Vec3 axis = front.axis;
  float kappa_in = front.sharpness;
  bool drawn = drawn_entry_axis(sp, in, entry, seed, front, axis, kappa_in);
  Vec3 origin = offset_origin(Vec3(ctx.P), Vec3(ctx.Ng), axis);
  float inside_length = 0.0f;
  for (int event = 0, allowed = reflections_allowed(ctx); event <= kMaxInternalReflections; ++event) {
    if (event > allowed) return out.lost = true, false;  // the host's path would have ended inside (ABI 2.9)
    // 2-3. Axis and bounding rays to the far side; mean normal, Toksvig width, exit roughness.
    Segment seg;
    if (!next_segment(ctx, in, front, event == 0 && drawn, axis, kappa_in, origin, seg)) return false;
    drawn = drawn && (event > 0 || kappa_in != front.sharpness);  // a planar first exit: the front SG's walk again
    inside_length += seg.axis.hit.t;
    const Vec3 n = seg.mean_normal;  // outward
    const float alpha_d = sqr(hit_roughness(in, seg.axis.closure));
    const bool toksvig = in.variant == SgVariant::kToksvig;
    // The paper: the exit normals' spread as roughness, kappa' = kG kD / (kG + kD) (alpha'^2 = alpha_G^2 + alpha_D^2).
    const float alpha2 = (toksvig ? toksvig_alpha2(seg.mean_length) : 0.0f) + alpha_d * alpha_d;
    const float roughness_exit = std::sqrt(std::sqrt(alpha2));
    // 4. Refract through the mean normal: the leaving lobe (eta = 1 / ior) in the frame whose +z is inside.
    const Frame exit_frame = Frame::from_normal(-n);
    const float cos_in = std::clamp(dot(axis, n), 1e-4f, 1.0f);
    const bool last = event == kMaxInternalReflections;
    const Vec3 incident = exit_incident(axis, n, cos_in, 1.0f / ior, last);
    SphericalGaussian exit;
    float exit_energy = 0.0f;
    const TransmissionSgTable::Axes exit_axes = table_axes(1.0f / ior, roughness_exit);  // the exit's lookups
    TableLookup exit_lookup;  // the SG made only if the walk leaves here (exit_lookup_energy)
    bool deferred = false;
    if (!exit_lookup_energy(*in.table, exit_axes, exit_frame, incident, exit_lookup, exit, exit_energy, deferred))
      return false;
    // 5. Russian roulette between the exit (E_x) and the internal reflection (1 - E_x): exit_roulette.
    const ExitRoulette r = exit_roulette(in, seg, exit_energy, exit_axes, seed, event, last, first_u);
    if (deferred && (last || r.leaves) && !table_lobe_sg(exit_lookup, exit_axes, exit_frame, exit, exit_energy))
      return false;
    if (!last && !r.leaves) {
      if (!reflect_internal(in, seg, r.energies, n, alpha2, hash_u32x2(seed, uint32_t(event)), axis, kappa_in, r.rest))
        return false;
      origin = offset_origin(Vec3(seg.axis.hit.P), Vec3(seg.axis.hit.Ng), axis);
      if (!is_finite(axis) || !is_finite(origin)) return false;
      continue;
    }
    if (r.leaves) out.leftover = r.rest;
    float kappa_geometric;
    if (toksvig) {  // the internal lobe's width reaches the outside magnified by Snell's law
      const float cos_out = std::max(std::fabs(dot(exit.axis, n)), 0.05f);
      const float m = ior * cos_in / cos_out;
      kappa_geometric = std::max(kappa_in, 1e-6f) / (m * m);
    } else {
      kappa_geometric = traced_cone_sharpness(seg, refract_out(axis, n, ior), ior);
    }
    const float kappa_out = 1.0f / (1.0f / exit.sharpness + 1.0f / kappa_geometric);
    out.sg = exit;
    out.sg.sharpness = std::clamp(kappa_out, 1e-3f, 1e7f);
    if (in.variant == SgVariant::kNoExitRefraction) out.sg.axis = axis;
    out.origin = Vec3(seg.axis.hit.P);
    const Vec3 Ng = Vec3(seg.axis.hit.Ng);
    out.origin_Ng = normalize(dot(Ng, n) >= 0.0f ? Ng : -Ng);  // unit: the exit lobe's surface (exit_lobe.h)
    out.weight = hit_color(in, seg.axis.closure);
    for (int ch = 0; ch < 3; ++ch) out.weight[ch] *= std::exp(-in.sigma_a[ch] * inside_length);
    out.roughness = std::clamp(std::sqrt(std::sqrt(2.0f / out.sg.sharpness)), 0.0f, 1.0f);
    out.lobe_count = 0;
    if (in.variant == SgVariant::kMixture && !solid_exit_mixture(in, seg, axis, kappa_in, kappa_geometric, ior,
                                                                 roughness_exit, seen_directly(ctx), drawn, out))
      return false;
    return is_finite(out.origin) && is_finite(out.sg.axis) && is_finite(out.weight);
  }
  return false;
}

bool sampled_reflection_at(const ShadingPoint &sp, int mode) {
  static const bool by_rule = measurement_knob("GLIMMER_FROSTED_SAMPLED_REFLECTION", int(kSampledReflectionByDefault),
                                               std::numeric_limits<int>::min(), std::numeric_limits<int>::max()) != 0;
  if (!seen_directly(*sp.ctx)) return false;
  return mode < 0 ? by_rule : mode != 0;
}

int stratified_first_roulette_level() {
  static const int level = measurement_knob("GLIMMER_FROSTED_STRATIFIED_ROULETTE", kStratifiedFirstRoulette, 0, 2);
  return level;
}

namespace {
// rand.z rescaled to the front transmission of wi into wo (local frame, wi.z > 0 > wo.z; entering, eta = ior):
// (rand.z - F) / (1 - F), F the Fresnel reflectance at the transmission's microfacet, the generalised half vector
// -(wi + eta wo) (Walter 2007 eq. 16); `control`: rand.z itself (the tests' negative control). -1: none.
float transmitted_rest(const Vec3 &wi, const Vec3 &wo, float ior, float rand_z, bool control) {
  if (!(wi.z > 0.0f) || !(wo.z < 0.0f)) return -1.0f;
  Vec3 m = -(wi + wo * ior);
  if (m.z < 0.0f) m = -m;
  if (!(dot(m, m) > 1e-20f)) return -1.0f;
  m = normalize(m);
  const float F = mf::fresnel_dielectric(dot(wi, m), ior);
  if (!(F < 1.0f) || !std::isfinite(F)) return -1.0f;
  const float u = control ? rand_z : (rand_z - F) / (1.0f - F);
  return std::isfinite(u) ? std::clamp(u, 0.0f, 0x1.fffffep-1f) : -1.0f;
}
}  // namespace

float stratified_first_roulette(const ShadingPoint &sp, const SgInputs &in, const Vec3 &rand,
                                const LocalSample &front) {
  const int level = stratified_roulette_level(in);
  if (level <= 0 || !in.sampled_reflection) return -1.0f;
  return transmitted_rest(sp.wi, front.wo, in.ior, rand.z, level == kStratifiedRouletteControl);
}

namespace {
// The exit draw's numbers (ExitLobe::leftover, stratified_first_roulette level 2): the lobe pick from the leftover
// when there is one; what is left of it within the picked lobe's share (cumulative weights as pick_mixture_lobe's)
// is the first draw's cos theta number (ExitLobe::sample reads u_phi, then u_cos, per draw); else the hashed ones.
float pick_u(float leftover, float hashed) { return leftover >= 0.0f ? leftover : hashed; }
float picked_rest(float leftover, const float *weight, int count, int k) {
  if (!(leftover >= 0.0f)) return -1.0f;
  double c = 0.0;
  for (int j = 0; j < k && j < count; ++j)
    if (weight[j] > 0.0f) c += double(weight[j]);
  if (!(weight[k] > 0.0f)) return -1.0f;
  const double r = (double(leftover) - c) / double(weight[k]);
  return std::isfinite(r) ? float(std::clamp(r, 0.0, double(0x1.fffffep-1f))) : -1.0f;
}
auto exit_draw_numbers(mf::WalkRng &rng, float first_cos) {
  return [&rng, first_cos, call = 0]() mutable {
    const float u = rng.next();  // drawn either way: the later draws' numbers as before
    return call++ == 1 && first_cos >= 0.0f ? first_cos : u;
  };
}

// kFloorViewOrigin 2 / 3 (ExitLobe::jitter): the origin moved by jitter[0] a + jitter[1] b, (a, b) uniform in the disk of
// radius 2 (unit variance per axis; bounded, unlike a Gaussian), from the sample's seed by a stream of its own (the
// other draws keep their numbers). Nothing without a jitter.
void jitter_exit_origin(ExitLobe &exit, uint32_t seed) {
  if (!(dot(exit.jitter[0], exit.jitter[0]) > 0.0f)) return;
  mf::WalkRng rng(hash_u32x2(seed, 0x5bd1e995u));
  const float u1 = rng.next(), u2 = rng.next();
  const float r = 2.0f * std::sqrt(u1), phi = kTwoPi * u2;
  const Vec3 moved = exit.origin + exit.jitter[0] * (r * std::cos(phi)) + exit.jitter[1] * (r * std::sin(phi));
  if (is_finite(moved)) exit.origin = moved;
}
}  // namespace

bool sample_sg_transmission(const ShadingPoint &sp, const SgInputs &in, const Vec3 &rand, const LocalSample &front,
                            LocalSample &out, bool *lost) {
  if (!(front.label & GLIMMER_LABEL_TRANSMIT) || !(front.pdf > 0.0f)) return false;
  const uint32_t seed = sp.seed_for(rand);
  ExitLobe exit;
  const Vec3 entry = normalize(sp.frame.to_world(Vec3(front.wo)));
  if (!trace_exit_lobe(sp, in, seed, exit, stratified_first_roulette(sp, in, rand, front), &entry)) {
    if (lost != nullptr) *lost = exit.lost;
    return false;
  }
  // 6. One direction from the exit SG restricted to the outside of the exit surface (the lobe it was fitted to
  // lies there): drawn again when it falls below (up to 16 times), then mirrored (glimmer/exit_lobe.h, whose
  // density the host uses for light sampling at the exit). The weight stays: the SG's energy is the lobe's,
  // whatever its part below the surface.
  mf::WalkRng rng(hash_u32x2(seed, 0x9e3779b9u));
  const int level = stratified_roulette_level(in);
  Vec3 wo;
  if (exit.lobe_count > 0) {
    // kMixture: the whole mixture leaves from the axis' exit point, every lobe restricted to its surface (the
    // host evaluates it whole there, ABI 2.7); one lobe picked by its share draws the continued direction.
    float weights[ExitLobe::kMaxLobes];
    for (int j = 0; j < exit.lobe_count; ++j) weights[j] = exit.lobe[j].weight;
    const float u_pick = rng.next();
    const int k = glimmer::pick_mixture_lobe(weights, exit.lobe_count, double(pick_u(exit.leftover, u_pick)));
    const glimmer::ExitLobe picked{Vec3(exit.lobe[k].axis), exit.lobe[k].sharpness, exit.origin_Ng, 0.0};
    const float rest = level == kStratifiedDrawControl ? exit.leftover  // the control: not rescaled to the lobe
                                                       : picked_rest(exit.leftover, weights, exit.lobe_count, k);
    wo = picked.sample(exit_draw_numbers(rng, rest));
    exit.sg.axis = Vec3(exit.lobe[k].axis);
    exit.sg.sharpness = exit.lobe[k].sharpness;
    exit.roughness = std::clamp(std::sqrt(std::sqrt(2.0f / exit.sg.sharpness)), 0.0f, 1.0f);
#if GLIMMER_ABI_MINOR >= 7
    if (out.mixture_out != nullptr) {
      GlimmerExitMixture &m = *out.mixture_out;
      m.count = uint32_t(exit.lobe_count);
      for (int j = 0; j < exit.lobe_count; ++j) {
        m.axis[j] = exit.lobe[j].axis;
        m.sharpness[j] = exit.lobe[j].sharpness;
        m.weight[j] = exit.lobe[j].weight;
      }
      out.exit_mixture = true;
    }
#endif
  } else {
    const glimmer::ExitLobe lobe{exit.sg.axis, exit.sg.sharpness, exit.origin_Ng, 0.0};
    wo = lobe.sample(exit_draw_numbers(rng, exit.leftover));
  }
  if (!(dot(wo, exit.origin_Ng) > 0.0f)) return false;
  // kCurvedExitWaist: where wo's ray from the waist crosses the exit's tangent plane (waist_t < 0 only where the solid
  // is seen directly: solid_exit_mixture makes it only there).
  if (exit.waist_t < 0.0f) {
    const Vec3 W = exit.origin + exit.sg.axis * exit.waist_t;
    const float dn = dot(wo, exit.origin_Ng);
    if (dn > 0.1f) {
      const Vec3 x = W + wo * (dot(exit.origin - W, exit.origin_Ng) / dn);
      if (is_finite(x)) exit.origin = x;
    }
  }
  jitter_exit_origin(exit, seed);  // kFloorViewOrigin 2 / 3 only
  const Spectrum weight = front.f_cos / front.pdf * exit.weight;
  if (!is_finite(weight) || !is_finite(wo)) return false;
  out.wo = sp.frame.to_local(wo);
  out.f_cos = weight;
  out.pdf = 1.0f;
  out.roughness = exit.roughness;
  out.eta = 1.0f;  // outside again
  out.label = GLIMMER_LABEL_TRANSMIT | GLIMMER_LABEL_SINGULAR;
  out.moved = true;
  out.origin = exit.origin;
  out.origin_Ng = exit.origin_Ng;
  out.exit_lobe = true;  // ABI 2.4: the host may sample lights at the exit with this lobe
  out.lobe_axis = exit.sg.axis;
  out.lobe_sharpness = exit.sg.sharpness;
  return true;
}

// ---- Thin panes ----------------------------------------------------------------------------------------

namespace {

// The bounding directions of an internal lobe (axis, sharpness kappa) that reach the flat face with outward
// normal n, as a Segment whose exit normals are all n: a pane's faces are parallel planes, nothing to trace.
Segment flat_face_segment(const Vec3 &axis, float kappa, const Vec3 &n) {
  Segment seg;
  seg.mean_normal = n;
  seg.axis.normal = n;
  const float theta_b = bounding_angle(kappa);
  const float c = std::cos(theta_b), s = std::sin(theta_b);
  const Frame f = Frame::from_normal(axis);
  for (const Vec3 &o : {f.s, -f.s, f.t, -f.t}) {
    const Vec3 dir = normalize(axis * c + o * s);
    if (!(dot(dir, n) > 0.0f)) continue;  // a wide lobe's edge that turns back: it meets the other face
    seg.bounding_dir[seg.bounding_count] = dir;
    seg.bounding_normal[seg.bounding_count++] = n;
  }
  return seg;
}

// Wyman 2005: a direction `d` inside meeting the face with outward normal n beyond the critical angle is
// clamped to it (returned as the incident direction -d' seen from inside, for the leaving table).
Vec3 incident_clamped_to_critical(const Vec3 &d, const Vec3 &n, float ior) {
  const float sin_crit = 1.0f / ior, cos_in = std::clamp(dot(d, n), 0.0f, 1.0f);
  if (!(std::sqrt(std::max(0.0f, 1.0f - cos_in * cos_in)) > sin_crit)) return -d;
  const Vec3 tangential = normalize(d - n * cos_in);
  return -normalize(tangential * sin_crit + n * std::sqrt(1.0f - sin_crit * sin_crit));
}

// PaneTail (frosted_glass_sg.h): the cores keep their axes, their weights x (1 - sum t_j) and their sharpness x
// core_scale; the tail lobes sit about lobe 0 (the axis ray's) at its unscaled sharpness / 4^j. The ladder was
// validated once (make_pane_ladder: sum t_j <= 0.9, the lobes fit); weights still sum to 1.
void add_tail_ladder(const PaneLadder &ladder, ExitLobe &m) {
  if (m.lobe_count <= 0 || !ladder.valid || m.lobe_count + ladder.levels > ExitLobe::kMaxLobes) return;
  float kappa = m.lobe[0].sharpness;
  const GlimmerVec3 axis = m.lobe[0].axis;
  for (int k = 0; k < m.lobe_count; ++k) {
    m.lobe[k].weight *= 1.0f - ladder.total;
    m.lobe[k].sharpness = std::clamp(m.lobe[k].sharpness * ladder.core_scale, 1e-3f, 1e7f);
  }
  for (int j = 0; j < ladder.levels; ++j) {
    kappa *= 0.25f;
    if (!(ladder.share[j] > 0.0f)) continue;
    ExitLobe::MixtureLobe &l = m.lobe[m.lobe_count++];
    l.axis = axis;
    l.sharpness = std::max(kappa, 1e-3f);
    l.weight = ladder.share[j];
  }
}


// Beer-Lambert over `length` (0 absorption stays exactly 1 at any length).
Spectrum beer_transmittance(const Spectrum &sigma_a, float length) {
  Spectrum t(1.0f);
  for (int ch = 0; ch < 3; ++ch)
    if (sigma_a[ch] > 0.0f) t[ch] = std::exp(-sigma_a[ch] * length);
  return t;
}

// The front BTDF as an SG (entering, eta = ior) in the pane frame, for wi (pane frame, wi.z > 0); `roughness` the
// pane's as the table reads it. False when the table does not cover the IOR or a value is not finite.
bool pane_front_lobe(const Vec3 &wi, const PaneSgInputs &in, float &roughness, SphericalGaussian &front) {
  if (in.table == nullptr || !(wi.z > 0.0f) || !is_finite(wi)) return false;
  if (!(in.ior >= TransmissionSgTable::kIorMin && in.ior <= TransmissionSgTable::kIorMax)) return false;
  roughness = std::clamp(std::isfinite(in.roughness) ? in.roughness : 0.0f, TransmissionSgTable::kRoughnessMin,
                         kTableRoughnessMax);
  float energy = 0.0f;
  return table_lobe(*in.table, Frame::from_normal(Vec3(0.0f, 0.0f, 1.0f)), wi, in.ior, roughness, front, energy);
}

// The internal lobe (axis, sharpness kappa_in; its bounding directions `seg`) leaves through the face with outward
// normal n, whose leaving table SG is `exit`: the exit SG convolved with the internal width refracted out (Snell's
// magnification), and for the mixture variants the exit lobe mixture (kMixtureShortTail: a kappa / 4 tail per ray;
// kMixture and kPaneWalkMixture: the heavy-tail ladder). Sets sg, through and the lobes; the weight is the caller's.
bool pane_leave(const PaneSgInputs &in, const Segment &seg, const Vec3 &axis, float kappa_in, const Vec3 &n,
                const SphericalGaussian &exit, float roughness, PaneExitLobe &out) {
  const float ior = in.ior;
  const float kappa_geometric = traced_cone_sharpness(seg, refract_out(axis, n, ior), ior);
  out.sg = exit;
  out.sg.sharpness = std::clamp(1.0f / (1.0f / exit.sharpness + 1.0f / kappa_geometric), 1e-3f, 1e7f);
  out.through = n.z < 0.0f;
  out.lobe_count = 0;
  const bool short_tail = in.variant == SgVariant::kMixtureShortTail;
  if (in.variant == SgVariant::kMixture || in.variant == SgVariant::kPaneWalkMixture || short_tail) {
    ExitLobe mixture;
    if (!build_exit_mixture(*in.table, seg, axis, kappa_in, kappa_geometric, ior, roughness,
                            kDefaultMixtureVariance, short_tail ? mixture_tail_for(roughness) : 0.0f, mixture))
      return false;
    if (!short_tail && in.ladder != nullptr) add_tail_ladder(*in.ladder, mixture);
    out.lobe_count = mixture.lobe_count;
    for (int k = 0; k < mixture.lobe_count; ++k) out.lobe[k] = mixture.lobe[k];
  }
  return true;
}

}  // namespace

bool pane_exit_lobe(const Vec3 &wi, const PaneSgInputs &in, uint32_t seed, PaneExitLobe &out) {
  // 1. The front BTDF as an SG (entering, eta = ior) in the pane frame.
  float roughness = 0.0f;
  SphericalGaussian front;
  if (!pane_front_lobe(wi, in, roughness, front)) return false;
  const float ior = in.ior;
  Vec3 axis = front.axis;
  float kappa_in = front.sharpness;
  const float alpha_d = roughness * roughness;
  const float kappa_reflect = 2.0f / std::max(alpha_d * alpha_d, 1e-7f);  // NDF sharpness; reflected lobe: kappa / 4
  const TransmissionSgTable::Axes exit_axes = table_axes(1.0f / ior, roughness);  // every event's exit lookups
  Spectrum weight = in.tint;
  for (int event = 0; event <= kMaxInternalReflections; ++event) {
    // 2. The face the axis reaches (outward normal n) after one crossing of the pane.
    const Vec3 n(0.0f, 0.0f, axis.z < 0.0f ? -1.0f : 1.0f);
    weight *= beer_transmittance(in.sigma_a, in.thickness / std::max(std::fabs(axis.z), 1e-6f));
    const Segment seg = flat_face_segment(axis, kappa_in, n);
    const bool last = event == kMaxInternalReflections;
    // 3. Leaving through the face: the table T(theta, 1 / ior, roughness) in the frame whose +z is inside.
    SphericalGaussian exit;
    float exit_energy = 0.0f;
    const Vec3 incident = last ? incident_clamped_to_critical(axis, n, ior) : -axis;
    if (!table_lobe(*in.table, exit_axes, Frame::from_normal(-n), incident, exit, exit_energy)) return false;
    // 4. Russian roulette between leaving (E_x over the axis and the bounding directions) and the reflection
    // between the faces (1 - E_x): the weight is unchanged either way, so no energy is dropped.
    const float transmitted = last ? 1.0f : mean_exit_energy(*in.table, seg, exit_energy, exit_axes);
    if (roulette(seed, event) >= transmitted) {
      kappa_in = 1.0f / (1.0f / kappa_in + 4.0f / kappa_reflect);
      axis = Vec3(axis.x, axis.y, -axis.z);
      continue;
    }
    // The spread: the exit SG convolved with the internal width refracted out (Snell's magnification).
    if (!pane_leave(in, seg, axis, kappa_in, n, exit, roughness, out)) return false;
    if (in.variant == SgVariant::kNoExitRefraction) out.sg.axis = axis;
    out.weight = weight;
    return is_finite(out.sg.axis) && is_finite(out.weight) && std::isfinite(out.sg.sharpness);
  }
  return false;
}

// SgVariant::kPaneWalkMixture (fifteenth session): the exit lobe of the light that crosses the pane without a
// reflection between the faces (the walk decided that, and its weight): pane_exit_lobe's first event without the
// roulette, the mixture with the heavy-tail ladder at the far face. The weight is the caller's (the walk's, Beer over
// its crossing included).
bool pane_exit_lobe_through(const Vec3 &wi, const PaneSgInputs &in, PaneExitLobe &out) {
  float roughness = 0.0f;
  SphericalGaussian front;
  if (!pane_front_lobe(wi, in, roughness, front)) return false;
  const Vec3 axis = front.axis, n(0.0f, 0.0f, -1.0f);  // entering: the axis goes down, to the far face
  if (!(axis.z < 0.0f)) return false;
  SphericalGaussian exit;
  float exit_energy = 0.0f;
  if (!table_lobe(*in.table, Frame::from_normal(-n), -axis, 1.0f / in.ior, roughness, exit, exit_energy))
    return false;
  PaneSgInputs mixture = in;
  mixture.variant = SgVariant::kPaneWalkMixture;
  if (!pane_leave(mixture, flat_face_segment(axis, front.sharpness, n), axis, front.sharpness, n, exit, roughness,
                  out))
    return false;
  out.weight = Spectrum(1.0f);
  return is_finite(out.sg.axis) && std::isfinite(out.sg.sharpness);
}

namespace {

// One singular sample from the pane's exit lobe `exit` (pane frame), moved to the exit face of the same point and
// carrying the lobe (ABI 2.4; the whole mixture, ABI 2.7). `weight`: the sample's f cos / pdf.
// leaving (optional, pane frame, one per mixture lobe or 1 for the single SG): the picked lobe's direction instead of
// a draw from it (pane_exact_leaving_level).
bool emit_pane_sample(const ShadingPoint &sp, const PaneExitLobe &exit, uint32_t seed, const Spectrum &weight,
                      bool flip, LocalSample &out, const Vec3 *leaving = nullptr) {
  const GlimmerShadingContext &ctx = *sp.ctx;
  const Vec3 axis = normalize(sp.frame.to_world(flip ? mf::flip_z_local(exit.sg.axis) : exit.sg.axis));
  // The exit face's outward normal: the geometric normal on the far side of wi (through) or on wi's side.
  Vec3 Ng(ctx.Ng);
  if (!is_finite(Ng) || !(dot(Ng, Ng) > 1e-12f)) Ng = sp.frame.n;
  Ng = normalize(Ng);
  const bool wi_above = dot(Ng, Vec3(ctx.wi)) >= 0.0f;
  const Vec3 n = (wi_above != exit.through) ? Ng : -Ng;
  // One direction from the exit SG restricted to the outside of the exit face (glimmer/exit_lobe.h's rule,
  // whose density the host uses for light sampling there).
  mf::WalkRng rng(hash_u32x2(seed, 0x7f4a7c15u));
  const auto to_world = [&](const Vec3 &a) { return normalize(sp.frame.to_world(flip ? mf::flip_z_local(a) : a)); };
  glimmer::ExitLobe lobe{axis, exit.sg.sharpness, n, 0.0};
  int k = 0;
  if (exit.lobe_count > 0) {  // kMixture: one lobe picked by its share; the whole mixture to the host (ABI 2.7)
    float weights[ExitLobe::kMaxLobes];
    for (int j = 0; j < exit.lobe_count; ++j) weights[j] = exit.lobe[j].weight;
    k = glimmer::pick_mixture_lobe(weights, exit.lobe_count, double(rng.next()));
    lobe.axis = to_world(Vec3(exit.lobe[k].axis));
    lobe.kappa = exit.lobe[k].sharpness;
#if GLIMMER_ABI_MINOR >= 7
    if (out.mixture_out != nullptr) {
      GlimmerExitMixture &m = *out.mixture_out;
      m.count = uint32_t(exit.lobe_count);
      for (int j = 0; j < exit.lobe_count; ++j) {
        m.axis[j] = to_world(Vec3(exit.lobe[j].axis));
        m.sharpness[j] = exit.lobe[j].sharpness;
        m.weight[j] = exit.lobe[j].weight;
      }
      out.exit_mixture = true;
    }
#endif
  }
  const Vec3 wo = leaving != nullptr ? to_world(leaving[k]) : lobe.sample([&rng] { return rng.next(); });
  if (!(dot(wo, n) > 0.0f) || !is_finite(wo) || !is_finite(weight) || !is_finite(axis)) return false;
  out.wo = sp.frame.to_local(wo);
  out.f_cos = weight;
  out.pdf = 1.0f;
  out.roughness = std::clamp(std::sqrt(std::sqrt(2.0f / float(lobe.kappa))), 0.0f, 1.0f);
  out.eta = 1.0f;  // air on both sides
  out.label = (exit.through ? GLIMMER_LABEL_TRANSMIT : GLIMMER_LABEL_REFLECT) | GLIMMER_LABEL_SINGULAR;
  out.moved = true;  // to the exit face of the same point: the host offsets the origin to that side
  out.origin = Vec3(ctx.P);
  out.origin_Ng = n;
  out.exit_lobe = true;
  out.lobe_axis = lobe.axis;
  out.lobe_sharpness = float(lobe.kappa);
  return is_finite(out.origin);
}

}  // namespace

bool sample_pane_sg(const ShadingPoint &sp, const PaneSgInputs &in, const Vec3 &rand, const Spectrum &front_weight,
                    bool flip, LocalSample &out) {
  const Vec3 wi = flip ? mf::flip_z_local(sp.wi) : sp.wi;
  const uint32_t seed = sp.seed_for(rand);
  PaneExitLobe exit;
  if (!pane_exit_lobe(wi, in, seed, exit)) return false;
  return emit_pane_sample(sp, exit, seed, front_weight * exit.weight, flip, out);
}

bool pane_exit_lobe_at(const Vec3 &d, const PaneSgInputs &in, PaneExitLobe &out) {
  if (in.table == nullptr || !is_finite(d) || d.z == 0.0f) return false;
  const float ior = in.ior;
  if (!(ior >= TransmissionSgTable::kIorMin && ior <= TransmissionSgTable::kIorMax)) return false;
  const float roughness = std::clamp(std::isfinite(in.roughness) ? in.roughness : 0.0f,
                                     TransmissionSgTable::kRoughnessMin, kTableRoughnessMax);
  const Vec3 n(0.0f, 0.0f, d.z < 0.0f ? -1.0f : 1.0f);
  float energy = 0.0f;
  if (!table_lobe(*in.table, Frame::from_normal(-n), -normalize(d), 1.0f / ior, roughness, out.sg, energy))
    return false;
  out.energy = energy;
  out.through = n.z < 0.0f;
  out.weight = Spectrum(1.0f);
  out.lobe_count = 0;
  return is_finite(out.sg.axis) && std::isfinite(out.sg.sharpness);
}

bool sample_pane_sg_at(const ShadingPoint &sp, const PaneSgInputs &in, const Vec3 &rand, const Vec3 &d,
                       const Spectrum &weight, bool flip, LocalSample &out) {
  PaneExitLobe exit;
  if (!pane_exit_lobe_at(d, in, exit)) return false;
  return emit_pane_sample(sp, exit, sp.seed_for(rand), weight, flip, out);
}

bool sample_pane_sg_through(const ShadingPoint &sp, const PaneSgInputs &in, const Vec3 &rand, const Vec3 &wi,
                            const Spectrum &weight, bool flip, LocalSample &out) {
  PaneExitLobe exit;
  if (!pane_exit_lobe_through(wi, in, exit)) return false;
  return emit_pane_sample(sp, exit, sp.seed_for(rand), weight, flip, out);
}

int pane_branch_level() {
  static const int level = measurement_knob("GLIMMER_FROSTED_PANE_BRANCH", kPaneBranchDefault, 0, 2);
  return level;
}
double pane_face_probability(double t_through, double t_back, int face_pick) {
  if (!(t_through > 0.0)) return 0.0;
  if (!(t_back > 0.0)) return 1.0;
  if (face_pick == 1) return 0.5;
  if (face_pick == 2) return std::sqrt(t_through) / (std::sqrt(t_through) + std::sqrt(t_back));
  return t_through / (t_through + t_back);
}

#if GLIMMER_ABI_MINOR >= 8
bool PaneSgExitState::packed() { return pane_branch_level() > 0; }
#endif
int pane_exact_leaving_level() {
  static const int level = measurement_knob("GLIMMER_FROSTED_PANE_EXACT_LEAVING", kPaneExactLeavingDefault, 0, 1);
  return level;
}
int pane_both_faces_level() {
  // Exactly 0, 1, 2, kPaneBothFacesControl (the camera-side lamp render test's negative control, tests/bridge/
  // test_frosted_pane_sg_render.cpp; session 34) or kPaneBothFacesNoColourGuard (session 35's coloured-Beer render
  // test's negative control); anything else the default (a typo cannot select a biased control).
  static const int level = measurement_level("GLIMMER_FROSTED_PANE_BOTH_FACES", kPaneBothFacesDefault,
                                             {0, 1, 2, kPaneBothFacesNoColourGuard, kPaneBothFacesControl});
  return level;
}
int pane_beer_split_level() {
  static const int level = measurement_knob("GLIMMER_FROSTED_PANE_BEER_SPLIT", kPaneBeerSplitDefault, 0, 1);
  return level;
}
int pane_front_grid_level() {
  // Exactly 0, 1, 2 or kPaneFrontGridExact; the controls (5, 6, 7, 9) only as the tests' explicit argument.
  static const int level =
      measurement_level("GLIMMER_FROSTED_PANE_FRONT_GRID", kPaneFrontGridDefault, {0, 1, 2, kPaneFrontGridExact});
  return level;
}
Vec3 pane_front_grid_numbers(const Vec3 &primary, const Vec3 &hashed, int k, int level, bool after_bounce) {
  static_assert(kPaneWalkSplit == 4, "the 2 x 2 grid holds the primary and 3 extras");
  if (level == 0 || (level != 2 && !after_bounce) || k < 1 || k >= kPaneWalkSplit) return hashed;
  const bool wrap = level != kPaneFrontGridControl;
  const auto shift = [wrap](float u, bool on) {
    if (!on) return u;
    if (!wrap) return 0.5f + 0.5f * u;  // the control: not uniform (the upper half only)
    // u + 1/2 mod 1; exact for the host's 24-bit numbers, and kept below 1 for finer ones (u + 0.5f could round up)
    return u < 0.5f ? std::min(u + 0.5f, 0x1.fffffep-1f) : u - 0.5f;
  };
  return Vec3(shift(primary.x, (k & 1) != 0), shift(primary.y, (k >> 1) != 0), hashed.z);
}

namespace {
// The exact exit for the host's lamps (PaneSgExitState) of the picked face's ends (t[k] > 0 on that face): only where
// the host combines the lamps with this sample (as method=path's exit state) and where the pane is seen directly (no
// diffuse or glossy bounce before: after one, e.g. the floor under the bench's pane, the SG's shape error is blurred
// away, lit_R / shadow_R 0.0006 / 0.0005, while the exact exit's noise is not: +32 % / +56 % variance there). False:
// no state (also where an end of either face in the state has no finite c_k, E_k = 0: the mixture as before).
// Called only where pane_exit_state_wanted. both_scale > 0 (session 33, pane_both_faces_level): the ends of both
// faces, c_k scaled by it (p_F; the control 1).
bool pane_exit_state_wanted(const ShadingPoint &sp, const LocalSample &out) {
  const GlimmerShadingContext &ctx = *sp.ctx;
  return out.state_out != nullptr && !sp.uncombined() && ctx.diffuse_bounce + ctx.glossy_bounce == 0;
}
bool pane_exit_state(const PaneWalkEnd *walks, const PaneExitLobe *lobes, const float *t, int ends, bool through,
                     double t_face, double both_scale, PaneSgExitState &x) {
  const bool both = both_scale > 0.0;
  const double scale = both ? both_scale : 1.0;  // x 1.0: the one-face c_k bit for bit
  int kept = 0;
  for (int k = 0; k < ends; ++k) {
    if (!(t[k] > 0.0f) || (lobes[k].through != through && !both)) continue;
    const float c = float(t[k] / t_face * scale) / lobes[k].energy;
    if (!(c > 0.0f && std::isfinite(c) && kept < PaneSgExitState::capacity())) return false;
    x.d[kept] = walks[k].d;
    x.c[kept++] = c;
  }
  return kept > 0;
}
// Whether a and b have one colour (b = s a for some s >= 0, to float rounding): the other face's ends can then take
// the picked face's weight's colour (the sample's weight is a Spectrum, the host's value q grey).
bool same_colour(const Spectrum &a, const Spectrum &b) {
  const float sa = a.x + a.y + a.z, sb = b.x + b.y + b.z, tol = 1e-5f * sa * sb;
  return std::fabs(a.x * sb - b.x * sa) <= tol && std::fabs(a.y * sb - b.y * sa) <= tol &&
         std::fabs(a.z * sb - b.z * sa) <= tol;
}
// pane_both_faces_level's scale of c_k for both faces' ends (0: the picked face's only): p_F at levels 1 and 2, 1 for
// the control; 0 without the packed state or where an end's colour differs from the face's weight's.
double pane_both_faces_scale(int level, double p_face, const PaneWalkEnd *walks, const float *t, int ends,
                             const Spectrum &weight) {
  if (level <= 0 || !PaneSgExitState::packed()) return 0.0;
  if (level != kPaneBothFacesNoColourGuard)
    for (int k = 0; k < ends; ++k)
      if (t[k] > 0.0f && !same_colour(weight, walks[k].throughput)) return 0.0;
  return level == kPaneBothFacesControl ? 1.0 : p_face;
}
// The picked face's exit mixture (its ends' lobes, weights t_k / t_face; one end: the single SG), the ends' own
// leaving directions in the mixture's order, whether every end has one, and the face's throughput sum. False: no end.
bool pane_face_mixture(const PaneWalkEnd *walks, const PaneExitLobe *lobes, const float *t, int ends, bool through,
                       double t_face, PaneExitLobe &exit, Vec3 *leaving, bool &all_leave, Spectrum &sum_face) {
  exit.through = through;
  exit.lobe_count = 0;
  for (int k = 0; k < ends; ++k) {
    if (!(t[k] > 0.0f) || lobes[k].through != through) continue;
    leaving[exit.lobe_count] = walks[k].leaving;
    all_leave = all_leave && dot(walks[k].leaving, walks[k].leaving) > 0.0f;
    sum_face += walks[k].throughput;
    if (exit.lobe_count == 0) exit.sg = lobes[k].sg;
    ExitLobe::MixtureLobe &l = exit.lobe[exit.lobe_count++];
    l.axis = lobes[k].sg.axis;
    l.sharpness = lobes[k].sg.sharpness;
    l.weight = float(t[k] / t_face);
  }
  if (exit.lobe_count == 0) return false;
  if (exit.lobe_count == 1) exit.lobe_count = 0;  // one lobe: the single SG (exit.sg), as the unsplit sample
  return true;
}
// Session 35 (frostedbeer35): coloured Beer, one end. Within the picked face (probability p_face, t_face its ends'
// sum of t) one end j with probability t_j / t_face from a number of its own hashed from the sample's seed; every other
// end's t is zeroed, so the mixture, the weight's sum and the exit state below see end j alone. Returns t_j (0: none).
double pick_pane_end(uint32_t seed, bool through, const PaneExitLobe *lobes, int ends, double t_face, float *t) {
  const double u = double(hash_u32x2(seed, 0x656e6473u) >> 8) * 0x1p-24 * t_face;
  double acc = 0.0;
  int j = -1;
  for (int k = 0; k < ends; ++k) {
    if (!(t[k] > 0.0f) || lobes[k].through != through) continue;
    j = k;  // the face's last end also takes u's rounding remainder
    acc += t[k];
    if (u < acc) break;
  }
  if (j < 0) return 0.0;
  for (int k = 0; k < ends; ++k)
    if (k != j) t[k] = 0.0f;
  return t[j];
}
}  // namespace

bool sample_pane_sg_split(const ShadingPoint &sp, const PaneSgInputs &in, const Vec3 &rand, const PaneWalkEnd *walks,
                          int n, bool flip, LocalSample &out, int ends, int face_pick, int exact_leaving,
                          int both_faces) {
  if (n < 1 || n > kPaneWalkSplit) return false;
  if (both_faces < 0) both_faces = pane_both_faces_level();
  // Coloured Beer (session 35): one end per sample (pick_pane_end) unless a test asks for the old one-colour state.
  const bool one_colour = both_faces == kPaneOneColourState || both_faces == kPaneBothFacesNoColourGuard;
  const bool one_end = !pane_split_applies(in.sigma_a) && !one_colour;
  if (both_faces == kPaneOneColourState || one_end) both_faces = 0;
  if (both_faces == 2 && face_pick != 0) face_pick = 3;  // t_F / t, the weight over p_F (session 33)
  if (ends < 0) ends = n;
  if (ends < 1 || ends > 2 * kPaneWalkSplit) return false;
  PaneExitLobe lobes[2 * kPaneWalkSplit];
  float t[2 * kPaneWalkSplit];
  Spectrum sum_T(0.0f);
  double t_all = 0.0, t_through = 0.0;
  for (int k = 0; k < ends; ++k) {
    t[k] = 0.0f;
    const Spectrum &T = walks[k].throughput;
    if (!(max_component(T) > 0.0f) || !is_finite(T) || !pane_exit_lobe_at(walks[k].d, in, lobes[k])) continue;
    t[k] = average(T);
    if (!(t[k] > 0.0f)) continue;
    sum_T += T;
    t_all += t[k];
    if (lobes[k].through) t_through += t[k];
  }
  if (!(t_all > 0.0)) return false;
  // The face: through with probability p_through (a number of its own, hashed from the closure's); main: t_through /
  // t_all (pane_face_probability).
  const uint32_t seed = sp.seed_for(rand);
  const double u = double(hash_u32x2(seed, 0x66616365u) >> 8) * 0x1p-24;
  const double p_through = pane_face_probability(t_through, t_all - t_through, face_pick);
  const bool through = face_pick == 0 ? u * t_all < t_through : u < p_through;  // main's test at 0 (bit for bit)
  double t_face = through ? t_through : t_all - t_through;
  if (!(t_face > 0.0)) return false;
  double p_face = through ? p_through : 1.0 - p_through;
  if (one_end) {  // the pick's probability p_F t_j / t_F; the end is then a face of its own (t_face = t_j)
    const double t_end = pick_pane_end(seed, through, lobes, ends, t_face, t);
    if (!(t_end > 0.0)) return false;
    p_face = (face_pick == 0 ? t_face / t_all : p_face) * (t_end / t_face);
    t_face = t_end;
  }
  PaneExitLobe exit;
  Vec3 leaving[2 * kPaneWalkSplit];  // the face's ends' own directions out, in the mixture's order
  bool all_leave = true;
  Spectrum sum_face(0.0f);
  if (!pane_face_mixture(walks, lobes, t, ends, through, t_face, exit, leaving, all_leave, sum_face)) return false;
  // The face's walks' throughput over n and over the face's probability (sum_T / n when p_face = t_face / t_all).
  const Spectrum weight = face_pick == 0 && !one_end ? sum_T / float(n) : sum_face * float(1.0 / (double(n) * p_face));
#if GLIMMER_ABI_MINOR >= 8
  PaneSgExitState x;
  // The ends' colour test (pane_both_faces_scale) only where a state may be written.
  const bool wanted = pane_exit_state_wanted(sp, out);
  const double both = wanted ? pane_both_faces_scale(both_faces, p_face, walks, t, ends, weight) : 0.0;
  // An end of the other face without a finite c_k (E_k = 0) leaves the picked face's own exact state (bd98090's),
  // not the SG mixture: that end's validity does not depend on the pick, so each estimator stays unbiased alone.
  const bool state = wanted && (pane_exit_state(walks, lobes, t, ends, through, t_face, both, x) ||
                                (both > 0.0 && pane_exit_state(walks, lobes, t, ends, through, t_face, 0.0, x)));
  if (exact_leaving < 0) exact_leaving = pane_exact_leaving_level();
  const bool exact = state && all_leave && exact_leaving > 0;  // the exit state's own directions
  if (!emit_pane_sample(sp, exit, seed, weight, flip, out, exact ? leaving : nullptr)) return false;
  if (state) {
    x.write(*out.state_out);
    out.exit_state = true;
  }
#else
  if (!emit_pane_sample(sp, exit, seed, weight, flip, out)) return false;
#endif
  return true;
}

}  // namespace glimmer::plugin::frosted
