// glint_jakob14 (XML node glint_jakob14_bsdf): the reference discrete
// stochastic microfacet BRDF of Jakob, Hasan, Yan, Lawrence, Ramamoorthi,
// Marschner 2014, "Discrete Stochastic Microfacet Models" (SIGGRAPH), with
// the same parameters, particle density and BRDF normalisation as `glint`, so
// the two converge to the same mean. Exact and slow: for tests and the
// time-vs-error benchmark.
//
// Particles live in a 4D domain: position x in the (scaled) uv plane and a
// direction code (u, v) in [0,1]^2 that the sampling warp of D(m) cos(theta_m)
// maps to the particle normal (GGX: tan^2 theta = alpha^2 u / (1 - u);
// Beckmann: tan^2 theta = -alpha^2 log(1 - u); phi = 2 pi v), so uniform codes
// give normals distributed exactly as D cos (Jakob 2014 sec. 4).
//
// Hierarchy (Jakob 2014 sec. 5): every unit uv cell holds
// floor(N) + [u < frac(N)] particles (TEA-seeded by the cell); a node is split
// in half along x, y, u, v in turn, the left child receiving
// Binomial(n, 1/2) particles: exact (popcount of n random bits) for n <= 512,
// Gaussian N(n/2, n/4) rounded above, seeded by the node id (TEA of the
// parent's id and the child index). Nodes with <= 8 particles are leaves whose
// particles are drawn explicitly (position and code uniform in the node).
//
// Query: count K of particles inside the footprint parallelogram A whose
// mirror reflection of wi lies in the cone of half-angle gamma around wo.
// Nodes are pruned by exact box/parallelogram tests in uv and by the exact
// angular distance from h = normalize(wi + wo) to the node's (theta, phi)
// rectangle against R_out = gamma / (2 wi.h - gamma) (the half-vector map
// r -> normalize(wi + r) is 1 / |wi + r|-Lipschitz); a node inside A whose
// normals all lie within gamma / 2 of h (reflection is 2-Lipschitz) counts
// all its particles without descending. Leaves test each particle exactly.
//
// BRDF: f cos_o = W(wi, wo) K / (N a(A) sigma_gamma), the same estimator as
// glint's unfiltered mode (glint.cpp eq. 2). Sampling and pdf: the same exact
// smooth-lobe mixture as glint (tables/glint_common.h).
#include <array>
#include <bit>
#include <memory>

#include "core/closure.h"
#include "glimmer/microfacet.h"
#include "glimmer/rng.h"
#include "tables/glint_common.h"
#include "tables/glint_particles.h"

namespace glimmer::plugin {

namespace mf = glimmer::microfacet;

class GlintJakob14Closure {
 public:
  static constexpr const char *kName = "glint_jakob14";
  static constexpr const char *kDoc =
      "Reference glints: Jakob et al. 2014 discrete stochastic microfacets, 4D hierarchy (slow, exact).";
  static constexpr uint32_t kFlags = GLIMMER_CLOSURE_REFERENCE;
  static constexpr uint64_t kLeafSize = 8;
  // Cost bound: after this many visited nodes the remaining ones are counted
  // by their expectation (only reached for absurd particle counts, e.g.
  // 1e12 per unit area under footprints of many units; never in tests).
  static constexpr int kNodeBudget = 20000;

  static std::span<const GlimmerParamSpec> params() {
    static const auto schema = glint::particle_field_params(
        {"base roughness (alpha = roughness^2); values below 0.15 are treated as 0.15 (as glint)",
         "query cone half-angle in degrees", "particle reflectance at normal incidence (Schlick Fresnel F0)"});
    return schema;
  }

  static std::unique_ptr<GlintJakob14Closure> create(const ParamReader &p) {
    auto c = std::make_unique<GlintJakob14Closure>();
    c->field_ = glint::ParticleField::parse(p);
    c->gamma_ = c->field_.gamma_deg * (kPi / 180.0f);
    c->cone_solid_angle_ = kTwoPi * (1.0f - std::cos(c->gamma_));
    return c;
  }

  // ---- The 4D hierarchy --------------------------------------------------
  struct Node {
    double x0, x1, y0, y1;  // uv box (scaled uv)
    double u0, u1, v0, v1;  // direction-code box
    uint64_t count;
    uint32_t id_a, id_b;    // TEA-derived node id
    int depth;
  };

  // Polar angle of the normal for direction code u (monotone in u).
  double code_theta(double u) const {
    const double a = field_.alpha;
    u = std::min(std::max(u, 0.0), 1.0);
    if (u >= 1.0) return 0.5 * M_PI;
    const double tan2 =
        field_.distribution == mf::Distribution::GGX ? a * a * u / (1.0 - u) : -a * a * std::log1p(-u);
    return std::atan(std::sqrt(std::max(tan2, 0.0)));
  }

