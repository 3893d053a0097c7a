// Directional probability tables of the separable discrete stochastic
// microfacet model (Wang, Wang, Holzschuch 2018, "Fast Global Illumination
// with Discrete Stochastic Microfacets Using a Filterable Model", sec. 4.2-4.4).
//
// P_gamma(wi, wo) is the probability that one particle, whose normal m is
// distributed like the projected-area microfacet distribution D(m) cos(theta_m),
// reflects wi into the cone of half-angle gamma around wo:
//
//   P_gamma(wi, wo) = Int_{cone(wo, gamma)} q(wi, r) dr,
//   q(wi, r) = D(h) cos(theta_h) / (4 (wi . h)),  h = normalize(wi + r)        (1)
//
// q is the density (per solid angle of r) of the reflected direction; the
// factor 1 / (4 wi.h) is the Jacobian of the half-vector map (Walter 2007).
// For an isotropic D, P depends on (theta_i, theta_o, dphi) with dphi folded to
// [0, 180] degrees.
//
// Construction (the paper's structure; steps 1-2 and the level-0 cap differ):
//  1-2. P_gamma for the material's gamma on a 1-degree grid (91 x 91 x 181
//     nodes), each node by a product rule over the cone (Gauss-Chebyshev
//     across the plane of (wi, wo), Gauss-Legendre along it) with points
//     per axis set by the scale on which q varies there (2 alpha (wi.h)
//     across, 2 alpha along); where an axis would need more than 24 points
//     (lobes narrow against the cone, e.g. roughness 0.15 at gamma 5 near
//     grazing) by the rim rule instead: Green's theorem turns the NDF's mass
//     over the half vectors of the cone into a loop integral of the slope
//     distribution's closed-form radial CDF along the image of the cone's
//     rim (exact for any lobe width). The paper's route, P at gamma = 1 degree
//     summed over 1-degree cones tiling the gamma cone, adds the small
//     cone's spread to the large one's: at roughness 0.2 (a lobe narrower
//     than the cone) the mean was 2.7..6.9 % low;
//  3. 9 Gaussian LOD levels (sigma = 1, 2, 5, 10, 20, 30, 45, 60, 90 degrees).
//     Level 0 ("1 degree") is P_gamma itself at the 1-degree base resolution;
//     levels 1..8 are P_gamma blurred over wo on the sphere (separable: along
//     theta_o, then along phi with sigma / sin(theta_o)), stored at a step
//     ~ sigma / 3;
//  4. energy: per theta_i, level 0 is scaled down to the smooth microfacet
//     albedo (+0.1 %, the energy grid's accuracy) where its own W-weighted
//     albedo exceeds it (the cone estimator averages W over the cone, and W
//     is convex near the horizon); then each blurred level is scaled so that
//     its reflected energy weighted by the BRDF's W(wi, wo) (the factor eval
//     multiplies P with, tables/glint_common.h), Int W P_sigma dwo, equals
//     that of level 0 (0.5-degree midpoint rule through the level's own
//     trilinear lookup). Normalising the probability mass alone let the blur
//     move P toward grazing wo, where W is large: the albedo grew to 2..4.7
//     at grazing incidence.
// Lookups are trilinear within a level and linear in sigma between levels.
// Storage (session 31, glinttable31): the values are built, cached on disk and validated in fp32 (`values`); lookups
// read a 16-bit copy (`halves`: unsigned floats, 5 exponent and 11 mantissa bits, of the level's values times a power
// of two, rounded up, so every node reads at most 2^-11 relative above its fp32 value). A lookup's loads are random
// accesses into several MB (the GI scene's largest single stall, a cache miss per lookup): half the bytes, a smaller
// working set.
//
// Tables are cached on disk (host->cache_dir) under a hash of their
// parameters; a corrupt or mismatching file is rebuilt with a warning.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <emmintrin.h>

#include "glimmer/closure_abi.h"
#include "tables/glint_factored_level0.h"

