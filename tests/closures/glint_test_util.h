// Brute-force pieces of the glint tests (test_glint*.cpp): the density of a
// particle's reflected direction and its mean over a query cone (the exact
// expectation of the Jakob 2014 / Wang 2018 count estimator).
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

#include "glimmer/math.h"
#include "glimmer/microfacet.h"
#include "closures/closure_checks.h"
#include "host/closure_instance.h"
#include "tables/glint_hierarchy.h"
#include "tables/glint_tables.h"

namespace glimmer::test {

namespace mf = glimmer::microfacet;

// The isotropic NDF a glint table is built from, D(m) by cos(theta_m) at alpha, as the closure gives it
// (glint.cpp, prepare).
inline plugin::glint::NdfFunction ndf_of(mf::Distribution dist, float alpha) {
  return [dist, alpha](double cos_m) {
    const double c = std::min(std::max(cos_m, 0.0), 1.0);
    const Vec3 m(static_cast<float>(std::sqrt(1.0 - c * c)), 0.0f, static_cast<float>(c));
    return static_cast<double>(mf::D(dist, m, alpha, alpha));
  };
}

// Density of the reflected direction r of a particle whose normal follows
// D(m) cos(theta_m): q(wi, r) = D(h) cos(theta_h) / (4 wi.h), h = normalize(wi + r)
// (Walter 2007's half-vector Jacobian). The smooth BRDF is
// f cos_o = F G2 (wi.h) / (cos_i cos_h) * q(wi, wo). Anisotropic: roughness
// alpha_x along the local x axis, alpha_y along y.
inline double reflected_density(mf::Distribution dist, double alpha_x, double alpha_y, const Vec3 &wi, const Vec3 &r) {
  const double sx = wi.x + r.x, sy = wi.y + r.y, sz = wi.z + r.z;
  const double len = std::sqrt(sx * sx + sy * sy + sz * sz);
  if (!(len > 1e-9)) return 0.0;
  const Vec3 h(static_cast<float>(sx / len), static_cast<float>(sy / len), static_cast<float>(sz / len));
  const double wi_h = (wi.x * sx + wi.y * sy + wi.z * sz) / len;
  if (!(h.z > 0.0f) || !(wi_h > 0.0)) return 0.0;
  return mf::D(dist, h, static_cast<float>(alpha_x), static_cast<float>(alpha_y)) * h.z / (4.0 * wi_h);
}
inline double reflected_density(mf::Distribution dist, double alpha, const Vec3 &wi, const Vec3 &r) {
  return reflected_density(dist, alpha, alpha, wi, r);
}

// Brute-force mean of q over the query cone of half-angle gamma around wo
// (rings of equal solid angle x uniform azimuths): the mean of the Jakob 2014
// / Wang 2018 count estimator. Directions of the cone below the horizon count
// (a particle's mirror direction; its normal is above the surface).
inline double cone_mean_reflected_density(mf::Distribution dist, double alpha_x, double alpha_y, const Vec3 &wi,
                                          const Vec3 &wo, double gamma_deg, int rings = 16) {
  const double ox = wo.x, oy = wo.y, oz = wo.z;
  const double ax = std::fabs(oz) < 0.9 ? 0.0 : 1.0, az = std::fabs(oz) < 0.9 ? 1.0 : 0.0;
  // e1 = normalize(a x wo), e2 = wo x e1
  double e1x = -az * oy, e1y = az * ox - ax * oz, e1z = ax * oy;
  const double l1 = std::sqrt(e1x * e1x + e1y * e1y + e1z * e1z);
  e1x /= l1, e1y /= l1, e1z /= l1;
  const double e2x = oy * e1z - oz * e1y, e2y = oz * e1x - ox * e1z, e2z = ox * e1y - oy * e1x;
  const double one_minus_cos_gamma = 1.0 - std::cos(gamma_deg * (M_PI / 180.0));
  const int n_psi = 4 * rings;
  double sum = 0.0;
  for (int k = 0; k < rings; ++k) {
    const double cos_rho = 1.0 - (k + 0.5) / rings * one_minus_cos_gamma;
    const double sin_rho = std::sqrt(std::max(0.0, 1.0 - cos_rho * cos_rho));
    for (int j = 0; j < n_psi; ++j) {
      const double psi = (j + 0.5 * (k & 1)) * 2.0 * M_PI / n_psi;
      const double c = std::cos(psi) * sin_rho, s = std::sin(psi) * sin_rho;
      const Vec3 r(static_cast<float>(ox * cos_rho + e1x * c + e2x * s),
                   static_cast<float>(oy * cos_rho + e1y * c + e2y * s),
                   static_cast<float>(oz * cos_rho + e1z * c + e2z * s));
      sum += reflected_density(dist, alpha_x, alpha_y, wi, r);
    }
  }
  return sum / (rings * n_psi);
}
inline double cone_mean_reflected_density(mf::Distribution dist, double alpha, const Vec3 &wi, const Vec3 &wo,
                                          double gamma_deg, int rings = 16) {
  return cone_mean_reflected_density(dist, alpha, alpha, wi, wo, gamma_deg, rings);
}

// Brute-force P_gamma for lobes of any width, over the particle normals
// instead of the cone: Pr[reflect(wi, m) within gamma of wo] for m ~ D cos,
// the fraction of an n_u x n_v midpoint grid of direction codes (u, v) of
// glint_jakob14's particles whose particle reflects into the cone
// (ParticleHierarchy::code_theta maps u to theta_m, v to phi_m = 2 pi v; the
// test is ParticleHierarchy::reflects'). A cone quadrature of q needs points
// on the lobe's scale; this needs them on the scale of the cone's edge in
// code space (error ~ 1 / n_u).
class LobeMassInCone {
 public:
  LobeMassInCone(mf::Distribution dist, double alpha, int n_u = 4096, int n_v = 2048) : n_u_(n_u), n_v_(n_v) {
    const plugin::glint::ParticleHierarchy codes(dist, alpha, 1.0, 0);
    for (int a = 0; a < n_u; ++a) {
      const double theta = codes.code_theta((a + 0.5) / n_u);
      sin_t_.push_back(std::sin(theta));
      cos_t_.push_back(std::cos(theta));
    }
    for (int b = 0; b < n_v; ++b) {
      const double phi = 2.0 * M_PI * (b + 0.5) / n_v;
      cos_p_.push_back(std::cos(phi));
      sin_p_.push_back(std::sin(phi));
    }
  }

