// Lamps seen through a frosted exit lobe (render/lamp_through_lobe.h; docs/frosted_glass.md "Lamps through the
// exit lobe"): the stratified two-set estimate of Int p(w) L(w) dw over a lamp, p the exit lobe's density
// (glimmer/exit_lobe.h), against a brute-force integral over the lamp's area, for quad area lamps of several sizes,
// distances and angles to the lobe's axis, lobes of sharpness 5..5000 tilted up to 75 degrees from the exit
// normal (q up to ~0.4), a sphere lamp (point light with a radius) and a point lamp (delta).
//  - the brute force is itself checked: with p = 1 it gives the quad's solid angle in closed form;
//  - the estimate's mean over 2048 random offsets is within 1 % (+ 4 standard errors) of the brute force;
//  - its noise per estimate is reported and asserted below one light sample's (p L / pdf_L, the exit NEE's);
//  - negative controls: the lobe without its redraw factor (q dropped, a known mistake of the density) and the
//    point approximation p(centre) L Omega (what a light reduced to its centre gives) fail the same check.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>

#include "glimmer/rng.h"
#include "render/lamp_through_lobe.h"
#include "render/light_area.h"
#include "render/light_point.h"
#include "render_test_util.h"

namespace glimmer::test {
namespace {

using render::LampEstimate;
using render::LightSample;

// A quad lamp of side `size` centred at P + dist * d, facing P, radiance 1 (strength 4 A).
scene::Light quad_lamp(const Vec3 &P, const Vec3 &d, float dist, float size) {
  scene::Light l;
  l.type = scene::LightType::Area;
  l.co = P + d * dist;
  const Frame f = Frame::from_normal(d);
  l.axisu = f.s;
  l.axisv = f.t;
  l.sizeu = l.sizev = size;
  l.dir = -d;
  return l;
}

// Brute force: Int p(w) L(w) dw over the quad by an n x n midpoint grid over its area (cos_l / r^2 dA), and the
// same with p = 1 (the quad's solid angle when L = 1).
struct BruteForce {
  double integral = 0.0, solid_angle = 0.0;
};
template <class Lobe>
BruteForce brute_force(const scene::Light &l, const Vec3 &P, const Lobe &lobe, int n) {
  BruteForce b;
  const double cell = double(l.sizeu) * l.sizev / (double(n) * n);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const Vec3 q = l.co + l.axisu * (((i + 0.5f) / n - 0.5f) * l.sizeu) + l.axisv * (((j + 0.5f) / n - 0.5f) * l.sizev);
      const Vec3 to = q - P;
      const double d2 = length_squared(to);
      const Vec3 w = to / float(std::sqrt(d2));
      const double dw = std::fabs(dot(w, l.dir)) / d2 * cell;
      b.solid_angle += dw;
      b.integral += lobe.pdf(w) * dw;
    }
  return b;
}

// The solid angle of a rectangle with half-sides a, b seen from distance d on its axis (closed form).
double rectangle_solid_angle(double a, double b, double d) {
  return 4.0 * std::asin(a * b / std::sqrt((a * a + d * d) * (b * b + d * d)));
}

struct Stats {
  double mean = 0.0, se = 0.0, rel_std = 0.0;
  double nee_rel_std = 0.0;  // one light sample's (p L / pdf_L) relative standard deviation
};
template <class Lamp, class Lobe>
Stats estimate(const Lamp &lamp, const Vec3 &P, const Lobe &lobe, int n, uint64_t seed) {
  Pcg32 rng(seed, 7);
  double sum = 0.0, sum2 = 0.0, nee = 0.0, nee2 = 0.0;
  for (int k = 0; k < n; ++k) {
    const float u = rng.next_float(), v = rng.next_float(), pick = rng.next_float();
    LampEstimate e;
    const double x = render::lamp_through_lobe(lamp, P, lobe, u, v, pick, e) ? double(average(e.value)) : 0.0;
    sum += x;
    sum2 += x * x;
    LightSample ls;
    double y = 0.0;
    if (lamp.sample(rng.next_float(), rng.next_float(), P, 1.0f, ls) && ls.pdf > 0.0f)
      y = lobe.pdf(ls.wi) * average(ls.radiance) / (ls.delta ? 1.0 : double(ls.pdf));
    nee += y;
    nee2 += y * y;
  }
  Stats s;
  s.mean = sum / n;
  const double var = std::max(0.0, sum2 / n - s.mean * s.mean);
  s.se = std::sqrt(var / n);
  s.rel_std = std::sqrt(var) / std::max(s.mean, 1e-300);
  const double nee_mean = nee / n;
  s.nee_rel_std = std::sqrt(std::max(0.0, nee2 / n - nee_mean * nee_mean)) / std::max(nee_mean, 1e-300);
  return s;
}

// The exit lobe: normal +z, axis tilted by `tilt` (radians) toward +x.
ExitLobe lobe_at(double tilt, double kappa) {
  return ExitLobe::make(Vec3(float(std::sin(tilt)), 0.0f, float(std::cos(tilt))), kappa, Vec3(0.0f, 0.0f, 1.0f));
}

// A direction uniform on the sphere.
Vec3 random_unit(Pcg32 &rng) {
  const float z = 2.0f * rng.next_float() - 1.0f, phi = 2.0f * float(M_PI) * rng.next_float();
  const float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
  return normalize(Vec3(r * std::cos(phi), r * std::sin(phi), z));
}

// A prepared mixture of 1-3 lobes: axes and normals anywhere, sharpness 1e-3..1e7, weights 0.05..1.05 normalised.
ExitLobeMixture random_prepared_mixture(Pcg32 &rng) {
  const auto unit = [&] { return random_unit(rng); };
  ExitLobeMixture m;
  m.count = 1 + int(rng.next_float() * 3.0f);
  for (int k = 0; k < m.count; ++k) {
    const double kappa = std::pow(10.0, -3.0 + 10.0 * rng.next_float());
    m.lobe[k] = ExitLobe::make(unit(), kappa, unit());
    m.weight[k] = 0.05 + rng.next_float();
  }
  m.normalize();
  m.prepare();
  return m;
}

constexpr double kDeg = M_PI / 180.0;

// The lamp integral draws its n x n lobe directions in two halves (draw_cos per cos theta number, vmf_phi per phi
// number, each made n times): they must be the lobe's draw(uc, up) bit for bit, for single lobes and mixtures, over
// random axes, sharpness 1e-3..1e7 and numbers including 0 and the largest below 1. Negative control: a phi half
// from a neighbouring number (up + 1 ulp) must differ somewhere.
TEST(LampThroughLobe, SplitDrawIsTheLobesDrawBitForBit) {
  Pcg32 rng(2026, 19);
  const auto same = [](const Vec3 &a, const Vec3 &b) {
    return std::memcmp(&a.x, &b.x, sizeof(float)) == 0 && std::memcmp(&a.y, &b.y, sizeof(float)) == 0 &&
           std::memcmp(&a.z, &b.z, sizeof(float)) == 0;
  };
  const auto number = [&] {
    const float x = rng.next_float();
    return x < 0.05f ? 0.0f : x > 0.95f ? 0x1.fffffep-1f : x;
  };
  int checked = 0, differ = 0, control_differs = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    ExitLobeMixture m = random_prepared_mixture(rng);
    const float uc = number(), up = number();
    const Vec3 split = ExitLobeMixture::draw_at(m.draw_cos(uc), vmf_phi(up)), whole = m.draw(uc, up);
    const Vec3 split1 = ExitLobe::draw_at(m.lobe[0].draw_cos(uc), vmf_phi(up)), whole1 = m.lobe[0].draw(uc, up);
    checked += 2;
    differ += !same(split, whole) + !same(split1, whole1);
    const Vec3 control = ExitLobe::draw_at(m.lobe[0].draw_cos(uc), vmf_phi(std::nextafter(up, 0.0f)));
    control_differs += !same(control, whole1);
  }
  std::printf("split draw: %d of %d differ from the whole draw; control (phi number 1 ulp off) differs at %d\n", differ,
              checked, control_differs);
  EXPECT_EQ(differ, 0);
  EXPECT_GT(control_differs, 1000);
}

