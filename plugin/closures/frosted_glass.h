// Frosted glass (XML frosted_glass_bsdf; the Blender Frosted Glass node),
// issue 12. Every interface the path meets is the exact rough dielectric of
// Walter et al. 2007 (eq. 20 reflection, eq. 21 transmission; GGX,
// visible-normal sampling) with the same multiple-scattering energy
// compensation as microfacet_dielectric's multi_ggx (f = f_ss / E(mu, alpha,
// eta), so a lossless interface conserves energy from both sides). The
// interface itself is core/dielectric_lobe.h, shared with microfacet_dielectric.
//
// method=path: the reference estimator, both refraction events are stochastic.
// method=sg: where the path enters a solid, the transmitted light is estimated
// with spherical Gaussians (de Rousiers 2012, closures/frosted_glass_sg.h):
// one SINGULAR sample that the host continues from the exit point; the front
// reflection stays this rough dielectric lobe. Thin panes: the same estimate
// between two parallel faces (pane_sample_sg; the light leaves through either
// face; the walk between the faces is exact and only the leaving crossing is
// an SG: above roughness 0.4 the leaving table's, up to 0.4 the exit mixture for
// light that crossed without a reflection between the faces,
// frosted::default_pane_variant). Paths arriving from inside a solid and cases
// the estimator cannot handle use path.
// method=auto: sg or path per shading point (auto_picks_sg below): sg where its
// measured error is small (entry roughness <= kAutoSgRoughnessMax) or where
// the glass is only seen after a diffuse or glossy bounce (its bias blurred
// by that bounce), path elsewhere.
//
// Two geometries:
//  - solid (thin = 0): the mesh is the object's boundary; the path tracer
//    refracts in and out. Interior absorption (Beer-Lambert, sigma = -ln(c) / d
//    for "absorption colour c after distance d") is applied at each interface
//    the path reaches from inside, over the segment it travelled inside: its
//    length is found by tracing back along wi with the host's trace_ray (the
//    previous vertex is the first surface that way, since the segment was
//    unoccluded). Without a trace_ray service, or on an open mesh where the
//    ray escapes, the segment is not attenuated.
//  - thin = 1 (window pane, sheet): the mesh is one sheet standing for two
//    parallel interfaces `thickness` apart, both sides in air. The slab is
//    integrated inside the closure by a position-free random walk between the
//    two interfaces (lateral offset ignored): sample() walks it (weight =
//    product of f cos / pdf of each event, absorption exp(-sigma thickness /
//    |cos|) per crossing) and returns it as one SINGULAR sample; eval() is the
//    front interface's reflection alone (deterministic, light-sampled): a
//    one-walk estimate of f through the pane at the entry had rare huge
//    values (MIS 27x noisier than BSDF sampling on a world-lit pane). Since
//    ABI 2.8 method=path's walk sample hands the host the state of its last
//    interface (PaneExitState, eval_exit), so the host light-samples through
//    that interface at the shading point with MIS, unbiased by the 1 / P_T
//    factor the state carries (docs/frosted_glass.md "Light sampling at a
//    pane's exit"). A transmitted sample keeps eta = 1.
//
// colour tints transmitted light at each interface crossing (a solid object
// or a pane seen through gives colour^2; reflections stay white).
// roughness, ior and colour are varying (textures); absorption and thickness
// are per material.
#pragma once

#include <array>
#include <bit>
#include <cmath>
#include <cstring>

#include "core/closure.h"
#include "core/dielectric_lobe.h"
#include "closures/frosted_glass_sg.h"
#include "core/microfacet_lobe_params.h"
#include "glimmer/microfacet_walk.h"
#include "glimmer/rng.h"

namespace glimmer::plugin {

// Beer-Lambert absorption of the interior: T(l) = exp(-sigma l), sigma = -ln(c) / d.
struct BeerAbsorption {
  Spectrum sigma{0.0f};
  bool active = false;

  static BeerAbsorption from(const Spectrum &color_at_distance, float distance) {
    BeerAbsorption b;
    for (int ch = 0; ch < 3; ++ch) {
      const float c = std::clamp(color_at_distance[ch], 1e-30f, 1.0f);
      b.sigma[ch] = -std::log(c) / distance;
    }
    b.active = b.sigma.x > 0.0f || b.sigma.y > 0.0f || b.sigma.z > 0.0f;
    return b;
  }
  Spectrum transmittance(float length) const {
    if (!active) return Spectrum(1.0f);
    return {std::exp(-sigma.x * length), std::exp(-sigma.y * length), std::exp(-sigma.z * length)};
  }
};

class FrostedGlassClosure {
 public:
  static constexpr const char *kName = "frosted_glass";
  static constexpr const char *kDoc =
      "Frosted (rough) glass object or thin pane: Walter 2007 rough dielectric interfaces with multi-GGX energy "
      "compensation, tinted transmission, Beer interior absorption; method=path is the exact path-traced reference.";
  static constexpr uint32_t kFlags = GLIMMER_CLOSURE_TRANSMISSIVE | GLIMMER_CLOSURE_NEEDS_TRACE;
  // Interface events of one pane walk after the entry (beyond: absorbed; a lossless pane at roughness 1 and
  // IOR 2.4 loses < 1e-4 of its energy there, test FrostedGlassThin.WhiteFurnace).
  static constexpr int kMaxPaneEvents = 4096;
  // method=auto uses sg up to this entry roughness: the sg estimate's mean relative error vs a 16k-path
  // reference is <= 1.5 % there on a sphere and a slab (0.3, tests/closures/test_frosted_sg.cpp), 2-14 % above.
  static constexpr float kAutoSgRoughnessMax = 0.3f;
  enum class Method { kPath = 0, kSg = 1, kAuto = 2 };  // the order of the "method" enum below

