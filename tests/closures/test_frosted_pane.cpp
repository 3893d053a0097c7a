// frosted_glass interior absorption (Beer) and thin panes (issue 12), through
// the plugin's C ABI:
//  - a brute-force path tracer through a slab (two infinite parallel planes
//    z = 0 and z = -L, outward normals +z / -z) with the SOLID closure at every
//    interface and a host whose trace_ray intersects the two planes: this is
//    how the renderer meets a real slab mesh (Beer length by tracing back);
//  - the slab's transmittance at normal incidence, roughness 1e-3 (smooth),
//    against the closed form (1-R)^2 tau / (1 - R^2 tau^2), tau = c^(L/d), for
//    the solid slab and the thin pane; negative control: the single-pass form
//    (1-R)^2 tau is rejected (the reference sees the interreflections);
//  - rough (0.5) oblique incidence: the thin pane's R and T per channel vs the
//    brute-force slab; negative control: a host returning the vertical depth
//    instead of the path length inside (a known bug) is rejected;
//  - thin pane: white furnace, the distribution of sample() vs the brute-force
//    slab's exit directions (two-sample chi2), and eval() = the front
//    reflection alone (0 on the far side; integrated over the sphere against
//    the non-singular samples' weight and fraction; the walk singular);
//  - thin pane reciprocity: the flux between two cones of directions is the same both ways, up to the multi_ggx
//    compensation's known factor E(mu_i) (negative control: without that factor it is rejected).
#include <gtest/gtest.h>
#include <tbb/parallel_for.h>

#include <array>
#include <cstdio>
#include <numeric>

#include "closures/frosted_glass.h"
#include "closures/microfacet_test_util.h"
#include "core/dielectric_lobe.h"

namespace {

using namespace glimmer;
using glimmer::mftest::make_closure;

std::string num(float v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.7g", double(v));
  return b;
}

// ---- A slab as the renderer would present it ---------------------------------
struct SlabHost {
  float thickness = 1.0f;
  bool vertical_depth_bug = false;  // negative control: report the depth, not the distance along the ray
  GlimmerHostServices services{};

