// glint (XML node glint_bsdf): separable, filterable discrete stochastic
// microfacets (Wang, Wang, Holzschuch 2018, CGF 37(7)).
//
// A surface carries N particles per unit (scaled) uv area; each particle is a
// tiny mirror whose normal follows D(m) cos(theta_m) (GGX or Beckmann). For a
// pixel footprint A (uv parallelogram from the ray differentials) and a query
// cone of half-angle gamma around wo, Jakob et al. 2014 count the particles in
// A that reflect wi into the cone. Wang 2018 separate space and direction: a
// particle reflects when its random threshold lambda is below the directional
// probability P_gamma(wi, wo) (tables/glint_tables.h), so the count K is
// found by a spatial traversal (tables/glint_particles.h). The thresholds
// belong to direction cells shaped like the glint cone, so the lit set renews
// when wi or wo moves by about gamma (twinkle), as in the exact model; the
// particles live at one level per material, so every footprint size sees the
// same particles.
//
// BRDF (our derivation of Jakob 2014 eq. 5 for a cone around wo): the smooth
// microfacet BRDF integrated over the cone is
//   Int_cone f cos = F G (wi.h) / (cos_i cos_h) P_gamma(wi, wo),
// so with W(wi, wo) = F(wi.h) G2(wi, wo) (wi.h) / (cos_i cos_h) and sigma the
// cone's solid angle:
//   unfiltered:  f cos_o = W K / (N a(A) sigma)          (E[K] = N a(A) P)      (2)
//   filtered:    f cos_o = W P / sigma                   (sec. 4.5)             (3)
// Filtered mode is used when the expected glint count N a(A) P exceeds
// filter_threshold (default 16, their Fig. 15), and when the path's LOD blur
// sigma_L is wider than the glint cone gamma (a path that has spread over
// more than gamma, e.g. after a rough bounce, does not resolve single
// glints: P is then the blurred P_sigma, and the pixel averages over
// (sigma_L / gamma)^2 direction cells). (3) is the expectation of (2), so
// the switch is continuous in the mean, and (3) tends to the smooth
// microfacet BRDF F G D / (4 cos_i) as gamma -> 0.
//
// LOD (sec. 4.4): P is looked up at a Gaussian blur sigma_L (degrees) equal
// to the path's spread angle, capped by the lobe width 2 alpha (blurring past
// the lobe would only widen it), linear between the 9 stored levels.
//
// Sampling: a mixture of visible-normal sampling of a GGX lobe (for either base distribution: the
// closed-form proposal, glint_common.h's kSamplingDistribution) widened to
// alpha_w = sqrt(alpha^2 + ((gamma + sigma_L) / 2)^2) (weight 0.9) and cosine
// sampling (0.1). pdf() is exactly that mixture's density; eval() returns the
// glint BRDF (2)/(3), so estimators stay unbiased wherever the glint BRDF is
// non-zero (the cosine part covers the whole hemisphere).
//
// Per-flake colour (flake_hue_variation / flake_value_variation, off by
// default): each counted particle has its own F0, a pure function of its
// identity; (2) uses W at the mean F0 of the counted flakes (Schlick is affine
// in F0) and (3) W at the mean flake F0 (tables/glint_flake_colour.h).
//
// Footprint: with placement="object" a triplanar projection of the
// object-space footprint (tables/glint_placement.h); otherwise
// a(A) = |duv_dx x duv_dy| uv_scale^2; a zero footprint is a point
// query resolved at the particle scale (a square holding one particle on
// average, 1 / N).
//
// Anisotropic base (roughness_u != roughness_v, tables/glint_aniso.h):
// alpha_x along the shading tangent (ctx.T), alpha_y along the bitangent. P
// is computed per query by a 7- or 19-point disk rule of the analytic
// anisotropic reflected density on the cone, the LOD blur widens the NDF
// per axis, and a small per-wi energy table keeps the estimator's reflected
// energy at the unblurred one's (capped at the smooth albedo), as the
// isotropic levels do. Direction cells and the particle walk are unchanged;
// sampling uses the anisotropic visible normals widened the same way.
// roughness_u == roughness_v is the isotropic model exactly.
//
// Lobes narrower than the cone (alpha <= 1.5 gamma; tables/glint_pseudo_normals.h):
// unblurred queries count particles with their own normals (m ~ D cos, lit
// iff the mirror direction of wi is within gamma of wo) instead of the
// direction cells, whose nested lit sets cannot follow a lobe narrower than
// the cone (docs/glints.md, "Pseudo-normals for lobes narrower than the cone").
//
// Dark test (speed, exact): in glint mode a small footprint is first counted
// at a bound P_max >= P (tables/glint_peak.h, L2-resident); no reflecting
// particle at P_max means none at P (nested lit sets), and the eval returns
// 0 without the table's cache miss.
#include <array>
#include <memory>
#include <new>
#include <string_view>
#include <type_traits>

#include "core/closure.h"
#include "glimmer/microfacet.h"
#include "glimmer/sampling.h"
#include "tables/glint_aniso.h"
#include "tables/glint_common.h"
#include "tables/glint_flake_colour.h"
#include "tables/glint_particles.h"
#include "tables/glint_peak.h"
#include "tables/glint_placement.h"
#include "tables/glint_pseudo_normals.h"
#include "tables/glint_small_dark.h"
#include "tables/glint_tables.h"