  static std::span<const GlimmerParamSpec> params() {
    static const std::array<GlimmerParamSpec, 8> schema{{
        {"color", GLIMMER_PARAM_COLOR, {1.0f, 1.0f, 1.0f}, 0.0f, 1.0f, nullptr, nullptr,
         "transmission tint per interface crossing (linear RGB in [0, 1])", GLIMMER_PARAM_VARYING},
        {"roughness", GLIMMER_PARAM_FLOAT, {0.3f, 0, 0}, 0.0f, 1.0f, nullptr, nullptr,
         "Cycles roughness in [0, 1] of both interfaces; alpha = roughness^2", GLIMMER_PARAM_VARYING},
        {"ior", GLIMMER_PARAM_FLOAT, {1.5f, 0, 0}, 1e-3f, 1e3f, nullptr, nullptr,
         "index of refraction n_inside / n_outside (> 0)", GLIMMER_PARAM_VARYING},
        {"absorption_color", GLIMMER_PARAM_COLOR, {1.0f, 1.0f, 1.0f}, 0.0f, 1.0f, nullptr, nullptr,
         "interior (Beer) absorption: the colour light keeps after absorption_distance inside; 1,1,1 = clear", 0},
        {"absorption_distance", GLIMMER_PARAM_FLOAT, {1.0f, 0, 0}, 1e-6f, 1e6f, nullptr, nullptr,
         "distance (scene units) at which light inside has absorption_color", 0},
        {"thin", GLIMMER_PARAM_BOOL, {0.0f, 0, 0}, 0.0f, 1.0f, nullptr, nullptr,
         "the surface is a thin pane (two parallel interfaces thickness apart, air on both sides), not a solid's "
         "boundary", 0},
        {"thickness", GLIMMER_PARAM_FLOAT, {0.01f, 0, 0}, 1e-6f, 1e6f, nullptr, nullptr,
         "thin: distance between the pane's two interfaces (scene units; absorption path length)", 0},
        {"method", GLIMMER_PARAM_ENUM, {0, 0, 0}, 0.0f, 0.0f, "path|sg|auto", "path",
         "transmission estimator: path = exact stochastic refraction at every interface (reference); sg = "
         "spherical-Gaussian estimate through the object (de Rousiers 2012; solids and thin panes); auto = sg at roughness "
         "<= 0.3 or after a diffuse/glossy bounce, path elsewhere", 0},
    }};
    return schema;
  }

  static std::unique_ptr<FrostedGlassClosure> create(const ParamReader &p) {
    auto c = std::make_unique<FrostedGlassClosure>();
    c->color_ = p.get_color("color");
    c->roughness_ = p.get_float("roughness");
    c->ior_ = p.get_float("ior");
    c->beer_ = BeerAbsorption::from(p.get_color("absorption_color"), p.get_float("absorption_distance"));
    c->thin_ = p.get_bool("thin");
    c->thickness_ = p.get_float("thickness");
    c->color_param_ = p.index("color");
    c->roughness_param_ = p.index("roughness");
    c->ior_param_ = p.index("ior");
    c->lobe_.build(interface_params(c->roughness_), c->ior_, false, true);
    c->method_ = static_cast<Method>(p.get_enum("method"));
    return c;
  }

  // method=sg / auto: the SG table (loaded from the host's cache or built once per process).
  void prepare(const GlimmerHostServices *host) {
    if (method_ != Method::kPath) table_ = &frosted::TransmissionSgTable::get(host);
  }

  LocalEval eval(const ShadingPoint &sp, const Vec3 &wo) const {
    DielectricLobe scratch;
    const DielectricLobe &lobe = lobe_at(sp, scratch);
    if (thin_) return pane_front_reflection(sp, lobe, wo);  // the walk through the pane is singular (both methods)
    if (uses_sg(sp) && wo.z < 0.0f) return {};  // sg: transmission is the singular sample alone
    LocalEval e = lobe.eval(sp.wi, wo);
    if (wo.z * sp.wi.z < 0.0f) e.f_cos *= color_at(sp);
    e.f_cos *= interior_transmittance(sp);
    return e;
  }

  bool sample(const ShadingPoint &sp, const Vec3 &rand, LocalSample &out) const {
    DielectricLobe scratch;
    const DielectricLobe &lobe = lobe_at(sp, scratch);
    if (thin_)
      return uses_sg_pane(sp) ? pane_sample_sg(sp, lobe, rand, out,
                                               frosted::default_pane_variant(sp.param_float(roughness_param_, roughness_)))
                              : pane_sample(sp, lobe, rand, out);
    if (!lobe.sample(sp.wi, rand, out)) return false;
    if (out.label & GLIMMER_LABEL_TRANSMIT) out.f_cos *= color_at(sp);
    out.f_cos *= interior_transmittance(sp);
    if (uses_sg(sp) && (out.label & GLIMMER_LABEL_TRANSMIT))
      return sample_sg(sp, rand, out, frosted::solid_sg_variant(sp.param_float(roughness_param_, roughness_)));
    return true;
  }

