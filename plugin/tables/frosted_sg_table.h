// The front interface's transmission lobe as a spherical Gaussian, after
// de Rousiers et al. 2012, "Real-Time Rendering of Rough Refraction" (sec. 4):
//
//   g(wo) = f_t(wi, wo) |cos(wo)|  ~  G(wo) = a exp(kappa (p . wo - 1))           (SG, eq. 4)
//
// g is the Walter 2007 transmission lobe of frosted_glass's interface (GGX,
// with the multi_ggx energy compensation, core/dielectric_lobe.h) per solid
// angle of wo, for wi at polar angle theta_i in the local frame and relative
// IOR eta = n_(wo side) / n_(wi side) (eta = ior entering, 1 / ior leaving).
//
// Fit (the paper's recipe: scale, mean and variance by sampling the BTDF):
// the BTDF is integrated by its own visible-normal sampling on a fixed
// stratified grid of random numbers (deterministic; the grid is warped toward
// GGX's slope tail and refined 16 x 16 in cells cut by the lobe's edge, 3 x 3 Gauss points elsewhere; see
// for_each_transmitted in the .cpp), giving the lobe's energy
// E = Int g and mean vector M = Int g wo / E. The SG with the same energy and
// mean: p = M / |M|, a = E kappa / (2 pi (1 - exp(-2 kappa))). The paper's
// variance match (von Mises-Fisher: |M| = coth(kappa) - 1 / kappa) is kept as
// SharpnessFit::kMoments, but GGX's long tails make that lobe far too wide
// (relative L2 error ~0.5-0.7 at low roughness, test_frosted_sg_table.cpp).
// SharpnessFit::kL2 keeps E and p and picks the kappa minimising the L2
// distance (golden-section search on ln kappa; energy stays exact): about half
// the error per lobe, but on the table's 48^2 samples it is unstable from node
// to node at low roughness (sharp SGs fit single samples), so the table stores
// the moment fit for now.
// By symmetry p lies in the plane of incidence. Stored with ln(kappa) and E so
// that all three vary smoothly over the table's coordinates:
//  - entering (eta > 1): the polar angle of p below the interface minus the
//    Snell angle asin(sin(theta_i) / eta) (a small, smooth offset);
//  - leaving (eta < 1): sin(polar angle of p) minus the Snell sine
//    x = sin(theta_i) / eta, which goes past 1 where total internal reflection
//    sets in. The Snell ANGLE asin(min(x, 1)) has a square-root kink there
//    that moves with theta_i and ior: an offset from it, tabulated over
//    theta_i and ior, was the cause of the leaving side's interpolation
//    errors (mean relative L2 0.27 at cell centres, 0.29 along ior alone).
//
// Table T(., roughness, ior) for entering (eta = ior; first coordinate
// theta_i, nodes crowding toward grazing) and leaving (eta = 1 / ior; first
// coordinate the Snell sine x up to the onset of TIR, x = 1, one fixed node
// for every ior, then theta_i up to grazing, where a sine is flat; nodes
// crowding at the onset and at grazing): built lazily on first use (once per
// process, thread-safe; ~40 s CPU, see docs/frosted_glass.md) and cached on
// disk like the glint tables (host->cache_dir, file keyed by the grid and the
// fit; HMAC-authenticated, then validated: sizes, finite values, energies in
// [0, 1.1], and 16 nodes re-fitted and compared; an unusable entry is rebuilt
// with a warning). Lookups are Catmull-Rom in each coordinate (4^3 nodes;
// trilinear left 498 entering cell centres above 1 % where this leaves 89) of
// ln(E + 1e-4) (E falls by decades past the TIR onset), ln kappa and the axis
// offset; at normal incidence the first coordinate is mirrored (E and kappa
// even in theta_i, the axis offset odd).
// Grid: see kThetaNodes etc. below.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "glimmer/closure_abi.h"
#include "glimmer/math.h"

namespace glimmer::plugin::frosted {

// G(w) = amplitude exp(sharpness (axis . w - 1)).
struct SphericalGaussian {
  Vec3 axis{0.0f, 0.0f, -1.0f};
  float amplitude = 0.0f, sharpness = 1.0f;

  double eval(const Vec3 &w) const;
  double eval(double x, double y, double z) const;  // w in double (normalised here)
  double integral() const;          // Int G over the sphere = 2 pi a (1 - exp(-2 kappa)) / kappa
  double integral_squared() const;  // Int G^2 = pi a^2 (1 - exp(-4 kappa)) / kappa
};

// Int G1 G2 over the sphere = 4 pi a1 a2 sinh(d) / (exp(k1 + k2) d), d = |k1 p1 + k2 p2|
// (de Rousiers 2012 eq. 15, the SG inner product).
double sg_inner_product(const SphericalGaussian &g1, const SphericalGaussian &g2);

// The fitted lobe in its interpolation-friendly form.
struct TransmissionLobe {
  float energy = 0.0f;         // E = Int g (directional transmittance of the interface)
  float log_sharpness = 0.0f;  // ln kappa
  float axis_offset = 0.0f;    // entering: polar angle of p below the interface minus the Snell angle (radians);
                               // leaving: sin of that angle minus the Snell sine sin(theta_i) / eta

