// GGX visible-normal SAMPLING MAPPINGS under the renderer's quasi-Monte-Carlo points (issue 13, scene c).
// No renderer: one pixel's BSDF-sampling estimate of the light reflected by a GGX surface (F = 1) from a small
// emitter, a cone of directions of half-angle 0.1 rad, is the mean over N samples of G2(wi, wo) / G1(wi) for
// wo = reflect(wi, wh) inside the cone (f cos / pdf with the visible-normal pdf). wh comes from one of three
// mappings of the same density (Heitz 2014 eq. 38):
//   cap     - today's sample_ggx_visible_normal (Dupuy & Benyoub 2023 spherical cap: azimuth 2 pi u1 around the
//             stretched view, height from u2),
//   disk    - Heitz 2018 (JCGT 7(4)): polar disk (radius sqrt(u1), angle 2 pi u2) warped onto the visible
//             hemisphere of the stretched configuration,
//   slopes  - Heitz & d'Eon 2014 slope space, as Cycles 3.4 maps GGX: slope x by the exact inverse of its
//             marginal CDF in u1, slope y from u2 folded at 0.5 (here the exact inverse of the conditional CDF
//             instead of Cycles' rational fit, so that the density is the same as the other two),
// fed with either the renderer's Owen-scrambled Sobol points (render::PixelSampler::get_path_start: film u, v and
// BSDF x, y of the camera set, as a single-closure conductor uses them) or independent PCG32 numbers. Each pixel has its own
// scramble (seed 1, pixel index) or its own PCG stream. The exact integral is a 2D midpoint quadrature over the
// cone in double (the integrand is smooth inside it). Counters: relative RMSE of the pixel estimates over 4096
// pixels (rmse_<mapping>_<sampler>, in units of the exact value) and, for the independent rows, z of the mean
// against the exact value (a check of the harness and of each mapping's density: |z| should be < 3, and the
// three independent RMSEs equal within their statistical error of about 2 %). Checks of the point set, cap mapping:
// owen_cap (the same Sobol dimensions with a per-node random Owen scramble instead of the sampler's hash),
// rot_cap / rot_slopes (unscrambled Sobol with a per-pixel Cranley-Patterson rotation, the randomization Cycles
// 3.4 applies to its PMJ02 points). With a pixel footprint (last argument, the emitter's axis moving with the film
// position across the pixel: a curved mirror), padded_cap takes film and BSDF numbers from two 2D sets (the
// renderer's layout before issue 13, session 6: each its own index shuffle and scramble) and j4d23_cap from one
// 4D set the other way round (BSDF = Sobol dimensions 0-1, film = 2-3); qmc_cap is the renderer's camera set
// (film = 0-1, BSDF = 2-3).
//   ./glimmer_benchmarks --benchmark_filter=GgxMapping
#include <benchmark/benchmark.h>

#include <cmath>
#include <string>
#include <vector>

#include "glimmer/microfacet.h"
#include "glimmer/rng.h"
#include "render/sampler.h"