namespace glimmer::plugin::glint {

enum class BaseDistribution : int { GGX = 0, Beckmann = 1 };

struct TableSpec {
  BaseDistribution distribution = BaseDistribution::GGX;
  float alpha = 0.25f;      // microfacet alpha (Cycles: roughness^2)
  float gamma_deg = 1.0f;   // query cone half-angle in degrees
  bool operator==(const TableSpec &) const = default;
};

inline constexpr int kLodCount = 9;
inline constexpr std::array<float, kLodCount> kLodSigmaDeg = {1, 2, 5, 10, 20, 30, 45, 60, 90};
// Grid step (degrees) of theta_o and dphi per level (divides 90 and 180).
inline constexpr std::array<int, kLodCount> kLodStepDeg = {1, 1, 2, 3, 6, 10, 15, 18, 30};
inline constexpr int kThetaICount = 91;  // theta_i = 0..90 degrees, 1-degree nodes
inline constexpr float kRadToDeg = 57.29577951308232f;
inline constexpr float kDegToRad = 0.017453292519943295f;

// One LOD level: values[((ti * n_theta_o) + to) * n_phi + phi] at nodes
// theta_i = ti deg, theta_o = to * step, dphi = phi * step.
struct LodLevel {
  float sigma_deg = 1.0f;
  int step_deg = 1;
  int n_theta_o = 91;
  int n_phi = 181;
  float inv_step = 1.0f;  // 1 / step_deg in float, as cell() multiplies by it (session 27: was divided per lookup)
  // cell()'s lane constants, set with the step (session 28: were assembled per lookup from inv_step, n_theta_o and
  // n_phi, ~10 instructions): the scale (1, inv_step, inv_step, 0) and the last corners (kThetaICount - 2,
  // n_theta_o - 2, n_phi - 2, 0). The defaults are step 1's.
  alignas(16) float lane_scale[4] = {1.0f, 1.0f, 1.0f, 0.0f};
  alignas(16) int32_t lane_last[4] = {kThetaICount - 2, 89, 179, 0};
  size_t i_stride = 91 * 181;  // theta_i_stride(), n_theta_o n_phi, set with the step (not multiplied per lookup)
  std::vector<float> values;  // fp32: built, cached on disk, validated; released once acquired (release_values)
  // What lookups read (pack_halves; node() decodes one): values[i] x 2^k as a 16-bit float without sign (IEEE
  // binary16's 5-bit exponent, bias 15, and the sign bit as an 11th mantissa bit), rounded up; below 2^-14 (the
  // smallest normal) 0. k per level so the largest value scales to [2^14, 2^15): nodes below 2^-28 of the level's
  // peak read 0. A half h decodes as the float of bits h << 12 (exponent rebiased by 2^-112, exact) times
  // half_scale = 2^(112 - k), one product per lane. The dark test's bounds (glint_peak.h) are taken over node().
  std::vector<uint16_t> halves;
  alignas(16) float half_scale[4] = {1.0f, 1.0f, 1.0f, 1.0f};

  // The grid of a level at `step` degrees: step_deg, inv_step, the node counts and cell()'s lane constants (values
  // not sized).
  void set_step(int step) {
    step_deg = step;
    inv_step = 1.0f / static_cast<float>(step);
    n_theta_o = 90 / step + 1;
    n_phi = 180 / step + 1;
    lane_scale[1] = lane_scale[2] = inv_step;
    lane_last[1] = n_theta_o - 2;
    lane_last[2] = n_phi - 2;
    i_stride = static_cast<size_t>(n_theta_o) * n_phi;
  }

  // x clamped to [0, hi], NaN to 0 (comparisons, not std::fmin/fmax: without
  // -ffinite-math-only those are library calls, 9 per lookup).
  static float clamp_deg(float x, float hi) { return x > 0.0f ? (x < hi ? x : hi) : 0.0f; }

