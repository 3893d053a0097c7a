// The spherical-Gaussian fit of frosted_glass's front-interface BTDF and its
// table (plugin/tables/frosted_sg_table.*, de Rousiers 2012 sec. 4):
//  - the L2 error estimator against brute-force quadrature on the sphere, with
//    a negative control (a mis-aimed SG must score much worse);
//  - the moment match: the SG's energy and mean direction equal the BTDF's,
//    measured by an independent uniform-sphere quadrature of eval();
//  - the fit error of the lobe over theta_o 0..89, roughness 0.05..1, IOR
//    1.33..2.4 entering and leaving (reported: this is the SG model's error);
//  - the table: interpolated lobe vs a direct fit at off-grid points (cell
//    centres, the worst place for linear interpolation): relative L2 <= 1 %,
//    with nearest-node lookup as the negative control;
//  - the table's disk cache: round trip bit for bit, and corrupt, truncated,
//    crafted (valid MAC, wrong values) and foreign entries refused.
// The table code comes from the plugin's objects (linked into this test).
#include <gtest/gtest.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <numeric>
#include <set>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <unistd.h>
#include <vector>

#include "closures/cache_test_util.h"
#include "core/dielectric_lobe.h"
#include "core/microfacet_lobe_params.h"
#include "glimmer/cache_blob.h"
#include "glimmer/rng.h"
#include "host/closure_instance.h"
#include "tables/frosted_sg_table.h"