  // method=sg's transmission: replaces `front` (the front interface's transmitted sample) by the SG estimate
  // through the object when it applies (else `front` stays, as method=path). False: no sample, the light is lost
  // (the host's bounce limits end the walk inside: frosted::reflections_allowed). Public for the tests' variants.
  bool sample_sg(const ShadingPoint &sp, const Vec3 &rand, LocalSample &front, frosted::SgVariant variant,
                 float mixture_variance = frosted::kDefaultMixtureVariance,
                 float mixture_tail = frosted::kDefaultMixtureTail, float curved_tail = -1.0f,
                 const frosted::CurvedShape *curved_shape = nullptr, int sampled_reflection = -1,
                 int stratified_roulette = -1, float exit_centroid = -1.0f, float exit_waist = -1.0f,
                 int entry_axis = -1, int floor_exit = -1, float floor_origin = -1.0f) const {
    frosted::SgInputs in;
    in.table = table_;
    in.self = reinterpret_cast<const GlimmerInstance *>(this);
    in.schema = params();
    in.roughness_param = roughness_param_;
    in.color_param = color_param_;
    in.roughness = sp.param_float(roughness_param_, roughness_);
    in.constant_roughness = roughness_;
    in.constant_color = color_;
    in.ior = sp.param_float(ior_param_, ior_);
    in.sigma_a = beer_.sigma;
    in.variant = variant;
    in.mixture_variance = mixture_variance;
    in.mixture_tail = mixture_tail;
    in.curved_tail = curved_tail;
    in.curved_shape = curved_shape;
    in.stratified_roulette = stratified_roulette;
    in.exit_centroid = exit_centroid;
    in.exit_waist = exit_waist;
    in.entry_axis = entry_axis;
    in.floor_exit = floor_exit;
    in.floor_origin = floor_origin;
    DielectricLobe scratch;  // the reflections' lobe (frosted::kSampledReflection), built only where it applies
    in.sampled_reflection = frosted::sampled_reflection_at(sp, sampled_reflection);
    if (in.sampled_reflection) in.lobe = &lobe_at(sp, scratch), in.lobe_roughness = in.roughness;
    LocalSample s;
#if GLIMMER_ABI_MINOR >= 7
    s.mixture_out = front.mixture_out;  // the host's buffer for the whole exit mixture (ABI 2.7)
#endif
    bool lost = false;
    if (frosted::sample_sg_transmission(sp, in, rand, front, s, &lost)) front = s;
    return !lost;
  }
  // method=sg through a thin pane (the paper's thin-object case, frosted_glass_sg.h): the front interface is
  // sampled exactly; a transmission becomes one singular sample from the pane's exit lobe (either face).
  // Decided per point only (eval must agree with sample): the table must cover the IOR.
  bool uses_sg_pane(const ShadingPoint &sp) const {
    if (!thin_ || table_ == nullptr) return false;
    const float ior = sp.param_float(ior_param_, ior_);
    if (!(ior >= frosted::TransmissionSgTable::kIorMin && ior <= frosted::TransmissionSgTable::kIorMax)) return false;
    return method_ == Method::kSg || (method_ == Method::kAuto && auto_picks_sg(sp));
  }
  // The pane's front interface for the sg samples: wi the incidence in the pane frame (flip: sp.wi was below it), s
  // the front sample from `rand`. kReflected: the sample is the front reflection (exact, as eval's
  // pane_front_reflection), written to out; kEntered: s transmits into the pane; kNone: no sample.
  enum class PaneFront { kNone, kReflected, kEntered };
  PaneFront pane_front_sample(const ShadingPoint &sp, const DielectricLobe &lobe, const Vec3 &rand, Vec3 &wi,
                              bool &flip, LocalSample &s, LocalSample &out) const {
    flip = sp.wi.z < 0.0f;
    wi = flip ? mf::flip_z_local(sp.wi) : sp.wi;
    if (!(wi.z > 0.0f) || !lobe.sample(wi, rand, s)) return PaneFront::kNone;
    if (s.label & GLIMMER_LABEL_TRANSMIT) return PaneFront::kEntered;
    if (flip) s.wo = mf::flip_z_local(s.wo);
    out = s;
    return PaneFront::kReflected;
  }
  // The sg pane's inputs at sp (per-point roughness and IOR, the tint, Beer, the thickness).
  frosted::PaneSgInputs pane_sg_inputs(const ShadingPoint &sp, frosted::SgVariant variant,
                                       const frosted::PaneLadder &ladder) const {
    frosted::PaneSgInputs in;
    in.table = table_;
    in.roughness = sp.param_float(roughness_param_, roughness_);
    in.ior = sp.param_float(ior_param_, ior_);
    in.tint = color_at(sp);
    in.sigma_a = beer_.sigma;
    in.thickness = thickness_;
    in.variant = variant;
    in.ladder = &ladder;
    return in;
  }
  // The sg pane sample (public for the tests' variants): the front interface's reflection as in method=path, its
  // transmission replaced by frosted::sample_pane_sg.
  bool pane_sample_sg(const ShadingPoint &sp, const DielectricLobe &lobe, const Vec3 &rand, LocalSample &out,
                      frosted::SgVariant variant, const frosted::PaneLadder &ladder = frosted::kPaneLadder,
                      int split = frosted::kPaneWalkSplit) const {
    Vec3 wi;
    bool flip;
    LocalSample s;
    const PaneFront front = pane_front_sample(sp, lobe, rand, wi, flip, s, out);
    if (front != PaneFront::kEntered) return front == PaneFront::kReflected;
    const frosted::PaneSgInputs in = pane_sg_inputs(sp, variant, ladder);
    if (variant == frosted::SgVariant::kPaneWalk) {
      if (split > 1 && (frosted::pane_split_applies(in.sigma_a) || frosted::pane_beer_split_level() > 0))
        return pane_sample_sg_split(sp, lobe, in, rand, wi, s, flip, out, std::min(split, frosted::kPaneWalkSplit));
      return pane_sample_sg_walk(sp, lobe, in, rand, s, flip, out);
    }
    if (variant == frosted::SgVariant::kPaneWalkMixture) return pane_sample_sg_walk(sp, lobe, in, rand, s, flip, out, &wi);
    return frosted::sample_pane_sg(sp, in, rand, s.f_cos / s.pdf * in.tint, flip, out);
  }
  // SgVariant::kPaneWalk (rough panes) and kPaneWalkMixture (smooth panes): the walk between the faces as
  // pane_sample's (walk_to_exit: the same numbers), its leaving direction replaced by the exit lobe at the last
  // internal direction (frosted::sample_pane_sg_at). kPaneWalkMixture (`wi` given, pane frame): light that leaves
  // through the far face without a reflection between the faces leaves as the mixture with the heavy-tail ladder
  // (frosted::sample_pane_sg_through) instead.
  bool pane_sample_sg_walk(const ShadingPoint &sp, const DielectricLobe &lobe, const frosted::PaneSgInputs &in,
                           const Vec3 &rand, const LocalSample &front, bool flip, LocalSample &out,
                           const Vec3 *mixture_wi = nullptr) const {
    Spectrum throughput = front.f_cos / front.pdf * in.tint;
    Vec3 d = front.wo, leaving;
    int reflections = 0;
    if (!walk_to_exit(sp, lobe, rand, d, throughput, leaving, &reflections)) return false;
    if (mixture_wi != nullptr && reflections == 0)
      return frosted::sample_pane_sg_through(sp, in, rand, *mixture_wi, throughput * in.tint, flip, out);
    return frosted::sample_pane_sg_at(sp, in, rand, d, throughput * in.tint, flip, out);
  }
  // kPaneWalk split (frosted_glass_sg.h, kPaneWalkSplit): the primary walk from `front` (the front sample drawn from
  // `rand`, wi in the pane frame) and split - 1 more front samples from numbers hashed from `rand`, those that
  // transmit kept with their own walks (a walk that fails is kept with zero throughput: it counts in n).
  // count_rejected: the tests' negative control, the extra front samples that reflect counted in n as zero walks
  // (biased low by the front's transmission probability). branch: frosted::pane_branch_level's level (-1: the
  // knob's; session 30): where the pane is seen directly, each walk's first event at the far face keeps both branches
  // (branch_walks) and the face is picked by frosted::pane_face_probability's level 2. exact_leaving: the tests'
  // level of frosted::pane_exact_leaving_level (-1: the knob's; session 32). both_faces: the tests' level of
  // frosted::pane_both_faces_level (-1: the knob's; session 33). front_grid: the tests' level of
  // frosted::pane_front_grid_level (-1: the knob's; session 35).
  bool pane_sample_sg_split(const ShadingPoint &sp, const DielectricLobe &lobe, const frosted::PaneSgInputs &in,
                            const Vec3 &rand, const Vec3 &wi, const LocalSample &front, bool flip, LocalSample &out,
                            int split, bool count_rejected = false, int branch = -1, int exact_leaving = -1,
                            int both_faces = -1, int front_grid = -1) const {
    frosted::PaneWalkEnd walks[2 * frosted::kPaneWalkSplit];
    int n = 0, ends = 0;
    const bool after_bounce = sp.ctx->diffuse_bounce + sp.ctx->glossy_bounce != 0;
    if (branch < 0) branch = frosted::pane_branch_level();
    if (split < 2 || after_bounce || lobe.mode == kSharp) branch = 0;  // camera-seen rough panes only
    if (front_grid < 0) front_grid = frosted::pane_front_grid_level();
    if (split != frosted::kPaneWalkSplit) front_grid = 0;
    if (frosted::pane_front_grid_exact(front_grid) && after_bounce && lobe.mode != kSharp) {  // branch is 0 here
      pane_front_grid_exact_walks(sp, lobe, in, rand, wi, front, front_grid, walks);
      return frosted::sample_pane_sg_split(sp, in, rand, walks, frosted::kPaneWalkSplit, flip, out,
                                           frosted::kPaneWalkSplit, 0, exact_leaving, both_faces);
    }
    const auto add_walk = [&](const Vec3 &numbers, const LocalSample &s) {
      ++n;
      if (branch > 0) {
        ends += branch_walks(sp, lobe, numbers, s, in.tint, walks + ends, branch == frosted::kPaneBranchControl);
        return;
      }
      walk_pane_end(sp, lobe, in, numbers, s, walks[ends++]);
    };
    add_walk(rand, front);
    mf::WalkRng rng = split_numbers(sp, rand);
    for (int k = 1; k < split; ++k) {
      const Vec3 hashed(rng.next(), rng.next(), rng.next());
      const Vec3 numbers = frosted::pane_front_grid_numbers(rand, hashed, k, front_grid, after_bounce);
      LocalSample s;
      if (!refracts(lobe, wi, numbers, s)) {
        if (count_rejected) walks[ends++] = frosted::PaneWalkEnd{}, ++n;
        continue;
      }
      add_walk(numbers, s);
    }
    const int face_pick = branch >= 2 ? 2 : 0;  // the control (9) keeps main's pick
    return frosted::sample_pane_sg_split(sp, in, rand, walks, n, flip, out, ends, face_pick, exact_leaving,
                                         both_faces);
  }
  // The split's extra front samples' numbers: one stream per sample, hashed from its seed.
  static mf::WalkRng split_numbers(const ShadingPoint &sp, const Vec3 &rand) {
    return mf::WalkRng(hash_u32x2(sp.seed_for(rand), 0x73706c74u));
  }
  // Whether the front sample drawn with `numbers` is a refraction into the pane (false: reflection, TIR, no sample).
  static bool refracts(const DielectricLobe &lobe, const Vec3 &wi, const Vec3 &numbers, LocalSample &s) {
    return lobe.sample(wi, numbers, s) && (s.label & GLIMMER_LABEL_TRANSMIT) && s.pdf > 0.0f;
  }
  // One walk of the split: the front refraction s (drawn with `numbers`) walked between the faces to its exit; `w`
  // is left as it was where the walk fails. The tint once per crossing (entry and exit).
  void walk_pane_end(const ShadingPoint &sp, const DielectricLobe &lobe, const frosted::PaneSgInputs &in,
                     const Vec3 &numbers, const LocalSample &s, frosted::PaneWalkEnd &w) const {
    Spectrum throughput = s.f_cos / s.pdf * in.tint;
    Vec3 d = s.wo, leaving;
    if (!walk_to_exit(sp, lobe, numbers, d, throughput, leaving)) return;
    w = frosted::PaneWalkEnd{d, throughput * in.tint, leaving};
  }
  // frosted::kPaneFrontGridExact (session 35, frostedgridexact35): the split's 4 walks after a bounce, the extras on
  // level 1's 2 x 2 grid without their coin, written to walks[0..3] (one end each, n = 4). The derivation: extra k's
  // microfacet numbers (x_k, y_k) are the primary's (x, y) shifted by ((k & 1) / 2, (k >> 1) / 2) mod 1, so the 4
  // numbers are one orbit O of the shift group and, (x, y) uniform, each member of O is the primary's with
  // probability 1/4. p_k = (1 - F(m_k)) x v_k (v_k: m_k's refraction is a sample, not TIR nor on the wrong side) is
  // the probability that one walk's front, drawn at m_k, enters: the primary entered (we are here) with probability
  // p_0. Walk k (its throughput h_k = f_cos / pdf of the refraction at m_k x its walk, with E[h_k | m_k] = H(m_k))
  // is weighted c_k = 4 p_k / P, P = p_0 + ... + p_3 (a function of O only, > 0 since p_0 > 0), and
  // sample_pane_sg_split averages over n = 4: the sample's weight is sum_k p_k h_k / P. Its expectation, the
  // primary's coin included: E_O[(1/4) sum_{i in O} p_i x sum_k p_k H(m_k) / P] = E_O[(1/4) sum_k p_k H(m_k)] =
  // E_m[p(m) H(m)], one walk's transmitted expectation exactly (the orbits where P = 0 never reach the split, and
  // there every p is 0). The proposal c_k = 4 p_k / (4 p_0) ((1 - F_k) / (1 - F_0)) misses the orbits whose
  // primary does not enter (v_0 = 0 while some v_k = 1: biased low) and is unbounded as F_0 -> 1; c_k in [0, 4] here.
  // kPaneFrontGridExactControl: P without the primary's p_0 (the normaliser off by one: the weights sum > 4; the
  // tests' negative control). kPaneFrontGridNoFresnelControl / kPaneFrontGridReflectControl (session 36): p_k = v_k
  // (NoFresnel), resp. F(m_k) v_k (Reflect): the Fresnel weight alone wrong (the tests' controls where F varies over
  // one orbit's facets).
  void pane_front_grid_exact_walks(const ShadingPoint &sp, const DielectricLobe &lobe, const frosted::PaneSgInputs &in,
                                   const Vec3 &rand, const Vec3 &wi, const LocalSample &front, int level,
                                   frosted::PaneWalkEnd *walks) const {
    constexpr int kN = frosted::kPaneWalkSplit;
    Vec3 numbers[kN] = {rand};
    LocalSample s[kN] = {front};
    double p[kN] = {}, total = 0.0;
    mf::WalkRng rng = split_numbers(sp, rand);  // the hashed numbers as pane_sample_sg_split's
    for (int k = 0; k < kN; ++k) {
      if (k > 0) {
        const Vec3 hashed(rng.next(), rng.next(), rng.next());
        numbers[k] = frosted::pane_front_grid_numbers(rand, hashed, k, level, true);
        // z = 1 >= F: the refraction, always (false where it is no sample: TIR or the wrong side).
        if (!refracts(lobe, wi, Vec3(numbers[k].x, numbers[k].y, 1.0f), s[k])) continue;
      }
      // the facet lobe.sample drew for this walk (wi.z > 0: the outside's IOR), DielectricLobe's one formula
      Vec3 m;
      const double F = lobe.visible_facet(wi, lobe.ior, numbers[k].x, numbers[k].y, m);
      p[k] = level == frosted::kPaneFrontGridNoFresnelControl ? 1.0
             : level == frosted::kPaneFrontGridReflectControl ? F
                                                              : 1.0 - F;
      if (k > 0 || level != frosted::kPaneFrontGridExactControl) total += p[k];
    }
    for (int k = 0; k < kN; ++k) {
      walks[k] = frosted::PaneWalkEnd{};
      if (!(p[k] > 0.0) || !(total > 0.0)) continue;
      walk_pane_end(sp, lobe, in, numbers[k], s[k], walks[k]);
      walks[k].throughput *= float(double(kN) * p[k] / total);
    }
  }
  // For the tests: the rough pane's split sample (kPaneWalk) with its negative control (count_rejected above).
  bool pane_sample_sg_split(const ShadingPoint &sp, const Vec3 &rand, LocalSample &out, int split, bool count_rejected,
                            int branch = -1, int exact_leaving = -1, int both_faces = -1, int front_grid = -1) const {
    DielectricLobe scratch;
    const DielectricLobe &lobe = lobe_at(sp, scratch);
    Vec3 wi;
    bool flip;
    LocalSample s;
    if (!thin_) return false;
    const PaneFront front = pane_front_sample(sp, lobe, rand, wi, flip, s, out);
    if (front != PaneFront::kEntered) return front == PaneFront::kReflected;
    const frosted::PaneSgInputs in = pane_sg_inputs(sp, frosted::SgVariant::kPaneWalk, frosted::kPaneLadder);
    return pane_sample_sg_split(sp, lobe, in, rand, wi, s, flip, out, std::clamp(split, 1, frosted::kPaneWalkSplit),
                                count_rejected, branch, exact_leaving, both_faces, front_grid);
  }
  // Session 36/37 (frostedtail36, frostedwalk37; docs/history/frosted_glass_sessions.md "Session 37 (frostedwalk37)"):
  // one event of the pane walk at the interface-local incidence wi (either side), its numbers from rng. Level 0
  // (kPaneWalkLobe, main's walk bit for bit): the lobe's own sample (a microfacet m, the Fresnel coin, weight g / E
  // with g = G2 / G1(wi), 0 where the direction is no sample). At IOR 2.4 and roughness >= 0.8 that weight's second
  // moment grows along the reflections between the faces (the transfer operator's spectral radius of
  // E[w^2 1{reflect}] is 1.11 at roughness 0.8, 1.28 at 1.0): the walk's throughput has infinite variance.
  // Level 1 (kPaneWalkResampled): kPaneWalkCandidates microfacets m_j (jittered 2 x 2 in the visible-normal
  // numbers), each with both branches' weights a = F g_R and (1 - F) g_T (0 where the branch is no sample); one
  // branch is picked with probability a_i / sum a, the weight is c = sum a / (K E). E[c h(picked)] =
  // (1 / (K E)) E[sum_i a_i h_i] = E_m[F g_R h_R + (1 - F) g_T h_T] / E, level 0's E[(g / E) h] exactly, for any h:
  // the same expectation event by event, so the same walk's. Spectral radius of E[c^2 1{reflect}]: 0.83 at
  // roughness 0.8, 0.75 at 1.0, < 0.998 at roughness 0.1..1, IOR 1.5 / 2.4 (finite variance). kPaneWalkControl
  // (the tests' negative control): both branches at full weight (F not applied in a: biased).
  static constexpr int kPaneWalkLobe = 0, kPaneWalkResampled = 1, kPaneWalkControl = 9;
  static constexpr int kPaneWalkCandidates = 4;
  template <int kLevel>
  static bool walk_event(const DielectricLobe &lobe, const Vec3 &wi, mf::WalkRng &rng, LocalSample &s) {
    if constexpr (kLevel == kPaneWalkLobe) return lobe.sample(wi, Vec3(rng.next(), rng.next(), rng.next()), s);
    return resampled_event(lobe, wi, rng, kLevel == kPaneWalkControl, s);
  }
  // The walk's sampler (the default rule, session 37): the resampled events where the interface's relative IOR
  // (ior or 1 / ior) >= kPaneWalkResampledIor and the lobe is energy-compensated (the tail is the compensation's
  // 1 / E: without it each event's weight is g <= 1). Main's walk's second moment is infinite from IOR ~2.05
  // (roughness 1.0) .. ~2.15 (0.8) (roughness 1.0 / 0.8: rho(M_2) 0.872 / 0.891 at IOR 1.9, 1.054 / 0.993 at
  // 2.1). Session 37 set 1.9; session 38 (frostedpane38) measured the pane crop's gain 1 / (variance x cost) of the
  // resampled walk over main's at IOR 1.6 / 1.7 / 1.8: 1.20 / 2.82 / 1.25 (90 % bootstrap over 16 seeds: 1.04-1.39 /
  // 1.05-5.61 / 1.03-1.50), and at 1.5 it loses (session 36: variance x0.917 at +25 % cost): 1.6, so every image
  // below IOR 1.6 (glass 1.5, water, acrylic, the bench) stays bit-identical. Scope of that measurement: one pane
  // (the bench's glass_R: roughness 0.5, method sg, entered from outside); the reciprocal side, method path and
  // roughness 0.1-0.3 / 0.8-1.0 between IOR 1.6 and 1.9 were not measured (the same expectation holds everywhere).
  static constexpr float kPaneWalkResampledIor = 1.6f;
  static bool resampled_walk(const DielectricLobe &lobe) {
    return lobe.compensate && (lobe.ior >= kPaneWalkResampledIor || lobe.ior * kPaneWalkResampledIor <= 1.0f);
  }
  // For the tests: the interface lobe a closure of this roughness and IOR builds (create and lobe_at's build).
  static DielectricLobe interface_lobe(float roughness, float ior) {
    DielectricLobe lobe;
    lobe.build(interface_params(roughness), ior, false, true);
    return lobe;
  }
  // For the tests: whether the closure's own lobe at sp takes the resampled walk (the rule above).
  bool uses_resampled_walk(const ShadingPoint &sp) const {
    DielectricLobe scratch;
    return resampled_walk(lobe_at(sp, scratch));
  }
  // For the tests: the walk between the faces from the internal direction d at level kLevel (walk_to_exit_at).
  template <int kLevel>
  bool pane_walk(const ShadingPoint &sp, const Vec3 &rand, Vec3 &d, Spectrum &throughput, Vec3 &leaving) const {
    DielectricLobe scratch;
    return walk_to_exit_at<kLevel>(sp, lobe_at(sp, scratch), rand, d, throughput, leaving, nullptr, nullptr);
  }
  // For the tests: the interface lobe at sp (per-point roughness and IOR).
  bool pane_sample_sg(const ShadingPoint &sp, const Vec3 &rand, LocalSample &out, frosted::SgVariant variant,
                      const frosted::PaneLadder &ladder = frosted::kPaneLadder,
                      int split = frosted::kPaneWalkSplit) const {
    DielectricLobe scratch;
    return pane_sample_sg(sp, lobe_at(sp, scratch), rand, out, variant, ladder, split);
  }
  bool uses_sg(const ShadingPoint &sp) const {
    if (thin_ || !(sp.wi.z > 0.0f)) return false;
    return method_ == Method::kSg || (method_ == Method::kAuto && auto_picks_sg(sp));
  }
  // method=auto's rule: sg where its error is small (the entry roughness) or hidden (the path already scattered
  // diffusely or glossily, so the glass is seen blurred by that bounce), path where the SG's error would show.
  bool auto_picks_sg(const ShadingPoint &sp) const {
    const GlimmerShadingContext &ctx = *sp.ctx;
    return sp.param_float(roughness_param_, roughness_) <= kAutoSgRoughnessMax ||
           ctx.diffuse_bounce + ctx.glossy_bounce > 0;
  }

#if GLIMMER_ABI_MINOR >= 8
  // ABI 2.8, method=path's pane: the state of the walk's last interface (pane_sample), read back by eval_exit.
  // d: the last internal direction (pane frame: entry side +z); weight: the walk's throughput up to that interface
  // (its crossing's Beer and both tints included, the interface's own f cos / pdf not); trials: the number of
  // independent draws of the interface's sampler at d until the first that leaves (>= 1; its expectation is
  // 1 / P_T(d), P_T the probability that the sampler leaves at d). docs/frosted_glass.md "Light sampling at a
  // pane's exit (sixteenth session)" derives why NEE at the exit weighted by trials is unbiased.
  struct PaneExitState {
    Vec3 d{0.0f};
    Spectrum weight{0.0f};
    float trials = 0.0f;
    void write(GlimmerExitState &st) const {
      static_assert(7 * sizeof(float) <= sizeof(GlimmerExitState));
      const float v[7] = {d.x, d.y, d.z, weight.x, weight.y, weight.z, trials};
      std::memcpy(st.words, v, sizeof v);
    }
    static PaneExitState read(const GlimmerExitState &st) {
      float v[7];
      std::memcpy(v, st.words, sizeof v);
      PaneExitState x;
      x.d = Vec3(v[0], v[1], v[2]);
      x.weight = Spectrum(v[3], v[4], v[5]);
      x.trials = v[6];
      return x;
    }
  };
  // f cos and pdf toward w (local) of the pane's last interface in `state`: the exit interface's transmission
  // from the last internal direction (Walter's BTDF with the energy compensation the sampler uses), f cos times
  // the state's weight x trials, pdf the sampler's unconditional density of that transmitted direction (the
  // leaving probability included). Zero on the other side of the exit face.
  // method=sg's rough pane (a moved exit-lobe sample with frosted::PaneSgExitState): f cos = pdf = q(w), the exact
  // exit's value over the sample's weight, sum_k c_k f_k(w) over the state's walks (f_k the exit interface's f cos
  // from d_k, as above), for the host's lamps through the exit lobe.
  LocalEval eval_exit(const ShadingPoint &sp, const GlimmerExitState &state, const Vec3 &w) const {
    if (!thin_) return {};
    if (uses_sg_pane(sp)) return eval_exit_sg(sp, state, w);
    const PaneExitState x = PaneExitState::read(state);
    if (!(x.trials > 0.0f)) return {};
    DielectricLobe scratch;
    LocalEval e = exit_interface_eval(lobe_at(sp, scratch), x.d, entry_side(sp, w));
    e.f_cos *= x.weight * x.trials;
    return e;
  }
  // w (local) on the entry side's frame: flipped when wi is below the pane.
  static Vec3 entry_side(const ShadingPoint &sp, const Vec3 &w) { return sp.wi.z < 0.0f ? mf::flip_z_local(w) : w; }
  // The exit interface's transmission toward wo (entry_side) from the last internal direction d (Walter's BTDF
  // with the sampler's energy compensation); zero on the other side of the exit face or for d in the plane.
  static LocalEval exit_interface_eval(const DielectricLobe &lobe, const Vec3 &d, const Vec3 &wo) {
    if (d.z == 0.0f) return {};
    const bool bottom = d.z < 0.0f;
    if (bottom ? !(wo.z < 0.0f) : !(wo.z > 0.0f)) return {};
    return lobe.eval(at_interface(-d, bottom), at_interface(wo, bottom));
  }
  LocalEval eval_exit_sg(const ShadingPoint &sp, const GlimmerExitState &state, const Vec3 &w) const {
    const Vec3 wo = entry_side(sp, w);
    // the ends' side: the exit face's, i.e. wo's where q can be > 0 (exit_interface_eval is 0 on the other side)
    const frosted::PaneSgExitState x = frosted::PaneSgExitState::read(state, wo.z < 0.0f);
    DielectricLobe scratch;
    const DielectricLobe &lobe = lobe_at(sp, scratch);
    float q = 0.0f;
    for (int k = 0; k < frosted::PaneSgExitState::capacity(); ++k)
      if (x.c[k] > 0.0f) q += x.c[k] * average(exit_interface_eval(lobe, x.d[k], wo).f_cos);
    LocalEval e;
    e.f_cos = Spectrum(q);
    e.pdf = q;
    return e;
  }
#endif