namespace glimmer::plugin {

namespace mf = glimmer::microfacet;
// The factored level 0 is used exactly where the pseudo-normals are not (tables/glint_factored_level0.h).
static_assert(glint::FactoredLevel0::kNarrowLobeRatio == glint::kPseudoNormalLobeRatio);

// The schema with density marked varying: it may be textured (glint_f_cos reads it per shading point).
// constexpr, so GlintClosure::params() is a constant-initialised static.
template <typename Schema>
constexpr Schema with_varying_density(Schema schema) {
  for (auto &spec : schema)
    if (std::string_view(spec.name) == "density") spec.flags |= GLIMMER_PARAM_VARYING;
  return schema;
}

class GlintClosure {
 public:
  static constexpr const char *kName = "glint";
  static constexpr const char *kDoc =
      "Glints: separable filterable discrete stochastic microfacets (Wang et al. 2018) over a GGX or Beckmann base.";
  static constexpr uint32_t kFlags = 0;
  // The adapter's clear() (no sample) out of line (core/closure.h no_sample; session 30).
  static constexpr bool kAdapterClearOutOfLine = true;
  // The adapter's LocalSample{} by stores, not a `rep stos` (core/closure.h write_local_sample_defaults; session 33).
  static constexpr bool kAdapterSampleDefaultsByStores = true;

  // Cost bound of one eval (particles visited); beyond it the mean (3) is
  // returned. Only reached when glint mode is forced far past the
  // filter_threshold (hundreds of glints per footprint).
  static constexpr int kMaxSteps = 8192;

  // The schema is a constant (constexpr) static: every eval's ShadingPoint takes it (the adapter's
  // shading_point_for), and a dynamically initialised static cost a call and its guard per eval.
  static std::span<const GlimmerParamSpec> params() {
    static constexpr auto schema = with_varying_density(glint::particle_field_params<6>(
        {"base roughness (alpha = roughness^2, Cycles' mapping); values below 0.15 are treated as 0.15",
         "query cone half-angle in degrees (size of a glint in direction; Jakob 2014 use 1..6)",
         "particle reflectance at normal incidence (Schlick Fresnel F0; 1 = Fresnel-free)"},
        {{{"filter_threshold", GLIMMER_PARAM_FLOAT, {16.0f, 0, 0}, 0.0f, 1e9f, nullptr, nullptr,
           "expected glints per footprint above which the filtered mean a(A) P is used (0 = always filtered)", 0},
          {"flake_hue_variation", GLIMMER_PARAM_FLOAT, {0.0f, 0, 0}, 0.0f, 180.0f, nullptr, nullptr,
           "per-flake colour (car paint): half-width in degrees of each flake's uniform hue offset from color "
           "(0 = off)", 0},
          {"flake_value_variation", GLIMMER_PARAM_FLOAT, {0.0f, 0, 0}, 0.0f, 1.0f, nullptr, nullptr,
           "per-flake colour (car paint): half-width of each flake's uniform relative value (brightness) "
           "offset from color (0 = off)", 0},
          {"placement", GLIMMER_PARAM_ENUM, {0, 0, 0}, 0, 0, "uv|object", "uv",
           "where the particles live: uv (density per unit of scaled uv area) or object (a triplanar projection of "
           "the object-space point, density per unit of object-space area scaled by uv_scale; for stretched or "
           "shared UVs)", 0},
          {"roughness_u", GLIMMER_PARAM_FLOAT, {-1.0f, 0, 0}, -1.0f, 1.0f, nullptr, nullptr,
           "base roughness along the shading tangent (brushed / stretched flakes; alpha_x = roughness_u^2, floored "
           "like roughness); negative (default -1) = roughness", 0},
          {"roughness_v", GLIMMER_PARAM_FLOAT, {-1.0f, 0, 0}, -1.0f, 1.0f, nullptr, nullptr,
           "base roughness along the bitangent (alpha_y = roughness_v^2, floored like roughness); negative "
           "(default -1) = roughness", 0}}}));
    return schema;
  }


  static std::unique_ptr<GlintClosure> create(const ParamReader &p) {
    auto c = std::make_unique<GlintClosure>();
    c->field_ = glint::ParticleField::parse(p);
    c->threshold_ = p.get_float("filter_threshold");
    c->dark_test_cap_ = std::min(static_cast<double>(c->threshold_), kDarkTestMaxExpected);
    c->density_param_ = p.index("density");
    c->gamma_rad_ = c->field_.gamma_deg * glint::kDegToRad;
    c->cell_keys_ = glint::DirectionCellKeys(c->field_.seed, c->gamma_rad_);
    c->small_dark_ = glint::make_small_dark_field(c->cell_keys_, c->gamma_rad_, kDarkTestMaxNodes, kMaxSteps,
                                                  c->field_.density);
    c->placement_ = static_cast<glint::Placement>(p.get_enum("placement"));
    c->flakes_ = std::make_unique<const glint::FlakePalette>(c->field_.color, p.get_float("flake_hue_variation"),
                                                             p.get_float("flake_value_variation"));
    c->albedo_ = sanitize(c->flakes_->mean());
    c->set_base_roughness(p);
    return c;
  }