  // The SG for wi = (sin theta_i, 0, cos theta_i) (the lobe goes toward -x, -z).
  SphericalGaussian sg(float cos_theta_i, float eta) const;
};

// Strata per axis of the fixed VNDF sampling grid used by the fit. (96 on the
// leaving side was measured: cell-centre interpolation error 0.111 -> 0.095
// mean, for 2.7x the build time; not taken.)
inline constexpr int kFitStrata = 48;

// How kappa is chosen once scale (energy) and mean (axis) are matched:
// kMoments = the vMF match of the mean length (the paper's variance);
// kL2 = the kappa minimising the L2 distance to the lobe (not the table: see above).
enum class SharpnessFit { kMoments, kL2 };

// Direct fit at (cos theta_i, eta, Cycles roughness).
// The fit the table stores.
inline constexpr SharpnessFit kTableFit = SharpnessFit::kMoments;

TransmissionLobe fit_transmission_lobe(float cos_theta_i, float eta, float roughness, int strata = kFitStrata,
                                       SharpnessFit how = kTableFit);

// Relative L2 error of `sg` against the lobe g it approximates,
// sqrt(Int (G - g)^2 / Int g^2), by the BTDF's own sampling (strata^2 samples):
// Int G^2 in closed form, Int G g and Int g^2 as sample means.
double transmission_fit_error(float cos_theta_i, float eta, float roughness, const SphericalGaussian &sg,
                              int strata = 128);

// kappa with coth(kappa) - 1 / kappa = mean_length (the vMF mean resultant length), in (0, 1).
double sharpness_from_mean_length(double mean_length);

class TransmissionSgTable {
 public:
  static constexpr int kThetaNodes = 71;       // entering: theta_i in [0, 89.5] degrees, crowding toward grazing
  static constexpr float kThetaMaxDeg = 89.5f;
  // Leaving: two segments crowding the nodes at the onset of TIR: the Snell sine x = ior sin(theta_i)
  // = 1 - (1 - t)^2 up to 1, then theta_i = theta_c + (89.5 deg - theta_c) s(t), s = t^2 + 2 t^3 - 2 t^4
  // (theta_c = asin(1 / ior); s ~ t^2 at the onset, 1 - 5 (1 - t)^2 at grazing). Odd, so that x = 1 is a node.
  static constexpr int kSineNodes = 81;
  static constexpr int kRoughnessNodes = 25;   // roughness in [0.04, 1], uniform in ln(roughness)
  static constexpr float kRoughnessMin = 0.04f;
  static constexpr int kIorNodes = 14;         // ior in [1.2, 2.5], uniform
  static constexpr float kIorMin = 1.2f, kIorMax = 2.5f;

  // The process-wide table, loaded from host->cache_dir or built (and saved
  // there) on the first call; host may be NULL (no cache, no log).
  static const TransmissionSgTable &get(const GlimmerHostServices *host = nullptr);

  // The disk cache (get() uses these): the entry's file name in `cache_dir`,
  // save (returns "" or why not), and load (nullptr with `problem` set when
  // missing, corrupt, for another grid or fit, or failing validation).
  static std::string cache_path(const std::string &cache_dir);
  std::string save(const std::string &path) const;
  static std::unique_ptr<TransmissionSgTable> load(const std::string &path, std::string &problem);
  bool loaded_from_cache() const { return loaded_from_cache_; }
  // The check nodes' stamp (session 32; frosted_sg_table.cpp): load() skips the 16 re-fits when <entry>.checked
  // (stamp_path, tables/checked_stamp.h) lists this build (build_id(): the plugin's GNU build id, "" where there is
  // none: never skipped) as one that checked these bytes; else it re-fits them and, when they pass, writes the stamp.
  // The load with a given build id is the tests' (another build's stamp). refitted_check_nodes(): whether this load
  // re-fitted them.
  static std::unique_ptr<TransmissionSgTable> load(const std::string &path, std::string &problem,
                                                   const std::string &build_id);
  static const std::string &build_id();
  static std::string stamp_path(const std::string &entry_path);
  bool refitted_check_nodes() const { return refitted_check_nodes_; }
  // Why this load's stamp could not be written ("" when it was, or was not needed); get() logs it.
  const std::string &stamp_not_written() const { return stamp_not_written_; }
  bool operator==(const TransmissionSgTable &o) const;