namespace {

using namespace glimmer;
using namespace glimmer::plugin;
using namespace glimmer::plugin::frosted;

constexpr double kDeg = M_PI / 180.0;

// Relative L2 distance of `a` from `b`: sqrt(Int (a - b)^2 / Int b^2), closed form.
double sg_relative_l2(const SphericalGaussian &a, const SphericalGaussian &b) {
  const double bb = b.integral_squared();
  if (!(bb > 0.0)) return 0.0;
  return std::sqrt(std::max(0.0, a.integral_squared() - 2.0 * sg_inner_product(a, b) + bb) / bb);
}

// Brute-force Int over the sphere of h(wo, g(wo)), g = the interface's
// transmission f_cos (eval; 0 above the interface), on an n x 2n grid in
// (t, phi) around `axis` with theta = pi t^2 (dense near the axis).
template <typename H>
double quadrature(float cos_theta_i, float eta, float roughness, const Vec3 &axis, int n, H &&h) {
  const Vec3 wi(std::sqrt(1 - cos_theta_i * cos_theta_i), 0.0f, cos_theta_i);
  DielectricLobe lobe;
  lobe.build(MicrofacetLobeParams::make(kMultiGgx, roughness, 0.0f), eta, false, true);
  const Frame frame = Frame::from_normal(normalize(axis));
  double sum = 0.0;
  for (int a = 0; a < n; ++a) {
    const double t = (a + 0.5) / n, theta = M_PI * t * t, jac = std::sin(theta) * 2 * M_PI * t;
    for (int b = 0; b < 2 * n; ++b) {
      const double phi = M_PI * (b + 0.5) / n;
      const Vec3 wo = normalize(frame.to_world(Vec3(float(std::sin(theta) * std::cos(phi)),
                                                    float(std::sin(theta) * std::sin(phi)), float(std::cos(theta)))));
      const double g = wo.z < 0.0f ? double(lobe.eval_local(wi, wo, eta).f_cos.x) : 0.0;
      sum += h(wo, g) * jac;
    }
  }
  return sum * (1.0 / n) * (M_PI / n);
}

TEST(FrostedSgFit, ErrorEstimatorMatchesQuadrature) {
  struct Case {
    float cos_i, eta, roughness;
  };
  for (const Case c : {Case{1.0f, 1.5f, 1.0f}, Case{0.7f, 1.33f, 0.7f}, Case{0.9f, 1.0f / 1.5f, 0.8f}}) {
    const SphericalGaussian sg = fit_transmission_lobe(c.cos_i, c.eta, c.roughness).sg(c.cos_i, c.eta);
    auto brute = [&](const SphericalGaussian &g) {
      const double diff = quadrature(c.cos_i, c.eta, c.roughness, sg.axis, 600, [&](const Vec3 &w, double f) {
        return (g.eval(w) - f) * (g.eval(w) - f);
      });
      const double norm =
          quadrature(c.cos_i, c.eta, c.roughness, sg.axis, 600, [](const Vec3 &, double f) { return f * f; });
      return std::sqrt(diff / norm);
    };
    const double estimated = transmission_fit_error(c.cos_i, c.eta, c.roughness, sg);
    const double reference = brute(sg);
    EXPECT_NEAR(estimated, reference, 0.01 + 0.02 * reference) << c.cos_i << " " << c.eta << " " << c.roughness;
    // Negative control: the same SG aimed 15 degrees off.
    SphericalGaussian off = sg;
    const double t = 15 * kDeg;
    off.axis = normalize(Vec3(float(sg.axis.x * std::cos(t) - sg.axis.z * std::sin(t)), 0.0f,
                              float(sg.axis.x * std::sin(t) + sg.axis.z * std::cos(t))));
    const double off_est = transmission_fit_error(c.cos_i, c.eta, c.roughness, off);
    EXPECT_NEAR(off_est, brute(off), 0.01 + 0.02 * off_est);
    EXPECT_GT(off_est, reference + 0.1);
    std::printf("[sg estimator] cos_i=%.2f eta=%.3f r=%.2f: estimated %.4f, quadrature %.4f; 15-degree-off SG %.4f\n",
                c.cos_i, c.eta, c.roughness, estimated, reference, off_est);
  }
}

TEST(FrostedSgFit, MomentsMatchTheBtdf) {
  // Energy and mean direction of the fitted SG vs an independent quadrature of eval(); the moment
  // fit's kappa matches the mean length (the L2 fit keeps energy and axis, changes kappa only).
  // 128^2 samples: this checks the recipe; the table's 48^2 is checked against direct fits below.
  for (float r : {0.3f, 0.6f, 1.0f})
    for (float eta : {1.33f, 2.4f, 1.0f / 1.5f})
      for (float cos_i : {1.0f, 0.6f}) {
        const SphericalGaussian sg =
            fit_transmission_lobe(cos_i, eta, r, 128, SharpnessFit::kMoments).sg(cos_i, eta);
        const double e = quadrature(cos_i, eta, r, sg.axis, 600, [](const Vec3 &, double f) { return f; });
        const double mx = quadrature(cos_i, eta, r, sg.axis, 600, [](const Vec3 &w, double f) { return f * w.x; });
        const double mz = quadrature(cos_i, eta, r, sg.axis, 600, [](const Vec3 &w, double f) { return f * w.z; });
        EXPECT_NEAR(sg.integral(), e, 2e-3 + 5e-3 * e) << "r=" << r << " eta=" << eta << " cos_i=" << cos_i;
        const double len = std::sqrt(mx * mx + mz * mz);
        const double angle = std::acos(std::clamp((sg.axis.x * mx + sg.axis.z * mz) / len, -1.0, 1.0));
        EXPECT_LT(angle, 0.5 * kDeg) << "r=" << r << " eta=" << eta << " cos_i=" << cos_i;
        // vMF: |mean| = coth(kappa) - 1/kappa.
        const double k = sg.sharpness;
        EXPECT_NEAR(1.0 / std::tanh(k) - 1.0 / k, len / e, 2e-3) << "r=" << r << " eta=" << eta << " cos_i=" << cos_i;
      }
}

TEST(FrostedSgFit, FitErrorOverTheRange) {
  std::vector<float> thetas;
  for (int d = 0; d <= 80; d += 10) thetas.push_back(float(d));
  for (float d : {85.0f, 89.0f}) thetas.push_back(d);
  const float roughs[] = {0.05f, 0.1f, 0.2f, 0.4f, 0.7f, 1.0f};
  const float iors[] = {1.33f, 1.5f, 1.7f, 2.0f, 2.4f};
  struct Point {
    float theta, r, eta;
    double err = 0.0, err_moments = 0.0, energy = 0.0;
  };
  std::vector<Point> pts;
  for (float t : thetas)
    for (float r : roughs)
      for (float ior : iors)
        for (float eta : {ior, 1.0f / ior}) pts.push_back({t, r, eta});
  tbb::parallel_for(size_t(0), pts.size(), [&](size_t i) {
    Point &p = pts[i];
    const float c = float(std::cos(p.theta * kDeg));
    const TransmissionLobe lobe = fit_transmission_lobe(c, p.eta, p.r, kFitStrata, SharpnessFit::kL2);
    p.energy = lobe.energy;
    p.err = transmission_fit_error(c, p.eta, p.r, lobe.sg(c, p.eta));
    const TransmissionLobe moments = fit_transmission_lobe(c, p.eta, p.r, kFitStrata, SharpnessFit::kMoments);
    p.err_moments = transmission_fit_error(c, p.eta, p.r, moments.sg(c, p.eta));
  });
  for (int side = 0; side < 2; ++side) {
    std::vector<double> errs, moments;
    double weighted = 0.0, weight = 0.0, moments_mean = 0.0;
    for (const Point &p : pts)
      if ((p.eta > 1.0f) == (side == 0) && p.energy > 1e-3) {
        ASSERT_TRUE(std::isfinite(p.err));
        moments_mean += p.err_moments;
        moments.push_back(p.err_moments);
        errs.push_back(p.err);
        weighted += p.err * p.energy;
        weight += p.energy;
      }
    std::sort(errs.begin(), errs.end());
    std::sort(moments.begin(), moments.end());
    std::printf("[sg fit error, L2 kappa] %s (eta %s): %zu lobes with energy > 1e-3: relative L2 median %.3f, mean %.3f, "
                "energy-weighted mean %.3f, 90th pct %.3f, max %.3f\n",
                side == 0 ? "entering" : "leaving", side == 0 ? "1.33..2.4" : "1/2.4..1/1.33", errs.size(),
                errs[errs.size() / 2], std::accumulate(errs.begin(), errs.end(), 0.0) / errs.size(), weighted / weight,
                errs[errs.size() * 9 / 10], errs.back());
    std::printf("    (the variance-matched kappa of the paper's recipe, which the table stores: relative L2 median %.3f, "
                "mean %.3f, max %.3f)\n",
                moments[moments.size() / 2], moments_mean / errs.size(), moments.back());
    // The L2 kappa must beat the variance match it starts from.
    EXPECT_LT(std::accumulate(errs.begin(), errs.end(), 0.0), moments_mean);
    for (float r : roughs) {
      double m = 0.0;
      int n = 0;
      for (const Point &p : pts)
        if ((p.eta > 1.0f) == (side == 0) && p.r == r && p.energy > 1e-3) m += p.err, ++n;
      std::printf("    roughness %.2f: mean relative L2 %.3f over %d lobes\n", r, n ? m / n : 0.0, n);
    }
  }
}

// Issue 12 acceptance: <= 1 %, met since fit version 10 (enabled). History
// (moment fits, 48^2 samples per node), at the entering table's cell centres
// (theta, roughness, ior):
//  - axis stored as an angle offset from the Snell angle on both sides (grid
//    61 x 25 x 14 x 2): 2338 of 6254 points above 1 %, mean relative L2 0.080;
//  - leaving side tabulated over the Snell sine with the axis as a sine offset
//    (frosted_sg_table.h): 2060 above 1 % (498 entering, mostly theta >= 80
//    deg; 1562 leaving), mean 0.049;
//  - plus the fit's lobe-edge refinement and Catmull-Rom lookups: 1062 of 6354
//    above 1 % (89 entering, at theta >= 80 deg and roughness ~0.1; 973
//    leaving, nearly all past the onset of TIR, ior sin(theta_i) > 1), mean
//    0.035;
//  - plus the sine's upper segment ending at grazing for each ior (no node
//    clamped to 89.5 deg, whose kink moved with ior): 896 (89 entering, 807
//    leaving), mean 0.032.
//  - plus the leaving side's upper segment (past the TIR onset) over theta_i
//    instead of the sine (which is flat at grazing), ln(E + 1e-4) interpolated
//    instead of E, and the leaving fit's tail row always refined: 575 of 6411
//    (89 entering, 486 leaving), mean 0.0058.
//  - fit version 6, the fit's grid warped toward GGX's slope tail
//    (u2 = 1 - (1 - v)^3): 123 of 6405 (46 entering at theta >= 80 deg,
//    roughness <= 0.125; 73 leaving at grazing, energy), mean 0.0020;
//  - 7: entering nodes crowding toward grazing (71), the leaving upper segment
//    crowding at both ends, the first coordinate mirrored at normal incidence:
//    8 of 6659, mean 0.0008, max 0.0203;
//  - 8: quadrature directions and the SG algebra in double (a float |axis| =
//    1 +- 6e-8 moved the L2 metric by ~1 % at kappa ~1e5), the upper segment
//    s = t^2 + 2 t^3 - 2 t^4: 2 of 6659, mean 0.0007, max 0.0165;
//  - 9: edge cells refined 16 x 16 instead of 8 x 8 (the moment kappa of
//    roughness ~0.05 jittered by ~0.03 in ln kappa from one roughness to the
//    next): 2 of 6659 above 1 % (leaving, roughness 0.21, ior 1.85, theta 81
//    and 85 deg, lobes of energy 0.0011-0.0012: 1.08 % and 1.01 %), mean
//    0.0006, max 0.0108. Still disabled: 2 points above;
//  - 10: 3 x 3 Gauss-Legendre points in the cells inside the lobe (one
//    midpoint before: the direct fit of those small lobes zig-zagged by ~0.01
//    in ln E from one roughness to the next, the quadrature aliasing with the
//    slope tail's shape): 0 of 6658 above 1 %, median 0.00018, mean 0.0004,
//    max 0.0067; nearest-node control max 113.
TEST(FrostedSgTable, InterpolationWithinOnePercent) {
  // The suite's table (built once by TableWarmUp below, loaded here; load() re-fits 16 nodes to check it).
  const TransmissionSgTable &table = TransmissionSgTable::get(host::default_host_services());
  // Cell centres in all three coordinates inside theta 0..89, roughness 0.05..1, IOR 1.33..2.4.
  struct Point {
    float theta, r, ior;
    int side;
    double err = 0.0, nearest_err = 0.0, energy = 0.0;
    double err_energy = 0.0, err_sharpness = 0.0, err_axis = 0.0;  // one parameter interpolated
  };
  std::vector<Point> pts;
  for (int i = 0; i + 1 < TransmissionSgTable::kThetaNodes; i += 2)
    for (int j = 0; j + 1 < TransmissionSgTable::kRoughnessNodes; j += 2)
      for (int k = 0; k + 1 < TransmissionSgTable::kIorNodes; ++k)
        for (int side = 0; side < 2; ++side) {
          Point p;
          p.theta = 0.5f * (TransmissionSgTable::theta_at(i) + TransmissionSgTable::theta_at(i + 1));
          p.r = std::sqrt(TransmissionSgTable::roughness_at(j) * TransmissionSgTable::roughness_at(j + 1));
          p.ior = 0.5f * (TransmissionSgTable::ior_at(k) + TransmissionSgTable::ior_at(k + 1));
          p.side = side;
          if (p.theta > 89 * kDeg || p.r < 0.05f || p.ior < 1.33f || p.ior > 2.4f) continue;
          pts.push_back(p);
        }
  tbb::parallel_for(size_t(0), pts.size(), [&](size_t n) {
    Point &p = pts[n];
    const float c = std::cos(p.theta), eta = p.side == 0 ? p.ior : 1.0f / p.ior;
    const TransmissionLobe direct = fit_transmission_lobe(c, eta, p.r);
    TransmissionLobe interp;
    ASSERT_TRUE(table.lookup(c, eta, p.r, interp));
    p.energy = direct.energy;
    const SphericalGaussian ref = direct.sg(c, eta);
    p.err = sg_relative_l2(interp.sg(c, eta), ref);
    // Which parameter fails: the direct fit with one interpolated parameter substituted.
    auto with = [&](float TransmissionLobe::*field) {
      TransmissionLobe one = direct;
      one.*field = interp.*field;
      return sg_relative_l2(one.sg(c, eta), ref);
    };
    p.err_energy = with(&TransmissionLobe::energy);
    p.err_sharpness = with(&TransmissionLobe::log_sharpness);
    p.err_axis = with(&TransmissionLobe::axis_offset);
    // Negative control: the lobe of the nearest node in every coordinate (the lookup at a grid point).
    int i = 0;
    for (int n = 1; n < TransmissionSgTable::kThetaNodes; ++n)
      if (std::fabs(TransmissionSgTable::theta_at(n) - p.theta) < std::fabs(TransmissionSgTable::theta_at(i) - p.theta))
        i = n;
    const float c_node = std::cos(TransmissionSgTable::theta_at(i));
    TransmissionLobe nearest;
    ASSERT_TRUE(table.lookup(c_node, eta, p.r, nearest));
    p.nearest_err = sg_relative_l2(nearest.sg(c, eta), ref);
  });
  double worst = 0.0, worst_nearest = 0.0, mean = 0.0;
  long counted = 0;
  std::vector<double> errs;
  for (const Point &p : pts) {
    if (p.energy < 1e-3) continue;  // total internal reflection: no lobe to interpolate
    EXPECT_LE(p.err, 0.01) << "theta=" << p.theta / kDeg << " r=" << p.r << " ior=" << p.ior << " side=" << p.side
                           << " energy=" << p.energy << "; interpolated alone: energy " << p.err_energy
                           << ", sharpness " << p.err_sharpness << ", axis " << p.err_axis;
    worst = std::max(worst, p.err);
    worst_nearest = std::max(worst_nearest, p.nearest_err);
    mean += p.err;
    errs.push_back(p.err);
    ++counted;
  }
  EXPECT_GT(worst_nearest, 0.01);
  std::sort(errs.begin(), errs.end());
  std::printf("[sg table] %ld off-grid points (cell centres, energy > 1e-3): interpolated vs direct fit relative L2 "
              "median %.5f, mean %.4f, max %.4f; nearest-theta-node control max %.4f\n",
              counted, errs.empty() ? 0.0 : errs[errs.size() / 2], mean / std::max(counted, 1L), worst, worst_nearest);
}

}  // namespace