  explicit SlabHost(float L, bool bug = false) : thickness(L), vertical_depth_bug(bug) {
    services.struct_size = sizeof(GlimmerHostServices);
    services.abi_version = GLIMMER_ABI_VERSION;
    services.host_data = this;
    services.trace_ray = &trace;
    services.log = [](void *, int, const char *) {};
  }
  static int trace(void *data, const GlimmerRay *ray, GlimmerRayHit *hit) {
    const auto *self = static_cast<const SlabHost *>(data);
    const Vec3 o(ray->origin), d(ray->direction);
    float best = ray->t_max;
    for (float plane : {0.0f, -self->thickness}) {
      if (d.z == 0.0f) continue;
      const float t = (plane - o.z) / d.z;
      if (t > ray->t_min && t < best) best = t;
    }
    if (!(best < ray->t_max)) return 0;
    hit->t = self->vertical_depth_bug ? best * std::fabs(d.z) : best;
    hit->P = o + d * best;
    hit->N = hit->Ng = Vec3(0.0f, 0.0f, (o + d * best).z > -0.5f * self->thickness ? 1.0f : -1.0f);
    return 1;
  }
};

// Shading context at one of the slab's interfaces (position-free: x = y = 0),
// as the renderer builds it: N toward wi, backfacing when wi is inside the slab.
GlimmerShadingContext slab_context(const Vec3 &wi, bool bottom, float L, const GlimmerHostServices *host) {
  GlimmerShadingContext ctx = host::make_local_context(wi, host);
  ctx.P = Vec3(0.0f, 0.0f, bottom ? -L : 0.0f);
  const Vec3 outward(0.0f, 0.0f, bottom ? -1.0f : 1.0f);
  ctx.backfacing = dot(wi, outward) < 0.0f ? 1u : 0u;
  ctx.N = ctx.Ng = ctx.backfacing ? -outward : outward;
  return ctx;
}

struct Exit {
  Vec3 w;
  double weight = 0.0;  // the path's or sample's weight, channel 0
};

struct SlabResult {
  Spectrum R{0.0f}, T{0.0f};
  double se_R = 0.0, se_T = 0.0;  // standard errors, channel 0
  std::vector<Exit> exits;        // exit directions and weights (when kept)
};

// Mean and standard error of a flux from its sums over m samples.
std::pair<double, double> mean_se(double sum, double sum2, double m) {
  const double mean = sum / m;
  return {mean, std::sqrt(std::max(0.0, sum2 / m - mean * mean) / m)};
}

// Per-channel mean of the weights over paths, their channel-0 standard errors.
struct Tally {
  double sum[2][3] = {{0, 0, 0}, {0, 0, 0}}, sum2[2] = {0, 0};
  void add(int side, const Spectrum &w) {
    for (int ch = 0; ch < 3; ++ch) sum[side][ch] += w[ch];
    sum2[side] += double(w.x) * w.x;
  }
  void merge(const Tally &o) {
    for (int s = 0; s < 2; ++s) {
      for (int ch = 0; ch < 3; ++ch) sum[s][ch] += o.sum[s][ch];
      sum2[s] += o.sum2[s];
    }
  }
  void finish(long n, SlabResult &r) const {
    r.R = Spectrum(float(sum[0][0] / n), float(sum[0][1] / n), float(sum[0][2] / n));
    r.T = Spectrum(float(sum[1][0] / n), float(sum[1][1] / n), float(sum[1][2] / n));
    r.se_R = mean_se(sum[0][0], sum2[0], double(n)).second;
    r.se_T = mean_se(sum[1][0], sum2[1], double(n)).second;
  }
};

constexpr long kBlocks = 64;

// The per-block tallies and exit directions of n paths, merged.
SlabResult gather(const std::vector<Tally> &tallies, const std::vector<std::vector<Exit>> &exits, long n) {
  Tally total;
  SlabResult r;
  for (long b = 0; b < kBlocks; ++b) {
    total.merge(tallies[b]);
    r.exits.insert(r.exits.end(), exits[b].begin(), exits[b].end());
  }
  total.finish(n / kBlocks * kBlocks, r);
  return r;
}

// Brute force: paths through the slab, the solid closure at every interface.
SlabResult trace_slab(const host::ClosureInstance &solid, const SlabHost &slab, const Vec3 &wi, long n, uint64_t seed,
                      bool keep_exits = false) {
  std::vector<Tally> tallies(kBlocks);
  std::vector<std::vector<Exit>> exits(kBlocks);
  tbb::parallel_for(long(0), kBlocks, [&](long b) {
    Pcg32 rng(seed, uint64_t(b) + 1);
    for (long i = 0; i < n / kBlocks; ++i) {
      Vec3 w = wi;
      bool bottom = false;
      Spectrum throughput(1.0f);
      for (int event = 0; event < 256; ++event) {
        const GlimmerShadingContext ctx = slab_context(w, bottom, slab.thickness, &slab.services);
        const float u[3] = {rng.next_float(), rng.next_float(), rng.next_float()};
        GlimmerSample s = glimmer_blank_sample();
        if (solid.sample(ctx, u, s) == GLIMMER_LABEL_NONE) break;
        throughput *= Spectrum(s.eval[0], s.eval[1], s.eval[2]) / s.pdf;
        const Vec3 wo(s.wo);
        const bool out_top = !bottom && wo.z > 0.0f, out_bottom = bottom && wo.z < 0.0f;
        if (out_top || out_bottom) {
          tallies[b].add(out_bottom ? 1 : 0, throughput);
          if (keep_exits) exits[b].push_back({wo, double(throughput.x)});
          break;
        }
        bottom = wo.z < 0.0f;  // crossed the slab to the other interface
        w = -wo;
      }
    }
  });
  return gather(tallies, exits, n);
}

// n draws over kBlocks blocks, each block its own stream (seed, block + 1): the context's path seed and three numbers
// u, then draw(block, ctx, u, exit, weight, side) (false: no sample); the weights tallied by side (1: transmitted).
template <class Draw>
SlabResult draw_pane_samples(const Vec3 &wi, long n, uint64_t seed, bool keep_exits, Draw &&draw) {
  std::vector<Tally> tallies(kBlocks);
  std::vector<std::vector<Exit>> exits(kBlocks);
  tbb::parallel_for(long(0), kBlocks, [&](long b) {
    Pcg32 rng(seed, uint64_t(b) + 1);
    GlimmerShadingContext ctx = host::make_local_context(wi);
    for (long i = 0; i < n / kBlocks; ++i) {
      ctx.path_seed = rng.next_u32();
      const float u[3] = {rng.next_float(), rng.next_float(), rng.next_float()};
      Exit e;
      Spectrum w;
      int side = 0;
      if (!draw(b, ctx, u, e, w, side)) continue;
      tallies[b].add(side, w);
      if (keep_exits) exits[b].push_back(e);
    }
  });
  return gather(tallies, exits, n);
}

// The thin closure's own sample weights, split by side.
SlabResult sample_pane(const host::ClosureInstance &pane, const Vec3 &wi, long n, uint64_t seed,
                       bool keep_exits = false) {
  return draw_pane_samples(wi, n, seed, keep_exits,
                           [&](long, GlimmerShadingContext &ctx, const float *u, Exit &e, Spectrum &w, int &side) {
                             GlimmerSample s = glimmer_blank_sample();
                             const uint32_t label = pane.sample(ctx, u, s);
                             if (label == GLIMMER_LABEL_NONE) return false;
                             w = Spectrum(s.eval[0], s.eval[1], s.eval[2]) / s.pdf;
                             side = (label & GLIMMER_LABEL_TRANSMIT) ? 1 : 0;
                             e = {Vec3(s.wo), double(w.x)};
                             return true;
                           });
}

// Main's (2397f6c's) pane sample at any IOR, test code only: FrostedGlassClosure::pane_sample's steps (the front
// lobe sample; entered: the walk between the faces, pdf 1) with the walk forced to level 0 (kPaneWalkLobe, main's
// walk: the closure's pane_walk<kPaneWalkLobe> test entry, walk_to_exit_at<0>), whatever resampled_walk's rule says.
// The plugin's default code is not touched. Colourless panes only (the tint, 1, is not applied). Returns the exit
// direction (world = the local frame of make_local_context) and the sample's weight (channel 0); false: no sample.
struct MainWalkPane {
  std::unique_ptr<plugin::FrostedGlassClosure> closure;
  plugin::DielectricLobe lobe;
  MainWalkPane(float rough, float ior) {
    const GlimmerParamValue values[] = {
        {"roughness", {rough, 0, 0}, nullptr}, {"ior", {ior, 0, 0}, nullptr}, {"thin", {1.0f, 0, 0}, nullptr}};
    plugin::ParamReader reader(plugin::FrostedGlassClosure::kName, plugin::FrostedGlassClosure::params(), values);
    closure = plugin::FrostedGlassClosure::create(reader);
    lobe = plugin::FrostedGlassClosure::interface_lobe(rough, ior);
  }
  bool sample(const GlimmerShadingContext &ctx, const Vec3 &rand, Exit &out) const {
    const plugin::ShadingPoint sp(&ctx, plugin::FrostedGlassClosure::params(), plugin::LocalFrame::Interface);
    const bool flip = sp.wi.z < 0.0f;
    const Vec3 wi = flip ? microfacet::flip_z_local(sp.wi) : sp.wi;
    plugin::LocalSample s;
    if (!(wi.z > 0.0f) || !lobe.sample(wi, rand, s)) return false;
    Vec3 wo = s.wo;
    Spectrum weight = s.f_cos / s.pdf;
    if (s.label & GLIMMER_LABEL_TRANSMIT) {
      Vec3 d = s.wo;
      if (!closure->pane_walk<plugin::FrostedGlassClosure::kPaneWalkLobe>(sp, rand, d, weight, wo)) return false;
      if (wo.z == 0.0f || !is_finite(weight)) return false;
    }
    out = {sp.frame.to_world(flip ? microfacet::flip_z_local(wo) : wo), double(weight.x)};
    return true;
  }
};

// Main's pane (MainWalkPane) drawn as sample_pane draws the closure (the same numbers for the same seed); mismatch
// (optional): the draws whose direction or weight differ from the closure's own sample() (through the C ABI) with
// the same numbers: 0 where the closure's rule picks main's walk (IOR 1.5), most where it does not (IOR 2.4).
SlabResult sample_pane_main_walk(const MainWalkPane &pane, const Vec3 &wi, long n, uint64_t seed,
                                 const host::ClosureInstance *abi = nullptr, long *mismatch = nullptr) {
  std::vector<long> differ(kBlocks, 0);
  const SlabResult r = draw_pane_samples(
      wi, n, seed, true, [&](long b, GlimmerShadingContext &ctx, const float *u, Exit &e, Spectrum &w, int &side) {
        const bool ok = pane.sample(ctx, Vec3(u[0], u[1], u[2]), e);
        if (abi != nullptr) {
          GlimmerSample s = glimmer_blank_sample();
          const bool abi_ok = abi->sample(ctx, u, s) != GLIMMER_LABEL_NONE;
          const bool same = abi_ok == ok && (!ok || (Vec3(s.wo).x == e.w.x && Vec3(s.wo).y == e.w.y &&
                                                     Vec3(s.wo).z == e.w.z && double(s.eval[0] / s.pdf) == e.weight));
          differ[b] += same ? 0 : 1;
        }
        w = Spectrum(float(e.weight));
        side = e.w.z < 0.0f ? 1 : 0;
        return ok;
      });
  if (mismatch != nullptr) *mismatch = std::accumulate(differ.begin(), differ.end(), 0L);
  return r;
}

std::vector<std::string> material(float rough, float ior, const Vec3 &absorb, float distance, bool thin, float L) {
  std::vector<std::string> a = {"roughness=" + num(rough), "ior=" + num(ior),
                                "absorption_color=" + num(absorb.x) + "," + num(absorb.y) + "," + num(absorb.z),
                                "absorption_distance=" + num(distance)};
  if (thin) {
    a.push_back("thin=1");
    a.push_back("thickness=" + num(L));
  }
  return a;
}

// Smooth slab at normal incidence (incoherent sum of interreflections).
double slab_closed_form(double ior, double tau, bool interreflections = true) {
  const double R = ((ior - 1) / (ior + 1)) * ((ior - 1) / (ior + 1));
  return (1 - R) * (1 - R) * tau / (interreflections ? 1 - R * R * tau * tau : 1.0);
}

// ---- Smooth slab / pane vs the closed form ---------------------------------------
TEST(FrostedGlassBeer, SmoothSlabAndPaneMatchClosedForm) {
  const Vec3 absorb(0.8f, 0.5f, 0.2f);
  const float distance = 1.0f, L = 0.7f;
  const long n = 1 << 20;
  for (float ior : {1.5f, 2.4f}) {
    SlabHost slab(L);
    auto solid = make_closure("frosted_glass", material(1e-3f, ior, absorb, distance, false, L));
    auto pane = make_closure("frosted_glass", material(1e-3f, ior, absorb, distance, true, L));
    const Vec3 normal(0.0f, 0.0f, 1.0f);
    const SlabResult a = trace_slab(*solid, slab, normal, n, 11);
    const SlabResult b = sample_pane(*pane, normal, n, 12);
    for (int ch = 0; ch < 3; ++ch) {
      const double tau = std::pow(double(absorb[ch]), double(L / distance));
      const double expect = slab_closed_form(ior, tau);
      // Channel 0's standard error scaled to this channel's transmittance (same paths, weights scale by tau).
      const double se_a = a.se_T * expect / std::max(double(a.T.x), 1e-12) + 1e-7;
      const double se_b = b.se_T * expect / std::max(double(b.T.x), 1e-12) + 1e-7;
      EXPECT_NEAR(a.T[ch], expect, 5 * se_a) << "solid slab ior=" << ior << " channel " << ch;
      EXPECT_NEAR(b.T[ch], expect, 5 * se_b) << "thin pane ior=" << ior << " channel " << ch;
      std::printf("[frosted beer smooth] ior %.2f channel %d: closed form T %.5f, solid slab %.5f +- %.1e, "
                  "thin pane %.5f +- %.1e\n", ior, ch, expect, a.T[ch], se_a, b.T[ch], se_b);
    }
    if (ior > 2.0f) {  // negative control: without interreflections the closed form is off by > 5 sigma
      const double tau = std::pow(double(absorb.x), double(L / distance));
      EXPECT_GT(std::fabs(a.T.x - slab_closed_form(ior, tau, false)), 5 * a.se_T);
      EXPECT_GT(std::fabs(b.T.x - slab_closed_form(ior, tau, false)), 5 * b.se_T);
    }
  }
}

// ---- Rough pane vs the brute-force slab ----------------------------------------
TEST(FrostedGlassBeer, RoughPaneMatchesPathTracedSlab) {
  const Vec3 absorb(0.9f, 0.6f, 0.3f);
  const float distance = 0.5f, L = 0.3f;
  const long n = 1 << 20;
  const Vec3 wi = mftest::direction_from(0.6f, 0.4f);
  for (float rough : {0.2f, 0.5f, 0.9f}) {
    SlabHost slab(L), buggy(L, true);
    auto solid = make_closure("frosted_glass", material(rough, 1.5f, absorb, distance, false, L));
    auto pane = make_closure("frosted_glass", material(rough, 1.5f, absorb, distance, true, L));
    const SlabResult ref = trace_slab(*solid, slab, wi, n, 21);
    const SlabResult got = sample_pane(*pane, wi, n, 22);
    for (int ch = 0; ch < 3; ++ch) {
      const double se_T = std::hypot(ref.se_T, got.se_T) * ref.T[ch] / std::max(double(ref.T.x), 1e-12) + 1e-7;
      const double se_R = std::hypot(ref.se_R, got.se_R) * ref.R[ch] / std::max(double(ref.R.x), 1e-12) + 1e-7;
      EXPECT_NEAR(got.T[ch], ref.T[ch], 5 * se_T) << "rough=" << rough << " channel " << ch;
      EXPECT_NEAR(got.R[ch], ref.R[ch], 5 * se_R) << "rough=" << rough << " channel " << ch;
    }
    std::printf("[frosted beer rough] roughness %.1f: slab (path traced) T %.4f %.4f %.4f R %.4f; pane T %.4f %.4f "
                "%.4f R %.4f (se %.1e)\n", rough, ref.T.x, ref.T.y, ref.T.z, ref.R.x, got.T.x, got.T.y, got.T.z,
                got.R.x, ref.se_T);
    // Negative control: absorbing over the depth instead of the path length is caught.
    const SlabResult bug = trace_slab(*solid, buggy, wi, n, 23);
    EXPECT_GT(std::fabs(bug.T.z - got.T.z), 5 * std::hypot(bug.se_T, got.se_T) * got.T.z / got.T.x)
        << "rough=" << rough;
  }
}

// ---- Thin pane: furnace, distribution, eval ------------------------------------
TEST(FrostedGlassThin, WhiteFurnace) {
  struct Case {
    float rough, ior, mu;
  };
  std::vector<Case> cases;
  for (float rough : {0.1f, 0.5f, 1.0f})
    for (float ior : {1.33f, 1.7f, 2.4f})
      for (float mu : {1.0f, 0.5f, 0.1f, 0.02f, -0.7f}) cases.push_back({rough, ior, mu});
  std::vector<mftest::Albedo> got(cases.size());
  tbb::parallel_for(size_t(0), cases.size(), [&](size_t i) {
    const Case &c = cases[i];
    auto pane = make_closure("frosted_glass", {"roughness=" + num(c.rough), "ior=" + num(c.ior), "thin=1"});
    got[i] = mftest::sampled_albedo(*pane, mftest::direction_from(c.mu, 0.7f), std::fabs(c.mu) <= 0.05f ? 256 : 128,
                                    700 + i);
  });
  // The 0.5 % bound of the solid closure's furnace where this estimate resolves it (standard error <= 0.1 %).
  // At roughness 1 and high IOR the walk's weight (a product of G2 / G1 / E over many internal events) is
  // so spread that 131k samples give a standard error of 1-4 %: there the check is 5 standard errors, and
  // the cases are counted and printed, not hidden.
  double worst = 0.0, worst_sigma = 0.0;
  int resolved = 0;
  for (size_t i = 0; i < cases.size(); ++i) {
    const double total = got[i].reflect.x + got[i].transmit.x, se = got[i].std_error;
    const std::string what = "rough=" + num(cases[i].rough) + " ior=" + num(cases[i].ior) + " mu=" +
                             num(cases[i].mu) + " R+T=" + std::to_string(total) + " +- " + std::to_string(se);
    if (se <= 0.001) {
      EXPECT_LT(std::fabs(1.0 - total), 0.005) << what;
      worst = std::max(worst, std::fabs(1.0 - total));
      ++resolved;
    } else {
      EXPECT_LT(std::fabs(1.0 - total), 5 * se) << what;
      worst_sigma = std::max(worst_sigma, std::fabs(1.0 - total) / se);
      std::printf("[frosted thin furnace] unresolved: %s\n", what.c_str());
    }
  }
  std::printf("[frosted thin furnace] %d of %zu cases resolved (se <= 0.1 %%): max |1 - (R+T)| %.4f%%; the others "
              "within %.2f standard errors\n", resolved, cases.size(), 100 * worst, worst_sigma);
}

struct PaneConfig {
  float rough, ior, z;
};
std::vector<PaneConfig> pane_configs() {
  std::vector<PaneConfig> c;
  for (float rough : {0.3f, 0.7f})
    for (float ior : {1.5f, 2.4f})
      for (float z : {0.9f, 0.3f}) c.push_back({rough, ior, z});
  return c;
}

// Main's statistic (2397f6c's two_sample_p, unchanged): two-sample chi2 on (cos theta, phi) cells of the sphere, the
// pane's sample() directions vs the brute-force slab's exit directions, equal counts (weights not used: it holds
// where the two walks draw their events from the same lobe, main's walk on both sides).
double two_sample_p(const std::vector<Exit> &a, const std::vector<Exit> &b, int n_t = 32, int n_phi = 32) {
  std::vector<double> ca(size_t(n_t) * n_phi, 0.0), cb(ca.size(), 0.0);
  auto cell = [&](const Vec3 &w) {
    const int it = std::clamp(int((w.z + 1.0f) * 0.5f * n_t), 0, n_t - 1);
    double phi = std::atan2(double(w.y), double(w.x));
    if (phi < 0.0) phi += 2.0 * M_PI;
    return size_t(it) * n_phi + std::min(int(phi / (2.0 * M_PI) * n_phi), n_phi - 1);
  };
  for (const Exit &e : a) ca[cell(e.w)] += 1.0;
  for (const Exit &e : b) cb[cell(e.w)] += 1.0;
  const double ka = std::sqrt(double(b.size()) / a.size()), kb = 1.0 / ka;
  double chi2 = 0.0, pa = 0.0, pb = 0.0;
  int bins = 0;
  auto add = [&](double x, double y) {
    chi2 += (ka * x - kb * y) * (ka * x - kb * y) / (x + y);
    ++bins;
  };
  for (size_t i = 0; i < ca.size(); ++i) {
    if (ca[i] + cb[i] < 20.0) {
      pa += ca[i];
      pb += cb[i];
    } else {
      add(ca[i], cb[i]);
    }
  }
  if (pa + pb > 0.0) add(pa, pb);
  return lab::chi2_survival(chi2, std::max(bins - 1, 1));
}

// Weighted two-sample chi2 on (cos theta, phi) cells of the sphere: per cell the flux sum_i w_i 1{w_i in cell} / n
// of the pane's sample() (w its sample weight f cos / pdf) against the brute-force slab's (w its path throughput),
// z = the difference over its standard error (each side's from its own second moment), chi2 = sum z^2 over the
// cells with >= 20 exits on each side (the rest pooled into one), dof = the cells (fluxes are not constrained to sum
// to a constant). Holds for any unbiased sampler, whatever its direction density (the walk's resampled events at
// IOR >= 1.6 (1.9 before session 38) draw other directions with other weights than the slab's lobe samples).
// unweighted_a: the negative control, the pane's weights replaced by 1 (the sampler's weight not applied).
// One side's exits added per cell (count, sum of weights, sum of squares): what weighted_two_sample_p reads.
struct ExitCells {
  struct Cell {
    double count = 0, sum = 0, sum2 = 0;
  };
  int n_t = 16, n_phi = 16;
  std::vector<Cell> cells = std::vector<Cell>(size_t(n_t) * n_phi);
  void add(const Exit &e, bool unweighted = false) {
    const int it = std::clamp(int((e.w.z + 1.0f) * 0.5f * n_t), 0, n_t - 1);
    double phi = std::atan2(double(e.w.y), double(e.w.x));
    if (phi < 0.0) phi += 2.0 * M_PI;
    Cell &c = cells[size_t(it) * n_phi + std::min(int(phi / (2.0 * M_PI) * n_phi), n_phi - 1)];
    const double w = unweighted ? 1.0 : e.weight;
    c.count += 1.0, c.sum += w, c.sum2 += w * w;
  }
  void add(const ExitCells &o) {
    for (size_t k = 0; k < cells.size(); ++k)
      cells[k].count += o.cells[k].count, cells[k].sum += o.cells[k].sum, cells[k].sum2 += o.cells[k].sum2;
  }
  double flux(double n) const {
    double f = 0.0;
    for (const Cell &c : cells) f += c.sum / n;
    return f;
  }
  size_t exits() const {
    double k = 0.0;
    for (const Cell &c : cells) k += c.count;
    return size_t(k);
  }
};

double weighted_two_sample_p(const ExitCells &a, long n_a, const ExitCells &b, long n_b, int *high = nullptr,
                             int *low = nullptr) {
  const double n[2] = {double(n_a), double(n_b)};
  const ExitCells *side_cells[2] = {&a, &b};
  ExitCells::Cell pooled[2];
  double chi2 = 0.0;
  int bins = 0;
  auto add = [&](const ExitCells::Cell *c) {
    double diff = 0.0, var = 0.0;
    for (int side = 0; side < 2; ++side) {
      const double mean = c[side].sum / n[side];
      diff += side == 0 ? mean : -mean;
      var += std::max(0.0, c[side].sum2 / n[side] - mean * mean) / n[side];
    }
    if (var > 0.0) chi2 += diff * diff / var, ++bins;
    if (high != nullptr && var > 0.0 && diff > 3.0 * std::sqrt(var)) ++*high;  // cells where a > b by > 3 se
    if (low != nullptr && var > 0.0 && diff < -3.0 * std::sqrt(var)) ++*low;
  };
  for (size_t k = 0; k < a.cells.size(); ++k) {
    const ExitCells::Cell c[2] = {side_cells[0]->cells[k], side_cells[1]->cells[k]};
    if (c[0].count < 20.0 || c[1].count < 20.0) {
      for (int side = 0; side < 2; ++side)
        pooled[side].count += c[side].count, pooled[side].sum += c[side].sum, pooled[side].sum2 += c[side].sum2;
    } else {
      add(c);
    }
  }
  if (pooled[0].count + pooled[1].count > 0.0) add(pooled);
  return lab::chi2_survival(chi2, std::max(bins, 1));
}

// The same from the exits themselves.
double weighted_two_sample_p(const std::vector<Exit> &a, long n_a, const std::vector<Exit> &b, long n_b,
                             bool unweighted_a = false, int *high = nullptr, int *low = nullptr) {
  ExitCells ca, cb;
  for (const Exit &e : a) ca.add(e, unweighted_a);
  for (const Exit &e : b) cb.add(e);
  return weighted_two_sample_p(ca, n_a, cb, n_b, high, low);
}

// The pane's sample() against the brute-force slab (the solid closure at both interfaces, main's walk inside it), two
// families on the same slab runs, each over the 8 configurations at main's Sidak threshold:
//  - main's test, whole (2397f6c's statistic, seeds, n and threshold): main's pane (MainWalkPane: the walk forced to
//    level 0, kPaneWalkLobe, whatever the rule) against the slab, unweighted directions (two_sample_p). Both sides
//    draw every event from the same lobe, so the counts are compared, not the weights: calibrated whatever the
//    weights' variance, at IOR 2.4 roughness 0.7 too. Check of the hook: at IOR 1.5 (the rule picks level 0)
//    MainWalkPane's draws are the closure's own sample() through the C ABI bit for bit (0 of n differ); at IOR 2.4
//    most differ (the closure's default there is the resampled walk).
//  - the default sampler, weighted (weighted_two_sample_p): holds for main's walk (IOR 1.5) and the resampled walk
//    events (IOR 2.4, FrostedGlassClosure::resampled_walk). At IOR 2.4 roughness 0.7 its standard errors are not
//    calibrated (the slab's weights have a heavy tail there: at IOR 2.4 rho(M_2) is 0.972 at r 0.5 and 1.107 at r 0.8,
//    docs "Session 36 (frostedtail36)"; r 0.7 lies between, not measured itself), so that pair is printed (with the
//    slab against itself), not asserted: session 37 measured p 5.8e-7 / 1.9e-4
//    there, the slab against itself 0.20 / 0.41. The resampled events' equivalence to level 0 there is proven in
//    tests/closures/test_frosted_pane_tail.cpp: per event (ResampledEventSameExpectationAsLobeSample, finite variance
//    on both sides) and per whole walk where main's walk has finite variance (ResampledWalkSameExpectationAsWalk).
// Negative controls: the pane at another roughness is told apart by both statistics; at IOR 2.4 the default pane's
// directions without their weights (the resampled events' weight c not applied) are told apart where c varies (r 0.3
// at z 0.3, r 0.7; at r 0.3 z 0.9 c stays near 1 and the control's p is 0.83: printed). Printed too: main's
// statistic on the default pane at IOR 2.4 (other directions, other weights: its power, not an error).
TEST(FrostedGlassThin, SampleDistributionMatchesPathTracedSlab) {
  const auto configs = pane_configs();
  const double threshold = mftest::sidak_threshold(int(configs.size()));
  const long n = 400000, n_used = n / kBlocks * kBlocks;
  double min_p = 1.0, min_p_main = 1.0, control_unweighted_max_p = 0.0, control_main_max_p = 0.0;
  for (size_t i = 0; i < configs.size(); ++i) {
    const PaneConfig &c = configs[i];
    SlabHost slab(0.2f);
    auto solid = make_closure("frosted_glass", {"roughness=" + num(c.rough), "ior=" + num(c.ior)});
    auto pane = make_closure("frosted_glass", {"roughness=" + num(c.rough), "ior=" + num(c.ior), "thin=1"});
    const Vec3 wi = mftest::direction_from(c.z, 0.3f);
    const SlabResult ref = trace_slab(*solid, slab, wi, n, 31 + i, true);
    long mismatch = 0;
    const MainWalkPane main_pane(c.rough, c.ior);
    const bool resampled = plugin::FrostedGlassClosure::resampled_walk(main_pane.lobe);  // the default rule
    const SlabResult main_walk = sample_pane_main_walk(main_pane, wi, n, 41 + i, pane.get(), &mismatch);
    const double p_main = two_sample_p(main_walk.exits, ref.exits);
    EXPECT_GE(p_main, threshold) << "main's walk: rough=" << c.rough << " ior=" << c.ior << " z=" << c.z;
    min_p_main = std::min(min_p_main, p_main);
    if (!resampled) {
      EXPECT_EQ(mismatch, 0) << "MainWalkPane is not the closure's level-0 sample()";
    } else {
      EXPECT_GT(mismatch, n / 4) << "MainWalkPane is the closure's default sample() at IOR 2.4";
    }
    std::printf(
        "[frosted thin chi2] rough %.1f ior %.1f z %.1f: main's walk (level 0) p %.4g (draws differing from "
        "sample() %ld of %ld)",
        c.rough, c.ior, c.z, p_main, mismatch, n_used);
    const SlabResult got = sample_pane(*pane, wi, n, 41 + i, true);
    const double p = weighted_two_sample_p(got.exits, n_used, ref.exits, n_used);
    const bool calibrated = !(resampled && c.rough > 0.5f);  // the reference's variance is finite
    std::printf("; default sampler weighted p %.4g", p);
    if (calibrated) {
      EXPECT_GE(p, threshold) << "rough=" << c.rough << " ior=" << c.ior << " z=" << c.z;
      min_p = std::min(min_p, p);
    } else {
      const SlabResult again = trace_slab(*solid, slab, wi, n, 61 + i, true);
      int high = 0, low = 0;
      weighted_two_sample_p(got.exits, n_used, ref.exits, n_used, false, &high, &low);
      std::printf(
          " (not asserted; cells pane > slab by > 3 se %d, < %d; the slab against itself p %.4g; R+T: pane "
          "%.5f +- %.5f, slab %.5f +- %.5f, again %.5f +- %.5f)",
          high, low, weighted_two_sample_p(again.exits, n_used, ref.exits, n_used), double(got.R.x + got.T.x),
          std::hypot(got.se_R, got.se_T), double(ref.R.x + ref.T.x), std::hypot(ref.se_R, ref.se_T),
          double(again.R.x + again.T.x), std::hypot(again.se_R, again.se_T));
    }
    if (resampled) {  // the resampled walk: its directions alone are not the slab's
      const double pc = weighted_two_sample_p(got.exits, n_used, ref.exits, n_used, true);
      if (c.rough > 0.5f || c.z < 0.5f) {
        EXPECT_LT(pc, 1e-6) << "control (weights not applied) rough=" << c.rough << " z=" << c.z;
        control_unweighted_max_p = std::max(control_unweighted_max_p, pc);
      }
      // main's statistic on the default pane at IOR 2.4 (printed: its power; the resampled events' directions have
      // another density, which is not an error, so it is not asserted)
      const double pc_main = two_sample_p(got.exits, ref.exits);
      control_main_max_p = std::max(control_main_max_p, pc_main);
      std::printf(", control (pane unweighted) p %.3g, main's statistic on the default pane p %.3g", pc, pc_main);
    }
    std::printf("\n");
  }
  // Negative control: the pane at another roughness is told apart (both statistics).
  double control_rough_p = 1.0, control_rough_p_main = 1.0;
  {
    SlabHost slab(0.2f);
    auto solid = make_closure("frosted_glass", {"roughness=0.3", "ior=1.5"});
    auto pane = make_closure("frosted_glass", {"roughness=0.36", "ior=1.5", "thin=1"});
    const Vec3 wi = mftest::direction_from(0.9f, 0.3f);
    const SlabResult got = sample_pane(*pane, wi, n, 51, true), ref = trace_slab(*solid, slab, wi, n, 52, true);
    control_rough_p = weighted_two_sample_p(got.exits, n_used, ref.exits, n_used);
    control_rough_p_main = two_sample_p(got.exits, ref.exits);
    EXPECT_LT(control_rough_p, 1e-6);
    EXPECT_LT(control_rough_p_main, 1e-6);
  }
  std::printf(
      "[frosted thin chi2] %zu configurations x %ld samples vs the path-traced slab: main's walk, main's "
      "statistic: min p = %.4g; default sampler, weighted: min p = %.4g (Sidak threshold %.3g); controls: "
      "roughness 0.36 vs 0.3 p %.3g (main's statistic %.3g), IOR 2.4 unweighted max p %.3g, IOR 2.4 default "
      "pane under main's statistic max p %.3g\n",
      configs.size(), n, min_p_main, min_p, threshold, control_rough_p, control_rough_p_main, control_unweighted_max_p,
      control_main_max_p);
}

// One pane sample (no Beer, colourless) with the walk's events at kLevel (FrostedGlassClosure::walk_event: 0 main's
// walk, 1 the resampled events, 9 their control), from the test's own numbers: the exit direction, its weight and the
// internal reflections before leaving (-1: the front reflection).
template <int kLevel>
bool pane_walk_draw(const plugin::DielectricLobe &lobe, const Vec3 &wi, Pcg32 &rng, Exit &out, int &reflections) {
  plugin::LocalSample s;
  if (!lobe.sample(wi, Vec3(rng.next_float(), rng.next_float(), rng.next_float()), s)) return false;
  double w = double(s.f_cos.x) / s.pdf;
  if (!(s.label & GLIMMER_LABEL_TRANSMIT)) return out = {s.wo, w}, reflections = -1, true;
  Vec3 d = s.wo;
  microfacet::WalkRng walk(rng.next_u32());
  for (int event = 0; event < plugin::FrostedGlassClosure::kMaxPaneEvents; ++event) {
    if (d.z == 0.0f) return false;
    const bool bottom = d.z < 0.0f;
    if (!plugin::FrostedGlassClosure::walk_event<kLevel>(lobe, bottom ? microfacet::flip_z_local(-d) : -d, walk, s))
      return false;
    w *= double(s.f_cos.x) / s.pdf;
    const Vec3 next = bottom ? microfacet::flip_z_local(s.wo) : s.wo;
    if (s.label & GLIMMER_LABEL_TRANSMIT) return out = {next, w}, reflections = event, true;
    d = next;
  }
  return false;
}

// n draws of pane_walk_draw<kLevel>, their exits split by the reflections before leaving into the classes of
// kReflectionClasses (the last: more).
// lower bounds: front, 0, 1, 2, 3-4, 5-8 (asserted), 9-12, 13-20, >= 21
constexpr int kReflectionClasses[] = {-1, 0, 1, 2, 3, 5, 9, 13, 21};
constexpr int kClasses = int(std::size(kReflectionClasses));
template <int kLevel>
std::array<ExitCells, kClasses> walk_exits_by_class(float rough, float ior, const Vec3 &wi, long n, uint64_t seed) {
  const plugin::DielectricLobe lobe = plugin::FrostedGlassClosure::interface_lobe(rough, ior);
  std::vector<std::array<ExitCells, kClasses>> blocks(kBlocks);
  tbb::parallel_for(long(0), kBlocks, [&](long b) {
    Pcg32 rng(seed, uint64_t(b) + 1);
    for (long i = 0; i < n / kBlocks; ++i) {
      Exit e;
      int k = 0;
      if (!pane_walk_draw<kLevel>(lobe, wi, rng, e, k)) continue;
      int c = kClasses - 1;
      while (k < kReflectionClasses[c]) --c;
      blocks[b][c].add(e);
    }
  });
  std::array<ExitCells, kClasses> all;
  for (const auto &block : blocks)
    for (int c = 0; c < kClasses; ++c) all[c].add(block[c]);
  return all;
}

// Session 37 follow-up (frostedwalk37b): where the slab test above cannot assert the resampled walk (roughness 0.7
// IOR 2.4: main's walk's weight has infinite variance), the resampled walk against main's walk on the pane itself,
// split by the internal reflections before leaving. The resampled event has level 0's expectation for any function
// of the event (walk_event's comment), so the two walks have the same flux into each (cell, reflection class); and a
// walk of <= 8 reflections has a bounded weight (each event's g / E <= 1 / E_min): finite variance on both sides, the
// weighted statistic calibrated. Main's walk gets 8x the draws (8 Mi). Asserted: the classes front .. 5-8
// reflections, the weighted two-sample chi2 per class (16 x 16 cells), Sidak over classes x configurations. Printed:
// 9-12, 13-20, >= 21 reflections (main's weights there span many decades: the statistic is not calibrated), each
// class's flux, and main's walk at n (another seed) against its 8n run: the calibration. Session 37b measured:
// with main at 8n, 9-12 / 13-20 reflections p 0.88 / 0.33 (z 0.9), 0.89 / 0.73 (z 0.3); with main at n (a first
// version of this test), 13-20 reflections p 8.4e-5 / 2.2e-17, every off cell the resampled walk above main's; and
// main at n against main at 8n, 9-12 reflections, p 0.0025 / 0.0018, its 6 / 4 off cells all below: the smaller run
// of main's heavy-tailed walk is typically low, the signature of the slab test's p at roughness 0.7 IOR 2.4 (there
// every off cell had the pane above the slab). Negative control: kPaneWalkControl's walks (F not applied) are
// rejected at 1 reflection.
TEST(FrostedGlassThin, ResampledWalkMatchesMainWalkByReflections) {
  using Closure = plugin::FrostedGlassClosure;
  const long n = 1 << 20, n_used = n / kBlocks * kBlocks, n_main = 8 * n_used;  // main's walk: 8x the draws
  const int asserted = 6;                                                       // the classes of <= 8 reflections
  const double threshold = mftest::sidak_threshold(2 * asserted);
  double min_p = 1.0, control_p = 1.0;
  for (float z : {0.9f, 0.3f}) {
    const Vec3 wi = mftest::direction_from(z, 0.3f);
    const uint64_t seed = 900 + uint64_t(z * 10);
    const auto main_walk = walk_exits_by_class<Closure::kPaneWalkLobe>(0.7f, 2.4f, wi, n_main, seed);
    const auto again = walk_exits_by_class<Closure::kPaneWalkLobe>(0.7f, 2.4f, wi, n, seed + 1);
    const auto resampled = walk_exits_by_class<Closure::kPaneWalkResampled>(0.7f, 2.4f, wi, n, seed + 2);
    const auto control = walk_exits_by_class<Closure::kPaneWalkControl>(0.7f, 2.4f, wi, n, seed + 3);
    for (int c = 0; c < kClasses; ++c) {
      int high = 0, low = 0, high_self = 0, low_self = 0;
      const double p = weighted_two_sample_p(resampled[c], n_used, main_walk[c], n_main, &high, &low);
      const double p_self = weighted_two_sample_p(again[c], n_used, main_walk[c], n_main, &high_self, &low_self);
      const double flux[2] = {main_walk[c].flux(double(n_main)), resampled[c].flux(double(n_used))};
      std::printf(
          "[frosted thin walk classes] r 0.7 ior 2.4 z %.1f reflections >= %2d: resampled vs main p %.4g%s "
          "(cells > 3 se above / below %d / %d); main n vs 8n p %.4g (%d / %d); flux main %.5f resampled %.5f "
          "(exits %zu / %zu)\n",
          z, kReflectionClasses[c], p, c < asserted ? "" : " (not asserted)", high, low, p_self, high_self, low_self,
          flux[0], flux[1], main_walk[c].exits(), resampled[c].exits());
      if (c < asserted) {
        EXPECT_GE(p, threshold) << "z=" << z << " class " << kReflectionClasses[c];
        min_p = std::min(min_p, p);
      }
      if (c == 2) control_p = std::min(control_p, weighted_two_sample_p(control[c], n_used, main_walk[c], n_main));
    }
  }
  EXPECT_LT(control_p, 1e-6);
  std::printf(
      "[frosted thin walk classes] resampled vs main's walk, <= 8 reflections: min p %.4g (Sidak threshold "
      "%.3g); control (F not applied, 1 reflection) p %.3g\n",
      min_p, threshold, control_p);
}

// The pane's eval() is the front interface's reflection alone; every path that enters the pane leaves as a
// SINGULAR sample (delta weight in eval, pdf 1: the host takes no light sample through the pane and gives its
// emission hits MIS weight 1; docs/frosted_glass.md "Light sampling through a pane"). Checked, with absorption:
//  - eval is exactly 0 on the far side (a transmitted direction is never light-sampled; the old one-walk
//    stochastic eval fails this: its transmission estimate is > 0 there);
//  - eval integrated over the sphere (uniform directions) = the non-singular samples' weight sum (the front
//    reflection), and Int pdf = the fraction of samples that are not singular (eval's pdf is sample()'s density);
//  - each non-singular sample's f cos and pdf = eval at its wo (same numbers);
//  - every sample that entered is singular with pdf 1, and together R and T are the path-traced slab's
//    (FrostedGlassBeer.RoughPaneMatchesPathTracedSlab, the furnace above);
//  - negative control: the fraction of ALL samples leaving on wi's side (the front reflection plus the walk's exits
//    back through the near face) is rejected as Int pdf (what an eval that counted those exits as the front lobe's
//    density would claim), where the walk's reflected share is resolved.
TEST(FrostedGlassThin, EvalIsTheFrontReflectionAndTheWalkIsSingular) {
  const auto configs = pane_configs();
  const long n = 1 << 20;
  double worst_sigma = 0.0, control_min_sigma = 1e30;
  for (size_t i = 0; i < configs.size(); ++i) {
    const PaneConfig &c = configs[i];
    auto pane = make_closure("frosted_glass", {"roughness=" + num(c.rough), "ior=" + num(c.ior), "thin=1",
                                               "absorption_color=0.7,0.7,0.7", "absorption_distance=0.3",
                                               "thickness=0.2"});
    const Vec3 wi = mftest::direction_from(c.z, 0.3f);
    // eval over the sphere: f on wi's side, pdf, and the far side's non-zero values (must be none).
    std::vector<std::array<double, 4>> acc(kBlocks, std::array<double, 4>{});  // f_R, f_R^2, pdf, pdf^2
    std::vector<long> far_nonzero(kBlocks, 0);
    tbb::parallel_for(long(0), kBlocks, [&](long b) {
      Pcg32 rng(900 + i, uint64_t(b) + 1);
      GlimmerShadingContext ctx = host::make_local_context(wi);
      for (long k = 0; k < n / kBlocks; ++k) {
        const float z = 2.0f * rng.next_float() - 1.0f;
        const Vec3 wo = mftest::direction_from(z, float(2.0 * M_PI) * rng.next_float());
        ctx.path_seed = rng.next_u32();
        Spectrum f;
        float pdf;
        pane->eval(ctx, wo, f, pdf);
        if (wo.z < 0.0f) {
          if (f.x != 0.0f || f.y != 0.0f || f.z != 0.0f || pdf != 0.0f) ++far_nonzero[b];
          continue;
        }
        const double fw = 4.0 * M_PI * f.x, pw = 4.0 * M_PI * pdf;
        acc[b][0] += fw;
        acc[b][1] += fw * fw;
        acc[b][2] += pw;
        acc[b][3] += pw * pw;
      }
    });
    // sample(): the non-singular samples (weight, count, consistency with eval) and the singular ones.
    struct SampleTally {
      double front = 0.0, front2 = 0.0;
      long smooth = 0, near_side = 0, bad_singular = 0, inconsistent = 0;
    };
    std::vector<SampleTally> st(kBlocks);
    tbb::parallel_for(long(0), kBlocks, [&](long b) {
      Pcg32 rng(60 + i, uint64_t(b) + 1);
      GlimmerShadingContext ctx = host::make_local_context(wi);
      SampleTally &t = st[b];
      for (long k = 0; k < n / kBlocks; ++k) {
        ctx.path_seed = rng.next_u32();
        const float u[3] = {rng.next_float(), rng.next_float(), rng.next_float()};
        GlimmerSample s = glimmer_blank_sample();
        const uint32_t label = pane->sample(ctx, u, s);
        if (label == GLIMMER_LABEL_NONE) continue;
        const Vec3 wo(s.wo);
        if (wo.z > 0.0f) ++t.near_side;
        if (label & GLIMMER_LABEL_SINGULAR) {
          if (s.pdf != 1.0f) ++t.bad_singular;
          continue;
        }
        ++t.smooth;
        const double w = s.eval[0] / s.pdf;
        t.front += w;
        t.front2 += w * w;
        Spectrum f;
        float pdf;
        pane->eval(ctx, wo, f, pdf);
        if (!(std::fabs(pdf - s.pdf) <= 1e-4f * s.pdf) || !(std::fabs(f.x - s.eval[0]) <= 1e-4f * s.eval[0]) ||
            (label & GLIMMER_LABEL_TRANSMIT))
          ++t.inconsistent;
      }
    });
    std::array<double, 4> e{};
    long far = 0;
    for (long b = 0; b < kBlocks; ++b) {
      for (int j = 0; j < 4; ++j) e[j] += acc[b][j];
      far += far_nonzero[b];
    }
    SampleTally t;
    for (const SampleTally &x : st) {
      t.front += x.front;
      t.front2 += x.front2;
      t.smooth += x.smooth;
      t.near_side += x.near_side;
      t.bad_singular += x.bad_singular;
      t.inconsistent += x.inconsistent;
    }
    const double m = double(n / kBlocks * kBlocks);
    const auto [eR, seR] = mean_se(e[0], e[1], m);
    const auto [eP, seP] = mean_se(e[2], e[3], m);
    const auto [sR, se_sR] = mean_se(t.front, t.front2, m);
    const double frac = t.smooth / m, se_frac = std::sqrt(frac * (1 - frac) / m) + 1e-6;
    const double near = t.near_side / m, se_near = std::sqrt(near * (1 - near) / m) + 1e-6;
    const double dR = std::fabs(eR - sR) / std::hypot(seR, se_sR), dP = std::fabs(eP - frac) / std::hypot(seP, se_frac);
    const double control = std::fabs(eP - near) / std::hypot(seP, se_near);
    const std::string what = "rough=" + num(c.rough) + " ior=" + num(c.ior) + " z=" + num(c.z);
    EXPECT_EQ(far, 0) << what;
    EXPECT_EQ(t.bad_singular, 0) << what;
    EXPECT_EQ(t.inconsistent, 0) << what;
    EXPECT_LT(dR, 5.0) << "front reflection: eval " << eR << " sampled " << sR << " " << what;
    EXPECT_LT(dP, 5.0) << "Int pdf " << eP << " vs non-singular fraction " << frac << " " << what;
    // The walk's exits back through the near face are resolved (> 20 se of the fraction): the control must fail.
    if (near - frac > 20 * se_near) {
      EXPECT_GT(control, 5.0) << "control: Int pdf " << eP << " vs all reflected " << near << " " << what;
      control_min_sigma = std::min(control_min_sigma, control);
    }
    worst_sigma = std::max({worst_sigma, dR, dP});
    std::printf("[frosted thin eval] %s: front R eval %.4f / sampled %.4f, Int pdf %.4f / non-singular %.4f; all "
                "reflected %.4f (control %.1f se); far-side eval non-zero %ld\n", what.c_str(), eR, sR, eP, frac, near,
                control, far);
  }
  std::printf("[frosted thin eval] worst deviation %.2f standard errors; control rejected by >= %.1f se\n", worst_sigma,
              control_min_sigma);
}

// ---- Thin pane: reciprocity (the walk is stochastic, so it is checked on fluxes) ----------------------------
// The pane has air on both sides, so f(wi, wo) = f(wo, wi) for the uncompensated interfaces. Each interface event
// of the walk divides by the multi_ggx albedo E at its incident direction (f = f_ss / E(mu_in), as
// microfacet_dielectric's, FrostedGlassPath.Reciprocity). Inside, each internal direction is the outgoing
// direction of one event and the incident direction of the next, at the same |cos| (parallel faces) and the same
// eta, so those factors cancel along a path and f(wi, wo) E(mu_i) = f(wo, wi) E(mu_o) exactly: the front
// reflection, the exits back through the near face and the transmission alike (Beer and the tint are symmetric).
// Only sample() sees the walk, so the check is on fluxes between cones A and B of directions:
//   Phi(A -> B) = Int_A Int_B f(wi, wo) E(mu_i) cos_i cos_o dwo dwi
// estimated with wi uniform in A and the pane's own samples (weight f cos / pdf, singular or not) landing in B,
// which equals Phi(B -> A) whatever the cones' size. Four cones of 15 degrees (two on each side, near and far from
// the normal), every pair both ways, roughness 0.3 / 0.7 / 1, IOR 1.5 / 2.4, absorbing and tinted.
// z-test per pair, Sidak-corrected at 0.01 over the pairs resolved (>= 400 hits each way). Negative control: the
// fluxes without E(mu_i) (claiming the compensated f itself is reciprocal) are rejected where E differs.
namespace reciprocity {

using glimmer::plugin::DielectricLobe;
using glimmer::plugin::MicrofacetLobeParams;
using glimmer::plugin::kMultiGgx;

constexpr float kConeHalfAngle = 15.0f * float(M_PI) / 180.0f;

struct Cone {
  Vec3 axis, t, b;
  explicit Cone(const Vec3 &a) : axis(normalize(a)) {
    t = normalize(cross(std::fabs(axis.x) > 0.9f ? Vec3(0.0f, 1.0f, 0.0f) : Vec3(1.0f, 0.0f, 0.0f), axis));
    b = cross(axis, t);
  }
  double solid_angle() const { return 2.0 * M_PI * (1.0 - std::cos(double(kConeHalfAngle))); }
  bool contains(const Vec3 &w) const { return dot(w, axis) >= std::cos(kConeHalfAngle); }
  Vec3 uniform(float u, float v) const {
    const float z = 1.0f - u * (1.0f - std::cos(kConeHalfAngle)), s = std::sqrt(std::max(0.0f, 1.0f - z * z));
    const float phi = 2.0f * float(M_PI) * v;
    return normalize(axis * z + t * (s * std::cos(phi)) + b * (s * std::sin(phi)));
  }
};

// Fluxes out of one cone into every cone (channel 0), with and without E(mu_i): sums and sums of squares.
struct Fluxes {
  std::vector<double> sum, sum2, raw, raw2;
  std::vector<long> hits;
  explicit Fluxes(size_t cones) : sum(cones), sum2(cones), raw(cones), raw2(cones), hits(cones) {}
};

Fluxes flux_from(const host::ClosureInstance &pane, const DielectricLobe &energy, float ior, const Cone &from,
                 const std::vector<Cone> &cones, long n, uint64_t seed) {
  std::vector<Fluxes> blocks(kBlocks, Fluxes(cones.size()));
  tbb::parallel_for(long(0), kBlocks, [&](long blk) {
    Pcg32 rng(seed, uint64_t(blk) + 1);
    Fluxes &f = blocks[blk];
    for (long i = 0; i < n / kBlocks; ++i) {
      const Vec3 wi = from.uniform(rng.next_float(), rng.next_float());
      GlimmerShadingContext ctx = host::make_local_context(wi);
      ctx.path_seed = rng.next_u32();
      const float u[3] = {rng.next_float(), rng.next_float(), rng.next_float()};
      GlimmerSample s = glimmer_blank_sample();
      if (pane.sample(ctx, u, s) == GLIMMER_LABEL_NONE) continue;
      const Vec3 wo = normalize(Vec3(s.wo));
      const double raw = from.solid_angle() * std::fabs(wi.z) * s.eval[0] / s.pdf;
      const double w = raw * energy.compensation(std::fabs(wi.z), ior);  // air on both sides: eta = ior
      for (size_t c = 0; c < cones.size(); ++c) {
        if (!cones[c].contains(wo)) continue;
        f.sum[c] += w;
        f.sum2[c] += w * w;
        f.raw[c] += raw;
        f.raw2[c] += raw * raw;
        ++f.hits[c];
      }
    }
  });
  Fluxes total(cones.size());
  for (const Fluxes &f : blocks)
    for (size_t c = 0; c < cones.size(); ++c) {
      total.sum[c] += f.sum[c];
      total.sum2[c] += f.sum2[c];
      total.raw[c] += f.raw[c];
      total.raw2[c] += f.raw2[c];
      total.hits[c] += f.hits[c];
    }
  return total;
}

}  // namespace reciprocity

TEST(FrostedGlassThin, ReciprocalUpToTheCompensation) {
  using namespace reciprocity;
  const std::vector<Cone> cones = {Cone(mftest::direction_from(0.95f, 0.3f)), Cone(mftest::direction_from(0.45f, 3.6f)),
                                   Cone(mftest::direction_from(-0.85f, 3.4f)),
                                   Cone(mftest::direction_from(-0.35f, 0.7f))};
  struct Case {
    float rough, ior;
  };
  const Case cases[] = {{0.3f, 1.5f}, {0.3f, 2.4f}, {0.7f, 1.5f}, {0.7f, 2.4f}, {1.0f, 1.5f}, {1.0f, 2.4f}};
  const long n = 1 << 18;
  struct PairResult {
    std::string what;
    double z, z_raw;
    bool resolved;
  };
  std::vector<PairResult> results;
  for (size_t k = 0; k < std::size(cases); ++k) {
    const Case &c = cases[k];
    auto pane = make_closure("frosted_glass", {"roughness=" + num(c.rough), "ior=" + num(c.ior), "thin=1",
                                               "color=0.9,0.8,0.7", "absorption_color=0.7,0.7,0.7",
                                               "absorption_distance=0.3", "thickness=0.2"});
    DielectricLobe energy;  // the pane's interfaces, for E(mu, eta)
    energy.build(MicrofacetLobeParams::make(kMultiGgx, c.rough, 0.0f), c.ior, false, true);
    std::vector<Fluxes> out;
    for (size_t a = 0; a < cones.size(); ++a)
      out.push_back(flux_from(*pane, energy, c.ior, cones[a], cones, n, 7000 + 10 * k + a));
    const double m = double(n / kBlocks * kBlocks);
    for (size_t a = 0; a < cones.size(); ++a)
      for (size_t b = a + 1; b < cones.size(); ++b) {
        const auto [ab, se_ab] = mean_se(out[a].sum[b], out[a].sum2[b], m);
        const auto [ba, se_ba] = mean_se(out[b].sum[a], out[b].sum2[a], m);
        const auto [rab, rse_ab] = mean_se(out[a].raw[b], out[a].raw2[b], m);
        const auto [rba, rse_ba] = mean_se(out[b].raw[a], out[b].raw2[a], m);
        const bool resolved = out[a].hits[b] >= 400 && out[b].hits[a] >= 400;
        const double z = (ab - ba) / std::max(std::hypot(se_ab, se_ba), 1e-300);
        const double z_raw = (rab - rba) / std::max(std::hypot(rse_ab, rse_ba), 1e-300);
        char line[256];
        std::snprintf(line, sizeof line, "rough %.1f ior %.1f cones %zu<->%zu: Phi %.4e / %.4e (se %.1e / %.1e, hits "
                      "%ld / %ld) z %.2f; without E(mu_i) z %.2f", c.rough, c.ior, a, b, ab, ba, se_ab, se_ba,
                      out[a].hits[b], out[b].hits[a], z, z_raw);
        results.push_back({line, z, z_raw, resolved});
        // Both reflections (0-1 above, 2-3 below) and both transmissions along the continued direction (0-2, 1-3)
        // carry enough light in every case; 0-3 and 1-2 (40+ degrees off it) are compared where they do.
        const bool lobe_pair = (a == 0 && b == 1) || (a == 0 && b == 2) || (a == 1 && b == 3) || (a == 2 && b == 3);
        if (lobe_pair) {
          EXPECT_TRUE(resolved) << line;
        }
      }
  }
  int resolved = 0;
  for (const PairResult &r : results) resolved += r.resolved ? 1 : 0;
  // Two-sided normal quantile for the Sidak-corrected 0.01: p per pair = 1 - 0.99^(1 / resolved).
  const double p_pair = mftest::sidak_threshold(resolved);
  double z_crit = 0.0;
  for (double z = 0.0; z < 10.0; z += 1e-3)
    if (std::erfc(z / std::sqrt(2.0)) <= p_pair) {
      z_crit = z;
      break;
    }
  double worst = 0.0, control_max = 0.0;
  for (const PairResult &r : results) {
    std::printf("[frosted thin reciprocity] %s%s\n", r.what.c_str(), r.resolved ? "" : " (not resolved)");
    if (!r.resolved) continue;
    EXPECT_LT(std::fabs(r.z), z_crit) << r.what;
    worst = std::max(worst, std::fabs(r.z));
    control_max = std::max(control_max, std::fabs(r.z_raw));
  }
  // Negative control: the compensated f is not reciprocal by itself (E(mu_i) / E(mu_o) up to a few % at roughness
  // 1 and IOR 2.4): the same test without the factor rejects it.
  EXPECT_GT(control_max, z_crit);
  std::printf("[frosted thin reciprocity] %d of %zu pairs resolved: worst |z| %.2f (Sidak-corrected limit %.2f); "
              "without E(mu_i) worst |z| %.2f\n", resolved, results.size(), worst, z_crit, control_max);
}

}  // namespace