  // R + T with the tint on T is not tabulated: the lossless interface's albedo
  // (1 with compensation) is an upper bound; the tint and absorption are the
  // host's to see in the sample weights.
  Spectrum albedo(const ShadingPoint &sp) const {
    DielectricLobe scratch;
    return lobe_at(sp, scratch).albedo(sp.wi);
  }

 private:
  // Both interfaces: isotropic GGX with multiple-scattering compensation.
  static MicrofacetLobeParams interface_params(float roughness) {
    return MicrofacetLobeParams::make(kMultiGgx, roughness, 0.0f);
  }

  const DielectricLobe &lobe_at(const ShadingPoint &sp, DielectricLobe &scratch) const {
    if (!sp.varies()) return lobe_;
    scratch.build(interface_params(sp.param_float(roughness_param_, roughness_)), sp.param_float(ior_param_, ior_),
                  false, false);
    return scratch;
  }

  Spectrum color_at(const ShadingPoint &sp) const { return sp.param_color(color_param_, color_); }

  // ---- Solid: absorption over the segment that reached this point from inside ----
  Spectrum interior_transmittance(const ShadingPoint &sp) const {
    if (!beer_.active || !(sp.wi.z < 0.0f)) return Spectrum(1.0f);
    const GlimmerShadingContext &ctx = *sp.ctx;
    if (ctx.host == nullptr || ctx.host->trace_ray == nullptr) return Spectrum(1.0f);
    const Vec3 back(ctx.wi);
    const GlimmerRay ray = frosted::unbounded_ray(frosted::offset_origin(Vec3(ctx.P), Vec3(ctx.Ng), back), back);
    GlimmerRayHit hit{};
    hit.struct_size = sizeof(GlimmerRayHit);
    if (!ctx.host->trace_ray(ctx.host->host_data, &ray, &hit) || !std::isfinite(hit.t)) return Spectrum(1.0f);
    return beer_.transmittance(std::max(hit.t, 0.0f));
  }