  // The grid cell of a lookup: its first corner (an index into values and halves) and the fractions along
  // theta_i, theta_o and dphi; angles in degrees, theta in [0, 90], dphi in
  // [0, 180]. The other corners are +1 (dphi), +theta_o_stride(), +theta_i_stride().
  struct Cell {
    size_t base;
    float ti, to, tp;
  };
  size_t theta_o_stride() const { return static_cast<size_t>(n_phi); }
  size_t theta_i_stride() const { return i_stride; }
  // The three axes in the lanes of one SSE register (issue 10, session 20):
  // the same clamps (x > 0 ? min(x, hi) : 0, NaN to 0), the same product by
  // 1 / step (theta_i's lane times 1, exact), truncation, integer minimum and
  // differences as cell_scalar, so the same corner and fractions
  // (test GlintTables.CellInLanesMatchesTheScalarForm).
  Cell cell(float theta_i_deg, float theta_o_deg, float dphi_deg) const {
    return cell(_mm_setr_ps(theta_i_deg, theta_o_deg, dphi_deg, 0.0f));
  }
  // The same with the angles in lanes 0..2 of `x` (lane 3 unused, any value).
  Cell cell(__m128 x) const {
    const __m128 clamped = _mm_and_ps(_mm_cmpgt_ps(x, _mm_setzero_ps()),
                                      _mm_min_ps(x, _mm_setr_ps(90.0f, 90.0f, 180.0f, 0.0f)));
    const __m128 f = _mm_mul_ps(clamped, _mm_load_ps(lane_scale));
    const __m128i k = _mm_cvttps_epi32(f);
    const __m128i last = _mm_load_si128(reinterpret_cast<const __m128i *>(lane_last));
    const __m128i over = _mm_cmpgt_epi32(k, last);
    const __m128i corner = _mm_or_si128(_mm_and_si128(over, last), _mm_andnot_si128(over, k));  // min(k, last)
    alignas(16) int32_t c[4];
    alignas(16) float t[4];
    _mm_store_si128(reinterpret_cast<__m128i *>(c), corner);
    _mm_store_ps(t, _mm_sub_ps(f, _mm_cvtepi32_ps(corner)));
    return {(static_cast<size_t>(c[0]) * n_theta_o + c[1]) * n_phi + c[2], t[0], t[1], t[2]};
  }
  // The scalar form of cell() (the reference of its test).
  Cell cell_scalar(float theta_i_deg, float theta_o_deg, float dphi_deg) const {
    const float inv_step = 1.0f / static_cast<float>(step_deg);
    const float fi = clamp_deg(theta_i_deg, 90.0f);
    const float fo = clamp_deg(theta_o_deg, 90.0f) * inv_step;
    const float fp = clamp_deg(dphi_deg, 180.0f) * inv_step;
    const int i0 = std::min(static_cast<int>(fi), kThetaICount - 2);
    const int o0 = std::min(static_cast<int>(fo), n_theta_o - 2);
    const int p0 = std::min(static_cast<int>(fp), n_phi - 2);
    return {(static_cast<size_t>(i0) * n_theta_o + o0) * n_phi + p0, fi - static_cast<float>(i0),
            fo - static_cast<float>(o0), fp - static_cast<float>(p0)};
  }

  // Fills halves and half_scale from values (see halves); after values are final (built or loaded).
  void pack_halves();
  // Node i as lookups read it (the decoded half).
  float node(size_t i) const { return decode_half(halves[i]); }
  // A half of `halves` as a float (the scalar form of lookup()'s decode).
  float decode_half(uint16_t h) const {
    const uint32_t bits = static_cast<uint32_t>(h) << 12;
    float x;
    __builtin_memcpy(&x, &bits, sizeof x);
    return x * half_scale[0];
  }