// ExitLobeMixture::pdf_and_draw_density skips the mirrored part's exponential where mirror x norm < 2^-54 pk (it
// cannot change the sum: exit_lobe.h, mirror_negligible). Against the density with every mirrored part added (the
// same sums written out here), over random mixtures (1-3 lobes, sharpness 1e-3..1e7, axes and normals anywhere) and
// directions uniform or near a lobe's axis: p and the draw density bit for bit, with many parts skipped. Negative
// control: the same skip with 2^-30 instead of 2^-54 changes p somewhere.
TEST(LampThroughLobe, SkippedMirrorPartsCannotChangeTheDensity) {
  Pcg32 rng(2026, 20);
  const auto unit = [&] { return random_unit(rng); };
  // The density with every mirrored part added (skip_below 0), or skipped below skip_below x pk (the control).
  const auto reference = [](const ExitLobeMixture &m, const Vec3 &w, double skip_below, double &draw) {
    draw = 0.0;
    double p = 0.0;
    for (int k = 0; k < m.count; ++k) {
      if (!(m.weight[k] > 0.0)) continue;
      const double v = m.prepared_vmf(k, w);
      draw += m.weight[k] * v;
      const float height = dot(w, m.lobe[k].n);
      if (!(height > 0.0f)) continue;
      double pk = v * m.constants[k].redraws;
      if (m.constants[k].mirror > 0.0 && !(m.constants[k].mirror * m.constants[k].norm < skip_below * pk))
        pk += m.constants[k].mirror * m.prepared_vmf(k, w - m.lobe[k].n * (2.0f * height));
      p += m.weight[k] * pk;
    }
    return p;
  };
  const auto bits = [](double x) {
    uint64_t b;
    std::memcpy(&b, &x, sizeof b);
    return b;
  };
  long checked = 0, differ = 0, skipped = 0, mirrored = 0, control_differs = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    ExitLobeMixture m = random_prepared_mixture(rng);
    for (int j = 0; j < 16; ++j) {
      // half uniform, half drawn from the mixture (where its density is not negligible)
      const Vec3 w = j < 8 ? unit() : m.draw(rng.next_float(), rng.next_float());
      double draw = 0.0, draw_ref = 0.0, draw_control = 0.0;
      const double p = m.pdf_and_draw_density(w, draw);
      const double p_ref = reference(m, w, 0.0, draw_ref);
      const double p_control = reference(m, w, 0x1p-30, draw_control);
      ++checked;
      differ += bits(p) != bits(p_ref) || bits(draw) != bits(draw_ref);
      control_differs += bits(p_control) != bits(p_ref);
      for (int k = 0; k < m.count; ++k) {
        const float height = dot(w, m.lobe[k].n);
        if (!(height > 0.0f) || !(m.constants[k].mirror > 0.0)) continue;
        ++mirrored;
        skipped += m.mirror_negligible(k, m.prepared_vmf(k, w) * m.constants[k].redraws);
      }
    }
  }
  std::printf("mirror skip: %ld of %ld densities differ from the unskipped sum; %ld of %ld mirrored parts skipped; "
              "control (2^-30) differs at %ld\n",
              differ, checked, skipped, mirrored, control_differs);
  EXPECT_EQ(differ, 0);
  EXPECT_GT(skipped, 10000);  // the skip is exercised (23934 of 234393 mirrored parts: q is large in many of these)
  EXPECT_GT(control_differs, 100);
}