  // ---- Thin pane: position-free walk between two parallel interfaces ----
  // The pane frame has the walk's wi side on top (z > 0). The top interface's
  // outward normal is +z, the bottom one's -z: its local frame flips z.
  static Vec3 at_interface(const Vec3 &v, bool bottom) { return bottom ? mf::flip_z_local(v) : v; }
  Spectrum crossing(float cos_inside) const { return beer_.transmittance(thickness_ / std::fabs(cos_inside)); }

  // The walk between the faces after entering (method=path's pane and sg's rough pane): from the internal direction
  // `d` (pane frame, entry side +z), at each crossing Beer over the crossing and one event of the interface lobe
  // (walk_event; its sampler by resampled_walk(lobe)), until one transmits. True: `d` is the last internal direction,
  // `leaving` the direction outside, `throughput` times every crossing's attenuation and event weight (the tint is
  // the caller's). Its numbers: a WalkRng seeded by (path seed, rand). False: a failed sample, d.z = 0, or no exit
  // within kMaxPaneEvents. before_exit (optional): the throughput before the leaving event's weight (its crossing's
  // Beer included).
  [[gnu::always_inline]] bool walk_to_exit(const ShadingPoint &sp, const DielectricLobe &lobe, const Vec3 &rand,
                                           Vec3 &d, Spectrum &throughput, Vec3 &leaving, int *reflections = nullptr,
                                           Spectrum *before_exit = nullptr) const {
    if (resampled_walk(lobe)) [[unlikely]] {
      // by value in and out: the caller's d and throughput stay in registers on main's walk
      const ResampledWalk r = walk_to_exit_resampled(sp, lobe, rand, d, throughput);
      d = r.d, throughput = r.throughput;
      if (!r.ok) return false;
      leaving = r.leaving;
      if (reflections != nullptr) *reflections = r.reflections;
      if (before_exit != nullptr) *before_exit = r.before_exit;
      return true;
    }
    return walk_to_exit_at<kPaneWalkLobe>(sp, lobe, rand, d, throughput, leaving, reflections, before_exit);
  }
  // The walk at level kLevel (walk_event's): level 0 inline (main's code), level 1 out of line (the rare high IOR).
  template <int kLevel>
  [[gnu::always_inline]] bool walk_to_exit_at(const ShadingPoint &sp, const DielectricLobe &lobe, const Vec3 &rand,
                                              Vec3 &d, Spectrum &throughput, Vec3 &leaving, int *reflections,
                                              Spectrum *before_exit) const {
    mf::WalkRng rng(sp.seed_for(rand));
    LocalSample s;
    for (int event = 0; event < kMaxPaneEvents; ++event) {
      if (d.z == 0.0f) return false;
      const bool bottom = d.z < 0.0f;
      throughput *= crossing(d.z);
      if (!walk_event<kLevel>(lobe, at_interface(-d, bottom), rng, s)) return false;
      const Spectrum before = throughput;
      throughput *= s.f_cos / s.pdf;
      const Vec3 next = at_interface(s.wo, bottom);
      if (s.label & GLIMMER_LABEL_TRANSMIT) {
        leaving = next;
        if (reflections != nullptr) *reflections = event;  // reflections between the faces before leaving
        if (before_exit != nullptr) *before_exit = before;
        return true;
      }
      d = next;
    }
    return false;
  }
  // walk_to_exit_at<kPaneWalkResampled> and exit_trials_at<kPaneWalkResampled>, compiled in frosted_glass_walk.cpp:
  // frosted_glass.cpp's code (main's walk and every default-path inlining decision) does not see them.
  struct ResampledWalk {
    Vec3 d, leaving;
    Spectrum throughput, before_exit;
    int reflections = 0;
    bool ok = false;
  };
  ResampledWalk walk_to_exit_resampled(const ShadingPoint &sp, const DielectricLobe &lobe, Vec3 rand, Vec3 d,
                                       Spectrum throughput) const;
  // Session 30 (frostedpane30, frosted::pane_branch_level): the walk from the front sample `front` with both branches
  // of its first event at the far face kept (expected value instead of the Fresnel coin there): the microfacet m from
  // the walk's numbers, the transmitted branch (weight x (1 - F(m))) ends there, the reflected one (weight x F(m))
  // walks on (its own numbers) to wherever it leaves. E[coin-chosen branch's weight] = (1 - F) w_T + F w_R, so the
  // two ends' sum has the one walk's expectation. Writes up to 2 ends (the tint applied as add_walk does); returns
  // how many (a failed branch: none; both failed: one empty end, as a failed walk).
  // control: the tests' negative control (both branches at full weight, F not applied: biased high).
  int branch_walks(const ShadingPoint &sp, const DielectricLobe &lobe, const Vec3 &numbers, const LocalSample &front,
                   const Spectrum &tint, frosted::PaneWalkEnd *out, bool control = false) const {
    int count = 0;
    Vec3 d = front.wo;
    if (d.z == 0.0f) return (out[0] = frosted::PaneWalkEnd{}), 1;
    const bool bottom = d.z < 0.0f;
    const Spectrum throughput = front.f_cos / front.pdf * tint * crossing(d.z);
    const Vec3 wi_l = at_interface(-d, bottom);
    const bool outside = wi_l.z > 0.0f;
    const Vec3 wi = outside ? wi_l : mf::flip_z_local(wi_l);
    mf::WalkRng rng(sp.seed_for(numbers));
    const float x = rng.next(), y = rng.next();
    Vec3 m;
    const float F = lobe.visible_facet(wi, outside ? lobe.ior : 1.0f / lobe.ior, x, y, m);
    const float f_t = control ? 1.0f : 1.0f - F, f_r = control ? 1.0f : F;
    LocalSample s;
    if (F < 1.0f && lobe.sample(wi_l, Vec3(x, y, 1.0f), s) && (s.label & GLIMMER_LABEL_TRANSMIT))
      out[count++] = frosted::PaneWalkEnd{d, throughput * (s.f_cos / s.pdf) * f_t * tint, at_interface(s.wo, bottom)};
    if (F > 0.0f && lobe.sample(wi_l, Vec3(x, y, 0.0f), s) && !(s.label & GLIMMER_LABEL_TRANSMIT)) {
      Vec3 d2 = at_interface(s.wo, bottom), leaving;
      Spectrum t2 = throughput * (s.f_cos / s.pdf) * f_r;
      if (walk_to_exit(sp, lobe, Vec3(numbers.x, numbers.y, numbers.z + 2.0f), d2, t2, leaving))
        out[count++] = frosted::PaneWalkEnd{d2, t2 * tint, leaving};
    }
    if (count == 0) out[count++] = frosted::PaneWalkEnd{};
    return count;
  }
  // walk_event's level 1 (frosted_glass_walk.cpp): kPaneWalkCandidates microfacets, both branches each, one picked
  // by its weight a (walk_event's comment). control: kPaneWalkControl (F not applied).
  static bool resampled_event(const DielectricLobe &lobe, const Vec3 &wi_in, mf::WalkRng &rng, bool control,
                              LocalSample &s);
  // method=path's pane: the front reflection is an ordinary rough lobe (eval's pane_front_reflection: light-sampled
  // and MIS-combined); every path that enters leaves as one SINGULAR sample (weight: the walk's product of f cos /
  // pdf, pdf 1), so the host gives its emission hits MIS weight 1 and takes no light sample through the pane. A
  // one-walk estimate of f toward a light direction is the walk's weight times the exit interface's density at the
  // walk's own internal direction: at roughness 0.2 that peaks at ~600 / sr where the pane's density is ~0.1-1, so
  // light samples through the pane were rare huge values (docs/frosted_glass.md "Light sampling through a pane").
  // Not moved (the path goes on from P, as before), so C-ABI callers without GlimmerSample.struct_size still get
  // the sample; it reports the pane's roughness, by which the host widens the footprint (a singular sample with
  // roughness > 0, bridge/render/renderer.cpp next_differentials).
  bool pane_sample(const ShadingPoint &sp, const DielectricLobe &lobe, const Vec3 &rand, LocalSample &out) const {
    const bool flip = sp.wi.z < 0.0f;
    const Vec3 wi = flip ? mf::flip_z_local(sp.wi) : sp.wi;
    LocalSample s;
    if (!(wi.z > 0.0f) || !lobe.sample(wi, rand, s)) return false;
    if (!(s.label & GLIMMER_LABEL_TRANSMIT)) {  // the front reflection, exact
      if (flip) s.wo = mf::flip_z_local(s.wo);
      out = s;
      return true;
    }
    const Spectrum tint = color_at(sp);
    Spectrum throughput = s.f_cos / s.pdf * tint, before_exit(0.0f);
    Vec3 d = s.wo, wo;
    if (!walk_to_exit(sp, lobe, rand, d, throughput, wo, nullptr, &before_exit)) return false;
    throughput *= tint;
    if (wo.z == 0.0f || !is_finite(throughput)) return false;
#if GLIMMER_ABI_MINOR >= 8
    // ABI 2.8: the exit state for light sampling through the last interface (only where the host combines a light
    // strategy with this sample: else nothing would read it).
    if (out.state_out != nullptr && !sp.uncombined() && max_component(before_exit) > 0.0f) {
      PaneExitState x;
      x.d = d;
      x.weight = before_exit * tint;
      x.trials = static_cast<float>(exit_trials(sp, lobe, rand, d));
      if (x.trials > 0.0f && is_finite(x.weight)) {
        x.write(*out.state_out);
        out.exit_state = true;
      }
    }
#endif
    out.wo = flip ? mf::flip_z_local(wo) : wo;
    out.f_cos = throughput;
    out.pdf = 1.0f;
    out.roughness = std::sqrt(lobe.ax * lobe.ay);
    out.eta = 1.0f;  // air on both sides
    out.label = ((wo.z < 0.0f) ? GLIMMER_LABEL_TRANSMIT : GLIMMER_LABEL_REFLECT) | GLIMMER_LABEL_GLOSSY |
                GLIMMER_LABEL_SINGULAR;
    return true;
  }

