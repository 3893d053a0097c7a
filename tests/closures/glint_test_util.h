// Brute-force pieces of the glint tests (test_glint*.cpp): the density of a
// particle's reflected direction and its mean over a query cone (the exact
// expectation of the Jakob 2014 / Wang 2018 count estimator).
#pragma once

#include <algorithm>
#include <cmath>

#include "glimmer/math.h"
#include "glimmer/microfacet.h"

namespace glimmer::test {

namespace mf = glimmer::microfacet;

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

}  // namespace glimmer::test