TEST(LampThroughLobe, BruteForceIsTheQuadsSolidAngleForAConstantDensity) {
  const Vec3 P(0.1f, -0.2f, 0.3f);
  for (const float size : {0.05f, 0.5f, 2.0f})
    for (const float dist : {1.0f, 3.0f}) {
      const scene::Light l = quad_lamp(P, normalize(Vec3(0.2f, 0.1f, 1.0f)), dist, size);
      const BruteForce b = brute_force(l, P, lobe_at(0.0, 1.0), 512);
      const double exact = rectangle_solid_angle(0.5 * size, 0.5 * size, dist);
      EXPECT_NEAR(b.solid_angle, exact, 2e-4 * exact) << "size " << size << " dist " << dist;
    }
}

// Estimate vs brute force over the configurations; returns the worst relative error (beyond the noise) of
// `wrong` (a deliberately wrong density for the estimate, nullptr: the right one) to check the negative control.
struct Case {
  double tilt_deg, kappa, off_axis_deg;  // lobe tilt from n; sharpness; the lamp's direction from the axis
  float size, dist;
};
const Case kCases[] = {
    {0, 5, 0, 0.5f, 1.0f},     {0, 5, 45, 2.0f, 1.0f},    {0, 50, 0, 0.05f, 3.0f},   {0, 50, 15, 0.5f, 3.0f},
    {40, 50, 15, 0.5f, 1.0f},  {40, 500, 0, 0.05f, 1.0f}, {40, 500, 5, 0.5f, 3.0f},  {40, 500, 0, 2.0f, 1.0f},
    {75, 5, 0, 0.5f, 1.0f},    {75, 5, 30, 2.0f, 3.0f},   {75, 50, 10, 0.5f, 1.0f},  {0, 5000, 0, 0.05f, 3.0f},
    {0, 5000, 0, 2.0f, 1.0f},  {40, 5000, 1, 0.05f, 1.0f}, {40, 5, 60, 0.05f, 3.0f} /* below the surface */, {75, 500, 0, 2.0f, 3.0f},
};

// The lamp's direction: the axis turned by off_axis about y, then about the axis by 30 degrees.
Vec3 lamp_direction(const ExitLobe &lobe, double off_axis) {
  const Frame f = Frame::from_normal(lobe.axis);
  const double phi = 30.0 * kDeg;
  return normalize(f.to_world(Vec3(float(std::sin(off_axis) * std::cos(phi)), float(std::sin(off_axis) * std::sin(phi)),
                                   float(std::cos(off_axis)))));
}

// Case c's quad lamp, c.off_axis_deg off `lobe`'s axis (lamp_direction), seen from P, and its area light of radiance 1
// (S / (4 A) = 1).
struct CaseLamp {
  Vec3 direction;
  scene::Light light;
  render::AreaLight area;
  CaseLamp(const Case &c, const Vec3 &P, const ExitLobe &lobe)
      : direction(lamp_direction(lobe, c.off_axis_deg * kDeg)),
        light(quad_lamp(P, direction, c.dist, c.size)),
        area(light, Spectrum(4.0f * c.size * c.size)) {}
};

// An estimate's relative error against the brute force, and its tolerance: 1 % + 4 standard errors.
double relative_error(const Stats &s, const BruteForce &ref) { return std::fabs(s.mean - ref.integral) / ref.integral; }
double tolerance(const Stats &s, const BruteForce &ref) { return 0.01 + 4.0 * s.se / ref.integral; }

// A lamp below the exit surface: the brute force is 0 and the estimate must be 0 exactly (true: skip the case).
bool lamp_gives_nothing(const Case &c, const Stats &s, const BruteForce &ref) {
  if (ref.integral != 0.0) return false;
  EXPECT_EQ(s.mean, 0.0) << "tilt " << c.tilt_deg << " kappa " << c.kappa << " off-axis " << c.off_axis_deg;
  return true;
}