  // The number of independent draws of the interface's sampler from the internal direction d (pane frame) until the
  // first that leaves the pane (a TRANSMIT sample), from numbers of their own (a WalkRng seeded by the path seed,
  // rand and a tag): geometric with mean 1 / P_T(d), independent of the walk given d. 0 when none leaves within
  // kMaxPaneEvents draws (then no exit state: P_T(d) < ~1e-3 there, and the walk did leave at d).
  int exit_trials(const ShadingPoint &sp, const DielectricLobe &lobe, const Vec3 &rand, const Vec3 &d) const {
    if (resampled_walk(lobe)) [[unlikely]]
      return exit_trials_resampled(sp, lobe, rand, d);  // by value (as walk_to_exit)
    return exit_trials_at<kPaneWalkLobe>(sp, lobe, rand, d);
  }
  int exit_trials_resampled(const ShadingPoint &sp, const DielectricLobe &lobe, Vec3 rand,
                            Vec3 d) const;  // frosted_glass_walk.cpp
  // exit_trials with the walk's own event sampler (level kLevel): its leaving probability at d.
  template <int kLevel>
  int exit_trials_at(const ShadingPoint &sp, const DielectricLobe &lobe, const Vec3 &rand, const Vec3 &d) const {
    mf::WalkRng rng(hash_u32x2(sp.seed_for(rand), 0x65786974u));
    const bool bottom = d.z < 0.0f;
    const Vec3 inside = at_interface(-d, bottom);
    LocalSample s;
    for (int n = 1; n <= kMaxPaneEvents; ++n)
      if (walk_event<kLevel>(lobe, inside, rng, s) && (s.label & GLIMMER_LABEL_TRANSMIT)) return n;
    return 0;
  }

  // The pane's eval (both methods): the front reflection alone (the light that enters leaves as a singular sample).
  LocalEval pane_front_reflection(const ShadingPoint &sp, const DielectricLobe &lobe, const Vec3 &wo_in) const {
    const bool flip = sp.wi.z < 0.0f;
    const Vec3 wi = flip ? mf::flip_z_local(sp.wi) : sp.wi;
    const Vec3 wo = flip ? mf::flip_z_local(wo_in) : wo_in;
    if (!(wi.z > 0.0f) || !(wo.z > 0.0f)) return {};
    return lobe.eval(wi, wo);
  }

  Spectrum color_{1.0f};
  float roughness_ = 0.3f, ior_ = 1.5f;
  BeerAbsorption beer_;
  bool thin_ = false;
  float thickness_ = 0.01f;
  uint32_t color_param_ = 0, roughness_param_ = 0, ior_param_ = 0;
  DielectricLobe lobe_;
  Method method_ = Method::kPath;
  const frosted::TransmissionSgTable *table_ = nullptr;
};

}  // namespace glimmer::plugin