  // roughness_u / roughness_v (negative: roughness), floored like roughness.
  // Equal alphas keep the isotropic model (tables) at that alpha.
  void set_base_roughness(const ParamReader &p) {
    const float ru = p.get_float("roughness_u"), rv = p.get_float("roughness_v");
    const float ax = ru < 0.0f ? field_.alpha : std::max(sqr(ru), glint::ParticleField::kMinAlpha);
    const float ay = rv < 0.0f ? field_.alpha : std::max(sqr(rv), glint::ParticleField::kMinAlpha);
    alpha_x_ = ax;
    alpha_y_ = ay;
    anisotropic_ = ax != ay;
    field_.alpha = std::max(ax, ay);  // isotropic: the alpha of the tables; anisotropic: caps the LOD blur
    aniso_spec_ = {field_.distribution, ax, ay, field_.gamma_deg};
    cone_rules_ = glint::AnisoConeRules(gamma_rad_);
    sampling_alpha_unblurred_ = widened_alpha(0.0f);
    pseudo_normals_ = !anisotropic_ && glint::uses_pseudo_normals(field_.alpha, gamma_rad_);
    pseudo_ = glint::PseudoNormalField(field_.distribution, field_.alpha, gamma_rad_, field_.seed);
    special_path_ = anisotropic_ || pseudo_normals_;
    max_spread_ = 2.0f * field_.alpha;
  }

  void prepare(const GlimmerHostServices *host) {
    if (anisotropic_) {
      energy_ = glint::acquire_aniso_energy(aniso_spec_, host);
      cone_solid_angle_ = 6.283185307179586f * (1.0f - std::cos(gamma_rad_));
      return;
    }
    glint::TableSpec spec;
    spec.distribution =
        field_.distribution == mf::Distribution::GGX ? glint::BaseDistribution::GGX : glint::BaseDistribution::Beckmann;
    spec.alpha = field_.alpha;
    spec.gamma_deg = field_.gamma_deg;
    const mf::Distribution dist = field_.distribution;
    const float alpha = field_.alpha;
    table_ = glint::acquire_table(
        spec,
        [dist, alpha](double cos_m) {
          const double c = std::min(std::max(cos_m, 0.0), 1.0);
          const Vec3 m(static_cast<float>(std::sqrt(1.0 - c * c)), 0.0f, static_cast<float>(c));
          return static_cast<double>(mf::D(dist, m, alpha, alpha));
        },
        host);
    cone_solid_angle_ = table_->cone_solid_angle();
    peak_ = glint::DirectionalPeakTable(*table_, field_.gamma_deg);
  }

  // LOD blur in degrees: the path's spread, capped by the lobe width 2 alpha.
  float lod_sigma_deg(const GlimmerShadingContext *ctx) const {
    const float spread = std::isfinite(ctx->spread_angle) ? std::max(ctx->spread_angle, 0.0f) : 0.0f;
    return std::min(spread, max_spread_) * glint::kRadToDeg;
  }

  // At zero blur (camera rays, the common case) the value computed at set-up.
  float sampling_alpha(float sigma_deg) const {
    return sigma_deg == 0.0f ? sampling_alpha_unblurred_ : widened_alpha(sigma_deg);
  }
  float widened_alpha(float sigma_deg) const {
    const float widen = 0.5f * (field_.gamma_deg + sigma_deg) * glint::kDegToRad;
    return std::sqrt(field_.alpha * field_.alpha + widen * widen);
  }
  // The sampling lobe per axis (both sampling_alpha when isotropic).
  struct SamplingLobe {
    float ax, ay;
  };
  SamplingLobe sampling_lobe(float sigma_deg) const {
    if (!anisotropic_) {
      const float a = sampling_alpha(sigma_deg);
      return {a, a};
    }
    float ax, ay;
    aniso_spec_.widened((field_.gamma_deg + sigma_deg) * glint::kDegToRad, ax, ay);
    return {ax, ay};
  }

  using TableCoords = glint::TableCoords;
  static TableCoords table_coords(const Vec3 &wi, const Vec3 &wo) { return glint::table_coords(wi, wo); }
  static float fast_acos_deg(float x) { return glint::fast_acos_deg(x); }

  // P at `c` (at most 1; 0 without a table). The lookup is a random access into several MB, and its miss was
  // the largest single cost of eval: the caller reads P before the Lambdas and the pdf, whose math (independent of
  // P) runs while the loads are outstanding. Session 27: read at once instead of prefetched and read after the pdf,
  // so the located cell is not kept (spilled and reloaded) across the pdf's calls (Beckmann's Lambdas and exp).
  // Session 42: level 0 is read as the analytic lobe of (wi, h) times a residual on 2-degree nodes where the table
  // has one and it covers (wi, wo) (tables/glint_factored_level0.h: 343 KB instead of 3 MB). Where the dark test can
  // apply (blur <= gamma), the factored P is clamped to the test's bound, so the test stays exact (the bound is taken
  // over the 1-degree nodes, which bound the 1-degree lookup by construction), whatever the footprint.
  [[gnu::always_inline]] float table_probability(const TableCoords &c, float sigma_deg, const Vec3 &wi,
                                                 const glint::HalfVector &h) const {
    if (!table_) return 0.0f;
    if (!table_->factored0.active() || !glint::FactoredLevel0::covers(c.theta_i, c.theta_o))
      return std::min(table_->lookup(table_->locate(sigma_deg, c.lanes())), 1.0f);
    const float lobe = h.valid ? table_->factored0.lobe()(dot(wi, h.h), h.h.z) : 0.0f;
    float P = table_->lookup_factored(table_->locate(sigma_deg, c.lanes(), /*factored_level0=*/true), lobe);
    if (!(sigma_deg > field_.gamma_deg) && !peak_.empty()) P = std::min(P, peak_.bound(c.lanes()));
    return std::min(P, 1.0f);
  }