TEST(LampThroughLobe, QuadLampsMatchTheBruteForceIntegral) {
  const Vec3 P(0.0f);
  double worst = 0.0, worst_ratio = 0.0, worst_q_dropped = 0.0, worst_point = 0.0;
  int q_dropped_fail = 0, point_fail = 0;
  for (const Case &c : kCases) {
    const ExitLobe lobe = lobe_at(c.tilt_deg * kDeg, c.kappa);
    const CaseLamp at(c, P, lobe);
    const Vec3 &d = at.direction;
    const render::AreaLight &lamp = at.area;
    const BruteForce ref = brute_force(at.light, P, lobe, 1024);
    const Stats s = estimate(lamp, P, lobe, 2048, 11);
    if (lamp_gives_nothing(c, s, ref)) continue;
    const double err = relative_error(s, ref), tol = tolerance(s, ref);
    EXPECT_LT(err, tol) << "tilt " << c.tilt_deg << " kappa " << c.kappa << " off-axis " << c.off_axis_deg
                        << " size " << c.size << " dist " << c.dist << ": estimate " << s.mean << " (se " << s.se
                        << "), brute force " << ref.integral;
    // Lower noise than one light sample (the exit NEE before), in every case.
    EXPECT_LE(s.rel_std, s.nee_rel_std + 1e-3) << "tilt " << c.tilt_deg << " kappa " << c.kappa;
    worst = std::max(worst, err);
    worst_ratio = std::max(worst_ratio, s.rel_std / std::max(s.nee_rel_std, 1e-300));
    std::printf("[lamp through lobe] tilt %2.0f kappa %6.0f q %.3f off-axis %2.0f size %.2f dist %.0f: brute force "
                "%.5g, estimate %.5g (rel. error %.4f, tol %.4f); rel. std per estimate %.3f vs one light sample %.3f\n",
                c.tilt_deg, c.kappa, lobe.below, c.off_axis_deg, double(c.size), double(c.dist), ref.integral, s.mean,
                err, tol, s.rel_std, s.nee_rel_std);
    // Negative control 1: the lobe's density without the redraw factor (q dropped).
    ExitLobe no_redraw = lobe;
    no_redraw.below = 0.0;
    const Stats wrong = estimate(lamp, P, no_redraw, 2048, 11);
    const double err_wrong = std::fabs(wrong.mean - ref.integral) / ref.integral;
    worst_q_dropped = std::max(worst_q_dropped, err_wrong);
    q_dropped_fail += err_wrong > 0.01 + 4.0 * wrong.se / ref.integral;
    // Negative control 2: the lamp reduced to its centre, p(d) L Omega.
    const double point = lobe.pdf(d) * ref.solid_angle;
    const double err_point = std::fabs(point - ref.integral) / ref.integral;
    worst_point = std::max(worst_point, err_point);
    point_fail += err_point > 0.01;
  }
  std::printf("[lamp through lobe] %zu cases: worst relative error %.4f, worst noise ratio to one light sample "
              "%.3f; negative controls fail in %d (q dropped, worst %.3f) and %d (centre only, worst %.3f) cases\n",
              std::size(kCases), worst, worst_ratio, q_dropped_fail, worst_q_dropped, point_fail, worst_point);
  EXPECT_GE(q_dropped_fail, 2);  // where q is large (lobes tilted 75 degrees, wide)
  EXPECT_GE(point_fail, 6);      // wherever the lamp is not small against the lobe
}

TEST(LampThroughLobe, SphereAndPointLampsMatchTheirIntegrals) {
  const Vec3 P(0.0f);
  const ExitLobe lobe = lobe_at(30.0 * kDeg, 40.0);
  const Vec3 d = lamp_direction(lobe, 12.0 * kDeg);
  scene::Light l;
  l.type = scene::LightType::Point;
  l.co = P + d * 2.0f;
  l.radius = 0.4f;
  const render::PointLight sphere(l, Spectrum(10.0f));
  // Brute force over the disk facing P (the sphere lamp's silhouette), radiance S / (4 pi * pi r^2).
  double ref = 0.0;
  const int n = 1024;
  const Frame f = Frame::from_normal(-d);
  const double radiance = 10.0 / (4.0 * M_PI * M_PI * l.radius * l.radius);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const double x = ((i + 0.5) / n * 2.0 - 1.0) * l.radius, y = ((j + 0.5) / n * 2.0 - 1.0) * l.radius;
      if (x * x + y * y > double(l.radius) * l.radius) continue;
      const Vec3 q = l.co + f.s * float(x) + f.t * float(y);
      const Vec3 to = q - P;
      const double d2 = length_squared(to);
      const Vec3 w = to / float(std::sqrt(d2));
      ref += lobe.pdf(w) * radiance * std::fabs(dot(w, f.n)) / d2 * (4.0 * double(l.radius) * l.radius / (double(n) * n));
    }
  const Stats s = estimate(sphere, P, lobe, 4096, 5);
  EXPECT_NEAR(s.mean, ref, 0.01 * ref + 4.0 * s.se);
  EXPECT_LE(s.rel_std, s.nee_rel_std + 1e-3);
  // A point lamp (delta): exactly p(wi) x its radiance term, every time.
  l.radius = 0.0f;
  const render::PointLight point(l, Spectrum(10.0f));
  LampEstimate e;
  ASSERT_TRUE(render::lamp_through_lobe(point, P, lobe, 0.3f, 0.7f, 0.5f, e));
  const double exact = lobe.pdf(d) * 10.0 / (4.0 * M_PI * 4.0);
  EXPECT_NEAR(average(e.value), exact, 1e-4 * exact);
  std::printf("[lamp through lobe] sphere lamp r 0.4 at 2: brute force %.5g, estimate %.5g (se %.2g), rel. std %.3f "
              "vs one light sample %.3f; point lamp %.5g vs %.5g\n",
              ref, s.mean, s.se, s.rel_std, s.nee_rel_std, double(average(e.value)), exact);
}