  // Trilinear lookup (of the halves).
  float lookup(float theta_i_deg, float theta_o_deg, float dphi_deg) const {
    return lookup(cell(theta_i_deg, theta_o_deg, dphi_deg));
  }
  // The same at a cell located by cell() (the eval locates it once for prefetch and lookup).
  // The four dphi pairs of halves (rows theta_i, theta_o + (0, 0), (1, 0), (0, 1), (1, 1)) interleaved into lanes
  // 00, 10, 01, 11 at dphi and at dphi + 1, decoded (<< 12, times half_scale), then the two theta_o lerps in two
  // lanes: the same operations in the same order as lookup_scalar (test GlintTables.LookupInLanesMatchesTheScalarForm).
  float lookup(const Cell &c) const {
    const size_t si = theta_i_stride(), so = theta_o_stride();
    const uint16_t *base = halves.data() + c.base;
    auto pair = [](const uint16_t *p) {
      uint32_t v;
      __builtin_memcpy(&v, p, sizeof v);
      return _mm_cvtsi32_si128(static_cast<int>(v));
    };
    const __m128i r00 = pair(base), r01 = pair(base + so), r10 = pair(base + si), r11 = pair(base + si + so);
    const __m128i a = _mm_unpacklo_epi16(r00, r10), b = _mm_unpacklo_epi16(r01, r11);  // 00 p0, 10 p0, 00 p1, 10 p1
    const __m128i h = _mm_unpacklo_epi32(a, b);  // 16-bit lanes 00 p0, 10 p0, 01 p0, 11 p0, 00 p1, 10 p1, 01 p1, 11 p1
    const __m128 scale = _mm_load_ps(half_scale);
    auto decode = [&](__m128i high) { return _mm_mul_ps(_mm_castsi128_ps(_mm_srli_epi32(high, 4)), scale); };
    const __m128 p0 = decode(_mm_unpacklo_epi16(_mm_setzero_si128(), h));  // lanes 00, 10, 01, 11 at dphi
    const __m128 p1 = decode(_mm_unpackhi_epi16(_mm_setzero_si128(), h));  // the same at dphi + 1
    const __m128 l = _mm_add_ps(p0, _mm_mul_ps(_mm_sub_ps(p1, p0), _mm_set1_ps(c.tp)));
    const __m128 l1 = _mm_movehl_ps(l, l);                                        // lanes 01, 11
    const __m128 ab = _mm_add_ps(l, _mm_mul_ps(_mm_sub_ps(l1, l), _mm_set1_ps(c.to)));  // lanes a, b
    const float va = _mm_cvtss_f32(ab), vb = _mm_cvtss_f32(_mm_shuffle_ps(ab, ab, 1));
    return va + (vb - va) * c.ti;
  }
  // The scalar form of lookup(const Cell &) (the reference of its test).
  float lookup_scalar(const Cell &c) const {
    return trilinear(c, [this](size_t i) { return node(i); });
  }
  // The trilinear lookup of the fp32 values (the build's energy normalisation and the cache's validation; the
  // reference of the halves' accuracy test).
  float lookup_exact(const Cell &c) const {
    return trilinear(c, [this](size_t i) { return values[i]; });
  }
  float lookup_exact(float theta_i_deg, float theta_o_deg, float dphi_deg) const {
    return lookup_exact(cell(theta_i_deg, theta_o_deg, dphi_deg));
  }
  // Trilinear interpolation at `c` of the nodes read by `at(i)` (the halves for lookup_scalar, the fp32 values for
  // lookup_exact): phi, then theta_o, then theta_i, the order lookup() follows in lanes. The strides from the counts
  // (i_stride is checked).
  template <class Node>
  float trilinear(const Cell &c, const Node &at) const {
    const size_t si = static_cast<size_t>(n_theta_o) * n_phi, so = n_phi;
    auto lerp_phi = [&](size_t i) {
      const float v0 = at(i), v1 = at(i + 1);
      return v0 + (v1 - v0) * c.tp;
    };
    const float a = lerp_phi(c.base) + (lerp_phi(c.base + so) - lerp_phi(c.base)) * c.to;
    const float b = lerp_phi(c.base + si) + (lerp_phi(c.base + si + so) - lerp_phi(c.base + si)) * c.to;
    return a + (b - a) * c.ti;
  }