  // The footprint of a shading point and, once located, the direction cells
  // and nodes of its particles (computed once per eval or sample).
  // fp and site are variant members, constructed where they are first written (place_footprint; locate and
  // provably_dark): their default member initialisers cost every eval ~15 stores (session 27), and fp is not
  // needed on the filtered route (area 0), site only where the particles are located. Both are trivially
  // destructible.
  struct Particles {
    Particles() {}  // NOLINT: fp and site left unconstructed (see above)
    union {
      glint::Footprint fp;
    };
    double area;  // fp.area(), computed once
    union {
      glint::GlintSite site;
    };
    bool located = false;
    // The pseudo-normal count once counted (pseudo_counted; set by
    // pseudo_normals_dark, read only where pseudo_normal_query). Plain
    // fields, not a GlintCount: its initialisers cost the direction cells'
    // path ~11 instructions per eval (session 15).
    int pseudo_count, pseudo_steps;
    bool pseudo_complete, pseudo_counted;
  };
  static_assert(std::is_trivially_destructible_v<glint::Footprint> &&
                std::is_trivially_destructible_v<glint::GlintSite>);  // Particles never destroys them
  // This thread's last footprint node list (glint::FootprintNodeMemo): the
  // host calls a shading point's closures several times over one footprint.
  // A pure memo (the same list as computed afresh), so images do not depend
  // on threads or call order.
  // Out of line: inlined, GCC recomputed the thread-local's address (a call
  // of __tls_get_addr) at every use. constinit (session 26): no guard variable and no dynamic initialisation, one
  // __tls_get_addr per call instead of two (33 -> ~16 instructions per call).
  [[gnu::noinline]] static glint::FootprintNodeMemo *node_memo() {
    static thread_local constinit glint::FootprintNodeMemo memo;
    return &memo;
  }
  void locate(const Vec3 &wi, const Vec3 &wo, float density, Particles &parts) const {
    if (!parts.located) {
      new (&parts.site) glint::GlintSite;
      glint::locate_glints(parts.fp, density, cell_keys_, wi, wo, gamma_rad_, parts.site, node_memo);
    }
    parts.located = true;
  }

  // Lobes narrower than the cone, unblurred (camera) queries: particles with
  // their own normals (tables/glint_pseudo_normals.h) instead of the
  // direction cells.
  bool pseudo_normal_query(float sigma_deg) const { return pseudo_normals_ && sigma_deg == 0.0f; }

  // The glint count of a footprint at (wi, wo): the pseudo-normal count
  // where it runs (its tiles fit), else the direction cells' count at P.
  template <typename Visitor = glint::NoParticleVisitor>
  glint::GlintCount count_particles(const Vec3 &wi, const Vec3 &wo, float P, float sigma_deg, float density,
                                    Particles &parts, Visitor &&visit = Visitor{}) const {
    // pseudo_normal_query(sigma_deg) as a branch on pseudo_normals_ first (session 27: as one expression GCC made it
    // branch-free, ~7 instructions per count where pseudo_normals_ is false).
    if (pseudo_normals_) [[unlikely]]
      if (sigma_deg == 0.0f) {
        glint::GlintCount k;
        if (pseudo_normal_count(wi, wo, density, parts, k, visit)) return k;
      }
    locate(wi, wo, density, parts);
    return glint::count_glints(parts.fp, parts.area, parts.site, P, kMaxSteps, std::forward<Visitor>(visit));
  }

  // The dark test is tried on footprints of at most kDarkTestMaxParticles
  // particles over at most kDarkTestMaxNodes particle nodes whose expected
  // glint count at P_max is at most kDarkTestMaxExpected (likely dark:
  // Pr(K = 0) >= e^-1). The walk at P_max finds more lit pairs and
  // positions than the walk at P, which over larger footprints costs more
  // than the table's miss (measured: area 1e-4, 1000 particles over ~10..20
  // nodes, 7 % slower with the test).
  static constexpr double kDarkTestMaxParticles = 100.0;
  static constexpr double kDarkTestMaxExpected = 1.0;
  // Session 34 (glintwalk34): 8 nodes (was 4; also the small route's max_nodes): at area 1e-6, aspect 64, 5196 of
  // 8192 evals (4820 the general route's lists over 4 nodes, which skipped the test, + 376 not dark by the small
  // route) read the table and counted at P; now 1255, per eval 2241.2 -> 2195.9 instructions, 1e-8 / 1e-6 / 1e-4
  // and aspect 4 unchanged, aspect 16 1722.4 -> 1721.9, every f and pdf bit the same (the test is exact). 16 nodes:
  // 2204.1.
  static constexpr int kDarkTestMaxNodes = 8;