// ABI 2.7: the whole exit lobe mixture (glimmer::ExitLobeMixture: frosted sg's core + tail lobes of 5 rays, axes
// spread over ~12 degrees, one exit surface) through quad lamps, against the brute-force integral of the mixture's
// density (unprepared: each lobe's ExitLobe::pdf); the estimate uses the prepared mixture, as the renderer (cached
// per-lobe constants), and draws its lobe directions from the vMF mixture (ExitLobeMixture::draw). Negative control:
// the host seeing only the first (axis core) lobe with all the weight, a 2.6 host's view of one picked lobe.
ExitLobeMixture mixture_at(double tilt, double kappa) {
  ExitLobeMixture m;
  const Vec3 n(0.0f, 0.0f, 1.0f);
  const double offsets[5][2] = {{0, 0}, {6, 0}, {-6, 0}, {0, 6}, {0, -6}};
  for (int k = 0; k < 5; ++k) {
    const double a = tilt + offsets[k][0] * kDeg, b = offsets[k][1] * kDeg;
    const Vec3 axis = normalize(Vec3(float(std::sin(a)), float(std::sin(b)), float(std::cos(a))));
    m.lobe[k] = ExitLobe::make(axis, kappa * (1.0 - 0.2) / (1.0 - 0.8), n);                  // core
    m.lobe[5 + k] = ExitLobe::make(axis, kappa * 0.25, n);                                  // tail
    m.weight[k] = (k == 0 ? 0.6 : 0.1) * 0.8;
    m.weight[5 + k] = (k == 0 ? 0.6 : 0.1) * 0.2;
  }
  m.count = 10;
  m.normalize();
  return m;
}

TEST(LampThroughLobe, WholeMixtureMatchesTheBruteForceIntegral) {
  const Vec3 P(0.0f);
  double worst = 0.0;
  int first_lobe_fail = 0, cases = 0;
  for (const Case &c : kCases) {
    if (c.kappa > 1000) continue;  // the mixture's spread (12 degrees) dominates sharper lobes anyway
    const ExitLobeMixture m = mixture_at(c.tilt_deg * kDeg, c.kappa);
    const CaseLamp at(c, P, m.lobe[0]);
    const render::AreaLight &lamp = at.area;
    const BruteForce ref = brute_force(at.light, P, m, 1024);
    ExitLobeMixture prepared = m;  // as the renderer evaluates it (per-lobe constants cached)
    prepared.prepare();
    const Stats s = estimate(lamp, P, prepared, 2048, 13);
    if (lamp_gives_nothing(c, s, ref)) continue;
    ++cases;
    const double err = relative_error(s, ref), tol = tolerance(s, ref);
    EXPECT_LT(err, tol) << "mixture: tilt " << c.tilt_deg << " kappa " << c.kappa << " off-axis "
                        << c.off_axis_deg << " size " << c.size << " dist " << c.dist << ": estimate " << s.mean
                        << " (se " << s.se << "), brute force " << ref.integral;
    EXPECT_LE(s.rel_std, s.nee_rel_std + 1e-3) << "mixture: tilt " << c.tilt_deg << " kappa " << c.kappa;
    worst = std::max(worst, err);
    ExitLobeMixture first = m;  // negative control: the first lobe alone
    first.count = 1;
    first.weight[0] = 1.0;
    const Stats wrong = estimate(lamp, P, first, 2048, 13);
    first_lobe_fail += relative_error(wrong, ref) > tolerance(wrong, ref);
  }
  std::printf("[lamp through lobe] whole mixture, %d cases: worst relative error %.4f; the first lobe alone fails "
              "in %d\n", cases, worst, first_lobe_fail);
  EXPECT_GE(first_lobe_fail, cases / 2);
}