  // Starts loading the cache lines of a lookup (a hint; no value read).
  void prefetch(float theta_i_deg, float theta_o_deg, float dphi_deg) const {
    prefetch(cell(theta_i_deg, theta_o_deg, dphi_deg));
  }
  // Session 35 (glintwalk35): the four hints as volatile asm. With __builtin_prefetch (in a loop over
  // {0, so, si, si + so}, or written out) GCC 12 emitted no prefetch at all where this was inlined into
  // DirectionalTable::prefetch(const Located &) (-O2 and -O3: docs/history/glints_sessions.md, Session 35
  // (glintwalk35)); nothing on main calls it.
  static void prefetch_line(const uint16_t *p) {
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
    asm volatile("prefetcht0 %0" : : "m"(*p));
#else
    __builtin_prefetch(p);  // elsewhere the builtin (whether the compiler keeps it is not checked off x86-64)
#endif
  }
  void prefetch(const Cell &c) const {
    const uint16_t *p = halves.data() + c.base;
    const size_t si = theta_i_stride(), so = theta_o_stride();
    prefetch_line(p);
    prefetch_line(p + so);
    prefetch_line(p + si);
    prefetch_line(p + si + so);
  }
};

// Level 0 read as the analytic lobe A times its residual R on 2-degree nodes (tables/glint_factored_level0.h): built
// from level 0's fp32 nodes by DirectionalTable::factor_level0 where applies(); inactive otherwise (lookups read the
// 1-degree level 0).
class FactoredLevel0 {
 public:
  static constexpr int kStepDeg = 2;               // of theta_i, theta_o and dphi
  static constexpr float kResidualCap = 4.0f;      // R at a node (see glint_factored_level0.h)
  static constexpr float kNarrowLobeRatio = 1.5f;  // glint_pseudo_normals.h's kPseudoNormalLobeRatio (asserted equal)
  // Where (2) is read: theta_i <= 80 degrees. Beyond, at forward grazing, the residual varies faster than its
  // 2-degree dphi nodes (glint_factored_level0.h): lookups read the 1-degree level 0 there (330 KB of its slices).
  static constexpr float kMaxThetaIDeg = 80.0f, kMaxThetaODeg = 90.0f;
  static constexpr int kNodesThetaI = static_cast<int>(kMaxThetaIDeg) / kStepDeg + 1;
  static_assert(static_cast<int>(kMaxThetaIDeg) % kStepDeg == 0 && kMaxThetaIDeg == static_cast<int>(kMaxThetaIDeg));
  // Lobes wider than the cone's 1.5 gamma (narrower ones keep the 1-degree level 0: glint_factored_level0.h).
  // The same float expression as glint_pseudo_normals.h's uses_pseudo_normals(alpha, gamma_deg * kDegToRad), negated.
  static bool applies(const TableSpec &spec) {
    return !(spec.alpha <= kNarrowLobeRatio * (spec.gamma_deg * kDegToRad));
  }
  // The slices' energy scales are small corrections; outside (kMinScale, kMaxScale) the form is not used.
  static constexpr double kMinScale = 0.9, kMaxScale = 1.1;

  FactoredLevel0() = default;
  // From level 0 with its fp32 values; sigma the cone's solid angle. `normalise`: each theta_i slice of R scaled so
  // that the W-weighted energy of the lookups (factored where covered, 1-degree elsewhere) equals level 0's (false:
  // the nodes' R as they are; tests only).
  // `scales`: the slices' scales saved with the table (slice_scales(); computed when null or empty).
  FactoredLevel0(const LodLevel &level0, const TableSpec &spec, float sigma, bool normalise = true,
                 const std::vector<double> *scales = nullptr);
  const std::vector<double> &slice_scales() const { return scales_; }  // empty when inactive or not normalised

  bool active() const { return !residual_.halves.empty(); }
  static bool covers(float theta_i_deg, float theta_o_deg) {
    return theta_i_deg <= kMaxThetaIDeg && theta_o_deg <= kMaxThetaODeg;
  }
  const Level0Lobe &lobe() const { return lobe_; }
  const LodLevel &residual() const { return residual_; }
  // theta_i clamped to kMaxThetaIDeg (the residual's last node: no extrapolation where a caller did not test covers).
  LodLevel::Cell cell(__m128 deg) const {
    return residual_.cell(_mm_min_ps(deg, _mm_setr_ps(kMaxThetaIDeg, 90.0f, 180.0f, 0.0f)));
  }
  // (2) of glint_factored_level0.h: `lobe` = lobe()(wi.h, cos theta_h) of the query located at `c`.
  float lookup(const LodLevel::Cell &c, float lobe) const { return lobe * residual_.lookup(c); }
  // The same from angles (degrees), A computed from them (tests and tools).
  float lookup_angles(float theta_i_deg, float theta_o_deg, float dphi_deg) const;
  size_t byte_size() const { return residual_.halves.size() * sizeof(uint16_t); }