namespace {

// ---- ABI 2.8: light sampling at the pane's exit (sixteenth session; session 37 both walk samplers) -----------------
// method=path's pane hands the host, with its singular walk sample, the state of the walk's last interface
// (GLIMMER_SAMPLE_EXIT_STATE) and eval_exit(state, w) = W T f_T(d, w) cos, pdf_T(d, w): W the walk's weight up to
// that interface, d the last internal direction, T the number of draws of the walk's own event sampler at d until
// the first that leaves (E[T | d] = 1 / P_T(d)), pdf_T the lobe's unconditional density of leaving toward w (the
// host's MIS weight; any such pdf keeps it unbiased). Checked per sample, through the C ABI, on 10 panes (roughness
// 0.1 / 0.3 / 0.6 at IOR 1.5, main's walk; roughness 0.3 / 0.6 at IOR 2.4, the resampled walk events of
// FrostedGlassClosure::resampled_walk; tinted, absorbing; wi at 0 and 60 degrees):
//  - every walk sample carries a state, its T (the state's trials) a whole number >= 1, and eval_exit at the
//    sample's own wo has f / pdf over the sample's weight the same for the three channels; with main's walk that
//    ratio is T exactly (its leaving event's weight is the lobe's f / pdf; the resampled event's weight is not);
//  - unbiasedness of light sampling at the exit: for test functions g (1; a smooth lobe off the far side's axis;
//    the near side), E[Int eval_exit(w) g(w) dw] over the walk samples = E[weight g(wo)] (the BSDF estimator of
//    the same integral): the paired differences within 4 standard errors of 0 (the integral by importance
//    sampling about wo, a mixture of three vMFs and the uniform sphere);
//  - the exit direction in expectation: the same paired difference for g = each of 12 x 12 cells of (cos theta,
//    phi) (the samples' weight in the cell against Int_cell eval_exit), chi2 = sum of the cells' z^2 over the
//    cells with >= 20 exits, (chi2 - dof) / sqrt(2 dof) < 4; weighted, so it holds for either sampler;
//  - main's walk only: the pdf is the sampler's unconditional density, E[T Int pdf_T(d, w) dw] = 1 within 4 se
//    (the resampled events leave with another probability; printed there).
// Negative control: without T (a state weight W, i.e. no 1 / P_T) the integrals and the cells are rejected
// (> 4 se / z > 4) wherever the pane traps light (60 degrees, and every roughness at normal incidence through its
// internal reflections; the cells where more than 5 % of the walks have T > 1), and Int pdf alone (main's walk).
struct VmfMix {
  // q(w) = 0.1 uniform + 0.3 each vMF(mu, kappa_k), kappa 10 / 100 / 1000.
  static constexpr float kKappa[3] = {10.0f, 100.0f, 1000.0f};
  static double vmf_pdf(const Vec3 &mu, double kappa, const Vec3 &w) {
    return kappa / (2.0 * M_PI * (1.0 - std::exp(-2.0 * kappa))) * std::exp(kappa * (double(dot(mu, w)) - 1.0));
  }
  static double pdf(const Vec3 &mu, const Vec3 &w) {
    double p = 0.1 / (4.0 * M_PI);
    for (float k : kKappa) p += 0.3 * vmf_pdf(mu, k, w);
    return p;
  }
  static Vec3 sample(const Vec3 &mu, Pcg32 &rng) {
    const float pick = rng.next_float(), u = rng.next_float(), v = rng.next_float();
    if (pick < 0.1f) return mftest::direction_from(2.0f * u - 1.0f, float(2.0 * M_PI) * v);
    const double kappa = kKappa[std::min(2, int((pick - 0.1f) / 0.3f))];
    const double c = std::clamp(1.0 + std::log(u + (1.0 - u) * std::exp(-2.0 * kappa)) / kappa, -1.0, 1.0);
    const Frame f = Frame::from_normal(mu);
    return normalize(f.to_world(mftest::direction_from(float(c), float(2.0 * M_PI) * v)));
  }
};

// One pane's tallies over its walk samples (per block, summed after).
struct ExitTally {
  static constexpr int kCosCells = 12, kPhiCells = 12, kCells = kCosCells * kPhiCells;
  // [0..2] paired differences LHS - RHS for g0..g2, [3..5] their squares; [6..11] the same without T (control);
  // [12] T Int pdf, [13] its square; [14] Int pdf (control), [15] its square.
  std::array<double, 16> acc{};
  // per cell: exits observed, the paired difference (Int_cell eval_exit - weight 1{wo in cell}) and its square,
  // the same without T (control)
  std::array<std::array<double, 5>, kCells> cells{};
  long walks = 0, missing = 0, bad_ratio = 0, multi = 0, largest = 0;
  bool lobe_sampler = true;  // main's walk: eval_exit's f / pdf at wo is the weight x T exactly