// Session 24 (frostedpane24): a lobe whose value is not its proposal's density (render::ValuedExitLobe: method=sg's
// rough pane values the lamps by the exact exit, the mixture draws the lobe's directions). The value here is a
// skewed lobe the proposal does not match: the mixture turned 8 degrees, its sharpness x 0.7, times
// (1 + 0.6 w.x) (clamped at 0), x 1.3. The estimate's mean over 2048 offsets must match the brute-force integral of
// the value within 1 % + 4 standard errors; negative control: the proposal's own density (the mixture, what the
// renderer integrated before) must miss it in at least half the cases.
struct SkewedValue {
  ExitLobeMixture turned;
  static double value(const void *self, const Vec3 &w) {
    const SkewedValue &v = *static_cast<const SkewedValue *>(self);
    return 1.3 * v.turned.pdf(w) * std::max(0.0, 1.0 + 0.6 * double(w.x));
  }
};
TEST(LampThroughLobe, ValuedLobeMatchesTheBruteForceIntegralOfItsValue) {
  const Vec3 P(0.0f);
  double worst = 0.0;
  int proposal_fail = 0, cases = 0;
  for (const Case &c : kCases) {
    if (c.kappa > 1000) continue;  // as the whole mixture's test
    ExitLobeMixture proposal = mixture_at(c.tilt_deg * kDeg, c.kappa);
    proposal.prepare();
    SkewedValue v;
    v.turned = mixture_at((c.tilt_deg + 8.0) * kDeg, c.kappa * 0.7);
    v.turned.prepare();
    const render::ValuedExitLobe lobe{&proposal, &SkewedValue::value, &v};
    const CaseLamp at(c, P, proposal.lobe[0]);
    const render::AreaLight &lamp = at.area;
    const BruteForce ref = brute_force(at.light, P, lobe, 1024);
    const Stats s = estimate(lamp, P, lobe, 2048, 17);
    if (lamp_gives_nothing(c, s, ref)) continue;
    ++cases;
    const double err = relative_error(s, ref), tol = tolerance(s, ref);
    EXPECT_LT(err, tol) << "valued: tilt " << c.tilt_deg << " kappa " << c.kappa << " off-axis " << c.off_axis_deg
                        << " size " << c.size << " dist " << c.dist << ": estimate " << s.mean << " (se " << s.se
                        << "), brute force " << ref.integral;
    worst = std::max(worst, err);
    const Stats wrong = estimate(lamp, P, proposal, 2048, 17);
    proposal_fail += relative_error(wrong, ref) > tolerance(wrong, ref);
  }
  std::printf("[lamp through lobe] valued lobe, %d cases: worst relative error %.4f; the proposal's density fails "
              "in %d\n", cases, worst, proposal_fail);
  EXPECT_GE(cases, 8);
  EXPECT_GE(proposal_fail, cases / 2);
}

// Session 28 (frostedcost28): lamp_through_lobe returns false at once for an area lamp wholly below every exit lobe's
// surface (lamp_below_exit, AreaLight::wholly_below). Against the estimate without that skip (the same mixture behind
// a ValuedExitLobe whose value is the mixture's own density: the same points and sums, no skip), over random prepared
// mixtures (1-3 lobes sharing one exit normal, as the host's), exit points, quad and round lamps near the exit's
// horizon (elevation -30..+30 deg, distances 0.3..5, sizes 0.05..2, tilted), numbers (u, v, pick): the same result,
// estimate, direction and distance bit for bit, with many lamps skipped. Negative control: a skip by the lamp's centre
// alone (below the plane) must differ from the unskipped estimate somewhere (a lamp straddling the horizon).
// 1..3 lobes leaving an exit of normal n (their redraw rule's side), sharpness 0.1..1e3, normalised weights.
ExitLobeMixture random_exit_mixture(Pcg32 &rng, const Vec3 &n) {
  ExitLobeMixture m;
  m.count = 1 + int(rng.next_float() * 3.0f);
  for (int k = 0; k < m.count; ++k) {
    Vec3 axis = random_unit(rng);
    if (dot(axis, n) < 0.0f) axis = -axis;
    m.lobe[k] = ExitLobe::make(axis, std::pow(10.0, -1.0 + 4.0 * rng.next_float()), n);
    m.weight[k] = 0.05 + rng.next_float();
  }
  m.normalize();
  return m;
}
TEST(LampThroughLobe, LampWhollyBelowTheExitIsSkippedExactly) {
  Pcg32 rng(2028, 28);
  const auto unit = [&] { return random_unit(rng); };
  const auto bits_equal = [](const auto &a, const auto &b) { return std::memcmp(&a, &b, sizeof a) == 0; };
  struct Own {
    static double value(const void *m, const Vec3 &w) { return static_cast<const ExitLobeMixture *>(m)->pdf(w); }
  };
  int trials = 0, skipped = 0, differ = 0, reached = 0, control_differs = 0;
  for (int trial = 0; trial < 4000; ++trial) {
    const Vec3 n = unit(), P(rng.next_float() - 0.5f, rng.next_float() - 0.5f, rng.next_float() - 0.5f);
    ExitLobeMixture m = random_exit_mixture(rng, n);
    m.prepare();
    const render::ValuedExitLobe unskipped{&m, &Own::value, &m};
    // The lamp's direction from P at elevation -30..+30 deg above the exit plane.
    const Frame f = Frame::from_normal(n);
    const float elevation = float((rng.next_float() * 60.0 - 30.0) * kDeg), phi = 2.0f * float(M_PI) * rng.next_float();
    const Vec3 d = normalize(f.to_world(Vec3(std::cos(elevation) * std::cos(phi), std::cos(elevation) * std::sin(phi),
                                             std::sin(elevation))));
    scene::Light l = quad_lamp(P, d, 0.3f + 4.7f * rng.next_float(), 0.05f + 1.95f * rng.next_float());
    const Frame tilt = Frame::from_normal(normalize(-d + unit() * 0.5f));
    l.axisu = tilt.s, l.axisv = tilt.t, l.dir = tilt.n;  // tilted, facing P within ~30 deg
    l.round = rng.next_float() < 0.3f;
    const render::AreaLight lamp(l, Spectrum(4.0f * l.sizeu * l.sizev));
    const bool below = lamp.wholly_below(P, n);
    for (int j = 0; j < 4; ++j) {
      const float u = rng.next_float(), v = rng.next_float(), pick = rng.next_float();
      LampEstimate a, b;
      const bool ra = render::lamp_through_lobe(lamp, P, m, u, v, pick, a);
      const bool rb = render::lamp_through_lobe(lamp, P, unskipped, u, v, pick, b);
      ++trials;
      skipped += below;
      reached += rb;
      const bool same = bits_equal(a.value, b.value) && bits_equal(a.wi, b.wi) && bits_equal(a.dist, b.dist);
      differ += ra != rb || (ra && !same);
      const bool control = dot(l.co - P, n) < 0.0f ? false : rb;  // skipped by the centre alone
      control_differs += control != rb;
    }
  }
  std::printf("[lamp through lobe] lamp below the exit: %d of %d estimates skipped, %d reach the lamp; differ from "
              "the unskipped estimate: %d; control (the centre alone below) differs at %d\n",
              skipped, trials, reached, differ, control_differs);
  EXPECT_EQ(differ, 0);
  EXPECT_GT(skipped, trials / 5);
  EXPECT_GT(reached, trials / 5);
  EXPECT_GT(control_differs, 20);
}

