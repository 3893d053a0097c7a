// Texture and utility nodes (bridge/render/nodes/): each node, compiled from a one-node
// shader graph exactly as the shader system compiles it, against an independent
// evaluation in this file:
//  - Noise / Musgrave / Wave: a reference Perlin noise written from the published
//    descriptions (Jenkins' generic lookup3 `hashword` loop, Perlin's gradient tables
//    written out, corner-sum interpolation instead of nested lerps) on a grid of
//    points, <= 1e-5. Negative controls: the same reference with the cubic fade of
//    Perlin's 1985 noise, or with lookup3's initial value off by one, misses by far more.
//  - Voronoi: brute force (sort every candidate point of Cycles' 3^3 neighbourhood; bisector planes for edges).
//  - Math / Vector Math / Mix / HSV / Color Ramp / Mapping / Fresnel / Layer Weight:
//    closed forms and hand-computed values, including Cycles' safe conventions.
// Parity with Blender's own Cycles: tests/addon/test_cycles_nodes_parity.py.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <fstream>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "render/nodes/node_program.h"
#include "render_test_util.h"
#include "scene/scene.h"

namespace glimmer::test {
namespace {

using render::nodes::ShadingPoint;
using Attributes = std::map<std::string, std::string>;

// ---- Compiling and running one node ------------------------------------------------------------------------

struct OneNode {
  scene::ShaderGraph graph;
  render::nodes::NodeProgram program;
  std::vector<std::string> warnings;
};

std::unique_ptr<OneNode> compile_node(const std::string &type, const Attributes &attributes, const std::string &output) {
  auto one = std::make_unique<OneNode>();
  one->graph.name = "test";
  one->graph.nodes.push_back({type, "n", attributes, {"test.xml", 3}});
  one->graph.nodes.push_back({"emission", "e", {}, {"test.xml", 4}});
  const scene::ShaderLink link{"n", output, "e", "color", {"test.xml", 5}};
  one->graph.links.push_back(link);
  render::nodes::BuildHooks hooks;
  hooks.external = [](const scene::ShaderLink &, render::nodes::SocketType &) { return -1; };
  hooks.warn = [w = &one->warnings](const scene::SourceLocation &where, const std::string &m) {
    w->push_back(where.str() + ": " + m);
  };
  one->program = render::nodes::compile_program(one->graph, link, hooks);
  return one;
}

Vec3 run(const OneNode &n, const ShadingPoint &sp) {
  return n.program.eval(sp, [](int, const ShadingPoint &) { return Vec3(0.0f); });
}

Vec3 eval_node(const std::string &type, const Attributes &attributes, const std::string &output,
               const ShadingPoint &sp = ShadingPoint{}) {
  return run(*compile_node(type, attributes, output), sp);
}

std::string num(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.9g", v);
  return buf;
}
std::string vec(const Vec3 &v) { return num(v.x) + " " + num(v.y) + " " + num(v.z); }

// ---- Reference Perlin noise --------------------------------------------------------------------------------

// Bob Jenkins' lookup3 hashword(k, length, initval) as published (generic loop).
uint32_t hashword(const uint32_t *k, size_t length, uint32_t initval) {
  auto rot = [](uint32_t x, int r) { return (x << r) | (x >> (32 - r)); };
  uint32_t a, b, c;
  a = b = c = 0xdeadbeefu + (static_cast<uint32_t>(length) << 2) + initval;
  while (length > 3) {
    a += k[0]; b += k[1]; c += k[2];
    a -= c; a ^= rot(c, 4); c += b;
    b -= a; b ^= rot(a, 6); a += c;
    c -= b; c ^= rot(b, 8); b += a;
    a -= c; a ^= rot(c, 16); c += b;
    b -= a; b ^= rot(a, 19); a += c;
    c -= b; c ^= rot(b, 4); b += a;
    length -= 3;
    k += 3;
  }
  switch (length) {
    case 3: c += k[2]; [[fallthrough]];
    case 2: b += k[1]; [[fallthrough]];
    case 1:
      a += k[0];
      c ^= b; c -= rot(b, 14);
      a ^= c; a -= rot(c, 11);
      b ^= a; b -= rot(a, 25);
      c ^= b; c -= rot(b, 16);
      a ^= c; a -= rot(c, 4);
      b ^= a; b -= rot(a, 14);
      c ^= b; c -= rot(b, 24);
      break;
    default: break;
  }
  return c;
}

struct Reference {
  bool cubic_fade = false;   // negative control: 3t^2 - 2t^3
  uint32_t initval = 13;     // Cycles hashes with initval 13; negative control: 14