 private:
  Level0Lobe lobe_;
  LodLevel residual_;  // R: 41 x 46 x 91 nodes (theta_i 0..80), theta_i's lane at step 2 as well
  std::vector<double> scales_;
  double slice_scale(const LodLevel &level0, const TableSpec &spec, int i) const;
};

class DirectionalTable {
 public:
  TableSpec spec;
  std::array<LodLevel, kLodCount> levels;
  double build_seconds = 0.0;  // precompute time (0 when loaded from the cache)
  bool loaded_from_cache = false;
  bool energy_checked = false;  // loaded, and this load ran the energy validation (no stamp of this build: load_table)
  std::string stamp_not_written;  // why that validation's stamp could not be written ("" when it was or not needed)

  // Solid angle of the query cone, 2 pi (1 - cos gamma).
  float cone_solid_angle() const { return 6.283185307179586f * (1.0f - std::cos(spec.gamma_deg * kDegToRad)); }

  // The levels a lookup at LOD blur sigma (degrees, clamped to [1, 90])
  // reads: `first` alone (t = 0) or first and first + 1, weights 1 - t, t.
  struct LevelPair {
    int first;
    float t;
  };
  static LevelPair levels_at(float sigma_deg) {
    if (!(sigma_deg > kLodSigmaDeg[0])) return {0, 0.0f};
    if (sigma_deg >= kLodSigmaDeg[kLodCount - 1]) return {kLodCount - 1, 0.0f};
    int l = 0;
    while (l + 2 < kLodCount && sigma_deg > kLodSigmaDeg[l + 1]) ++l;
    return {l, (sigma_deg - kLodSigmaDeg[l]) / (kLodSigmaDeg[l + 1] - kLodSigmaDeg[l])};
  }

  // P at LOD blur sigma: linear between the two levels bracketing sigma.
  float lookup(float sigma_deg, float theta_i_deg, float theta_o_deg, float dphi_deg) const {
    return lookup(locate(sigma_deg, theta_i_deg, theta_o_deg, dphi_deg));
  }

  // Starts loading what lookup() will read (see LodLevel::prefetch).
  void prefetch(float sigma_deg, float theta_i_deg, float theta_o_deg, float dphi_deg) const {
    prefetch(locate(sigma_deg, theta_i_deg, theta_o_deg, dphi_deg));
  }

  // A lookup located once (levels and cells), then prefetched and read:
  // the same arithmetic as lookup(sigma, ...) above, without locating twice.
  struct Located {
    LevelPair lp;
    LodLevel::Cell first{}, second{};  // second: only when lp.t > 0
  };
  Located locate(float sigma_deg, float theta_i_deg, float theta_o_deg, float dphi_deg) const {
    return locate(sigma_deg, _mm_setr_ps(theta_i_deg, theta_o_deg, dphi_deg, 0.0f));
  }
  // The same with the angles in lanes 0..2 of `deg` (lane 3 unused). `factored_level0`: level 0 located in factored0's
  // residual, for lookup_factored (the closure, where factored0 is active and covers the query).
  Located locate(float sigma_deg, __m128 deg, bool factored_level0 = false) const {
    Located at;
    at.lp = levels_at(sigma_deg);
    at.first = factored_level0 && at.lp.first == 0 ? factored0.cell(deg) : levels[at.lp.first].cell(deg);
    if (at.lp.t > 0.0f) at.second = levels[at.lp.first + 1].cell(deg);
    return at;
  }
  // lookup() of a locate(..., true): level 0 read as factored0's (2) with `lobe` the query's A
  // (FactoredLevel0::lobe()).
  float lookup_factored(const Located &at, float lobe) const {
    return toward_second(at,
                         at.lp.first == 0 ? factored0.lookup(at.first, lobe) : levels[at.lp.first].lookup(at.first));
  }
  void prefetch(const Located &at) const {
    levels[at.lp.first].prefetch(at.first);
    if (at.lp.t > 0.0f) levels[at.lp.first + 1].prefetch(at.second);
  }
  float lookup(const Located &at) const { return toward_second(at, levels[at.lp.first].lookup(at.first)); }
  // `a` read at the first level; linear toward the second level where the blur lies between them.
  float toward_second(const Located &at, float a) const {
    if (!(at.lp.t > 0.0f)) return a;
    const float b = levels[at.lp.first + 1].lookup(at.second);
    return a + (b - a) * at.lp.t;
  }