  // True when glint_f_cos is provably 0 without reading the table: glint
  // mode is certain (N a(A) P_max <= filter_threshold, blur <= gamma) and the
  // footprint holds no reflecting particle at P_max >= P (tables/glint_peak.h),
  // hence none at P (the count is nested in P). When it is not dark,
  // glint_f_cos counts again at P over the same cells and nodes.
  // Its cheap refusals (dark_test_applies) are taken inline, before the call: in the GI scene they end almost
  // every eval's test (session 25). The body out of line (session 14: GCC inlined it into f_cos_and_pdf, 81
  // instructions per eval more at area 1e-8).
  bool dark_test_applies(float sigma_deg, double particles) const {
    return !peak_.empty() && !(sigma_deg > field_.gamma_deg) && particles <= kDarkTestMaxParticles;
  }
  // The dark test's count. Session 37 (glint1e8_37): small_footprint_dark_avx2 called from f_cos_and_pdf (this
  // function inlined there) and the rest out of line (provably_dark_located, provably_dark_generic): the call through
  // provably_dark's own frame (five registers, the kWalkAvx2 load, the arguments moved twice) cost ~20 instructions
  // per eval at area 1e-8.
  [[gnu::always_inline]] bool provably_dark(const Vec3 &wi, const Vec3 &wo, float density, float P_max,
                                            Particles &parts) const {
#if GLIMMER_GLINT_WALK_AVX2
    // Session 24: a footprint of at most kDarkTestMaxNodes nodes in a box of at most kBoxSpan x kBoxSpan, smaller
    // than a node, without the node list (tables/glint_small_dark.h); the same answer as the count below.
    if (glint::kWalkAvx2) {
      // Unset (session 37): small_footprint_dark_avx2 writes the cells, locate_glint_nodes the list (kNotDark);
      // kGeneric's locate constructs the site afresh; a dark answer reads nothing.
      new (&parts.site) glint::GlintSite(glint::GlintSite::Unset{});
      const glint::SmallDark d =
          glint::small_footprint_dark_avx2(*small_dark_, parts.fp, parts.area, density, wi, wo, P_max, parts.site);
      if (d == glint::SmallDark::kDark) return true;
      if (d == glint::SmallDark::kNotDark) return provably_dark_located(parts);
    }
#endif
    return provably_dark_generic(wi, wo, density, P_max, parts);
  }
  // small_footprint_dark_avx2 said kNotDark: the cells are located; the node list for the count at P. False.
  [[gnu::noinline]] static bool provably_dark_located(Particles &parts) {
    glint::locate_glint_nodes(parts.fp, parts.site, node_memo);
    parts.located = true;
    return false;
  }
  // The general route: the count at P_max over the node list (at most kDarkTestMaxNodes nodes).
  [[gnu::noinline]] bool provably_dark_generic(const Vec3 &wi, const Vec3 &wo, float density, float P_max,
                                               Particles &parts) const {
    locate(wi, wo, density, parts);
    if (parts.site.node_list().count > kDarkTestMaxNodes) return false;
    const glint::GlintCount k = glint::count_glints(parts.fp, parts.area, parts.site, P_max, kMaxSteps);
    return k.complete && k.count == 0;
  }
  bool provably_dark_if_applies(const Vec3 &wi, const Vec3 &wo, const TableCoords &c, float sigma_deg, float density,
                                Particles &parts) const {
    const double particles = static_cast<double>(density) * parts.area;
    if (!dark_test_applies(sigma_deg, particles)) return false;
    const float P_max = std::min(peak_.bound(c.lanes()), 1.0f);
    const double expected_max = particles * P_max;
    if (!(expected_max <= dark_test_cap_)) return false;  // <= threshold_ and <= kDarkTestMaxExpected
    return provably_dark(wi, wo, density, P_max, parts);
  }

  // The pseudo-normal count of a footprint (false: the query's tiles do not
  // fit, the caller counts in the direction cells); out of line, so the
  // direction cells' path keeps its code (session 15: inlined, glint at
  // roughness 0.4 took +27 instructions per eval at area 1e-8).
  template <typename Visitor>
  [[gnu::noinline]] bool pseudo_normal_count(const Vec3 &wi, const Vec3 &wo, float density, Particles &parts,
                                             glint::GlintCount &k, Visitor &visit) const {
    if constexpr (!std::decay_t<Visitor>::kVisitsParticles)
      if (parts.pseudo_counted) {  // counted by pseudo_normals_dark
        k.count = parts.pseudo_count, k.steps = parts.pseudo_steps, k.complete = parts.pseudo_complete;
        return true;
      }
    glint::PseudoNormalTiles tiles;
    if (!glint::pseudo_normal_tiles(pseudo_, wi, wo, glint::PseudoNormalField::kMargin, tiles)) return false;
    const glint::NodeList &nodes = glint::footprint_nodes<glint::kSmallBoxSpan>(parts.fp, density, node_memo);
    k = glint::count_pseudo_normal_glints(parts.fp, nodes, density, pseudo_, tiles, wi, wo, kMaxSteps,
                                          visit);
    return true;
  }