  uint32_t lattice_hash(const std::vector<int> &cell) const {
    std::vector<uint32_t> k(cell.begin(), cell.end());
    return hashword(k.data(), k.size(), initval);
  }
  float fade(float t) const {
    return cubic_fade ? t * t * (3.0f - 2.0f * t) : ((6.0f * t - 15.0f) * t + 10.0f) * t * t * t;
  }
  // Gradient vectors, written out (Perlin's improved-noise set in 3D; Cycles' sets in 1D, 2D, 4D).
  static std::vector<float> gradient(uint32_t h, int dims) {
    if (dims == 1) {
      const float g = static_cast<float>(1 + (h & 7));
      return {(h & 8) ? -g : g};
    }
    if (dims == 2) {
      static const float g2[8][2] = {{1, 2}, {-1, 2}, {1, -2}, {-1, -2}, {2, 1}, {2, -1}, {-2, 1}, {-2, -1}};
      return {g2[h & 7][0], g2[h & 7][1]};
    }
    if (dims == 3) {
      static const float g3[16][3] = {{1, 1, 0},  {-1, 1, 0},  {1, -1, 0}, {-1, -1, 0}, {1, 0, 1},  {-1, 0, 1},
                                      {1, 0, -1}, {-1, 0, -1}, {0, 1, 1},  {0, -1, 1},  {0, 1, -1}, {0, -1, -1},
                                      {1, 1, 0},  {0, -1, 1},  {-1, 1, 0}, {0, -1, -1}};
      return {g3[h & 15][0], g3[h & 15][1], g3[h & 15][2]};
    }
    // 4D: 32 gradients with three +-1 entries; which axis is zero depends on the range of h.
    const uint32_t k = h & 31;
    std::vector<float> g(4, 0.0f);
    const int first = k < 24 ? 0 : 1, second = k < 16 ? 1 : 2, third = k < 8 ? 2 : 3;
    g[first] += (k & 1) ? -1.0f : 1.0f;
    g[second] += (k & 2) ? -1.0f : 1.0f;
    g[third] += (k & 4) ? -1.0f : 1.0f;
    return g;
  }
  // Sum over the 2^N cell corners of (product of fade weights) * (gradient . offset), times Cycles' scale.
  float signed_noise(const std::vector<float> &p) const {
    const int n = static_cast<int>(p.size());
    std::vector<int> cell(n);
    std::vector<float> f(n);
    for (int i = 0; i < n; ++i) {
      cell[i] = static_cast<int>(std::floor(p[i]));
      f[i] = p[i] - std::floor(p[i]);
    }
    double sum = 0.0;
    for (int corner = 0; corner < (1 << n); ++corner) {
      std::vector<int> c(n);
      double weight = 1.0, g_dot = 0.0;
      for (int i = 0; i < n; ++i) {
        const int bit = (corner >> i) & 1;
        c[i] = cell[i] + bit;
        const float s = fade(f[i]);
        weight *= bit ? s : 1.0f - s;
      }
      const std::vector<float> g = gradient(lattice_hash(c), n);
      for (int i = 0; i < n; ++i) g_dot += g[i] * (f[i] - ((corner >> i) & 1));
      sum += weight * g_dot;
    }
    static const double scale[5] = {0.0, 0.2500, 0.6616, 0.9820, 0.8344};
    return static_cast<float>(sum * scale[n]);
  }
  float fbm(std::vector<float> p, float octaves, float roughness) const {
    octaves = std::clamp(octaves, 0.0f, 15.0f);
    double sum = 0.0, norm = 0.0, amplitude = 1.0;
    const int whole = static_cast<int>(std::floor(octaves));
    std::vector<float> q(p.size());
    auto octave = [&](int i) {
      for (size_t d = 0; d < p.size(); ++d) q[d] = p[d] * std::pow(2.0f, static_cast<float>(i));
      return signed_noise(q);
    };
    for (int i = 0; i <= whole; ++i) {
      sum += amplitude * octave(i);
      norm += amplitude;
      amplitude *= std::clamp(roughness, 0.0f, 1.0f);
    }
    const double value = 0.5 * sum / norm + 0.5;
    const double frac = octaves - whole;
    if (frac == 0.0) return static_cast<float>(value);
    const double more = 0.5 * (sum + amplitude * octave(whole + 1)) / (norm + amplitude) + 0.5;
    return static_cast<float>((1.0 - frac) * value + frac * more);
  }
  float hash01(const std::vector<float> &k) const {
    std::vector<uint32_t> w;
    for (float f : k) w.push_back(std::bit_cast<uint32_t>(f));
    return static_cast<float>(hashword(w.data(), w.size(), initval)) / 4294967295.0f;
  }
  // The Noise texture: distortion by noise at per-axis offsets, fBM, colour channels at more offsets.
  Vec3 noise_texture(std::vector<float> p, float detail, float roughness, float distortion) const {
    const size_t n = p.size();
    auto offset = [&](int seed) {
      std::vector<float> o(n);
      for (size_t i = 0; i < n; ++i)
        o[i] = 100.0f + 100.0f * (n == 1 ? hash01({static_cast<float>(seed)})
                                         : hash01({static_cast<float>(seed), static_cast<float>(i)}));
      return o;
    };
    auto shifted = [&](const std::vector<float> &a, const std::vector<float> &o) {
      std::vector<float> r(n);
      for (size_t i = 0; i < n; ++i) r[i] = a[i] + o[i];
      return r;
    };
    if (distortion != 0.0f) {
      std::vector<float> warped = p;
      for (size_t i = 0; i < n; ++i) warped[i] += distortion * signed_noise(shifted(p, offset(static_cast<int>(i))));
      p = warped;
    }
    return {fbm(p, detail, roughness), fbm(shifted(p, offset(static_cast<int>(n))), detail, roughness),
            fbm(shifted(p, offset(static_cast<int>(n) + 1)), detail, roughness)};
  }
};

// Grid of shading points (generated coordinates) and w values.
struct GridPoint {
  Vec3 co;
  float w;
};
std::vector<GridPoint> grid() {
  std::vector<GridPoint> g;
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < 6; ++j)
      for (int k = 0; k < 4; ++k)
        g.push_back({Vec3(-1.37f + 0.53f * i, -0.91f + 0.47f * j, 0.13f + 0.61f * k), -0.7f + 0.37f * (i + j + k)});
  return g;
}

std::vector<float> dims_point(int dims, const Vec3 &v, float w) {
  switch (dims) {
    case 1: return {w};
    case 2: return {v.x, v.y};
    case 3: return {v.x, v.y, v.z};
    default: return {v.x, v.y, v.z, w};
  }
}

// Largest |node - reference| over the grid of the noise value (fac, the colour's red channel) and of
// the colour's green and blue channels.
struct NoiseError {
  double fac = 0.0, color = 0.0;
};
NoiseError noise_error(int dims, float scale, float detail, float roughness, float distortion, const Reference &ref) {
  const char *names[] = {"", "1D", "2D", "3D", "4D"};
  auto node = compile_node("noise_texture",
                           {{"dimensions", names[dims]}, {"scale", num(scale)}, {"detail", num(detail)},
                            {"roughness", num(roughness)}, {"distortion", num(distortion)}},
                           "color");
  auto fac = compile_node("noise_texture",
                          {{"dimensions", names[dims]}, {"scale", num(scale)}, {"detail", num(detail)},
                           {"roughness", num(roughness)}, {"distortion", num(distortion)}},
                          "fac");
  NoiseError worst;
  for (const GridPoint &g : grid()) {
    ShadingPoint sp;
    sp.generated = g.co;
    // w is an input socket: use a second node with w set (the vector input reads generated coordinates).
    auto with_w = compile_node("noise_texture",
                               {{"dimensions", names[dims]}, {"scale", num(scale)}, {"detail", num(detail)},
                                {"roughness", num(roughness)}, {"distortion", num(distortion)}, {"w", num(g.w)}},
                               "color");
    const Vec3 got = run(*with_w, sp);
    const Vec3 expected = ref.noise_texture(dims_point(dims, g.co * scale, g.w * scale), detail, roughness, distortion);
    worst.fac = std::max(worst.fac, std::fabs(double(got.x - expected.x)));
    worst.color = std::max({worst.color, std::fabs(double(got.y - expected.y)), std::fabs(double(got.z - expected.z))});
    EXPECT_EQ(run(*fac, sp).x, run(*node, sp).x) << "fac is the colour's red channel (w = 0)";
  }
  return worst;
}

TEST(Nodes, NoiseMatchesReferencePerlinOnAGrid) {
  const Reference ref;
  for (int dims = 1; dims <= 4; ++dims) {
    SCOPED_TRACE("dimensions " + std::to_string(dims));
    const NoiseError one = noise_error(dims, 2.3f, 0.0f, 0.5f, 0.0f, ref);
    const NoiseError fbm = noise_error(dims, 1.7f, 3.0f, 0.6f, 0.0f, ref);
    const NoiseError distorted = noise_error(dims, 1.1f, 2.5f, 0.45f, 0.8f, ref);
    EXPECT_LE(std::max(one.fac, one.color), 1e-5) << "one octave";
    EXPECT_LE(std::max(fbm.fac, fbm.color), 1e-5) << "fBM, 4 octaves";
    EXPECT_LE(distorted.fac, 1e-5) << "fractional detail, distortion";
    // With distortion, the colour's green and blue channels are noise at coordinates offset by 100..200,
    // where one float step is 7.6e-6..1.5e-5: a last-bit difference in a distorted coordinate moves them by
    // about that much times the gradient. Held to 4 float steps at 200.
    EXPECT_LE(distorted.color, 4 * 1.5e-5) << "colour channels, distortion";
    std::printf("noise %dD: max |error| one octave %.2g, fBM %.2g, distorted fac %.2g, distorted colour %.2g\n", dims,
                std::max(one.fac, one.color), std::max(fbm.fac, fbm.color), distorted.fac, distorted.color);
  }
}

TEST(Nodes, NoiseReferenceNegativeControls) {
  Reference cubic;
  cubic.cubic_fade = true;
  Reference seed;
  seed.initval = 14;
  for (int dims = 1; dims <= 4; ++dims) {
    SCOPED_TRACE("dimensions " + std::to_string(dims));
    EXPECT_GT(noise_error(dims, 2.3f, 0.0f, 0.5f, 0.0f, cubic).fac, 1e-3);
    EXPECT_GT(noise_error(dims, 2.3f, 0.0f, 0.5f, 0.0f, seed).fac, 1e-2);
  }
}

TEST(Nodes, NoiseReferenceHashIsLookup3) {
  // hashword of no bytes is the initial value itself: a sanity check of the loop's set-up.
  EXPECT_EQ(hashword(nullptr, 0, 0), 0xdeadbeefu);
  // Noise is zero on lattice points (every gradient is dotted with a zero offset).
  const Reference ref;
  EXPECT_EQ(ref.signed_noise({2.0f, -3.0f, 5.0f}), 0.0f);
  EXPECT_EQ(eval_node("noise_texture", {{"scale", "1"}, {"detail", "0"}}, "fac", [] {
              ShadingPoint sp;
              sp.generated = Vec3(2.0f, -3.0f, 5.0f);
              return sp;
            }()).x, 0.5f);
}

TEST(Nodes, MusgraveFbmIsAWeightedSumOfReferenceNoise) {
  const Reference ref;
  const float H = 1.3f, lacunarity = 2.2f, detail = 3.5f, scale = 1.4f;
  auto node = compile_node("musgrave_texture",
                           {{"musgrave_type", "fBM"}, {"scale", num(scale)}, {"detail", num(detail)},
                            {"dimension", num(H)}, {"lacunarity", num(lacunarity)}},
                           "fac");
  auto ridged = compile_node("musgrave_texture",
                             {{"musgrave_type", "ridged_multifractal"}, {"scale", num(scale)}, {"detail", "1"},
                              {"offset", "1"}, {"gain", "2"}},
                             "fac");
  double worst = 0.0;
  for (const GridPoint &g : grid()) {
    ShadingPoint sp;
    sp.generated = g.co;
    std::vector<float> p = dims_point(3, g.co * scale, 0.0f);
    double expected = 0.0;
    for (int i = 0; i < 4; ++i) {
      const double weight = std::pow(lacunarity, -H * i) * (i == 3 ? 0.5 : 1.0);  // 3 octaves + half of a 4th
      std::vector<float> q = p;
      for (float &c : q) c *= std::pow(lacunarity, static_cast<float>(i));
      expected += weight * ref.signed_noise(q);
    }
    worst = std::max(worst, std::fabs(run(*node, sp).x - expected));
    // One octave of ridged multifractal: (offset - |noise|)^2.
    const double r = 1.0 - std::fabs(ref.signed_noise(p));
    EXPECT_NEAR(run(*ridged, sp).x, r * r, 1e-5);
  }
  EXPECT_LE(worst, 1e-5);
}

TEST(Nodes, WaveBandsAndRingsClosedForm) {
  for (const GridPoint &g : grid()) {
    ShadingPoint sp;
    sp.generated = g.co;
    const Vec3 p = (g.co * 3.0f + Vec3(1e-6f)) * 0.999999f;
    const double bands = 0.5 + 0.5 * std::sin(20.0 * p.y + 0.4 - kPi / 2);
    EXPECT_NEAR(eval_node("wave_texture", {{"scale", "3"}, {"bands_direction", "y"}, {"phase_offset", "0.4"}}, "fac",
                          sp).x, bands, 2e-5);
    const double n = std::sqrt(p.x * p.x + p.y * p.y) * 20.0 / (2 * kPi);
    EXPECT_NEAR(eval_node("wave_texture", {{"scale", "3"}, {"wave_type", "rings"}, {"rings_direction", "z"},
                                           {"profile", "saw"}}, "fac", sp).x,
                n - std::floor(n), 2e-5);
    EXPECT_NEAR(eval_node("wave_texture", {{"scale", "3"}, {"profile", "tri"}, {"bands_direction", "diagonal"}}, "fac",
                          sp).x,
                [&] {
                  const double t = (p.x + p.y + p.z) * 10.0 / (2 * kPi);
                  return std::fabs(t - std::floor(t + 0.5)) * 2.0;
                }(),
                2e-5);
  }
  // Distortion adds distortion * (2 fBM - 1) to the phase, with fBM of the reference noise.
  const Reference ref;
  ShadingPoint sp;
  sp.generated = Vec3(0.31f, -0.72f, 0.4f);
  const Vec3 p = (sp.generated * 2.0f + Vec3(1e-6f)) * 0.999999f;
  const double phase = 20.0 * p.x + 1.5 * (2.0 * ref.fbm({p.x * 1.5f, p.y * 1.5f, p.z * 1.5f}, 2.0f, 0.5f) - 1.0);
  EXPECT_NEAR(eval_node("wave_texture", {{"scale", "2"}, {"distortion", "1.5"}, {"detail_scale", "1.5"}}, "fac", sp).x,
              0.5 + 0.5 * std::sin(phase - kPi / 2), 2e-5);
}

// ---- Voronoi: brute force --------------------------------------------------------------------------------

struct Feature {
  double distance;
  std::vector<float> cell, point;
};

// Every feature point of the 3^3 block of cells around x's cell (Cycles' candidate set), sorted by
// distance (Euclidean or Manhattan): the ranks are read off the sorted list.
std::vector<Feature> brute_force_features(const Vec3 &x, float randomness, bool manhattan, const Reference &ref) {
  std::vector<Feature> all;
  const float base[3] = {std::floor(x.x), std::floor(x.y), std::floor(x.z)};
  for (int i = -1; i <= 1; ++i)
    for (int j = -1; j <= 1; ++j)
      for (int k = -1; k <= 1; ++k) {
        const std::vector<float> c = {base[0] + i, base[1] + j, base[2] + k};
        const std::vector<float> jitter = {ref.hash01(c), ref.hash01({c[0], c[1], c[2], 1.0f}),
                                           ref.hash01({c[0], c[1], c[2], 2.0f})};
        Feature f{0.0, c, {c[0] + jitter[0] * randomness, c[1] + jitter[1] * randomness,
                          c[2] + jitter[2] * randomness}};
        const double d[3] = {f.point[0] - x.x, f.point[1] - x.y, f.point[2] - x.z};
        f.distance = manhattan ? std::fabs(d[0]) + std::fabs(d[1]) + std::fabs(d[2])
                               : std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        all.push_back(f);
      }
  std::sort(all.begin(), all.end(), [](const Feature &a, const Feature &b) { return a.distance < b.distance; });
  return all;
}

TEST(Nodes, VoronoiF1F2MatchBruteForce) {
  const Reference ref;
  for (const char *metric : {"euclidean", "manhattan"}) {
    for (const GridPoint &g : grid()) {
      ShadingPoint sp;
      sp.generated = g.co;
      const Vec3 x = g.co * 2.5f;
      const auto features = brute_force_features(x, 0.9f, std::string(metric) == "manhattan", ref);
      for (int rank = 0; rank < 2; ++rank) {
        const Attributes a = {{"metric", metric}, {"feature", rank ? "f2" : "f1"}, {"scale", "2.5"},
                              {"randomness", "0.9"}};
        const Feature &f = features[rank];
        EXPECT_NEAR(eval_node("voronoi_texture", a, "distance", sp).x, f.distance, 1e-5) << metric << " F" << rank + 1;
        const Vec3 position = eval_node("voronoi_texture", a, "position", sp) * 2.5f;
        EXPECT_NEAR(position.x, f.point[0], 1e-5);
        EXPECT_NEAR(position.z, f.point[2], 1e-5);
        const Vec3 color = eval_node("voronoi_texture", a, "color", sp);
        EXPECT_EQ(color.x, ref.hash01(f.cell));
        EXPECT_EQ(color.z, ref.hash01({f.cell[0], f.cell[1], f.cell[2], 2.0f}));
      }
    }
  }
}

TEST(Nodes, VoronoiSphereRadiusAndEdgeMatchBruteForce) {
  const Reference ref;
  for (const GridPoint &g : grid()) {
    ShadingPoint sp;
    sp.generated = g.co;
    const Vec3 x = g.co * 2.0f;
    const auto features = brute_force_features(x, 1.0f, false, ref);
    // n-sphere radius: half the distance from the nearest point to the nearest other point.
    const Feature &nearest = features[0];
    const Vec3 c(nearest.point[0], nearest.point[1], nearest.point[2]);
    const auto around = brute_force_features(c, 1.0f, false, ref);
    EXPECT_NEAR(eval_node("voronoi_texture", {{"feature", "n_sphere_radius"}, {"scale", "2"}}, "radius", sp).x,
                around[1].distance / 2.0, 1e-5);
    // Distance to the nearest edge: the smallest distance from x to a bisector plane of the nearest and another point.
    double edge = 1e9;
    for (size_t i = 1; i < features.size(); ++i) {
      const Vec3 q(features[i].point[0], features[i].point[1], features[i].point[2]);
      const Vec3 n = normalize(q - c);
      edge = std::min(edge, double(dot((c + q) * 0.5f - x, n)));
    }
    EXPECT_NEAR(eval_node("voronoi_texture", {{"feature", "distance_to_edge"}, {"scale", "2"}}, "distance", sp).x,
                edge, 1e-5);
  }
}

TEST(Nodes, VoronoiSmoothF1ApproachesF1) {
  ShadingPoint sp;
  sp.generated = Vec3(0.3f, 0.8f, -0.2f);
  const float f1 = eval_node("voronoi_texture", {{"scale", "3"}}, "distance", sp).x;
  EXPECT_NEAR(eval_node("voronoi_texture", {{"scale", "3"}, {"feature", "smooth_f1"}, {"smoothness", "0"}}, "distance",
                        sp).x, f1, 1e-6);
  EXPECT_LT(eval_node("voronoi_texture", {{"scale", "3"}, {"feature", "smooth_f1"}, {"smoothness", "1"}}, "distance",
                      sp).x, f1);
}

// ---- Math ---------------------------------------------------------------------------------------------------

float math(const std::string &op, float a, float b = 0.0f, float c = 0.0f, bool clamp = false) {
  return eval_node("math",
                   {{"math_type", op}, {"value1", num(a)}, {"value2", num(b)}, {"value3", num(c)},
                    {"use_clamp", clamp ? "true" : "false"}},
                   "value").x;
}

TEST(Nodes, MathOperationsAgainstStd) {
  const float values[] = {-2.5f, -1.0f, -0.3f, 0.0f, 0.4f, 1.0f, 2.0f, 3.7f};
  for (float a : values)
    for (float b : values) {
      SCOPED_TRACE(num(a) + ", " + num(b));
      EXPECT_FLOAT_EQ(math("add", a, b), a + b);
      EXPECT_FLOAT_EQ(math("subtract", a, b), a - b);
      EXPECT_FLOAT_EQ(math("multiply", a, b), a * b);
      EXPECT_FLOAT_EQ(math("divide", a, b), b == 0.0f ? 0.0f : a / b);
      EXPECT_FLOAT_EQ(math("multiply_add", a, b, 0.7f), a * b + 0.7f);
      EXPECT_FLOAT_EQ(math("minimum", a, b), std::min(a, b));
      EXPECT_FLOAT_EQ(math("maximum", a, b), std::max(a, b));
      EXPECT_FLOAT_EQ(math("less_than", a, b), a < b ? 1.0f : 0.0f);
      EXPECT_FLOAT_EQ(math("greater_than", a, b), a > b ? 1.0f : 0.0f);
      EXPECT_FLOAT_EQ(math("arctan2", a, b), std::atan2(a, b));
      EXPECT_FLOAT_EQ(math("modulo", a, b), b == 0.0f ? 0.0f : std::fmod(a, b));
      const bool whole = std::trunc(b) == b;
      const float pw = std::pow(a, b);
      EXPECT_FLOAT_EQ(math("power", a, b), (a < 0.0f && !whole) || !std::isfinite(pw) ? 0.0f : pw);
      EXPECT_FLOAT_EQ(math("logarithm", a, b),
                      a <= 0.0f || b <= 0.0f || std::log(b) == 0.0f ? 0.0f : std::log(a) / std::log(b));
      EXPECT_FLOAT_EQ(math("snap", a, b), b == 0.0f ? 0.0f : std::floor(a / b) * b);
      EXPECT_FLOAT_EQ(math("compare", a, b, 0.5f), std::fabs(a - b) <= 0.5f ? 1.0f : 0.0f);
      EXPECT_FLOAT_EQ(math("add", a, b, 0.0f, true), std::clamp(a + b, 0.0f, 1.0f));
    }
  for (float a : values) {
    SCOPED_TRACE(num(a));
    EXPECT_FLOAT_EQ(math("sine", a), std::sin(a));
    EXPECT_FLOAT_EQ(math("cosine", a), std::cos(a));
    EXPECT_FLOAT_EQ(math("tangent", a), std::tan(a));
    EXPECT_FLOAT_EQ(math("sinh", a), std::sinh(a));
    EXPECT_FLOAT_EQ(math("cosh", a), std::cosh(a));
    EXPECT_FLOAT_EQ(math("tanh", a), std::tanh(a));
    EXPECT_FLOAT_EQ(math("arcsine", a), std::asin(std::clamp(a, -1.0f, 1.0f)));
    EXPECT_FLOAT_EQ(math("arccosine", a), std::acos(std::clamp(a, -1.0f, 1.0f)));
    EXPECT_FLOAT_EQ(math("arctangent", a), std::atan(a));
    EXPECT_FLOAT_EQ(math("round", a), std::floor(a + 0.5f));
    EXPECT_FLOAT_EQ(math("absolute", a), std::fabs(a));
    EXPECT_FLOAT_EQ(math("floor", a), std::floor(a));
    EXPECT_FLOAT_EQ(math("ceil", a), std::ceil(a));
    EXPECT_FLOAT_EQ(math("fraction", a), a - std::floor(a));
    EXPECT_FLOAT_EQ(math("sqrt", a), a > 0.0f ? std::sqrt(a) : 0.0f);
    EXPECT_FLOAT_EQ(math("inversesqrt", a), a > 0.0f ? 1.0f / std::sqrt(a) : 0.0f);
    EXPECT_FLOAT_EQ(math("sign", a), a > 0.0f ? 1.0f : (a < 0.0f ? -1.0f : 0.0f));
    EXPECT_FLOAT_EQ(math("exponent", a), std::exp(a));
    EXPECT_FLOAT_EQ(math("radians", a), a * kPi / 180.0f);
    EXPECT_FLOAT_EQ(math("degrees", a), a * 180.0f / kPi);
    EXPECT_FLOAT_EQ(math("trunc", a), std::trunc(a));
  }
  // Hand-computed values of the less common operations.
  EXPECT_FLOAT_EQ(math("wrap", 5.5f, 2.0f, 0.0f), 1.5f);
  EXPECT_FLOAT_EQ(math("wrap", -0.5f, 3.0f, 1.0f), 1.5f);
  EXPECT_FLOAT_EQ(math("wrap", 7.0f, 1.0f, 1.0f), 1.0f);  // empty range: the minimum
  EXPECT_FLOAT_EQ(math("pingpong", 2.5f, 2.0f), 1.5f);
  EXPECT_FLOAT_EQ(math("pingpong", 5.0f, 2.0f), 1.0f);
  EXPECT_FLOAT_EQ(math("pingpong", 5.0f, 0.0f), 0.0f);
  EXPECT_FLOAT_EQ(math("smoothmin", 1.0f, 1.0f, 1.0f), 1.0f - 1.0f / 6.0f);
  EXPECT_FLOAT_EQ(math("smoothmin", 0.0f, 3.0f, 1.0f), 0.0f);  // farther apart than c: plain min
  EXPECT_FLOAT_EQ(math("smoothmax", 1.0f, 1.0f, 1.0f), 1.0f + 1.0f / 6.0f);
  EXPECT_FLOAT_EQ(math("power", -2.0f, 3.0f), -8.0f);
  EXPECT_FLOAT_EQ(math("power", -2.0f, 0.5f), 0.0f);
  EXPECT_FLOAT_EQ(math("power", 0.0f, -1.0f), 0.0f);  // Inf -> 0
  EXPECT_FLOAT_EQ(math("logarithm", 8.0f, 2.0f), 3.0f);
}

TEST(Nodes, MathRejectsUnknownOperationWithFileLine) {
  try {
    compile_node("math", {{"math_type", "cube"}}, "value");
    FAIL() << "no error";
  } catch (const scene::SceneError &e) {
    EXPECT_NE(std::string(e.what()).find("test.xml:3"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("smoothmax"), std::string::npos) << e.what();
  }
  try {
    compile_node("math", {}, "result");
    FAIL() << "no error";
  } catch (const scene::SceneError &e) {
    EXPECT_NE(std::string(e.what()).find("its outputs: value"), std::string::npos) << e.what();
  }
}

// ---- Vector Math ---------------------------------------------------------------------------------------------

Vec3 vmath(const std::string &op, const Vec3 &a, const Vec3 &b = Vec3(0.0f), const Vec3 &c = Vec3(0.0f),
           float scale = 1.0f, const char *out = "vector") {
  return eval_node("vector_math",
                   {{"math_type", op}, {"vector1", vec(a)}, {"vector2", vec(b)}, {"vector3", vec(c)},
                    {"scale", num(scale)}},
                   out);
}

void expect_vec(const Vec3 &got, const Vec3 &want, float tol = 1e-6f) {
  EXPECT_NEAR(got.x, want.x, tol);
  EXPECT_NEAR(got.y, want.y, tol);
  EXPECT_NEAR(got.z, want.z, tol);
}

TEST(Nodes, VectorMathOperations) {
  const Vec3 a(1.5f, -2.0f, 0.5f), b(0.0f, 3.0f, -1.0f), c(2.0f, 2.0f, 2.0f);
  expect_vec(vmath("add", a, b), a + b);
  expect_vec(vmath("subtract", a, b), a - b);
  expect_vec(vmath("multiply", a, b), a * b);
  expect_vec(vmath("divide", a, b), Vec3(0.0f, -2.0f / 3.0f, -0.5f));
  expect_vec(vmath("multiply_add", a, b, c), a * b + c);
  expect_vec(vmath("cross_product", a, b), cross(a, b));
  expect_vec(vmath("project", a, b), b * (dot(a, b) / dot(b, b)));
  expect_vec(vmath("reflect", a, Vec3(0, 0, 2)), Vec3(1.5f, -2.0f, -0.5f));
  expect_vec(vmath("reflect", a, Vec3(0.0f)), a);  // zero normal: unchanged (Cycles: NaN)
  // Refraction with eta 1: straight through; total internal reflection: zero.
  expect_vec(vmath("refract", normalize(Vec3(1, 0, -1)), Vec3(0, 0, 1), Vec3(0.0f), 1.0f), normalize(Vec3(1, 0, -1)));
  expect_vec(vmath("refract", normalize(Vec3(1, 0, -0.2f)), Vec3(0, 0, 1), Vec3(0.0f), 1.5f), Vec3(0.0f));
  expect_vec(vmath("faceforward", a, Vec3(0, 0, 1), Vec3(0, 0, -1)), a);
  expect_vec(vmath("faceforward", a, Vec3(0, 0, 1), Vec3(0, 0, 1)), -a);
  EXPECT_FLOAT_EQ(vmath("dot_product", a, b, c, 1, "value").x, dot(a, b));
  EXPECT_FLOAT_EQ(vmath("distance", a, b, c, 1, "value").x, length(a - b));
  EXPECT_FLOAT_EQ(vmath("length", a, b, c, 1, "value").x, length(a));
  expect_vec(vmath("scale", a, b, c, 2.5f), a * 2.5f);
  expect_vec(vmath("normalize", a), a / length(a));
  expect_vec(vmath("normalize", Vec3(0.0f)), Vec3(0.0f));
  expect_vec(vmath("snap", Vec3(1.7f, -1.2f, 5.0f), Vec3(0.5f, 0.5f, 0.0f)), Vec3(1.5f, -1.5f, 0.0f));
  expect_vec(vmath("floor", a), Vec3(1, -2, 0));
  expect_vec(vmath("ceil", a), Vec3(2, -2, 1));
  expect_vec(vmath("modulo", Vec3(5.5f, -5.5f, 1.0f), Vec3(2.0f, 2.0f, 0.0f)), Vec3(1.5f, -1.5f, 0.0f));
  expect_vec(vmath("wrap", Vec3(5.5f, -0.5f, 0.2f), Vec3(2, 3, 1), Vec3(0, 1, 0)), Vec3(1.5f, 1.5f, 0.2f));
  expect_vec(vmath("fraction", a), Vec3(0.5f, 0.0f, 0.5f));
  expect_vec(vmath("absolute", a), abs(a));
  expect_vec(vmath("minimum", a, b), min(a, b));
  expect_vec(vmath("maximum", a, b), max(a, b));
  expect_vec(vmath("sine", a), Vec3(std::sin(a.x), std::sin(a.y), std::sin(a.z)));
  expect_vec(vmath("cosine", a), Vec3(std::cos(a.x), std::cos(a.y), std::cos(a.z)));
  expect_vec(vmath("tangent", a), Vec3(std::tan(a.x), std::tan(a.y), std::tan(a.z)), 1e-5f);
}

// ---- Mix, HSV, Color Ramp ------------------------------------------------------------------------------------

Vec3 mix(const std::string &mode, float fac, const Vec3 &c1, const Vec3 &c2, bool clamp = false) {
  return eval_node("mix",
                   {{"mix_type", mode}, {"fac", num(fac)}, {"color1", vec(c1)}, {"color2", vec(c2)},
                    {"use_clamp", clamp ? "true" : "false"}},
                   "color");
}

TEST(Nodes, MixBlendModesAgainstFormulas) {
  const Vec3 a(0.2f, 0.6f, 0.9f), b(0.7f, 0.3f, 0.0f);
  const float t = 0.4f, s = 0.6f;  // s = 1 - t
  expect_vec(mix("mix", t, a, b), s * a + t * b);
  expect_vec(mix("add", t, a, b), a + t * b);
  expect_vec(mix("multiply", t, a, b), s * a + t * a * b);
  expect_vec(mix("subtract", t, a, b), a - t * b);
  expect_vec(mix("screen", t, a, b), Vec3(1.0f) - (Vec3(s) + t * (Vec3(1.0f) - b)) * (Vec3(1.0f) - a));
  // Overlay per channel: a < 0.5 -> a (s + 2 t b), else 1 - (s + 2 t (1 - b)) (1 - a).
  expect_vec(mix("overlay", t, a, b), Vec3(0.2f * (s + 2 * t * 0.7f), 1 - (s + 2 * t * 0.7f) * 0.4f,
                                           1 - (s + 2 * t * 1.0f) * (1 - 0.9f)));
  expect_vec(mix("divide", t, a, b), Vec3(s * 0.2f + t * 0.2f / 0.7f, s * 0.6f + t * 0.6f / 0.3f, 0.9f));
  expect_vec(mix("difference", t, a, b), s * a + t * abs(a - b));
  expect_vec(mix("darken", t, a, b), s * a + t * min(a, b));
  expect_vec(mix("lighten", t, a, b), s * a + t * max(a, b));
  expect_vec(mix("dodge", t, a, b), Vec3(0.2f / (1 - t * 0.7f), std::min(0.6f / (1 - t * 0.3f), 1.0f), 0.9f));
  expect_vec(mix("burn", t, a, b), Vec3(std::max(1 - 0.8f / (s + t * 0.7f), 0.0f), 1 - 0.4f / (s + t * 0.3f),
                                        1 - 0.1f / s));
  expect_vec(mix("soft_light", t, a, b),
             s * a + t * ((Vec3(1.0f) - a) * b * a + a * (Vec3(1.0f) - (Vec3(1.0f) - b) * (Vec3(1.0f) - a))));
  expect_vec(mix("linear_light", t, a, b), a + t * (2.0f * b - Vec3(1.0f)));
  // HSV modes with pure colours: red's value blended with a dark green's; blue's hue onto grey-free red.
  expect_vec(mix("value", 0.5f, Vec3(1, 0, 0), Vec3(0, 0.5f, 0)), Vec3(0.75f, 0, 0));
  expect_vec(mix("hue", 1.0f, Vec3(1, 0, 0), Vec3(0, 0, 0.3f)), Vec3(0, 0, 1));
  expect_vec(mix("saturation", 1.0f, Vec3(1, 0.5f, 0.5f), Vec3(0, 0, 1)), Vec3(1, 0, 0));
  expect_vec(mix("color", 1.0f, Vec3(0.5f, 0.5f, 1.0f), Vec3(0, 0.8f, 0)), Vec3(0, 1, 0));
  expect_vec(mix("hue", 1.0f, a, Vec3(0.3f)), a);  // a grey has no hue: unchanged
  // Factor clamped to [0, 1]; use_clamp clamps the result.
  expect_vec(mix("mix", 2.0f, a, b), b);
  expect_vec(mix("add", 1.0f, a, b, true), Vec3(0.9f, 0.9f, 0.9f));
  expect_vec(mix("add", 1.0f, Vec3(0.8f), Vec3(0.7f), true), Vec3(1.0f));
}

TEST(Nodes, HueSaturationValue) {
  auto hsv = [](float h, float s, float v, float fac, const Vec3 &c) {
    return eval_node("hsv", {{"hue", num(h)}, {"saturation", num(s)}, {"value", num(v)}, {"fac", num(fac)},
                             {"color", vec(c)}}, "color");
  };
  expect_vec(hsv(0.5f, 1, 1, 1, Vec3(0.3f, 0.6f, 0.9f)), Vec3(0.3f, 0.6f, 0.9f));  // neutral settings
  expect_vec(hsv(0.5f + 1.0f / 3.0f, 1, 1, 1, Vec3(1, 0, 0)), Vec3(0, 1, 0));        // red -> green
  expect_vec(hsv(0.5f, 0, 1, 1, Vec3(1, 0.5f, 0)), Vec3(1, 1, 1));                   // desaturate: value stays
  expect_vec(hsv(0.5f, 1, 0.5f, 1, Vec3(1, 0.5f, 0)), Vec3(0.5f, 0.25f, 0));
  expect_vec(hsv(0.5f, 1, 0.5f, 0.5f, Vec3(1, 0.5f, 0)), Vec3(0.75f, 0.375f, 0));    // fac blends
}

TEST(Nodes, ColorRampLinearAndConstant) {
  const Attributes table = {{"ramp", "0 0 0  1 0.5 0  0 0 1"}, {"ramp_alpha", "1 0.5 0"}};
  auto ramp = [&](float fac, bool interpolate, const char *out = "color") {
    Attributes a = table;
    a["fac"] = num(fac);
    a["interpolate"] = interpolate ? "true" : "false";
    return eval_node("rgb_ramp", a, out);
  };
  // Three entries at fac 0, 0.5, 1.
  expect_vec(ramp(0.25f, true), Vec3(0.5f, 0.25f, 0.0f));
  expect_vec(ramp(0.75f, true), Vec3(0.5f, 0.25f, 0.5f));
  EXPECT_FLOAT_EQ(ramp(0.75f, true, "alpha").x, 0.25f);
  expect_vec(ramp(0.75f, false), Vec3(1.0f, 0.5f, 0.0f));  // the entry at or below
  expect_vec(ramp(-3.0f, true), Vec3(0.0f));
  expect_vec(ramp(7.0f, true), Vec3(0, 0, 1));
  EXPECT_THROW(compile_node("rgb_ramp", {{"ramp", "0 0"}}, "color"), scene::SceneError);
  EXPECT_THROW(compile_node("rgb_ramp", {{"ramp", "0 0 0 1 1 1"}, {"ramp_alpha", "1"}}, "color"), scene::SceneError);
}

// ---- Mapping, texture coordinates, Fresnel, Layer Weight -------------------------------------------------------

TEST(Nodes, MappingRotatesScalesTranslates) {
  auto map = [](const char *type, const Vec3 &v, const Vec3 &loc, const Vec3 &rot, const Vec3 &scale) {
    return eval_node("mapping", {{"mapping_type", type}, {"vector", vec(v)}, {"location", vec(loc)},
                                 {"rotation", vec(rot)}, {"scale", vec(scale)}}, "vector");
  };
  const float q = kPi / 2;
  expect_vec(map("point", Vec3(1, 0, 0), Vec3(0.0f), Vec3(0, 0, q), Vec3(1.0f)), Vec3(0, 1, 0));
  expect_vec(map("point", Vec3(0, 1, 0), Vec3(0.0f), Vec3(q, 0, 0), Vec3(1.0f)), Vec3(0, 0, 1));
  expect_vec(map("point", Vec3(0, 0, 1), Vec3(0.0f), Vec3(0, q, 0), Vec3(1.0f)), Vec3(1, 0, 0));
  expect_vec(map("point", Vec3(1, 2, 3), Vec3(1, 1, 1), Vec3(0.0f), Vec3(2.0f)), Vec3(3, 5, 7));
  expect_vec(map("vector", Vec3(1, 2, 3), Vec3(1, 1, 1), Vec3(0.0f), Vec3(2.0f)), Vec3(2, 4, 6));
  // Euler XYZ: R = Rz Ry Rx, so x first: (0,1,0) -Rx(90)-> (0,0,1) -Rz(90)-> (0,0,1).
  expect_vec(map("point", Vec3(0, 1, 0), Vec3(0.0f), Vec3(q, 0, q), Vec3(1.0f)), Vec3(0, 0, 1));
  // Texture mapping is the inverse of point mapping.
  const Vec3 loc(0.3f, -1.0f, 2.0f), rot(0.4f, -0.7f, 1.1f), scale(2.0f, 0.5f, 1.5f), v(0.2f, 0.9f, -0.4f);
  const Vec3 there = map("point", v, loc, rot, scale);
  expect_vec(map("texture", there, loc, rot, scale), v, 1e-5f);
  expect_vec(map("normal", Vec3(0, 0, 3), Vec3(0.0f), Vec3(0.0f), Vec3(1, 1, 2)), Vec3(0, 0, 1));
}

TEST(Nodes, FresnelAndLayerWeightClosedForms) {
  ShadingPoint sp;
  sp.N = Vec3(0, 0, 1);
  sp.direction = Vec3(0, 0, -1);  // normal incidence
  const float eta = 1.5f;
  EXPECT_NEAR(eval_node("fresnel", {{"ior", num(eta)}}, "fac", sp).x, std::pow((eta - 1) / (eta + 1), 2), 1e-6);
  // Layer weight with blend b is the Fresnel of eta = 1 / (1 - b).
  EXPECT_NEAR(eval_node("layer_weight", {{"blend", "0.2"}}, "fresnel", sp).x, std::pow((1.25 - 1) / (1.25 + 1), 2), 1e-6);
  // Oblique: Fresnel against the textbook s/p formula; facing = 1 - |cos| at blend 0.5, 1 - |cos|^(2b) below.
  const float theta = 0.9f;
  sp.direction = Vec3(std::sin(theta), 0, -std::cos(theta));
  const double ci = std::cos(theta), st = std::sin(theta) / eta, ct = std::sqrt(1 - st * st);
  const double rs = (ci - eta * ct) / (ci + eta * ct), rp = (eta * ci - ct) / (eta * ci + ct);
  EXPECT_NEAR(eval_node("fresnel", {{"ior", num(eta)}}, "fac", sp).x, 0.5 * (rs * rs + rp * rp), 1e-6);
  EXPECT_NEAR(eval_node("layer_weight", {{"blend", "0.5"}}, "facing", sp).x, 1 - ci, 1e-6);
  EXPECT_NEAR(eval_node("layer_weight", {{"blend", "0.25"}}, "facing", sp).x, 1 - std::pow(ci, 0.5), 1e-6);
  // Backfacing: the ratio inverts; beyond the critical angle, total reflection.
  sp.backfacing = true;
  EXPECT_FLOAT_EQ(eval_node("fresnel", {{"ior", num(eta)}}, "fac", sp).x, 1.0f);
  // A linked normal input replaces the shading normal.
  sp.backfacing = false;
  sp.direction = Vec3(0, 0, -1);
  sp.N = Vec3(1, 0, 0);
  EXPECT_NEAR(eval_node("fresnel", {{"ior", num(eta)}, {"normal", "0 0 1"}}, "fac", sp).x, 0.04, 1e-6);
}

TEST(Nodes, TextureCoordinateOutputs) {
  ShadingPoint sp;
  sp.P = Vec3(1, 2, 3);
  sp.N = Vec3(0, 0, 1);
  sp.generated = Vec3(0.1f, 0.2f, 0.3f);
  sp.uv[0] = 0.25f;
  sp.uv[1] = 0.75f;
  sp.direction = normalize(Vec3(1, 0, -1));
  expect_vec(eval_node("texture_coordinate", {}, "generated", sp), sp.generated);
  expect_vec(eval_node("texture_coordinate", {}, "uv", sp), Vec3(0.25f, 0.75f, 0));
  expect_vec(eval_node("texture_coordinate", {}, "reflection", sp), normalize(Vec3(1, 0, 1)));
  expect_vec(eval_node("texture_coordinate", {}, "camera", sp), sp.P);  // identity camera in this harness
  auto window = compile_node("texture_coordinate", {}, "window");
  ASSERT_EQ(window->warnings.size(), 1u);
  EXPECT_NE(window->warnings[0].find("test.xml:5"), std::string::npos) << window->warnings[0];
}

// ---- Converters, gradient, white noise ----------------------------------------------------------------------

TEST(Nodes, ConvertersClosedForms) {
  expect_vec(eval_node("value", {{"value", "0.37"}}, "value"), Vec3(0.37f));
  expect_vec(eval_node("color", {{"value", "0.1 0.2 0.3"}}, "color"), Vec3(0.1f, 0.2f, 0.3f));
  expect_vec(eval_node("invert", {{"fac", "0.25"}, {"color", "0.2 0.6 1"}}, "color"),
             0.75f * Vec3(0.2f, 0.6f, 1.0f) + 0.25f * Vec3(0.8f, 0.4f, 0.0f));
  expect_vec(eval_node("gamma", {{"color", "0.25 -0.5 4"}, {"gamma", "0.5"}}, "color"), Vec3(0.5f, -0.5f, 2.0f));
  // a = 1 + contrast, b = bright - contrast / 2, max(a c + b, 0).
  expect_vec(eval_node("brightness_contrast", {{"color", "0.5 0.1 0.9"}, {"bright", "0.1"}, {"contrast", "0.4"}}, "color"),
             Vec3(1.4f * 0.5f - 0.1f, std::max(1.4f * 0.1f - 0.1f, 0.0f), 1.4f * 0.9f - 0.1f));
  EXPECT_FLOAT_EQ(eval_node("clamp", {{"value", "2"}, {"min", "0.5"}, {"max", "1.5"}}, "result").x, 1.5f);
  EXPECT_FLOAT_EQ(eval_node("clamp", {{"value", "2"}, {"min", "1.5"}, {"max", "0.5"}}, "result").x, 0.5f);  // minmax
  EXPECT_FLOAT_EQ(eval_node("clamp", {{"clamp_type", "range"}, {"value", "2"}, {"min", "1.5"}, {"max", "0.5"}},
                            "result").x, 1.5f);
  auto map = [](const char *type, float v, bool clamp = true) {
    return eval_node("map_range", {{"range_type", type}, {"value", num(v)}, {"from_min", "1"}, {"from_max", "3"},
                                   {"to_min", "10"}, {"to_max", "20"}, {"steps", "4"},
                                   {"clamp", clamp ? "true" : "false"}}, "result").x;
  };
  EXPECT_FLOAT_EQ(map("linear", 2.0f), 15.0f);
  EXPECT_FLOAT_EQ(map("linear", 5.0f), 20.0f);
  EXPECT_FLOAT_EQ(map("linear", 5.0f, false), 30.0f);
  EXPECT_FLOAT_EQ(map("stepped", 2.2f), 10.0f + 10.0f * std::floor(0.6f * 5.0f) / 4.0f);
  EXPECT_FLOAT_EQ(map("smoothstep", 1.5f), 10.0f + 10.0f * (0.25f * 0.25f * (3.0f - 0.5f)));
  EXPECT_FLOAT_EQ(map("smootherstep", 1.5f), 10.0f + 10.0f * (0.25f * 0.25f * 0.25f * (0.25f * (1.5f - 15.0f) + 10.0f)));
  EXPECT_FLOAT_EQ(eval_node("separate_xyz", {{"vector", "1 2 3"}}, "y").x, 2.0f);
  expect_vec(eval_node("combine_xyz", {{"x", "1"}, {"y", "2"}, {"z", "3"}}, "vector"), Vec3(1, 2, 3));
  EXPECT_FLOAT_EQ(eval_node("separate_rgb", {{"color", "0.1 0.2 0.3"}}, "b").x, 0.3f);
  expect_vec(eval_node("combine_rgb", {{"r", "0.1"}, {"g", "0.2"}, {"b", "0.3"}}, "image"), Vec3(0.1f, 0.2f, 0.3f));
  EXPECT_FLOAT_EQ(eval_node("rgb_to_bw", {{"color", "1 0 0"}}, "val").x, 0.2126f);
}

TEST(Nodes, GradientTypesClosedForms) {
  ShadingPoint sp;
  sp.generated = Vec3(0.6f, 0.3f, 0.2f);
  const float r = length(sp.generated);
  const std::pair<const char *, float> cases[] = {
      {"linear", 0.6f},  {"quadratic", 0.36f}, {"easing", 3 * 0.36f - 2 * 0.216f}, {"diagonal", 0.45f},
      {"radial", std::atan2(0.3f, 0.6f) / (2 * kPi) + 0.5f}, {"quadratic_sphere", (0.999999f - r) * (0.999999f - r)},
      {"spherical", 0.999999f - r}};
  for (const auto &[type, expected] : cases)
    EXPECT_NEAR(eval_node("gradient_texture", {{"gradient_type", type}}, "fac", sp).x, expected, 1e-6) << type;
  sp.generated = Vec3(1.7f, 0, 0);
  EXPECT_FLOAT_EQ(eval_node("gradient_texture", {}, "fac", sp).x, 1.0f);  // clamped
}

TEST(Nodes, WhiteNoiseIsTheHashOfTheCoordinates) {
  const Reference ref;
  ShadingPoint sp;
  sp.generated = Vec3(0.3f, -1.25f, 7.0f);
  const Vec3 c3 = eval_node("white_noise_texture", {}, "color", sp);
  EXPECT_EQ(c3.x, ref.hash01({0.3f, -1.25f, 7.0f}));
  EXPECT_EQ(c3.y, ref.hash01({0.3f, -1.25f, 7.0f, 1.0f}));
  EXPECT_EQ(eval_node("white_noise_texture", {{"dimensions", "1D"}, {"w", "0.5"}}, "value", sp).x, ref.hash01({0.5f}));
  EXPECT_EQ(eval_node("white_noise_texture", {{"dimensions", "4D"}, {"w", "2"}}, "color", sp).z,
            ref.hash01({2.0f, 7.0f, -1.25f, 0.3f}));
}

TEST(Nodes, DocsSupportTableIsGeneratedFromTheNodeTable) {
  std::ifstream in(std::string(GLIMMER_TEST_SOURCE_DIR) + "/docs/scene-format.md");
  const std::string doc((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string begin = "<!-- nodes:begin (glimmer describe --nodes) -->\n", end = "<!-- nodes:end -->";
  const size_t a = doc.find(begin), b = doc.find(end);
  ASSERT_NE(a, std::string::npos);
  ASSERT_NE(b, std::string::npos);
  EXPECT_EQ(doc.substr(a + begin.size(), b - a - begin.size()), render::nodes::support_table_markdown())
      << "regenerate: build/glimmer describe --nodes";
}

TEST(Nodes, HugeCoordinatesGiveFiniteValues) {
  ShadingPoint sp;
  sp.generated = Vec3(0.3f, 0.2f, 0.1f);
  for (const char *type : {"noise_texture", "voronoi_texture", "musgrave_texture", "wave_texture", "white_noise_texture"})
    for (const char *scale : {"1e30", "-3e38"}) {
      const auto node = compile_node(type, {{"scale", scale}}, std::string(type) == "musgrave_texture" ? "fac" : "color");
      const Vec3 v = run(*node, sp);
      EXPECT_TRUE(is_finite(v)) << type << " scale " << scale;
    }
}

// ---- Whole scenes through the renderer ---------------------------------------------------------------------

// A quad seen head-on filling the frame, emission colour from `nodes` (which must define the output "tex color").
std::string emission_quad(const std::string &name, const std::string &nodes) {
  return write_file(name,
                    "<cycles>\n<camera width=\"16\" height=\"16\" fov=\"0.5\" />\n<camera />\n"
                    "<shader name=\"s\">\n" + nodes +
                        "\n<emission name=\"e\" strength=\"1\" />\n<connect from=\"tex color\" to=\"e color\" />\n"
                        "<connect from=\"e emission\" to=\"output surface\" />\n</shader>\n"
                        "<state shader=\"s\"><mesh P=\"-1 -1 3  1 -1 3  1 1 3  -1 1 3\" nverts=\"4\" "
                        "verts=\"0 1 2 3\" UV=\"0 0 1 0 1 1 0 1\" /></state>\n</cycles>\n");
}

TEST(Nodes, NodeChainRendersWithoutWarnings) {
  // texture coordinate -> mapping -> noise -> color ramp -> math -> mix -> emission, plus a checker into the mix.
  const std::string path = emission_quad(
      "chain.xml",
      "<texture_coordinate name=\"tc\" />\n<mapping name=\"m\" scale=\"2 2 2\" />\n"
      "<noise_texture name=\"n\" scale=\"3\" detail=\"4\" />\n"
      "<rgb_ramp name=\"r\" ramp=\"0 0 0  1 1 1\" interpolate=\"true\" />\n"
      "<math name=\"k\" math_type=\"power\" value2=\"2\" />\n<checker_texture name=\"c\" />\n"
      "<mix name=\"tex\" mix_type=\"multiply\" fac=\"1\" />\n"
      "<connect from=\"tc uv\" to=\"m vector\" />\n<connect from=\"m vector\" to=\"n vector\" />\n"
      "<connect from=\"n fac\" to=\"r fac\" />\n<connect from=\"r color\" to=\"k value1\" />\n"
      "<connect from=\"k value\" to=\"tex color1\" />\n<connect from=\"c color\" to=\"tex color2\" />");
  render::RenderOptions opt;
  opt.samples = 1;
  const scene::Scene scene = scene::load_scene(path);
  render::Renderer renderer(scene, plugin(), opt);
  const render::RenderResult r = renderer.render();
  EXPECT_EQ(r.nan_samples, 0u);
  for (const auto &w : renderer.warnings()) ADD_FAILURE() << w;
  // The image varies (a constant fallback would be flat) and stays within [0, 1].
  float lo = 1e9f, hi = -1e9f;
  for (int i = 0; i < r.width * r.height; ++i) {
    lo = std::min(lo, r.combined[4 * i]);
    hi = std::max(hi, r.combined[4 * i]);
  }
  EXPECT_GE(lo, 0.0f);
  EXPECT_LE(hi, 1.0f);
  EXPECT_GT(hi - lo, 0.1f);
}

TEST(Nodes, UnknownSocketOrSettingIsAnErrorWithFileLine) {
  std::string out;
  const std::string bad_socket = emission_quad(
      "bad_socket.xml", "<noise_texture name=\"tex\" />\n<math name=\"k\" />\n<connect from=\"k value\" to=\"tex scal\" />");
  EXPECT_EQ(run_cli("render '" + bad_socket + "' -o '" + (temp_dir() / "bad.exr").string() + "' --samples 1", out), 1);
  EXPECT_NE(out.find("bad_socket.xml:"), std::string::npos) << out;
  EXPECT_NE(out.find("its inputs: vector, w, scale"), std::string::npos) << out;
  const std::string bad_enum = emission_quad("bad_enum.xml", "<noise_texture name=\"tex\" dimensions=\"5D\" />");
  EXPECT_EQ(run_cli("render '" + bad_enum + "' -o '" + (temp_dir() / "bad.exr").string() + "' --samples 1", out), 1);
  EXPECT_NE(out.find("bad_enum.xml:5"), std::string::npos) << out;
}


TEST(Nodes, LightPathSeesCameraAndDiffuseRays) {
  // An emitter whose colour is `is_camera_ray` (or `is_diffuse_ray`) fills the left half of the view; a white
  // diffuse quad fills the right half, facing it. The emitter reads 1 (0) to the camera; only the
  // diffuse-ray emitter lights the quad when lights are found by BSDF rays alone.
  auto scene = [](const std::string &name, const std::string &output) {
    return write_file(
        name, "<cycles>\n<camera width=\"16\" height=\"8\" fov=\"0.9\" />\n<camera />\n"
              "<integrator max_bounce=\"1\" sample_clamp_direct=\"0\" sample_clamp_indirect=\"0\" />\n"
              "<shader name=\"em\">\n<light_path name=\"lp\" />\n<emission name=\"e\" strength=\"1\" />\n"
              "<connect from=\"lp " + output + "\" to=\"e color\" />\n<connect from=\"e emission\" to=\"output surface\" />\n"
              "</shader>\n<shader name=\"white\">\n<diffuse_bsdf name=\"d\" color=\"1 1 1\" />\n"
              "<connect from=\"d bsdf\" to=\"output surface\" />\n</shader>\n"
              "<state shader=\"em\"><mesh P=\"-4 -2 2  0 -2 4  0 2 4  -4 2 2\" nverts=\"4\" verts=\"0 1 2 3\" /></state>\n"
              "<state shader=\"white\"><mesh P=\"0 -2 4  4 -2 2  4 2 2  0 2 4\" nverts=\"4\" verts=\"0 1 2 3\" /></state>\n"
              "</cycles>\n");
  };
  render::RenderOptions opt;
  opt.samples = 16;
  opt.strategy = render::LightStrategy::BsdfOnly;
  const auto camera = render_scene(scene("lp_camera.xml", "is_camera_ray"), opt);
  const auto diffuse = render_scene(scene("lp_diffuse.xml", "is_diffuse_ray"), opt);
  EXPECT_NEAR(mean_channel(camera, 0, 1, 2, 6, 6), 1.0, 1e-6) << "the emitter seen by the camera";
  EXPECT_NEAR(mean_channel(diffuse, 0, 1, 2, 6, 6), 0.0, 1e-6);
  EXPECT_NEAR(mean_channel(camera, 0, 10, 2, 15, 6), 0.0, 1e-6) << "not lit: diffuse rays see 0";
  EXPECT_GT(mean_channel(diffuse, 0, 10, 2, 15, 6), 0.05) << "lit by the emitter seen from diffuse rays";
}

}  // namespace
}  // namespace glimmer::test