namespace {

using namespace glimmer;
namespace mf = glimmer::microfacet;

constexpr float kConeHalfAngle = 0.1f;
constexpr int kPixels = 4096;

// Heitz 2018, "Sampling the GGX Distribution of Visible Normals", JCGT 7(4), listing of sec. 2.
Vec3 sample_disk_heitz2018(const Vec3 &wi, float ax, float ay, float u1, float u2) {
  const Vec3 vh = normalize(Vec3(ax * wi.x, ay * wi.y, wi.z));
  const float len2 = vh.x * vh.x + vh.y * vh.y;
  const Vec3 t1 = len2 > 0.0f ? Vec3(-vh.y, vh.x, 0.0f) / std::sqrt(len2) : Vec3(1.0f, 0.0f, 0.0f);
  const Vec3 t2 = cross(vh, t1);
  const float r = std::sqrt(u1), phi = kTwoPi * u2;
  const float p1 = r * std::cos(phi);
  const float s = 0.5f * (1.0f + vh.z);
  const float p2 = (1.0f - s) * safe_sqrt(1.0f - p1 * p1) + s * r * std::sin(phi);
  const Vec3 nh = p1 * t1 + p2 * t2 + safe_sqrt(1.0f - p1 * p1 - p2 * p2) * vh;
  return normalize(Vec3(ax * nh.x, ay * nh.y, std::max(nh.z, 0.0f)));
}

// Heitz & d'Eon 2014 (CGF 33(4)) / Heitz 2014 supplemental: the stretched visible slopes of GGX.
// Slope x: the marginal CDF inverted in closed form (a quadratic in x for A = 2 u1 / G1 - 1).
// Slope y given x: y = sqrt(1 + x^2) t with t of density proportional to (1 + t^2)^-2; with t = tan(b) its CDF on
// t >= 0 is (b + sin(2b) / 2) / (pi / 2), inverted by safeguarded Newton in double.
double inverse_half_cdf_t(double u) {
  const double target = 0.5 * kPi * u;
  double lo = 0.0, hi = 0.5 * kPi, b = 0.5 * target;
  for (int it = 0; it < 60; ++it) {
    const double g = b + 0.5 * std::sin(2.0 * b) - target;
    if (std::fabs(g) < 1e-13) break;
    if (g > 0.0) hi = b; else lo = b;
    double next = b - g / (1.0 + std::cos(2.0 * b));
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    b = next;
  }
  return std::tan(b);
}
Vec3 sample_slopes_heitz2014(const Vec3 &wi, float ax, float ay, float u1, float u2) {
  const Vec3 ws = normalize(Vec3(ax * wi.x, ay * wi.y, wi.z));
  const double cos_t = ws.z, sin_t = std::sqrt(std::max(0.0, 1.0 - cos_t * cos_t));
  double sx, sy;
  if (cos_t > 0.99999) {  // normal incidence: the slope distribution itself
    const double r = std::sqrt(u1 / std::max(1.0 - u1, 1e-12)), phi = kTwoPi * u2;
    sx = r * std::cos(phi);
    sy = r * std::sin(phi);
  } else {
    const double tan_t = sin_t / cos_t;
    const double g1 = 2.0 / (1.0 + std::sqrt(1.0 + tan_t * tan_t));
    const double a = 2.0 * u1 / g1 - 1.0;
    const double tmp = std::min(1.0 / (a * a - 1.0), 1e10);
    const double d = std::sqrt(std::max(tan_t * tan_t * tmp * tmp - (a * a - tan_t * tan_t) * tmp, 0.0));
    const double x1 = tan_t * tmp - d, x2 = tan_t * tmp + d;
    sx = (a < 0.0 || x2 > 1.0 / tan_t) ? x1 : x2;
    const double sign = u2 > 0.5f ? 1.0 : -1.0;
    const double uf = u2 > 0.5f ? 2.0 * (u2 - 0.5) : 2.0 * (0.5 - u2);
    sy = sign * inverse_half_cdf_t(uf) * std::sqrt(1.0 + sx * sx);
  }
  // Rotate from the plane of incidence, unstretch; the normal of slope (x, y) is (-x, -y, 1) normalized.
  const double len_xy = std::sqrt(double(ws.x) * ws.x + double(ws.y) * ws.y);
  const double c = len_xy > 0.0 ? ws.x / len_xy : 1.0, s = len_xy > 0.0 ? ws.y / len_xy : 0.0;
  const double px = (c * sx - s * sy) * ax, py = (s * sx + c * sy) * ay;
  const double inv = 1.0 / std::sqrt(px * px + py * py + 1.0);
  return Vec3(static_cast<float>(-px * inv), static_cast<float>(-py * inv), static_cast<float>(inv));
}

enum class Mapping { Cap, Disk, Slopes };
Vec3 sample_mapping(Mapping m, const Vec3 &wi, float a, float u1, float u2) {
  switch (m) {
    case Mapping::Cap: return mf::sample_ggx_visible_normal(wi, a, a, u1, u2);
    case Mapping::Disk: return sample_disk_heitz2018(wi, a, a, u1, u2);
    case Mapping::Slopes: return sample_slopes_heitz2014(wi, a, a, u1, u2);
  }
  return Vec3(0.0f, 0.0f, 1.0f);
}

struct Setup {
  Vec3 wi;
  float alpha;
  Vec3 axis;  // the emitter cone's axis
  float cos_half;
  float footprint;  // angle (rad) the axis sweeps across the pixel: a curved mirror's pixel footprint
};
// The view at theta_deg in the xz-plane; the cone centred on the mirror direction, or (edge) rotated by its
// half-angle towards the normal, so the specular peak lies on its rim.
Setup make_setup(float alpha, float theta_deg, bool edge, float footprint) {
  const float t = theta_deg * kPi / 180.0f;
  const float tc = edge ? t - kConeHalfAngle : t;
  return {Vec3(std::sin(t), 0.0f, std::cos(t)), alpha, Vec3(-std::sin(tc), 0.0f, std::cos(tc)), std::cos(kConeHalfAngle),
          footprint};
}
// The cone's axis seen from film position (fx, fy) in [0, 1)^2 of the pixel.
Vec3 axis_at(const Setup &s, float fx, float fy) {
  if (s.footprint == 0.0f) return s.axis;
  const Vec3 b1 = normalize(cross(s.axis, Vec3(0.0f, 1.0f, 0.0f))), b2 = cross(s.axis, b1);
  return normalize(s.axis + s.footprint * ((fx - 0.5f) * b1 + (fy - 0.5f) * b2));
}

// f cos / pdf for the visible-normal pdf with F = 1: G2(wi, wo) / G1(wi), zero outside the cone.
float sample_weight(const Setup &s, const Vec3 &axis, const Vec3 &wh) {
  const Vec3 wo = mf::reflect_about(s.wi, wh);
  if (!(wo.z > 0.0f) || dot(wo, axis) < s.cos_half) return 0.0f;
  return mf::G2(mf::Distribution::GGX, s.wi, wo, s.alpha, s.alpha) / mf::G1(mf::Distribution::GGX, s.wi, s.alpha, s.alpha);
}

// Exact integral of f cos over the cone: midpoint rule in (angle from the axis, azimuth), f cos = D G2 / (4 wi.z).
double cone_integral(const Setup &s, const Vec3 &axis, int nt, int np) {
  const Vec3 b1 = normalize(cross(axis, Vec3(0.0f, 1.0f, 0.0f)));
  const Vec3 b2 = cross(axis, b1);
  double sum = 0.0;
  for (int i = 0; i < nt; ++i) {
    const double t = (i + 0.5) * kConeHalfAngle / nt;
    double ring = 0.0;
    for (int j = 0; j < np; ++j) {
      const double p = (j + 0.5) * kTwoPi / np;
      const Vec3 wo = normalize(static_cast<float>(std::cos(t)) * axis +
                                static_cast<float>(std::sin(t) * std::cos(p)) * b1 +
                                static_cast<float>(std::sin(t) * std::sin(p)) * b2);
      if (!(wo.z > 0.0f)) continue;
      const Vec3 wh = normalize(s.wi + wo);
      ring += double(mf::D(mf::Distribution::GGX, wh, s.alpha, s.alpha)) *
              mf::G2(mf::Distribution::GGX, s.wi, wo, s.alpha, s.alpha) / (4.0 * s.wi.z);
    }
    sum += ring * std::sin(t);
  }
  return sum * (kConeHalfAngle / nt) * (kTwoPi / np);
}
// With a footprint, the mean over the pixel (midpoint rule on the film: the cone integral is smooth in the axis).
double exact_integral(const Setup &s) {
  if (s.footprint == 0.0f) return cone_integral(s, s.axis, 2048, 2048);
  const int nf = 16;
  double sum = 0.0;
  for (int i = 0; i < nf; ++i)
    for (int j = 0; j < nf; ++j) sum += cone_integral(s, axis_at(s, (i + 0.5f) / nf, (j + 0.5f) / nf), 512, 512);
  return sum / (nf * nf);
}

// A fully random nested uniform (Owen) scramble: every node of the binary tree has its own hashed flip, as a
// check of the sampler's Laine-Karras hash scramble.
uint32_t owen_scramble_per_node(uint32_t v, uint32_t seed) {
  uint32_t r = v;
  for (int b = 31; b >= 0; --b) {
    const uint32_t prefix = b == 31 ? 0u : v >> (b + 1);
    r ^= (hash_u32x3(seed, prefix, static_cast<uint32_t>(b)) & 1u) << b;
  }
  return r;
}

// Where a pixel's (film, BSDF) numbers come from.
enum class Sampler {
  Independent,  // PCG32
  Renderer,     // PixelSampler::get_path_start: the camera set, film = dims 0, 1 and BSDF = dims 2, 3
  Padded,       // PixelSampler: film and BSDF from two 2D sets, each its own shuffle and scramble (padding)
  Joint4D,      // PixelSampler: one 4D set, BSDF = dims 0, 1 and film = dims 2, 3 (jointly stratified)
  OwenPerNode,  // Sobol dims 0, 1 (BSDF) with a per-node Owen scramble, film by PCG32
  Rotated,      // Sobol dims 0, 1 (BSDF, a (0, m, 2)-net like PMJ02) with a per-pixel Cranley-Patterson
                // rotation instead of a scramble, as Cycles 3.4 randomizes its PMJ02 points; film by PCG32
};
struct SampleNumbers {
  float u1, u2, fx, fy;
};
SampleNumbers numbers(Sampler k, int px, int i, Pcg32 &rng) {
  SampleNumbers n{};
  const auto pixel = static_cast<uint32_t>(px), index = static_cast<uint32_t>(i);
  switch (k) {
    case Sampler::Independent:
      n = {rng.next_float(), rng.next_float(), rng.next_float(), rng.next_float()};
      break;
    case Sampler::Renderer: {
      float film[2], bsdf[4], light[2];
      render::PixelSampler(1u, pixel, index).get_path_start(film, bsdf, light);
      n = {bsdf[0], bsdf[1], film[0], film[1]};
      break;
    }
    case Sampler::Padded: {
      float film[2], bsdf[2];
      const render::PixelSampler sampler(1u, pixel, index);
      sampler.get(0u, film);
      sampler.get(render::bounce_set(0, render::kSetLight), bsdf);
      n = {bsdf[0], bsdf[1], film[0], film[1]};
      break;
    }
    case Sampler::Joint4D: {
      float x[4];
      render::PixelSampler(1u, pixel, index).get(render::bounce_set(0, render::kSetBsdf), x);
      n = {x[0], x[1], x[2], x[3]};
      break;
    }
    case Sampler::OwenPerNode: {
      const uint32_t seed = hash_u32x2(1u, pixel);
      n.u1 = uint_to_unit_float(owen_scramble_per_node(render::sobol_by_matrix(0, index), seed));
      n.u2 = uint_to_unit_float(owen_scramble_per_node(render::sobol_by_matrix(1, index), seed ^ 0x5bd1e995u));
      n.fx = rng.next_float();
      n.fy = rng.next_float();
      break;
    }
    case Sampler::Rotated: {
      const uint32_t seed = hash_u32x2(1u, pixel);
      n.u1 = uint_to_unit_float(render::sobol_by_matrix(0, index) + hash_u32x2(seed, 0u));  // + offset mod 1
      n.u2 = uint_to_unit_float(render::sobol_by_matrix(1, index) + hash_u32x2(seed, 1u));
      n.fx = rng.next_float();
      n.fy = rng.next_float();
      break;
    }
  }
  return n;
}

struct Error {
  double rel_rmse, z_mean;
};
Error pixel_error(const Setup &s, double exact, Mapping m, Sampler k, int spp) {
  double sq = 0.0, sum = 0.0, sum2 = 0.0;
  for (int px = 0; px < kPixels; ++px) {
    Pcg32 rng(0x9e3779b97f4a7c15ULL, static_cast<uint64_t>(px));
    double acc = 0.0;
    for (int i = 0; i < spp; ++i) {
      const SampleNumbers n = numbers(k, px, i, rng);
      acc += sample_weight(s, axis_at(s, n.fx, n.fy), sample_mapping(m, s.wi, s.alpha, n.u1, n.u2));
    }
    const double est = acc / spp;
    sq += (est - exact) * (est - exact);
    sum += est;
    sum2 += est * est;
  }
  const double mean = sum / kPixels, var = std::max(sum2 / kPixels - mean * mean, 0.0);
  return {std::sqrt(sq / kPixels) / exact, (mean - exact) / std::sqrt(var / kPixels + 1e-300)};
}

void BM_GgxMappingRmse(benchmark::State &state) {
  const float alpha = static_cast<float>(state.range(0)) / 100.0f;
  const float theta = static_cast<float>(state.range(1));
  const bool edge = state.range(2) != 0;
  const int spp = static_cast<int>(state.range(3));
  const float footprint = static_cast<float>(state.range(4)) / 100.0f;
  const Setup s = make_setup(alpha, theta, edge, footprint);
  for (auto _ : state) {
    const double exact = exact_integral(s);
    const char *names[] = {"cap", "disk", "slopes"};
    const Mapping maps[] = {Mapping::Cap, Mapping::Disk, Mapping::Slopes};
    for (int k = 0; k < 3; ++k) {
      const Error q = pixel_error(s, exact, maps[k], Sampler::Renderer, spp);
      const Error r = pixel_error(s, exact, maps[k], Sampler::Independent, spp);
      state.counters[std::string("qmc_") + names[k]] = q.rel_rmse;
      state.counters[std::string("ind_") + names[k]] = r.rel_rmse;
      state.counters[std::string("z_") + names[k]] = r.z_mean;
    }
    state.counters["owen_cap"] = pixel_error(s, exact, Mapping::Cap, Sampler::OwenPerNode, spp).rel_rmse;
    state.counters["rot_cap"] = pixel_error(s, exact, Mapping::Cap, Sampler::Rotated, spp).rel_rmse;
    state.counters["rot_slopes"] = pixel_error(s, exact, Mapping::Slopes, Sampler::Rotated, spp).rel_rmse;
    if (footprint > 0.0f) {
      state.counters["padded_cap"] = pixel_error(s, exact, Mapping::Cap, Sampler::Padded, spp).rel_rmse;
      state.counters["j4d23_cap"] = pixel_error(s, exact, Mapping::Cap, Sampler::Joint4D, spp).rel_rmse;
    }
    state.counters["exact"] = exact;
  }
}
// Arguments: alpha x 100, view angle (degrees), emitter on the peak (0) or with the peak on its rim (1), spp,
// pixel footprint x 100 (rad).
void GgxMappingArgs(benchmark::internal::Benchmark *b) {
  for (int a : {5, 10, 30})
    for (int theta : {0, 45, 75})
      for (int edge : {0, 1})
        for (int spp : {16, 64, 256}) b->Args({a, theta, edge, spp, 0});
  // Scene (c)'s highlight: alpha 0.09 (roughness 0.3), view about 45 degrees, the reflected direction sweeping
  // about 0.2 rad across one pixel of the sphere.
  for (int edge : {0, 1})
    for (int spp : {16, 64, 256}) b->Args({10, 45, edge, spp, 20});
}
BENCHMARK(BM_GgxMappingRmse)->Apply(GgxMappingArgs)->Iterations(1)->Unit(benchmark::kMillisecond);

}  // namespace