// Session 29 (frostedcost29): ValuedExitLobe::pdf_and_draw_density makes the proposal's draw density only where the
// value is > 0 (lamp_through_lobe reads it only after p > 0). Against the former order (the proposal's density for
// every point, then the value; a test-local copy) over random prepared mixtures sharing one exit normal, a value that
// is the mixture's density on one side of a random plane through P and 0 on the other (the pane's exact exit is 0 on
// the other side of its exit face), quad and round lamps in random directions, numbers (u, v, pick): the same result,
// estimate, direction and distance bit for bit. Negative control: the proposal's density skipped everywhere (draw 0)
// must differ somewhere.
struct HalfSpaceValue {
  const ExitLobeMixture *m;
  Vec3 side;
  static double value(const void *self, const Vec3 &w) {
    const HalfSpaceValue &h = *static_cast<const HalfSpaceValue *>(self);
    return dot(w, h.side) > 0.0f ? h.m->pdf(w) : 0.0;
  }
};
struct ProposalAlwaysFirst : render::ValuedExitLobe {  // the order before session 29
  double pdf_and_draw_density(const Vec3 &w, double &draw) const {
    proposal->pdf_and_draw_density(w, draw);
    return value(context, w);
  }
};
struct ProposalNever : render::ValuedExitLobe {  // the negative control
  double pdf_and_draw_density(const Vec3 &w, double &draw) const {
    draw = 0.0;
    return value(context, w);
  }
};
TEST(LampThroughLobe, ValuedLobeWithoutTheProposalWhereTheValueIsZero) {
  Pcg32 rng(2029, 29);
  const auto unit = [&] { return random_unit(rng); };
  const auto bits_equal = [](const auto &a, const auto &b) { return std::memcmp(&a, &b, sizeof a) == 0; };
  int trials = 0, reached = 0, differ = 0, control_differs = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    const Vec3 n = unit(), P(rng.next_float() - 0.5f, rng.next_float() - 0.5f, rng.next_float() - 0.5f);
    ExitLobeMixture m = random_exit_mixture(rng, n);
    m.prepare();
    const HalfSpaceValue half{&m, unit()};
    const render::ValuedExitLobe valued{&m, &HalfSpaceValue::value, &half};
    const ProposalAlwaysFirst before{valued};
    const ProposalNever control{valued};
    Vec3 d = unit();
    if (dot(d, n) < 0.0f) d = -d;  // above the exit: the lamp can count
    scene::Light l = quad_lamp(P, d, 0.3f + 4.7f * rng.next_float(), 0.05f + 1.95f * rng.next_float());
    const Frame tilt = Frame::from_normal(normalize(-d + unit() * 0.5f));
    l.axisu = tilt.s, l.axisv = tilt.t, l.dir = tilt.n;
    l.round = rng.next_float() < 0.3f;
    const render::AreaLight lamp(l, Spectrum(4.0f * l.sizeu * l.sizev));
    for (int j = 0; j < 4; ++j) {
      const float u = rng.next_float(), v = rng.next_float(), pick = rng.next_float();
      LampEstimate a, b, c;
      const bool ra = render::lamp_through_lobe(lamp, P, valued, u, v, pick, a);
      const bool rb = render::lamp_through_lobe(lamp, P, before, u, v, pick, b);
      const bool rc = render::lamp_through_lobe(lamp, P, control, u, v, pick, c);
      ++trials;
      reached += rb;
      const auto same = [&](const LampEstimate &x) {
        return bits_equal(x.value, b.value) && bits_equal(x.wi, b.wi) && bits_equal(x.dist, b.dist);
      };
      differ += ra != rb || (ra && !same(a));
      control_differs += rc != rb || (rc && !same(c));
    }
  }
  std::printf("[lamp through lobe] valued lobe, the proposal only where the value is > 0: %d estimates, %d reach the "
              "lamp; differ from the former order: %d; control (no proposal density) differs at %d\n",
              trials, reached, differ, control_differs);
  EXPECT_EQ(differ, 0);
  EXPECT_GT(reached, trials / 5);
  EXPECT_GT(control_differs, 20);
}