  // The dark test of the pseudo-normal count (unblurred query, lobe
  // narrower than the cone): where glint mode is certain (N a P_max <=
  // filter_threshold) the count does not depend on P, so it is done first;
  // none lit: f = 0 without the table's read; else glint_or_filtered takes
  // the count (parts.pseudo_count). Any footprint size: the count is needed
  // anyway.
  [[gnu::noinline]] bool pseudo_normals_dark(const Vec3 &wi, const Vec3 &wo, const TableCoords &c, float density,
                                             Particles &parts) const {
    parts.pseudo_counted = false;
    if (peak_.empty() || flakes_->varies()) return false;
    const float P_max = std::min(peak_.bound(c.lanes()), 1.0f);
    if (!(static_cast<double>(density) * parts.area * P_max <= threshold_)) return false;
    glint::GlintCount k;
    glint::NoParticleVisitor no_visit;
    if (!pseudo_normal_count(wi, wo, density, parts, k, no_visit)) return false;
    parts.pseudo_count = k.count, parts.pseudo_steps = k.steps, parts.pseudo_complete = k.complete;
    parts.pseudo_counted = true;
    return k.complete && k.count == 0;
  }

  // The glint BRDF times cos(wo): equations (2) and (3) at P (table_probability); `h` the half vector of (wi, wo).
  // `lambdas` from glint::eval_lambdas (W's G2 at the base alpha).
  // Inlining pinned (session 23): glint.cpp sits at GCC's inline-unit-growth limit, so a header edit elsewhere
  // could flip GCC's choices; f_cos_and_pdf and counted_glint_f_cos stay out of line and place_footprint,
  // table_probability and locate inlined, as GCC chose on main 4b4755c. Session 27 (glintfixed27): glint_f_cos
  // inlined into counted_f_cos_and_pdf (no call, no second test of wi.z and wo.z): GI glint 635.4 -> 633.2 M.
  [[gnu::always_inline]] Spectrum glint_f_cos(const Vec3 &wi, const Vec3 &wo, float P, const glint::HalfVector &h,
                                              const glint::EvalLambdas &lambdas, float sigma_deg, float density,
                                              Particles &parts) const {
    // No test of its own (session 27): the caller tested wi.z and wo.z, glint_weight_of tests them again (sp.wi is
    // reloaded after the Lambdas' call), and without a table P is 0.
    Spectrum weight;
    if (!glint::glint_weight_of(flakes_->mean(), flakes_->mean_is_white(), wi, wo, h, lambdas.wi, lambdas.wo, weight))
      return Spectrum(0.0f);
    if (!(P > 0.0f)) return Spectrum(0.0f);
    if (sigma_deg > field_.gamma_deg) return weight * (P / cone_solid_angle_);  // (3) here: no call (session 25)
    return glint_or_filtered(wi, wo, P, weight, sigma_deg, density, parts);
  }

  // P of the anisotropic base (tables/glint_aniso.h): the disk rule of the
  // widened lobe on the cone, times the energy scale at (wi, blur).
  float aniso_probability(const Vec3 &wi, const Vec3 &wo, float sigma_deg) const {
    const float sigma = sigma_deg * glint::kDegToRad;
    float ax, ay;
    aniso_spec_.widened(sigma, ax, ay);
    const float phi_i = std::atan2(std::fabs(wi.y), std::fabs(wi.x)) * glint::kRadToDeg;
    const float t = sigma / (2.0f * aniso_spec_.alpha_max());
    const float scale = energy_->lookup(fast_acos_deg(wi.z), phi_i, t);
    return std::min(cone_solid_angle_ * scale * cone_rules_.cone_mean_q(field_.distribution, ax, ay, wi, wo), 1.0f);
  }

  // The glint BRDF times cos(wo) of the anisotropic base: (2) and (3) with P per query.
  Spectrum aniso_f_cos(const Vec3 &wi, const Vec3 &wo, float sigma_deg, float density, Particles &parts) const {
    if (!energy_ || !(wi.z > 0.0f) || !(wo.z > 0.0f)) return Spectrum(0.0f);
    const float P = aniso_probability(wi, wo, sigma_deg);
    Spectrum weight;
    if (!glint::glint_weight(field_.distribution, alpha_x_, alpha_y_, flakes_->mean(), wi, wo, weight))
      return Spectrum(0.0f);
    if (!(P > 0.0f)) return Spectrum(0.0f);
    return glint_or_filtered(wi, wo, P, weight, sigma_deg, density, parts);
  }