namespace {

using namespace glimmer;
using namespace glimmer::plugin::frosted;

// ---- The suite's table: built once, before every test that needs it ------------
// ctest runs this first (tests/CMakeLists.txt: fixture glimmer_tables, its own long timeout); every closure,
// bridge and frosted addon test requires the fixture and then loads the table from the cache instead of fitting
// it again (13 min on the loaded 2-core machine: two test processes fitting it at once each ran past their
// 900 s timeout, and every later test started over). Fails when the cache is not written or does not load back
// equal to the table in memory.
TEST(TableWarmUp, FrostedSgTableIsCachedForTheSuite) {
  const GlimmerHostServices *services = host::default_host_services();
  ASSERT_NE(services->cache_dir, nullptr);
  ASSERT_NE(services->cache_dir[0], '\0') << "no cache folder: every test would fit the SG table again";
  const TransmissionSgTable &table = TransmissionSgTable::get(services);
  std::string problem;
  auto loaded = TransmissionSgTable::load(TransmissionSgTable::cache_path(services->cache_dir), problem);
  ASSERT_TRUE(loaded) << problem;
  EXPECT_TRUE(*loaded == table);
}

// The table's fit is bit-identical for any thread count: 106 nodes spread over both sides, every roughness and
// ior, fitted on 1 and on 3 threads, equal bit for bit to each other and to the suite's table (built by
// TableWarmUp on one thread per core, dynamic chunks, and loaded from the cache here). Control: the nodes are
// not all alike (the comparison would pass on a constant), and a reversed index list gives the reversed fits.
// lookup_energies (the sg exit energies of a segment's bounding rays, seventeenth session) is lookup()'s energy bit
// for bit, with the same coverage: both sides (entering / leaving), roughness and IOR inside and outside the grid,
// incidences from normal to beyond the grid's last angle, batches of 1..8.
TEST(FrostedSgTable, BatchedEnergiesAreTheLookupsEnergies) {
  const TransmissionSgTable &table = TransmissionSgTable::get(host::default_host_services());
  Pcg32 rng(41);
  long compared = 0, differing = 0, valid = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    const float ior = 1.1f + 1.5f * rng.next_float();  // 1.1..2.6: outside the grid at both ends
    const float eta = (trial & 1) ? 1.0f / ior : ior;
    const float roughness = (trial % 7 == 0) ? 0.001f : 1.05f * rng.next_float();
    const int n = 1 + int(rng.next_u32() % TransmissionSgTable::kMaxEnergyBatch);
    float cos_i[TransmissionSgTable::kMaxEnergyBatch], energy[TransmissionSgTable::kMaxEnergyBatch];
    bool ok[TransmissionSgTable::kMaxEnergyBatch];
    for (int i = 0; i < n; ++i) cos_i[i] = (trial % 5 == 0) ? 1e-4f * rng.next_float() : rng.next_float();
    table.lookup_energies(cos_i, n, eta, roughness, energy, ok);
    for (int i = 0; i < n; ++i) {
      TransmissionLobe lobe;
      const bool expected = table.lookup(cos_i[i], eta, roughness, lobe);
      ++compared;
      valid += expected;
      if (ok[i] != expected || (expected && std::memcmp(&energy[i], &lobe.energy, sizeof(float)) != 0)) ++differing;
    }
  }
  std::printf("[frosted sg table] batched energies: %ld compared (%ld covered), %ld differ from lookup()\n", compared,
              valid, differing);
  EXPECT_EQ(differing, 0);
  EXPECT_GT(valid, compared / 3);
  EXPECT_LT(valid, compared);  // the uncovered cases were exercised too
}