  size_t byte_size() const;  // values (until released), halves and the factored level 0
  // Level 0 as lookup_factored reads it (factored0), built from level 0's fp32 values where FactoredLevel0::applies.
  FactoredLevel0 factored0;
  // `scales`: the slices' scales read from the cache (computed when null or empty).
  void factor_level0(const std::vector<double> *scales = nullptr) {
    if (FactoredLevel0::applies(spec)) factored0 = FactoredLevel0(levels[0], spec, cone_solid_angle(), true, scales);
  }
  void pack_halves() {
    for (LodLevel &l : levels) l.pack_halves();
  }
  // Frees the fp32 values once packed and cached (acquire_table): lookups, the dark test's bounds and every closure
  // read only the halves, so a shared table holds half the bytes (session 31: 14.5 -> 7.3 MB per table instead of
  // 21.8 MB with both). lookup_exact() and save_table() need the values: call them before.
  void release_values() {
    for (LodLevel &l : levels) std::vector<float>().swap(l.values);
  }
};

// The isotropic NDF D(m) as a function of cos(theta_m) (used only while building).
using NdfFunction = std::function<double(double cos_theta_m)>;

// Builds the table (steps 1-4 above, then the halves) with up to `threads` worker threads.
std::unique_ptr<DirectionalTable> build_directional_table(const TableSpec &spec, const NdfFunction &ndf,
                                                          int threads = 2);

// Reference (no table) value of P_gamma by dense quadrature of (1); for tests.
double directional_probability_reference(const NdfFunction &ndf, double gamma_deg, double theta_i_deg,
                                         double theta_o_deg, double dphi_deg, int rings = 24);

// P_gamma by the rim rule (exact for any lobe width; see glint_tables.cpp),
// or -1 where the rim's half vectors leave the upper hemisphere; for tests.
double directional_probability_by_rim(BaseDistribution dist, double alpha, double gamma_deg, double theta_i_deg,
                                      double theta_o_deg, double dphi_deg);

// Stable 64-bit key of a spec (file name of the cache entry).
uint64_t table_key(const TableSpec &spec);

// Disk cache (files 0600 in a private 0700 folder, written atomically). load
// returns nullptr (and sets `problem`) when the entry is missing, not a
// regular file (removed), truncated, fails its HMAC-SHA256 (corrupt or
// crafted), is for another spec, or fails the energy validation.
std::unique_ptr<DirectionalTable> load_table(const std::string &path, const TableSpec &spec, std::string &problem);
// The energy validation runs once per plugin build and entry bytes: when it passes, load writes the entry's checked
// stamp (tables/checked_stamp.h) and a later load by the same build of the same bytes skips it
// (DirectionalTable::energy_checked says whether this load ran it). The build id is plugin_build_id() (tests pass
// another build's).
std::unique_ptr<DirectionalTable> load_table(const std::string &path, const TableSpec &spec, std::string &problem,
                                             const std::string &build_id);
bool save_table(const std::string &path, const DirectionalTable &table, std::string &problem);
std::string table_cache_path(const std::string &cache_dir, const TableSpec &spec);

// Process-wide table provider: shares one table per spec among instances
// (weakly held: freed when the last instance goes), loads from / writes to
// host->cache_dir, rebuilds a corrupt cache entry with a warning through
// host->log, and logs the precompute time.
std::shared_ptr<const DirectionalTable> acquire_table(const TableSpec &spec, const NdfFunction &ndf,
                                                      const GlimmerHostServices *host);

}  // namespace glimmer::plugin::glint