  // Catmull-Rom weights of the 4 nodes around a grid coordinate on one axis (frosted_sg_table.cpp catmull_rom_taps).
  struct Taps {
    int index[4];
    float weight[4];
    float parity[4];  // -1 where a mirrored node's odd quantity (the axis offset) changes sign
  };
  // The lookups' setup, shared by lookup(), lookup_scalar() and lookup_energies(): for one (eta, roughness) the side
  // (0 entering, 1 leaving), ior = max(eta, 1 / eta), whether the grid covers them, and then the roughness taps b
  // and the IOR taps c; per incidence the first axis' taps a (theta entering, the Snell sine leaving), false where
  // lookup() returns false (off the grid, or theta_i beyond kThetaMaxDeg). The axes are the same for every lookup
  // with one (eta, roughness) (two catmull_rom_taps and a logf, ~115 instructions): a material makes them once and
  // passes them to its lookups (frosted_glass_sg.cpp table_axes; issue 12, session 22).
  struct Axes {
    float eta = 1.0f;
    int side = 0;
    float ior = 1.0f;
    bool in_grid = false;
    Taps b{}, c{};
  };
  static Axes axes(float eta, float roughness);
  static bool first_taps(float cos_theta_i, const Axes &axes, Taps &a);
  // Interpolated lobe for relative IOR eta (> 1 entering, < 1 leaving); false
  // when ior = max(eta, 1 / eta) or roughness lies outside the grid (the caller
  // then fits directly).
  bool lookup(float cos_theta_i, float eta, float roughness, TransmissionLobe &out) const;
  // The same with the axes of (eta, roughness) made beforehand by axes(): the same bits.
  bool lookup(float cos_theta_i, const Axes &axes, TransmissionLobe &out) const;
  // lookup()'s energy alone (the same value, bit for bit) at n <= kMaxEnergyBatch incidences for one (eta,
  // roughness): the roughness and IOR taps once, the energy's 64 nodes per incidence (the sg exit energies of a
  // segment's 4 bounding rays). valid[i] false where lookup() would return false.
  static constexpr int kMaxEnergyBatch = 8;
  // lookup() by three scalar sums over the 64 taps (lookup() before the twenty-first session, which makes them one
  // 4-lane sum): the tests' reference for lookup()'s bits.
  bool lookup_scalar(float cos_theta_i, float eta, float roughness, TransmissionLobe &out) const;
  void lookup_energies(const float *cos_theta_i, int n, float eta, float roughness, float *energy, bool *valid) const;
  void lookup_energies(const float *cos_theta_i, int n, const Axes &axes, float *energy, bool *valid) const;

  // Node coordinates (for the tests' off-grid points).
  static float theta_at(int i);
  static float sine_at(int i, float ior);
  static float roughness_at(int j);
  static float ior_at(int k);

  // Builds every node (slow: use get()) on `threads` threads (0: one per hardware thread). Each node is fitted
  // on its own by a fixed quadrature (no random numbers, no shared state), so the table is bit-identical for
  // any thread count (FrostedSgTable.FitIsBitIdenticalForAnyThreadCount).
  explicit TransmissionSgTable(unsigned threads = 0);

  // The nodes in storage order (side, first coordinate, roughness, ior), node_count() of them.
  static constexpr size_t node_count() {
    return size_t(kThetaNodes + kSineNodes) * kRoughnessNodes * kIorNodes;
  }
  const TransmissionLobe &node_at(size_t idx) const { return nodes_[idx]; }
  // The fits of the nodes `indices` (storage order) on `threads` threads (0: one per hardware thread): the
  // threads take chunks of nodes from a shared counter (the cost per node varies ~10x with the incidence and
  // the roughness), and result[n] is the fit of node indices[n] whichever thread computed it.
  static std::vector<TransmissionLobe> fit_nodes(const std::vector<size_t> &indices, unsigned threads);

 private:
  static constexpr int first_nodes(int side) { return side == 0 ? kThetaNodes : kSineNodes; }
  static size_t index(int side, int i, int j, int k) {
    return ((size_t(side) * kThetaNodes + i) * kRoughnessNodes + j) * kIorNodes + k;
  }
  const TransmissionLobe &node(int side, int i, int j, int k) const { return nodes_[index(side, i, j, k)]; }
  // [side 0: entering, theta][roughness][ior] then [side 1: leaving, Snell sine][roughness][ior]
  std::vector<TransmissionLobe> nodes_;
  // What lookup() interpolates for the energy: ln(E + kEnergyFloor) per node (derived from nodes_ after a build
  // or a load, not stored). The energy falls by decades past the onset of TIR at low roughness, where a cubic
  // in E itself missed the direct fit by 10-70 %; its logarithm is close to linear there. The floor (a tenth
  // of the smallest lobe energy the checks count, 1e-3) keeps nodes without a lobe (E = 0) finite.
  static constexpr float kEnergyFloor = 1e-4f;
  std::vector<float> log_energy_;
  // lookup()'s three interpolated quantities of each node side by side, (ln(E + floor), ln kappa, axis offset, 0):
  // one 4-lane product and sum per tap (derived with log_energy_).
  std::vector<std::array<float, 4>> lookup_nodes_;
  void derive_interpolated();
  bool loaded_from_cache_ = false;
  bool refitted_check_nodes_ = false;
  std::string stamp_not_written_;
  struct Empty {};
  explicit TransmissionSgTable(Empty);  // no nodes built (load fills them)
  // Where validation refits nodes: (first coordinate index over both sides, roughness, ior).
  static std::array<std::array<int, 3>, 16> check_nodes();
  static TransmissionLobe fit_node(size_t idx);
};

}  // namespace glimmer::plugin::frosted