// lookup() sums its 64 taps as one 4-lane product and sum (twenty-first session); lookup_scalar is the three scalar
// sums it replaced. Bit for bit equal over the coverage of BatchedEnergiesAreTheLookupsEnergies. Control: the
// comparison is not vacuous (lookups with a nonzero axis offset and different values were compared), and a lookup
// one roughness ulp away differs somewhere.
TEST(FrostedSgTable, LookupIsTheScalarTapSumBitForBit) {
  const TransmissionSgTable &table = TransmissionSgTable::get(host::default_host_services());
  Pcg32 rng(43);
  long compared = 0, differing = 0, valid = 0, offset_nonzero = 0, neighbour_differs = 0;
  for (int trial = 0; trial < 40000; ++trial) {
    const float ior = 1.1f + 1.5f * rng.next_float();
    const float eta = (trial & 1) ? 1.0f / ior : ior;
    const float roughness = (trial % 7 == 0) ? 0.001f : 1.05f * rng.next_float();
    const float cos_i = (trial % 5 == 0) ? 1e-4f * rng.next_float() : rng.next_float();
    TransmissionLobe packed, scalar;
    const bool ok = table.lookup(cos_i, eta, roughness, packed), expected = table.lookup_scalar(cos_i, eta, roughness, scalar);
    ++compared;
    valid += expected;
    if (ok != expected || (expected && (std::memcmp(&packed.energy, &scalar.energy, sizeof(float)) != 0 ||
                                        std::memcmp(&packed.log_sharpness, &scalar.log_sharpness, sizeof(float)) != 0 ||
                                        std::memcmp(&packed.axis_offset, &scalar.axis_offset, sizeof(float)) != 0)))
      ++differing;
    if (!expected) continue;
    offset_nonzero += scalar.axis_offset != 0.0f;
    TransmissionLobe near;
    if (table.lookup(cos_i, eta, std::nextafter(roughness, 2.0f), near))
      neighbour_differs += near.energy != scalar.energy || near.log_sharpness != scalar.log_sharpness ||
                           near.axis_offset != scalar.axis_offset;
  }
  std::printf("[frosted sg table] packed lookup: %ld compared (%ld covered, %ld with an axis offset), %ld differ from "
              "the scalar sums; a roughness ulp away: %ld differ\n",
              compared, valid, offset_nonzero, differing, neighbour_differs);
  EXPECT_EQ(differing, 0);
  EXPECT_GT(valid, compared / 3);
  EXPECT_LT(valid, compared);
  EXPECT_GT(offset_nonzero, valid / 2);
  EXPECT_GT(neighbour_differs, valid / 10);
}