  // (2) or (3) once P and W are known. The filtered test inline, the count out of line (session 27: the calls that
  // end at (3) no longer pay the count's call and register saves).
  [[gnu::always_inline]] Spectrum glint_or_filtered(const Vec3 &wi, const Vec3 &wo, float P, const Spectrum &weight,
                                                   float sigma_deg, float density, Particles &parts) const {
    const double expected = static_cast<double>(density) * parts.area * P;
    if (expected > threshold_ || sigma_deg > field_.gamma_deg) return weight * (P / cone_solid_angle_);  // (3)
    return counted_glint_f_cos(wi, wo, P, weight, sigma_deg, density, parts);
  }
  // (2) where glint mode holds (the expected count at most filter_threshold, the blur at most gamma).
  [[gnu::noinline]] Spectrum counted_glint_f_cos(const Vec3 &wi, const Vec3 &wo, float P, const Spectrum &weight,
                                                float sigma_deg, float density, Particles &parts) const {
    const double area = parts.area;
    if (flakes_->varies()) return coloured_flakes_f_cos(wi, wo, density, P, weight, sigma_deg, parts);
    // Twinkle: the particles are counted in the direction cells of (wi, wo) (or by their pseudo-normals).
    const glint::GlintCount k = count_particles(wi, wo, P, sigma_deg, density, parts);
    if (!k.complete) return weight * (P / cone_solid_angle_);  // step cap: the mean (3)
    if (k.count == 0) return Spectrum(0.0f);
    const double scale =
        static_cast<double>(k.count) / (static_cast<double>(density) * area * cone_solid_angle_);
    return weight * static_cast<float>(scale);  // (2)
  }

  // The footprint the particles are counted over (the placement's parallelogram and its area); the walk fills the
  // node list. Inlining pinned (session 25: with placed_footprint pinned, GCC outlined this one, r0.4 area 1e-8
  // +11 instructions per eval).
  [[gnu::always_inline]] void place_footprint(const ShadingPoint &sp, Particles &parts) const {
    new (&parts.fp) glint::Footprint(glint::placed_footprint(field_, placement_, sp.ctx, parts.area));
  }

  // f_cos at wo and the pdf of sampling lobe `w` for eval and sample: the
  // dark test first (no table read), else the lookup requested before the
  // pdf is computed, then the BRDF; the half vector h of (wi, wo) computed
  // once for the pdf and the weight, and (isotropic base) the three Smith
  // Lambdas of W and the pdf in one packed computation (glint::eval_lambdas).
  [[gnu::noinline]] Spectrum f_cos_and_pdf(const ShadingPoint &sp, const Vec3 &wo, float sigma_deg, const SamplingLobe &w,
                                           float &pdf) const {
    const glint::HalfVector h = glint::reflection_half_vector(sp.wi, wo);
    if (special_path_) {  // anisotropic base, or pseudo-normals: one test on the direction cells' path
      if (anisotropic_) {
        const float density = sp.param_float(density_param_, field_.density);
        Particles parts;  // default-initialised: value-initialising would zero the 1 KB node list
        place_footprint(sp, parts);
        pdf = glint::smooth_lobe_pdf(w.ax, w.ay, sp.wi, wo, h);
        return aniso_f_cos(sp.wi, wo, sigma_deg, density, parts);
      }
      if (pseudo_normal_query(sigma_deg)) return pseudo_normal_f_cos_and_pdf(sp, wo, w, h, pdf);
    }
    return counted_f_cos_and_pdf<false>(sp, wo, sigma_deg, w, h, pdf);
  }

  // f_cos_and_pdf of an unblurred query on a lobe narrower than the cone
  // (isotropic base): the same steps with the pseudo-normals' dark test
  // (out of line: the direction cells' path keeps its code).
  [[gnu::noinline]] Spectrum pseudo_normal_f_cos_and_pdf(const ShadingPoint &sp, const Vec3 &wo, const SamplingLobe &w,
                                                         const glint::HalfVector &h, float &pdf) const {
    return counted_f_cos_and_pdf<true>(sp, wo, 0.0f, w, h, pdf);
  }

  // The counted BRDF and its pdf (isotropic base): the dark test first (the
  // pseudo-normals' or the direction cells'), else the table lookup, the
  // packed Lambdas, the pdf and the weight.
  template <bool kPseudoNormals>
  [[gnu::always_inline]] Spectrum counted_f_cos_and_pdf(const ShadingPoint &sp, const Vec3 &wo, float sigma_deg,
                                                        const SamplingLobe &w, const glint::HalfVector &h,
                                                        float &pdf) const {
    // Below the surface (either side) the pdf and the BRDF are 0 (smooth_lobe_pdf's and glint_f_cos's own tests).
    if (!(sp.wi.z > 0.0f) || !(wo.z > 0.0f)) {
      pdf = 0.0f;
      return Spectrum(0.0f);
    }
    const float density = sp.param_float(density_param_, field_.density);
    const TableCoords c = table_coords(sp.wi, wo);
    Particles parts;  // default-initialised: value-initialising would zero the 1 KB node list
    // A blur wider than the cone is the filtered mean (3), which needs no footprint (neither does the dark test,
    // which it refuses): area 0 stands for it (session 25).
    if (kPseudoNormals || !(sigma_deg > field_.gamma_deg))
      place_footprint(sp, parts);
    else
      parts.area = 0.0;
    const bool dark = kPseudoNormals ? pseudo_normals_dark(sp.wi, wo, c, density, parts)
                                     : provably_dark_if_applies(sp.wi, wo, c, sigma_deg, density, parts);
    if (dark) {  // wi.z, wo.z > 0 tested above (session 37: not again after the dark test's call)
      pdf = glint::smooth_lobe_pdf_above(w.ax, w.ay, sp.wi, wo, h);  // one Lambda, no W
      return Spectrum(0.0f);
    }
    const float P = table_probability(c, sigma_deg, sp.wi, h);  // first: the Lambdas' and pdf's math overlaps its loads
    const glint::EvalLambdasPdf lp = glint::eval_lambdas_and_pdf(field_.distribution, field_.alpha, w.ax, sp.wi, wo, h);
    pdf = lp.pdf;
    return glint_f_cos(sp.wi, wo, P, h, lp.lambdas, sigma_deg, density, parts);
  }