  // Binomial(n, 1/2) from the node's random stream.
  static uint64_t split_count(uint64_t n, uint32_t a, uint32_t b) {
    if (n <= 512) {
      uint64_t c = 0;
      for (uint64_t w = 0; w * 32 < n; ++w) {
        uint32_t bits = hash_u32(a ^ hash_u32(b + static_cast<uint32_t>(w) * 0x9e3779b9u));
        const uint64_t left = n - w * 32;
        if (left < 32) bits &= (1u << left) - 1u;
        c += static_cast<uint64_t>(std::popcount(bits));
      }
      return c;
    }
    // Gaussian approximation (Box-Muller), rounded and clamped.
    const double u1 = (uint_to_unit_float(hash_u32(a + 0x68bc21ebu)) + 0.5 / 16777216.0);
    const double u2 = uint_to_unit_float(hash_u32(b ^ 0x02e5be93u));
    const double z = std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
    const double c = std::floor(0.5 * static_cast<double>(n) + 0.5 * std::sqrt(static_cast<double>(n)) * z + 0.5);
    return static_cast<uint64_t>(std::min(std::max(c, 0.0), static_cast<double>(n)));
  }

  struct Query {
    glint::Footprint fp;
    double inv_det;
    Vec3 wi, wo, h;
    double theta_h, phi_h;
    double cos_gamma;
    double r_out, r_in;
    double theta_ih;  // angle between wi and h
  };

  bool inside_footprint(const Query &q, double x, double y) const {
    const double px = x - q.fp.cx, py = y - q.fp.cy;
    const double s = (px * q.fp.by - py * q.fp.bx) * q.inv_det;
    const double t = (q.fp.ax * py - q.fp.ay * px) * q.inv_det;
    return std::fabs(s) <= 0.5 && std::fabs(t) <= 0.5;
  }

  // Separating-axis test of a uv box against the footprint parallelogram.
  bool box_overlaps(const Query &q, const Node &n) const {
    const glint::Footprint &f = q.fp;
    const double ex = 0.5 * (std::fabs(f.ax) + std::fabs(f.bx)), ey = 0.5 * (std::fabs(f.ay) + std::fabs(f.by));
    if (n.x1 < f.cx - ex || n.x0 > f.cx + ex || n.y1 < f.cy - ey || n.y0 > f.cy + ey) return false;
    // Axes: normals of the parallelogram edges.
    const double axes[2][2] = {{-f.ay, f.ax}, {-f.by, f.bx}};
    const double cx = 0.5 * (n.x0 + n.x1) - f.cx, cy = 0.5 * (n.y0 + n.y1) - f.cy;
    const double hx = 0.5 * (n.x1 - n.x0), hy = 0.5 * (n.y1 - n.y0);
    for (const auto &a : axes) {
      const double box_r = hx * std::fabs(a[0]) + hy * std::fabs(a[1]);
      const double par_r = 0.5 * (std::fabs(a[0] * f.ax + a[1] * f.ay) + std::fabs(a[0] * f.bx + a[1] * f.by));
      if (std::fabs(cx * a[0] + cy * a[1]) > box_r + par_r) return false;
    }
    return true;
  }

  bool box_inside(const Query &q, const Node &n) const {
    return inside_footprint(q, n.x0, n.y0) && inside_footprint(q, n.x1, n.y0) && inside_footprint(q, n.x0, n.y1) &&
           inside_footprint(q, n.x1, n.y1);
  }