  static int cell_of(const Vec3 &w) {
    const int i = std::clamp(int((w.z + 1.0f) * 0.5f * kCosCells), 0, kCosCells - 1);
    const float phi = std::atan2(w.y, w.x) + float(M_PI);
    return i * kPhiCells + std::clamp(int(phi / float(2.0 * M_PI) * kPhiCells), 0, kPhiCells - 1);
  }
  static double g(int j, const Vec3 &w) {  // the test functions
    if (j == 0) return 1.0;
    if (j == 1) return std::exp(6.0 * (double(dot(w, normalize(Vec3(0.4f, 0.1f, -1.0f)))) - 1.0));  // far side
    return w.z > 0.0f ? 1.0 : 0.0;  // the near side: exits back through the entry face
  }
  void add(const ExitTally &o) {
    for (size_t j = 0; j < acc.size(); ++j) acc[j] += o.acc[j];
    for (int c = 0; c < kCells; ++c)
      for (int k = 0; k < 5; ++k) cells[c][k] += o.cells[c][k];
    walks += o.walks, missing += o.missing, bad_ratio += o.bad_ratio, multi += o.multi;
    largest = std::max(largest, o.largest);
  }
  // The state's T and the per-sample identities (above); false: bad_ratio.
  bool consistent(const Spectrum &weight, const Spectrum &f, float pdf, const GlimmerExitState &state,
                  double &trials) const {
    trials = double(plugin::FrostedGlassClosure::PaneExitState::read(state).trials);
    if (!(trials >= 1.0) || trials != std::round(trials) || !(pdf > 0.0f)) return false;
    const double ratio = double(f.x) / pdf / weight.x;
    bool ok = !lobe_sampler || std::fabs(ratio - trials) < 1e-3 * trials;
    for (int c = 1; c < 3; ++c) ok = ok && std::fabs(double(f[c]) / pdf / weight[c] - ratio) < 1e-3 * ratio;
    return ok;
  }