  double operator()(const Vec3 &wi_f, const Vec3 &wo_f, double gamma_rad) const {
    const double wi[3] = {wi_f.x, wi_f.y, wi_f.z}, wo[3] = {wo_f.x, wo_f.y, wo_f.z};
    const double cos_gamma = std::cos(gamma_rad);
    // r = 2 (wi.m) m - wi, so r.wo = 2 (wi.m)(wo.m) - wi.wo.
    const double wi_wo = wi[0] * wo[0] + wi[1] * wo[1] + wi[2] * wo[2];
    long long hits = 0;
    for (int b = 0; b < n_v_; ++b) {
      const double ix = wi[0] * cos_p_[b] + wi[1] * sin_p_[b], ox = wo[0] * cos_p_[b] + wo[1] * sin_p_[b];
      for (int a = 0; a < n_u_; ++a) {
        const double wi_m = sin_t_[a] * ix + cos_t_[a] * wi[2];
        const double wo_m = sin_t_[a] * ox + cos_t_[a] * wo[2];
        hits += (wi_m > 0.0) & (2.0 * wi_m * wo_m - wi_wo > cos_gamma);
      }
    }
    return static_cast<double>(hits) / (static_cast<double>(n_u_) * n_v_);
  }

 private:
  int n_u_, n_v_;
  std::vector<double> sin_t_, cos_t_, cos_p_, sin_p_;
};

// Smooth microfacet white-furnace albedo Int G2 D / (4 cos_i) dwo (F = 1), anisotropic roughness ax x ay
// (ax = ay: isotropic), over visible normals: G2 / G1(wi) where reflect(wi, h) is above the horizon, midpoint
// rule on the sampler's unit square (side^2 points). Its only discontinuity is the horizon cut, so it converges
// where a grid over wo does not (at 89 degrees a 0.5 x 1-degree wo grid is 2 % low for GGX 0.35). The glint
// furnace tests check it against a wo grid at moderate incidence.
inline double smooth_albedo_vndf(mf::Distribution dist, double ax, double ay, const Vec3 &wi, int side = 512) {
  const float x = static_cast<float>(ax), y = static_cast<float>(ay);
  const float g1 = mf::G1(dist, wi, x, y);
  double sum = 0.0;
  for (int i = 0; i < side; ++i)
    for (int j = 0; j < side; ++j) {
      const Vec3 h = mf::sample_visible_normal(dist, wi, x, y, (i + 0.5f) / side, (j + 0.5f) / side);
      const Vec3 wo = mf::reflect_about(wi, h);
      if (wo.z > 0.0f) sum += mf::G2(dist, wi, wo, x, y) / g1;
    }
  return sum / (static_cast<double>(side) * side);
}

// The red channel of a glint closure instance's eval at wo (and its pdf).
inline float eval_f(const host::ClosureInstance &c, const GlimmerShadingContext &ctx, const Vec3 &wo, float *pdf = nullptr) {
  Spectrum f;
  float p;
  c.eval(ctx, wo, f, p);
  if (pdf) *pdf = p;
  return f.x;
}

// Outgoing directions on a grid x grid raster around the mirror direction of wi = (theta_i, phi_i): polar angle
// and azimuth each within +-span degrees of (theta_i, phi_i + 180), cell centres, only those with polar angle in
// (0, theta_max) degrees.
inline std::vector<Vec3> directions_around_mirror(double theta_i, double phi_i, double span, int grid,
                                                  double theta_max) {
  std::vector<Vec3> wos;
  for (int a = 0; a < grid; ++a)
    for (int b = 0; b < grid; ++b) {
      const double theta_o = theta_i + span * (2.0 * (a + 0.5) / grid - 1.0);
      const double phi_o = phi_i + 180.0 + span * (2.0 * (b + 0.5) / grid - 1.0);
      if (theta_o <= 0.0 || theta_o >= theta_max) continue;
      wos.push_back(spherical_dir(theta_o, phi_o));
    }
  return wos;
}

}  // namespace glimmer::test