// Session 32 (frostedtime32): where the lobe's peak draw density is at most kLobeSetRatio x the lamp's smallest
// sampling density, lamp_through_lobe leaves the lobe's directions out and weights the lamp's points 1 / own (one
// strategy). Whatever the ratio, the estimate must stay unbiased: with the ratio forced to infinity (the lobe set left
// out for every area lamp, also where the lobe is sharp against the lamp and carried most of the estimate) every case
// of kCases is within 1 % + 4 standard errors of the brute force. Negative control: the lobe set left out without
// re-weighting the lamp's points (their power-heuristic weight kept: the lamp set's share alone, a test-local
// estimator) misses where the lobe's directions mattered. Also counted: the cases the default ratio skips (both code
// paths are then covered by QuadLampsMatchTheBruteForceIntegral).
template <class Lobe>
double lamp_share_alone(const render::AreaLight &lamp, const Vec3 &P, const Lobe &lobe, int n_estimates,
                        uint64_t seed) {
  constexpr int n = render::kLampStrata, count = n * n;
  Pcg32 rng(seed, 7);
  double sum = 0.0;
  for (int e = 0; e < n_estimates; ++e) {
    const float u = rng.next_float(), v = rng.next_float();
    for (int k = 0; k < count; ++k) {
      LightSample ls;
      if (!lamp.sample((float(k % n) + u) / n, (float(k / n) + v) / n, P, 1.0f, ls)) continue;
      double draw = 0.0;
      const double p = lobe.pdf_and_draw_density(ls.wi, draw);
      if (!(p > 0.0)) continue;
      const double own = ls.pdf;
      sum += average(ls.radiance) * p * own / (count * (own * own + draw * draw));
    }
  }
  return sum / n_estimates;
}
TEST(LampThroughLobe, SkippedLobeSetStaysUnbiased) {
  const Vec3 P(0.0f);
  double worst = 0.0, worst_ratio = 0.0, worst_control = 0.0;
  int checked = 0, control_fail = 0, skipped_by_default = 0;
  for (const Case &c : kCases) {
    const ExitLobe lobe = lobe_at(c.tilt_deg * kDeg, c.kappa);
    const CaseLamp at(c, P, lobe);
    skipped_by_default += render::lobe_set_negligible(at.area, P, lobe, render::kLobeSetRatio);
    EXPECT_TRUE(render::lobe_set_negligible(at.area, P, lobe, HUGE_VAL));
    const BruteForce ref = brute_force(at.light, P, lobe, 1024);
    Pcg32 rng(11, 7);
    double sum = 0.0, sum2 = 0.0;
    const int n_estimates = 2048;
    for (int k = 0; k < n_estimates; ++k) {
      const float u = rng.next_float(), v = rng.next_float(), pick = rng.next_float();
      rng.next_float(), rng.next_float();  // estimate()'s light sample numbers: the same (u, v, pick) sequence
      LampEstimate e;
      const bool hit = render::lamp_through_lobe(at.area, P, lobe, u, v, pick, e, HUGE_VAL);
      const double x = hit ? double(average(e.value)) : 0.0;
      sum += x, sum2 += x * x;
    }
    Stats s;
    s.mean = sum / n_estimates;
    s.se = std::sqrt(std::max(0.0, sum2 / n_estimates - s.mean * s.mean) / n_estimates);
    if (lamp_gives_nothing(c, s, ref)) continue;
    ++checked;
    const double err = relative_error(s, ref), tol = tolerance(s, ref);
    EXPECT_LT(err, tol) << "tilt " << c.tilt_deg << " kappa " << c.kappa << " off-axis " << c.off_axis_deg << " size "
                        << c.size << " dist " << c.dist << ": estimate " << s.mean << " (se " << s.se
                        << "), brute force " << ref.integral;
    worst = std::max(worst, err);
    worst_ratio = std::max(worst_ratio, err / tol);
    const double control = lamp_share_alone(at.area, P, lobe, n_estimates, 11);
    const double err_control = std::fabs(control - ref.integral) / ref.integral;
    worst_control = std::max(worst_control, err_control);
    control_fail += err_control > tol;
  }
  std::printf("[lamp through lobe] lobe set always left out: %d cases, worst relative error %.4f (worst error / "
              "tolerance %.2f); control (lamp points' MIS weight kept) fails in %d cases, worst %.3f; the default "
              "ratio %.2g leaves it out in %d of %zu cases\n",
              checked, worst, worst_ratio, control_fail, worst_control, render::kLobeSetRatio, skipped_by_default,
              std::size(kCases));
  EXPECT_GE(checked, 14);
  EXPECT_GE(control_fail, 3);
  EXPECT_GE(skipped_by_default, 1);
  EXPECT_LT(skipped_by_default, int(std::size(kCases)));
}

}  // namespace
}  // namespace glimmer::test