  // One sample of the pane at ctx through the C ABI.
  void sample(const host::ClosureInstance &pane, const GlimmerShadingContext &ctx, Pcg32 &rng) {
    constexpr int kDirs = 16;
    const float u[3] = {rng.next_float(), rng.next_float(), rng.next_float()};
    GlimmerSample s = glimmer_blank_sample();
    GlimmerExitState state{};
    s.exit_state = &state;
    if (!(pane.sample(ctx, u, s) & GLIMMER_LABEL_SINGULAR)) return;  // none, or the front reflection
    const Spectrum weight(s.eval[0], s.eval[1], s.eval[2]);
    const Vec3 wo(s.wo);
    if (!(std::min({weight.x, weight.y, weight.z}) > 1e-30f)) return;  // absorbed (Beer) or denormal
    ++walks;
    if (!(s.flags & GLIMMER_SAMPLE_EXIT_STATE)) {
      ++missing;
      return;
    }
    Spectrum f;
    float pdf;
    pane.eval_exit(ctx, state, wo, f, pdf);
    double trials = 0.0;
    if (!consistent(weight, f, pdf, state, trials)) {
      ++bad_ratio;
      return;
    }
    multi += trials > 1.0 ? 1 : 0;
    largest = std::max(largest, long(trials));
    double lhs[3] = {0, 0, 0}, pdf_integral = 0.0;
    std::array<double, kCells> mine{};  // this state's Int_c eval_exit
    int touched[kDirs + 1];
    touched[kDirs] = cell_of(wo);
    for (int i = 0; i < kDirs; ++i) {
      const Vec3 w = VmfMix::sample(wo, rng);
      const double q = VmfMix::pdf(wo, w);
      Spectrum fw;
      float pw;
      pane.eval_exit(ctx, state, w, fw, pw);
      for (int j = 0; j < 3; ++j) lhs[j] += double(fw.x) * g(j, w) / q / kDirs;
      pdf_integral += double(pw) / q / kDirs;
      touched[i] = cell_of(w);
      mine[touched[i]] += double(fw.x) / q / kDirs;
    }
    for (int j = 0; j < 3; ++j) {
      const double rhs = double(weight.x) * g(j, wo), d = lhs[j] - rhs, dc = lhs[j] / trials - rhs;
      acc[j] += d, acc[3 + j] += d * d, acc[6 + j] += dc, acc[9 + j] += dc * dc;
    }
    acc[12] += trials * pdf_integral, acc[13] += trials * pdf_integral * trials * pdf_integral;
    acc[14] += pdf_integral, acc[15] += pdf_integral * pdf_integral;
    cells[touched[kDirs]][0] += 1.0;
    std::array<bool, kCells> done{};
    for (int c : touched) {
      if (done[c]) continue;  // counted already
      done[c] = true;
      const double rhs = c == touched[kDirs] ? double(weight.x) : 0.0;
      const double d = mine[c] - rhs, dc = mine[c] / trials - rhs;
      cells[c][1] += d, cells[c][2] += d * d, cells[c][3] += dc, cells[c][4] += dc * dc;
    }
  }