TEST(FrostedSgTable, FitIsBitIdenticalForAnyThreadCount) {
  const TransmissionSgTable &table = TransmissionSgTable::get(host::default_host_services());
  std::vector<size_t> indices;
  for (size_t idx = 7; idx < TransmissionSgTable::node_count(); idx += 503) indices.push_back(idx);
  ASSERT_EQ(indices.size(), 106u);
  const std::vector<TransmissionLobe> one = TransmissionSgTable::fit_nodes(indices, 1);
  const std::vector<TransmissionLobe> three = TransmissionSgTable::fit_nodes(indices, 3);
  std::vector<size_t> reversed(indices.rbegin(), indices.rend());
  const std::vector<TransmissionLobe> back = TransmissionSgTable::fit_nodes(reversed, 2);
  auto same_bits = [](const TransmissionLobe &a, const TransmissionLobe &b) {
    return std::memcmp(&a.energy, &b.energy, sizeof(float)) == 0 &&
           std::memcmp(&a.log_sharpness, &b.log_sharpness, sizeof(float)) == 0 &&
           std::memcmp(&a.axis_offset, &b.axis_offset, sizeof(float)) == 0;
  };
  std::set<float> energies, sharpness;
  for (size_t n = 0; n < indices.size(); ++n) {
    EXPECT_TRUE(same_bits(one[n], three[n])) << "node " << indices[n] << ": 1 vs 3 threads";
    EXPECT_TRUE(same_bits(one[n], table.node_at(indices[n]))) << "node " << indices[n] << ": vs the suite's table";
    EXPECT_TRUE(same_bits(one[n], back[indices.size() - 1 - n])) << "node " << indices[n] << ": reversed list";
    energies.insert(one[n].energy);
    sharpness.insert(one[n].log_sharpness);
  }
  EXPECT_GT(energies.size(), indices.size() / 2);
  EXPECT_GT(sharpness.size(), indices.size() / 2);
}