  // Equation (2) with per-flake colours (tables/glint_flake_colour.h): the
  // K counted flakes' Schlick F sum to K F(mean F0 of those flakes); `mean_weight`
  // is W at the palette's mean F0, returned as (3) at the step cap.
  Spectrum coloured_flakes_f_cos(const Vec3 &wi, const Vec3 &wo, float density, float P, const Spectrum &mean_weight,
                                 float sigma_deg, Particles &parts) const {
    glint::FlakeColourSum flakes{*flakes_};
    const glint::GlintCount k = count_particles(wi, wo, P, sigma_deg, density, parts, flakes);
    if (!k.complete) return mean_weight * (P / cone_solid_angle_);
    if (k.count == 0) return Spectrum(0.0f);
    Spectrum weight;
    const float inv_k = 1.0f / static_cast<float>(k.count);
    if (!glint::glint_weight(field_.distribution, alpha_x_, alpha_y_, flakes.sum * inv_k, wi, wo, weight))
      return Spectrum(0.0f);
    return weight * static_cast<float>(static_cast<double>(k.count) /
                                       (static_cast<double>(density) * parts.area * cone_solid_angle_));
  }

  LocalEval eval(const ShadingPoint &sp, const Vec3 &wo) const {
    const float sigma = lod_sigma_deg(sp.ctx);
    LocalEval e;
    e.f_cos = f_cos_and_pdf(sp, wo, sigma, sampling_lobe(sigma), e.pdf);
    return e;
  }

  bool sample(const ShadingPoint &sp, const Vec3 &rand, LocalSample &out) const {
    const Vec3 &wi = sp.wi;
    const float sigma = lod_sigma_deg(sp.ctx);
    const SamplingLobe w = sampling_lobe(sigma);
    if (!glint::sample_smooth_lobe(w.ax, w.ay, wi, rand, out.wo)) return false;
    out.f_cos = f_cos_and_pdf(sp, out.wo, sigma, w, out.pdf);
    // alpha units, as the conductor reports (sqrt(ax ay) when anisotropic)
    out.roughness = anisotropic_ ? std::sqrt(w.ax * w.ay) : w.ax;
    out.label = GLIMMER_LABEL_REFLECT | GLIMMER_LABEL_GLOSSY;
    return out.pdf > 0.0f;
  }

  // The albedo the host is given: the mean flake F0, a constant sanitized once at create (session 30: the adapter
  // built the shading frame and sanitized it per call, 62 instructions).
  const Spectrum &sanitized_albedo() const { return albedo_; }

 private:
  glint::ParticleField field_;
  float threshold_ = 16.0f;
  double dark_test_cap_ = 1.0;  // min(threshold_, kDarkTestMaxExpected): the dark test's two bounds as one
  float max_spread_ = 0.32f;    // 2 alpha, the LOD blur's cap (lod_sigma_deg)
  float gamma_rad_ = 0.035f;
  glint::DirectionCellKeys cell_keys_{0};  // per-material part of the direction-cell seeds
  // The dark test's constants for small footprints (glint_small_dark.h), made out of line and held by pointer (this
  // file is at GCC's inlining budget; docs/history/glints_sessions.md, "Session 24 (glintdark24)").
  std::unique_ptr<const glint::SmallDarkField> small_dark_;
  std::shared_ptr<const glint::DirectionalTable> table_;
  glint::DirectionalPeakTable peak_;  // bounds of table_'s lookups in glint mode (the dark test)
  float cone_solid_angle_ = 1.0f;
  float sampling_alpha_unblurred_ = 0.16f;  // sampling_alpha(0), set with the base roughness
  uint32_t density_param_ = 0;
  glint::Placement placement_ = glint::Placement::UV;
  std::unique_ptr<const glint::FlakePalette> flakes_;  // per-flake F0 (car paint); mean() = color when off
  Spectrum albedo_{1.0f};                              // sanitize(flakes_->mean()) (sanitized_albedo)
  // Base roughness per axis (tangent, bitangent); equal: the isotropic model.
  float alpha_x_ = 0.16f, alpha_y_ = 0.16f;
  bool anisotropic_ = false;
  glint::AnisoSpec aniso_spec_;
  glint::AnisoConeRules cone_rules_;
  std::shared_ptr<const glint::AnisoEnergyTable> energy_;
  bool pseudo_normals_ = false;  // isotropic lobe narrower than the cone (glint::uses_pseudo_normals)
  bool special_path_ = false;    // anisotropic_ || pseudo_normals_ (f_cos_and_pdf tests it once)
  glint::PseudoNormalField pseudo_;
};

GLIMMER_REGISTER_CLOSURE(GlintClosure)

}  // namespace glimmer::plugin