  long resolved() const { return walks - missing - bad_ratio; }
  // z of the mean of acc[i] (its square at `square`) against `expect`.
  double z(int i, int square, double expect) const {
    const auto [mean, se] = mean_se(acc[i], acc[square], double(resolved()));
    return (mean - expect) / se;
  }
  // (chi2 - dof) / sqrt(2 dof) of the cells' paired differences (the cells with >= 20 exits observed), with T
  // (control: without).
  double chi2_z(bool control) const {
    double chi2 = 0.0;
    int dof = 0;
    for (const auto &c : cells) {
      if (c[0] < 20.0) continue;
      const auto [mean, se] = mean_se(control ? c[3] : c[1], control ? c[4] : c[2], double(resolved()));
      if (!(se > 0.0)) continue;
      chi2 += (mean / se) * (mean / se);
      ++dof;
    }
    return (chi2 - dof) / std::sqrt(2.0 * std::max(dof, 1));
  }
};

ExitTally tally_pane_exit(float rough, float ior, float deg, long n) {
  auto pane =
      make_closure("frosted_glass", {"roughness=" + num(rough), "ior=" + num(ior), "thin=1", "color=0.9,0.8,0.7",
                                     "absorption_color=0.7,0.7,0.7", "absorption_distance=0.3", "thickness=0.2"});
  const Vec3 wi = mftest::direction_from(std::cos(deg * float(M_PI) / 180.0f), 0.3f);
  std::vector<ExitTally> blocks(kBlocks);
  const bool lobe_sampler = !plugin::FrostedGlassClosure::resampled_walk(MainWalkPane(rough, ior).lobe);
  tbb::parallel_for(long(0), kBlocks, [&](long b) {
    Pcg32 rng(7100 + uint64_t(rough * 100) + uint64_t(deg) + (lobe_sampler ? 0 : 5000), uint64_t(b) + 1);
    GlimmerShadingContext ctx = host::make_local_context(wi);
    blocks[b].lobe_sampler = lobe_sampler;
    for (long k = 0; k < n / kBlocks; ++k) {
      ctx.path_seed = rng.next_u32();
      blocks[b].sample(*pane, ctx, rng);
    }
  });
  ExitTally total;
  for (const ExitTally &t : blocks) total.add(t);
  total.lobe_sampler = lobe_sampler;
  return total;
}

TEST(FrostedGlassThin, EvalExitIsTheWalksLastInterfaceWithItsLeavingProbability) {
  double worst_z = 0.0, worst_pdf_z = 0.0, control_min_z = 1e30, worst_chi2_z = -1e30, control_min_chi2_z = 1e30;
  struct Pane {
    float ior, rough, deg;
  };
  std::vector<Pane> panes;
  for (float rough : {0.1f, 0.3f, 0.6f})
    for (float deg : {0.0f, 60.0f}) panes.push_back({1.5f, rough, deg});
  for (float rough : {0.3f, 0.6f})
    for (float deg : {0.0f, 60.0f}) panes.push_back({2.4f, rough, deg});  // the resampled walk events
  for (const Pane &p : panes) {
    const ExitTally t = tally_pane_exit(p.rough, p.ior, p.deg, 1 << 16);
    EXPECT_EQ(t.missing, 0) << "walk samples without an exit state";
    EXPECT_EQ(t.bad_ratio, 0) << "eval_exit's f / pdf at wo: not grey over the weight, or (main's walk) not the "
                                 "weight x T, or T not a whole number >= 1";
    const long m = t.resolved();
    std::printf(
        "[frosted pane exit] IOR %.1f roughness %.1f, %2.0f deg: %ld walks (%.2f %% with T > 1, largest T "
        "%ld); z (g0, g1, g2) %+.2f %+.2f %+.2f, T Int pdf %+.2f; control (no T) %+.2f %+.2f %+.2f, Int pdf "
        "%+.2f; exit cells chi2 z %+.2f, control %+.2f\n",
        p.ior, p.rough, p.deg, m, 100.0 * t.multi / std::max<long>(m, 1), t.largest, t.z(0, 3, 0), t.z(1, 4, 0),
        t.z(2, 5, 0), t.z(12, 13, 1), t.z(6, 9, 0), t.z(7, 10, 0), t.z(8, 11, 0), t.z(14, 15, 1), t.chi2_z(false),
        t.chi2_z(true));
    for (int j = 0; j < 3; ++j) {
      worst_z = std::max(worst_z, std::fabs(t.z(j, 3 + j, 0)));
      EXPECT_LT(std::fabs(t.z(j, 3 + j, 0)), 4.0) << "g" << j << " IOR " << p.ior;
    }
    worst_chi2_z = std::max(worst_chi2_z, t.chi2_z(false));
    EXPECT_LT(t.chi2_z(false), 4.0) << "IOR " << p.ior;
    control_min_z = std::min(control_min_z, std::fabs(t.z(6, 9, 0)));
    EXPECT_GT(std::fabs(t.z(6, 9, 0)), 4.0) << "control: without the trials the exit's light is not unbiased";
    if (t.lobe_sampler) {  // main's walk: pdf_T is its sampler's density
      worst_pdf_z = std::max(worst_pdf_z, std::fabs(t.z(12, 13, 1)));
      EXPECT_LT(std::fabs(t.z(12, 13, 1)), 4.0);
      control_min_z = std::min(control_min_z, std::fabs(t.z(14, 15, 1)));
      EXPECT_GT(std::fabs(t.z(14, 15, 1)), 4.0) << "control: Int pdf alone is P_T, not 1";
    }
    // The control needs walks whose T is not 1 (at roughness 0.1 head-on few of them).
    if (t.multi > m / 20) {
      control_min_chi2_z = std::min(control_min_chi2_z, t.chi2_z(true));
      EXPECT_GT(t.chi2_z(true), 4.0) << "control: the exit cells without T, IOR " << p.ior;
    }
  }
  std::printf(
      "[frosted pane exit] worst |z| %.2f (integrals), %.2f (T Int pdf, IOR 1.5); control min |z| %.2f; exit "
      "cells chi2 worst z %+.2f, control (no T) min z %+.2f\n",
      worst_z, worst_pdf_z, control_min_z, worst_chi2_z, control_min_chi2_z);
}

}  // namespace