  // Exact min / max angular distance from h to the (theta, phi) rectangle of a node.
  void angular_range(const Query &q, const Node &n, double &d_min, double &d_max) const {
    const double t0 = code_theta(n.u0), t1 = code_theta(n.u1);
    const double p0 = 2.0 * M_PI * n.v0, p1 = 2.0 * M_PI * n.v1;
    auto wrap = [](double a) {  // to (-pi, pi]
      a = std::fmod(a + M_PI, 2.0 * M_PI);
      if (a < 0) a += 2.0 * M_PI;
      return a - M_PI;
    };
    const double d0 = std::fabs(wrap(p0 - q.phi_h)), d1 = std::fabs(wrap(p1 - q.phi_h));
    const bool inside_phi = wrap(q.phi_h - p0) >= 0.0 && wrap(q.phi_h - p0) <= p1 - p0;
    const double near_dphi = inside_phi ? 0.0 : std::min(d0, d1);
    // Farthest azimuth: the point of [p0, p1] farthest from phi_h (the antipode if inside).
    const double anti = wrap(q.phi_h + M_PI - p0);
    const double far_dphi = (anti >= 0.0 && anti <= p1 - p0) ? M_PI : std::max(d0, d1);
    const double st = std::sin(q.theta_h), ct = std::cos(q.theta_h);
    auto cos_dist = [&](double theta, double dphi) { return std::sin(theta) * st * std::cos(dphi) + std::cos(theta) * ct; };
    // Max of cos over theta for the nearest azimuth: clamp theta* to [t0, t1].
    const double theta_star = std::atan2(st * std::cos(near_dphi), ct);
    const double tc = std::min(std::max(theta_star, t0), t1);
    d_min = std::acos(std::min(std::max(cos_dist(tc, near_dphi), -1.0), 1.0));
    const double c_far = std::min(cos_dist(t0, far_dphi), cos_dist(t1, far_dphi));
    d_max = std::acos(std::min(std::max(c_far, -1.0), 1.0));
  }

  bool particle_reflects(const Query &q, double u, double v) const {
    const double theta = code_theta(u), phi = 2.0 * M_PI * v;
    const Vec3 m(static_cast<float>(std::sin(theta) * std::cos(phi)),
                 static_cast<float>(std::sin(theta) * std::sin(phi)), static_cast<float>(std::cos(theta)));
    const float wi_m = dot(q.wi, m);
    if (!(wi_m > 0.0f)) return false;
    const Vec3 r = 2.0f * wi_m * m - q.wi;
    return static_cast<double>(dot(r, q.wo)) > q.cos_gamma;
  }

  // Expectation of a node's count (8 x 8 stratified points in uv and in the
  // direction code), rounded: the bounded-cost fallback.
  uint64_t expected_count(const Query &q, const Node &n) const {
    int in_uv = 0, in_dir = 0;
    for (int a = 0; a < 8; ++a)
      for (int b = 0; b < 8; ++b) {
        const double fa = (a + 0.5) / 8.0, fb = (b + 0.5) / 8.0;
        in_uv += inside_footprint(q, n.x0 + (n.x1 - n.x0) * fa, n.y0 + (n.y1 - n.y0) * fb);
        in_dir += particle_reflects(q, n.u0 + (n.u1 - n.u0) * fa, n.v0 + (n.v1 - n.v0) * fb);
      }
    return static_cast<uint64_t>(std::floor(static_cast<double>(n.count) * in_uv * in_dir / 4096.0 + 0.5));
  }

  uint64_t count(const Query &q) const {
    const glint::Footprint &f = q.fp;
    const double ex = 0.5 * (std::fabs(f.ax) + std::fabs(f.bx)), ey = 0.5 * (std::fabs(f.ay) + std::fabs(f.by));
    const int64_t i0 = static_cast<int64_t>(std::floor(f.cx - ex)), i1 = static_cast<int64_t>(std::floor(f.cx + ex));
    const int64_t j0 = static_cast<int64_t>(std::floor(f.cy - ey)), j1 = static_cast<int64_t>(std::floor(f.cy + ey));
    if ((i1 - i0 + 1) * (j1 - j0 + 1) > 4096) return 0;  // footprints over 4096 unit cells are not supported
    uint64_t k = 0;
    int visited = 0;
    std::array<Node, 512> stack;
    for (int64_t j = j0; j <= j1; ++j)
      for (int64_t i = i0; i <= i1; ++i) {
        const glint::NodeStream s = glint::node_stream(field_.seed ^ 0x5bd1e995u, 0, i, j);
        Node root{static_cast<double>(i), static_cast<double>(i + 1), static_cast<double>(j), static_cast<double>(j + 1),
                  0.0, 1.0, 0.0, 1.0, glint::node_particle_count(s, field_.density, 1.0), s.a, s.b, 0};
        int top = 0;
        stack[top++] = root;
        while (top > 0) {
          const Node n = stack[--top];
          if (n.count == 0 || !box_overlaps(q, n)) continue;
          if (++visited > kNodeBudget) {
            k += expected_count(q, n);
            continue;
          }
          double d_min, d_max;
          angular_range(q, n, d_min, d_max);
          if (d_min > q.r_out) continue;
          const bool all_in_uv = box_inside(q, n);
          if (all_in_uv && d_max < q.r_in && q.theta_ih + d_max < 0.5 * M_PI) {
            k += n.count;
            continue;
          }
          if (n.count <= kLeafSize || n.depth >= 200 || top + 2 > static_cast<int>(stack.size())) {
            const glint::NodeStream ps{n.id_a, n.id_b};
            for (uint32_t p = 0; p < n.count; ++p) {
              const double x = n.x0 + (n.x1 - n.x0) * ps(4 * p + 1), y = n.y0 + (n.y1 - n.y0) * ps(4 * p + 2);
              if (!inside_footprint(q, x, y)) continue;
              const double u = n.u0 + (n.u1 - n.u0) * ps(4 * p + 3), v = n.v0 + (n.v1 - n.v0) * ps(4 * p + 4);
              if (particle_reflects(q, u, v)) ++k;
            }
            continue;
          }
          const uint64_t left = split_count(n.count, n.id_a, n.id_b);
          Node a = n, b = n;
          a.count = left;
          b.count = n.count - left;
          a.depth = b.depth = n.depth + 1;
          uint32_t a0 = n.id_a, a1 = n.id_b ^ 1u, b0 = n.id_a, b1 = n.id_b ^ 2u;
          tea<8>(a0, a1);
          tea<8>(b0, b1);
          a.id_a = a0, a.id_b = a1, b.id_a = b0, b.id_b = b1;
          switch (n.depth % 4) {
            case 0: a.x1 = b.x0 = 0.5 * (n.x0 + n.x1); break;
            case 1: a.y1 = b.y0 = 0.5 * (n.y0 + n.y1); break;
            case 2: a.u1 = b.u0 = 0.5 * (n.u0 + n.u1); break;
            default: a.v1 = b.v0 = 0.5 * (n.v0 + n.v1); break;
          }
          stack[top++] = a;
          stack[top++] = b;
        }
      }
    return k;
  }