// ---- Disk cache: round trip, corruption, crafted entries ------------------------
TEST(FrostedSgTable, DiskCacheRoundTripAndValidation) {
  const auto dir = std::filesystem::temp_directory_path() / ("glimmer_frosted_sg_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  const std::string path = TransmissionSgTable::cache_path(dir.string());
  const TransmissionSgTable &built = TransmissionSgTable::get(host::default_host_services());
  ASSERT_EQ(built.save(path), "");
  std::string problem;
  auto loaded = TransmissionSgTable::load(path, problem);
  ASSERT_TRUE(loaded) << problem;
  EXPECT_TRUE(loaded->loaded_from_cache());
  EXPECT_TRUE(*loaded == built);  // bit for bit

  std::ifstream in(path, std::ios::binary);
  const std::vector<unsigned char> good((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  auto write = [&](const std::vector<unsigned char> &bytes) {
    std::ofstream(path, std::ios::binary | std::ios::trunc).write(reinterpret_cast<const char *>(bytes.data()),
                                                                   std::streamsize(bytes.size()));
  };
  // One flipped bit in a node: refused by the MAC.
  std::vector<unsigned char> bad = good;
  bad[bad.size() / 2] ^= 1u;
  write(bad);
  EXPECT_FALSE(TransmissionSgTable::load(path, problem));
  EXPECT_NE(problem.find("MAC"), std::string::npos) << problem;
  // Truncated.
  write(std::vector<unsigned char>(good.begin(), good.begin() + good.size() / 3));
  EXPECT_FALSE(TransmissionSgTable::load(path, problem));
  // Entries with a valid MAC (as a writer holding the key would make them) but wrong contents:
  const std::vector<unsigned char> payload(good.begin(), good.end() - 32);
  const size_t header = 8 + 4 + 8 + 8;
  auto crafted = [&](size_t node, int field, float value) {
    std::vector<unsigned char> p = payload;
    std::memcpy(p.data() + header + (node * 3 + field) * 4, &value, 4);
    EXPECT_EQ(write_cache_blob(path, p), "");
    return TransmissionSgTable::load(path, problem);
  };
  EXPECT_FALSE(crafted(7, 0, std::numeric_limits<float>::quiet_NaN()));
  EXPECT_NE(problem.find("non-finite"), std::string::npos) << problem;
  EXPECT_FALSE(crafted(7, 0, 3.0f));
  EXPECT_NE(problem.find("out-of-range"), std::string::npos) << problem;
  // A plausible but wrong value at a node the loader re-fits (check node 0: first 5, roughness 3, ior 1).
  const size_t check = (size_t(5) * TransmissionSgTable::kRoughnessNodes + 3) * TransmissionSgTable::kIorNodes + 1;
  float e;
  std::memcpy(&e, payload.data() + header + check * 12, 4);
  EXPECT_FALSE(crafted(check, 0, e * 0.99f));
  EXPECT_NE(problem.find("differs from its fit"), std::string::npos) << problem;
  // Another grid or fit version: the header key differs.
  std::vector<unsigned char> other = payload;
  other[12] ^= 0xffu;  // a byte of the key
  EXPECT_EQ(write_cache_blob(path, other), "");
  EXPECT_FALSE(TransmissionSgTable::load(path, problem));
  EXPECT_NE(problem.find("bad header"), std::string::npos) << problem;
  // The untouched entry loads again.
  write(good);
  EXPECT_TRUE(TransmissionSgTable::load(path, problem)) << problem;
  std::printf("[sg table cache] %zu bytes; bit flip, truncation, NaN, out-of-range, a re-fitted node off by 1 %% "
              "and a foreign key all refused\n", good.size());
  std::filesystem::remove_all(dir);
}

// Session 32 (frostedtime32): the check nodes' stamp. The first load of an entry re-fits the 16 check nodes and writes
// <entry>.checked; the next load by the same build skips the re-fits and gives the same table bit for bit. Negative
// controls, each of which must re-fit again: a load as another build (another build id; since session 39 it then
// joins the stamp's list), the stamp with a flipped MAC bit, no build id (the stamp is never trusted); and a crafted
// entry (valid MAC, a check node off by 1 %) next to the good entry's stamp is still refused ("differs from its fit":
// the stamp binds the entry's bytes). The stamp's own rules: test_checked_stamp.cpp.
TEST(FrostedSgTable, CheckedStampSkipsTheRefitsOfTheSameBuildAndBytes) {
  const auto dir = std::filesystem::temp_directory_path() / ("glimmer_frosted_stamp_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  const std::string path = TransmissionSgTable::cache_path(dir.string());
  const TransmissionSgTable &built = TransmissionSgTable::get(host::default_host_services());
  ASSERT_EQ(built.save(path), "");
  const std::string &id = TransmissionSgTable::build_id();
  ASSERT_FALSE(id.empty()) << "no GNU build id in the plugin: the stamp is never used";
  std::string problem;
  auto first = TransmissionSgTable::load(path, problem);
  ASSERT_TRUE(first) << problem;
  EXPECT_TRUE(first->refitted_check_nodes());
  EXPECT_TRUE(std::filesystem::exists(TransmissionSgTable::stamp_path(path)));
  auto second = TransmissionSgTable::load(path, problem);
  ASSERT_TRUE(second) << problem;
  EXPECT_FALSE(second->refitted_check_nodes());
  EXPECT_TRUE(*second == built);  // bit for bit
  // Controls: another build, no build id.
  auto other_build = TransmissionSgTable::load(path, problem, id + "00");
  ASSERT_TRUE(other_build) << problem;
  EXPECT_TRUE(other_build->refitted_check_nodes());
  auto no_id = TransmissionSgTable::load(path, problem, "");
  ASSERT_TRUE(no_id) << problem;
  EXPECT_TRUE(no_id->refitted_check_nodes());
  // (The stamp lists both builds since session 39: this build still skips, and so does the other one.)
  auto again = TransmissionSgTable::load(path, problem);
  ASSERT_TRUE(again) << problem;
  EXPECT_FALSE(again->refitted_check_nodes());
  auto other_again = TransmissionSgTable::load(path, problem, id + "00");
  ASSERT_TRUE(other_again) << problem;
  EXPECT_FALSE(other_again->refitted_check_nodes());
  // A flipped bit in the stamp's MAC (its last byte: the payload intact, so only the MAC check can refuse it).
  const std::string stamp = TransmissionSgTable::stamp_path(path);
  std::ifstream in_stamp(stamp, std::ios::binary);
  std::vector<unsigned char> stamp_bytes((std::istreambuf_iterator<char>(in_stamp)), std::istreambuf_iterator<char>());
  in_stamp.close();
  ASSERT_GT(stamp_bytes.size(), 40u);
  std::vector<unsigned char> flipped = stamp_bytes;
  flipped.back() ^= 1u;
  std::ofstream(stamp, std::ios::binary | std::ios::trunc)
      .write(reinterpret_cast<const char *>(flipped.data()), std::streamsize(flipped.size()));
  auto after_flip = TransmissionSgTable::load(path, problem);
  ASSERT_TRUE(after_flip) << problem;
  EXPECT_TRUE(after_flip->refitted_check_nodes());
  // A crafted entry (valid MAC, check node 0's energy off by 1 %) beside the good entry's stamp: refused.
  std::ifstream in(path, std::ios::binary);
  const std::vector<unsigned char> good((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  in.close();
  ASSERT_FALSE(TransmissionSgTable::load(path, problem)->refitted_check_nodes());  // the good entry is stamped
  std::vector<unsigned char> payload(good.begin(), good.end() - 32);
  const size_t header = 8 + 4 + 8 + 8;
  const size_t check = (size_t(5) * TransmissionSgTable::kRoughnessNodes + 3) * TransmissionSgTable::kIorNodes + 1;
  float e;
  std::memcpy(&e, payload.data() + header + check * 12, 4);
  e *= 0.99f;
  std::memcpy(payload.data() + header + check * 12, &e, 4);
  ASSERT_EQ(write_cache_blob(path, payload), "");
  EXPECT_FALSE(TransmissionSgTable::load(path, problem));
  EXPECT_NE(problem.find("differs from its fit"), std::string::npos) << problem;
  std::printf("[sg table cache] stamp: build %s; the second load skips the re-fits; another build, no build id, a "
              "flipped bit all re-fit; a crafted entry beside the stamp refused (%s)\n",
              id.c_str(), problem.c_str());
  std::filesystem::remove_all(dir);
}

// A cache folder that takes no more bytes (RLIMIT_FSIZE: a full disk or quota, also for root): the load still
// succeeds, re-fits its check nodes, writes no stamp and reports why in stamp_not_written() (which get(), the
// process-wide table, logs as a warning; get() runs once per process, so the log line itself is checked only for the
// glint table: GlintCacheHostile.UnwritableStampIsLoggedAndTheCheckRunsAgain); once writable, the next load stamps
// and the one after skips the re-fits.
TEST(FrostedSgTable, UnwritableStampIsReportedAndTheRefitsRunAgain) {
  const auto dir = std::filesystem::temp_directory_path() / ("glimmer_frosted_nostamp_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  const std::string path = TransmissionSgTable::cache_path(dir.string());
  ASSERT_EQ(TransmissionSgTable::get(host::default_host_services()).save(path), "");
  const std::string stamp = TransmissionSgTable::stamp_path(path);
  std::string problem;
  for (int attempt = 0; attempt < 2; ++attempt) {
    const test::FileSizeLimit limit(16);
    ASSERT_TRUE(limit.ok());
    const auto table = TransmissionSgTable::load(path, problem);
    ASSERT_TRUE(table) << problem;
    EXPECT_TRUE(table->refitted_check_nodes()) << "attempt " << attempt;
    EXPECT_NE(table->stamp_not_written().find("File too large"), std::string::npos) << table->stamp_not_written();
    EXPECT_FALSE(std::filesystem::exists(stamp));
  }
  const auto writable = TransmissionSgTable::load(path, problem);
  ASSERT_TRUE(writable) << problem;
  EXPECT_TRUE(writable->refitted_check_nodes());
  EXPECT_EQ(writable->stamp_not_written(), "");
  const auto stamped = TransmissionSgTable::load(path, problem);
  ASSERT_TRUE(stamped) << problem;
  EXPECT_FALSE(stamped->refitted_check_nodes());
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir), std::filesystem::directory_iterator()), 3)
      << "entry, key, stamp: a temporary file was left behind";
  std::printf("[sg table cache] unwritable folder: the stamp not written (refits every load), stamped once writable\n");
  std::filesystem::remove_all(dir);
}

}  // namespace