  Spectrum glint_f_cos(const GlimmerShadingContext *ctx, const Vec3 &wi, const Vec3 &wo) const {
    Spectrum weight;
    if (!glint::glint_weight(field_.distribution, field_.alpha, field_.color, wi, wo, weight)) return Spectrum(0.0f);
    Query q;
    q.fp = field_.footprint(ctx);
    const double det = q.fp.ax * q.fp.by - q.fp.ay * q.fp.bx;
    q.inv_det = 1.0 / det;
    q.wi = wi;
    q.wo = wo;
    q.h = normalize(wi + wo);
    q.theta_h = std::acos(std::min(std::max(static_cast<double>(q.h.z), -1.0), 1.0));
    q.phi_h = std::atan2(static_cast<double>(q.h.y), static_cast<double>(q.h.x));
    q.cos_gamma = std::cos(static_cast<double>(gamma_));
    const double wi_h = dot(wi, q.h);
    const double denom = 2.0 * wi_h - gamma_;
    q.r_out = denom > 0.0 ? std::min(M_PI, 1.0001 * gamma_ / denom + 1e-7) : M_PI;
    q.r_in = 0.4999 * gamma_;
    q.theta_ih = std::acos(std::min(std::max(wi_h, -1.0), 1.0));
    const uint64_t k = count(q);
    if (k == 0) return Spectrum(0.0f);
    const double scale =
        static_cast<double>(k) / (static_cast<double>(field_.density) * q.fp.area() * cone_solid_angle_);
    return weight * static_cast<float>(scale);
  }

  float sampling_alpha() const {
    const float widen = 0.5f * gamma_;
    return std::sqrt(field_.alpha * field_.alpha + widen * widen);
  }

  LocalEval eval(const ShadingPoint &sp, const Vec3 &wo) const {
    LocalEval e;
    e.f_cos = glint_f_cos(sp.ctx, sp.wi, wo);
    e.pdf = glint::smooth_lobe_pdf(field_.distribution, sampling_alpha(), sp.wi, wo);
    return e;
  }

  bool sample(const ShadingPoint &sp, const Vec3 &rand, LocalSample &out) const {
    const float alpha_w = sampling_alpha();
    if (!glint::sample_smooth_lobe(field_.distribution, alpha_w, sp.wi, rand, out.wo)) return false;
    out.pdf = glint::smooth_lobe_pdf(field_.distribution, alpha_w, sp.wi, out.wo);
    out.f_cos = glint_f_cos(sp.ctx, sp.wi, out.wo);
    out.roughness = std::sqrt(alpha_w);
    out.label = GLIMMER_LABEL_REFLECT | GLIMMER_LABEL_GLOSSY;
    return out.pdf > 0.0f;
  }

  Spectrum albedo(const ShadingPoint &) const { return field_.color; }

 private:
  glint::ParticleField field_;
  float gamma_ = 0.035f;  // radians
  float cone_solid_angle_ = 1.0f;
};

GLIMMER_REGISTER_CLOSURE(GlintJakob14Closure)

}  // namespace glimmer::plugin
