#include "render/nodes/sky_model.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

namespace glimmer::render::nodes {

namespace atmosphere {

// Values of Cycles' intern/sky/source/sky_nishita.cpp (Blender 3.4) at 380, 400, ..., 780 nm.
const float kSolarIrradiance[kWavelengths] = {
    1.45756829855592995315f, 1.56596305559738380175f, 1.65148449067670455293f, 1.71496242737209314555f,
    1.75797983805020541226f, 1.78256407885924539336f, 1.79095108475838560302f, 1.78541550133410664714f,
    1.76815554864306845317f, 1.74122069647250410362f, 1.70647127164943679389f, 1.66556087452739887134f,
    1.61993437242451854274f, 1.57083597368892080581f, 1.51932335059305478886f, 1.46628494965214395407f,
    1.41245852740172450623f, 1.35844961970384092709f, 1.30474913844739281998f, 1.25174963272610817455f,
    1.19975998755420620867f};
const float kRayleighScattering[kWavelengths] = {
    5.424820087636473e-5f, 4.418549866505454e-5f, 3.635151910165377e-5f, 3.017929012024763e-5f,
    2.526320226989157e-5f, 2.130859310621843e-5f, 1.809838025320633e-5f, 1.547057129129042e-5f,
    1.330284977336850e-5f, 1.150184784075764e-5f, 9.99557429990163e-6f,  8.72799973630707e-6f,
    7.65513700977967e-6f,  6.74217203751443e-6f,  5.96134125832052e-6f,  5.29034598065810e-6f,
    4.71115687557433e-6f,  4.20910481110487e-6f,  3.77218381260133e-6f,  3.39051255477280e-6f,
    3.05591531679811e-6f};
const float kOzoneAbsorption[kWavelengths] = {
    3.25126849861e-9f,  5.85395365047e-9f,  1.977191155085e-8f, 7.309568762914e-8f, 2.0084561514287e-7f,
    4.0383958096161e-7f, 6.3551335912363e-7f, 9.6707041180970e-7f, 1.54797400424410e-6f, 2.09038647223331e-6f,
    2.46128056164565e-6f, 2.73551299461512e-6f, 2.15125863128643e-6f, 1.59051840791988e-6f, 1.12356197979857e-6f,
    7.3527551487574e-7f, 4.6450130357806e-7f, 3.3096079921048e-7f, 2.2512612292678e-7f, 1.4879129266490e-7f,
    1.6828623364192e-7f};
const float kCieXyz[kWavelengths][3] = {
    {0.00136800000f, 0.00003900000f, 0.00645000100f}, {0.01431000000f, 0.00039600000f, 0.06785001000f},
    {0.13438000000f, 0.00400000000f, 0.64560000000f}, {0.34828000000f, 0.02300000000f, 1.74706000000f},
    {0.29080000000f, 0.06000000000f, 1.66920000000f}, {0.09564000000f, 0.13902000000f, 0.81295010000f},
    {0.00490000000f, 0.32300000000f, 0.27200000000f}, {0.06327000000f, 0.71000000000f, 0.07824999000f},
    {0.29040000000f, 0.95400000000f, 0.02030000000f}, {0.59450000000f, 0.99500000000f, 0.00390000000f},
    {0.91630000000f, 0.87000000000f, 0.00165000100f}, {1.06220000000f, 0.63100000000f, 0.00080000000f},
    {0.85444990000f, 0.38100000000f, 0.00019000000f}, {0.44790000000f, 0.17500000000f, 0.00002000000f},
    {0.16490000000f, 0.06100000000f, 0.00000000000f}, {0.04677000000f, 0.01700000000f, 0.00000000000f},
    {0.01135916000f, 0.00410200000f, 0.00000000000f}, {0.00289932700f, 0.00104700000f, 0.00000000000f},
    {0.00069007860f, 0.00024920000f, 0.00000000000f}, {0.00016615050f, 0.00006000000f, 0.00000000000f},
    {0.00004150994f, 0.00001499000f, 0.00000000000f}};

double rayleigh_density(double h) { return std::exp(-h / kRayleighScaleHeight); }
double mie_density(double h) { return std::exp(-h / kMieScaleHeight); }
double ozone_density(double h) {
  if (h < 10e3 || h >= 40e3) return 0.0;
  return h < 25e3 ? (h - 10e3) / 15e3 : (40e3 - h) / 15e3;
}
double rayleigh_phase(double mu) { return 3.0 / (16.0 * M_PI) * (1.0 + mu * mu); }
double mie_phase(double mu) {
  const double g2 = double(kMieG) * kMieG;
  return 3.0 * (1.0 - g2) * (1.0 + mu * mu) /
         (8.0 * M_PI * (2.0 + g2) * std::pow(1.0 + g2 - 2.0 * kMieG * mu, 1.5));
}

}  // namespace atmosphere

namespace {

using namespace atmosphere;

// Column amounts (m of sea-level-equivalent air, dust, ozone-peak) along a path, before the
// node's density factors. Double precision: at 6.4e6 m a float height is only good to 0.5 m.
struct Columns {
  double air = 0.0, dust = 0.0, ozone = 0.0;
};

void add(Columns &c, const Columns &rho, double ds) {
  c.air += rho.air * ds;
  c.dust += rho.dust * ds;
  c.ozone += rho.ozone * ds;
}

// A point of the atmosphere in the Earth-centred frame (the observer on the +z axis).
struct Point {
  double x, y, z;
};
Point along(const Point &P, const Vec3 &d, double s) { return {P.x + d.x * s, P.y + d.y * s, P.z + d.z * s}; }
double dot(const Point &P, const Vec3 &d) { return P.x * d.x + P.y * d.y + P.z * d.z; }
double radius_squared(const Point &P) { return P.x * P.x + P.y * P.y + P.z * P.z; }

Columns densities_at(const Point &P) {
  const double h = std::sqrt(radius_squared(P)) - kEarthRadius;
  return {rayleigh_density(h), mie_density(h), ozone_density(h)};
}

// Distance from P (inside the atmosphere) along unit d to the atmosphere's outer sphere.
double distance_to_space(const Point &P, const Vec3 &d) {
  const double b = dot(P, d), c = radius_squared(P) - double(kAtmosphereRadius) * kAtmosphereRadius;
  return -b + std::sqrt(std::max(b * b - c, 0.0));
}

// Cycles' shadow test for the sun's path: a sun below the observer's horizon plane (d.z < 0) whose
// line through P meets the Earth's sphere.
bool earth_blocks(const Point &P, const Vec3 &d) {
  if (d.z >= 0.0f) return false;
  const double b = dot(P, d), c = radius_squared(P) - double(kEarthRadius) * kEarthRadius;
  return b * b - c >= 0.0;
}

// Column amounts from P to space along d by Cycles' 8-node Gauss-Laguerre rule: the integral of
// f(x) e^-x over (0, inf) with x = 25 s / L, the weights carrying e^x, so the path [0, L] holds every
// node (nodes x_i / 25 and weights w_i e^x_i / 25 of the n = 8 Laguerre rule, as fractions of L).
Columns columns_to_space(const Point &P, const Vec3 &d) {
  static constexpr double kNode[kDepthNodes] = {0.006811185292, 0.03614807107, 0.09004346519, 0.1706680068,
                                                0.2818362161,  0.4303406404,  0.6296271457,  0.9145252695};
  static constexpr double kWeight[kDepthNodes] = {0.01750893642, 0.04135477391, 0.06678839063, 0.09507698807,
                                                  0.1283416365,  0.1707430204,  0.2327233347,  0.3562490486};
  const double L = distance_to_space(P, d);
  Columns c;
  for (int i = 0; i < kDepthNodes; ++i) add(c, densities_at(along(P, d, kNode[i] * L)), kWeight[i] * L);
  return c;
}

double extinction(const Columns &c, const Atmosphere &a, int wl, bool with_ozone) {
  return c.air * a.air_density * kRayleighScattering[wl] + c.dust * a.dust_density * kMieExtinctionRatio * kMieScattering +
         (with_ozone ? c.ozone * a.ozone_density * kOzoneAbsorption[wl] : 0.0);
}

Point observer(const Atmosphere &a) { return {0.0, 0.0, double(kEarthRadius) + a.altitude}; }

Vec3 from_elevation_azimuth(float elevation, float azimuth) {
  return {std::cos(elevation) * std::cos(azimuth), std::cos(elevation) * std::sin(azimuth), std::sin(elevation)};
}

// Angle between unit vectors, accurate near 0 (the sun disc is 0.27 degrees wide).
float angle_between(const Vec3 &a, const Vec3 &b) { return 2.0f * std::atan2(length(a - b), length(a + b)); }

float wrap_angle(float a) {  // to [-pi, pi)
  a = std::fmod(a + kPi, kTwoPi);
  return (a < 0.0f ? a + kTwoPi : a) - kPi;
}

}  // namespace

Vec3 xyz_to_scene_linear(const Vec3 &c) {
  // Inverse of Blender's datafiles/colormanagement/luts/srgb_to_xyz.spimtx (Rec.709 / sRGB, D65).
  const Vec3 rgb(3.2404542f * c.x - 1.5371385f * c.y - 0.4985314f * c.z,
                 -0.9692660f * c.x + 1.8760108f * c.y + 0.0415560f * c.z,
                 0.0556434f * c.x - 0.2040259f * c.y + 1.0572252f * c.z);
  return max(rgb, Vec3(0.0f));
}

Vec3 spectrum_to_xyz(const float *spectrum) {
  Vec3 xyz(0.0f);
  for (int wl = 0; wl < kWavelengths; ++wl)
    xyz = xyz + Vec3(kCieXyz[wl][0], kCieXyz[wl][1], kCieXyz[wl][2]) * spectrum[wl];
  return xyz * kWavelengthStep;
}

// Nishita 1993 eq. 4 for one direction, discretised as Cycles 3.4 does: the view ray cut into 32
// equal segments, each scattering sigma_s(P) phase E_sun at its midpoint P with the transmittance to
// the camera over the WHOLE segment (camera to the segment's far end) and toward the sun (the
// Gauss-Laguerre depth; nothing when the Earth blocks the sun).
Vec3 nishita_sky_xyz(const Vec3 &dir, const Vec3 &sun_dir, const Atmosphere &a) {
  const Point origin = observer(a);
  const double ds = distance_to_space(origin, dir) / kViewSegments;
  const double mu = dot(dir, sun_dir);
  const double phase_air = rayleigh_phase(mu), phase_dust = mie_phase(mu);
  double spectrum[kWavelengths] = {};
  Columns view;  // from the camera to the current segment's far end
  for (int i = 0; i < kViewSegments; ++i) {
    const Point P = along(origin, dir, (i + 0.5) * ds);
    const Columns rho = densities_at(P);
    add(view, rho, ds);
    if (earth_blocks(P, sun_dir)) continue;
    Columns path = columns_to_space(P, sun_dir);
    add(path, view, 1.0);
    for (int wl = 0; wl < kWavelengths; ++wl) {
      const double scattering = rho.air * a.air_density * kRayleighScattering[wl] * phase_air +
                                rho.dust * a.dust_density * kMieScattering * phase_dust;
      spectrum[wl] += std::exp(-extinction(path, a, wl, true)) * scattering * kSolarIrradiance[wl] * ds;
    }
  }
  float out[kWavelengths];
  for (int wl = 0; wl < kWavelengths; ++wl) out[wl] = float(spectrum[wl]);
  return spectrum_to_xyz(out);
}

Vec3 nishita_sun_xyz(float elevation, float solid_angle, const Atmosphere &a) {
  const Columns c = columns_to_space(observer(a), from_elevation_azimuth(elevation, 0.0f));
  float spectrum[kWavelengths];
  for (int wl = 0; wl < kWavelengths; ++wl)
    spectrum[wl] = float(kSolarIrradiance[wl] * std::exp(-extinction(c, a, wl, false)) / solid_angle);
  return spectrum_to_xyz(spectrum);
}

double perez(const double k[5], double theta, double gamma) {
  return (1.0 + k[0] * std::exp(k[1] / std::cos(theta))) *
         (1.0 + k[2] * std::exp(k[3] * gamma) + k[4] * std::cos(gamma) * std::cos(gamma));
}

// ---- SkyModel ------------------------------------------------------------------------------------------------

SkyModel::SkyModel(const Settings &s) : s_(s) {
  if (s_.type == Type::Nishita) {
    s_.atmosphere.altitude = std::clamp(s_.atmosphere.altitude, 1.0f, 59999.0f);
    s_.sun_size = std::max(s_.sun_size, 1e-5f);
    sun_dir_ = from_elevation_azimuth(s_.sun_elevation, sun_azimuth());
    precompute_nishita();
  } else {
    sun_dir_ = normalize(s_.sun_direction);
    precompute_preetham();
  }
}

float SkyModel::table_row_elevation(int j) {
  return (0.5f * kPi + 0.25f * kPi / kTableHeight) * sqr(float(j) / kTableHeight);
}

float SkyModel::table_column_azimuth(int i) {
  if (i >= kTableWidth / 2) i = kTableWidth - 1 - i;  // the mirrored half
  return kTwoPi * float(i) / kTableWidth - kPi;
}

void SkyModel::precompute_nishita() {
  const Vec3 sun_local = from_elevation_azimuth(s_.sun_elevation, 0.0f);  // the table's sun at azimuth 0
  table_.assign(size_t(kTableWidth) * kTableHeight, Vec3(0.0f));
  tbb::parallel_for(tbb::blocked_range<int>(0, kTableHeight), [&](const tbb::blocked_range<int> &rows) {
    for (int j = rows.begin(); j < rows.end(); ++j) {
      for (int i = 0; i < kTableWidth / 2; ++i) {  // the sky is symmetric about the sun's azimuth
        const Vec3 xyz = nishita_sky_xyz(from_elevation_azimuth(table_row_elevation(j), table_column_azimuth(i)),
                                         sun_local, s_.atmosphere);
        table_[size_t(j) * kTableWidth + i] = xyz;
        table_[size_t(j) * kTableWidth + (kTableWidth - 1 - i)] = xyz;
      }
    }
  });
  const float half = 0.5f * s_.sun_size, solid_angle = kTwoPi * (1.0f - std::cos(half));
  sun_bottom_ = nishita_sun_xyz(std::max(s_.sun_elevation - half, 0.0f), solid_angle, s_.atmosphere);
  sun_top_ = nishita_sun_xyz(std::max(s_.sun_elevation + half, 0.0f), solid_angle, s_.atmosphere);
}

// Preetham et al. 1999, appendix A.2: zenith luminance (kcd/m^2, times Cycles' 0.06) and chromaticity,
// and the Perez coefficients A..E of Y, x, y as linear functions of the turbidity T.
void SkyModel::precompute_preetham() {
  const double T = s_.turbidity, theta = safe_acos(sun_dir_.z);
  const double chi = (4.0 / 9.0 - T / 120.0) * (M_PI - 2.0 * theta);
  const double zenith_Y = ((4.0453 * T - 4.9710) * std::tan(chi) - 0.2155 * T + 2.4192) * 0.06;
  // [T^2 T 1] M [theta^3 theta^2 theta 1]^T
  static constexpr double kZenithX[3][4] = {
      {0.00166, -0.00375, 0.00209, 0.0}, {-0.02903, 0.06377, -0.03202, 0.00394}, {0.11693, -0.21196, 0.06052, 0.25886}};
  static constexpr double kZenithY[3][4] = {
      {0.00275, -0.00610, 0.00317, 0.0}, {-0.04214, 0.08970, -0.04153, 0.00516}, {0.15346, -0.26756, 0.06670, 0.26688}};
  auto chromaticity = [&](const double (&m)[3][4]) {
    const double t[3] = {T * T, T, 1.0}, th[4] = {theta * theta * theta, theta * theta, theta, 1.0};
    double sum = 0.0;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) sum += t[r] * m[r][c] * th[c];
    return sum;
  };
  // {slope, intercept} of A..E for Y, x, y.
  static constexpr double kPerez[3][5][2] = {
      {{0.1787, -1.4630}, {-0.3554, 0.4275}, {-0.0227, 5.3251}, {0.1206, -2.5771}, {-0.0670, 0.3703}},
      {{-0.0193, -0.2592}, {-0.0665, 0.0008}, {-0.0004, 0.2125}, {-0.0641, -0.8989}, {-0.0033, 0.0452}},
      {{-0.0167, -0.2608}, {-0.0950, 0.0092}, {-0.0079, 0.2102}, {-0.0441, -1.6537}, {-0.0109, 0.0529}}};
  const double zenith[3] = {zenith_Y, chromaticity(kZenithX), chromaticity(kZenithY)};
  for (int c = 0; c < 3; ++c) {
    double k[5];
    for (int i = 0; i < 5; ++i) k[i] = kPerez[c][i][0] * T + kPerez[c][i][1];
    for (int i = 0; i < 5; ++i) perez_[c][i] = float(k[i]);
    // Preetham eq. 2: value(theta, gamma) = zenith F(theta, gamma) / F(0, theta_sun).
    zenith_[c] = float(zenith[c] / perez(k, 0.0, theta));
  }
}

Vec3 SkyModel::preetham(const Vec3 &d) const {
  const double gamma = angle_between(d, sun_dir_);
  const double theta = std::min(double(safe_acos(d.z)), M_PI / 2 - 0.001);  // the ground repeats the horizon
  double value[3];
  for (int c = 0; c < 3; ++c) {
    const double k[5] = {perez_[c][0], perez_[c][1], perez_[c][2], perez_[c][3], perez_[c][4]};
    value[c] = zenith_[c] * perez(k, theta, gamma);
  }
  const double Y = value[0], x = value[1], y = value[2];
  if (y == 0.0) return Vec3(0.0f);
  return xyz_to_scene_linear(Vec3(float(x / y * Y), float(Y), float((1.0 - x - y) / y * Y)));
}

Vec3 SkyModel::nishita_table(float elevation, float longitude) const {
  const float fy = std::clamp(std::sqrt(std::max(elevation, 0.0f) / (0.5f * kPi)) * kTableHeight - 0.5f, 0.0f,
                              float(kTableHeight - 1));
  const float fx = (longitude + kPi) / kTwoPi * kTableWidth - 0.5f;
  const int y0 = std::min(int(fy), kTableHeight - 2), x0 = int(std::floor(fx));
  const float ty = fy - y0, tx = fx - x0;
  auto texel = [&](int x, int y) { return table_[size_t(y) * kTableWidth + ((x % kTableWidth) + kTableWidth) % kTableWidth]; };
  const Vec3 low = texel(x0, y0) * (1.0f - tx) + texel(x0 + 1, y0) * tx;
  const Vec3 high = texel(x0, y0 + 1) * (1.0f - tx) + texel(x0 + 1, y0 + 1) * tx;
  return low * (1.0f - ty) + high * ty;
}

// The sun disc: the radiance at its bottom and top edge interpolated by elevation (Cycles), limb
// darkening 1 - 0.6 (1 - sqrt(1 - (angle / radius)^2)).
Vec3 SkyModel::nishita_sun(const Vec3 &d, float angle) const {
  const float half = 0.5f * s_.sun_size, e = s_.sun_elevation, elevation = std::asin(std::clamp(d.z, -1.0f, 1.0f));
  float t;
  if (e - half > 0.0f) t = (elevation - e) / s_.sun_size + 0.5f;
  else if (e + half > 0.0f) t = elevation / (e + half);
  else return Vec3(0.0f);
  const float limb = 1.0f - 0.6f * (1.0f - safe_sqrt(1.0f - sqr(angle / half)));
  return (sun_bottom_ + (sun_top_ - sun_bottom_) * t) * (s_.sun_intensity * limb);
}

Vec3 SkyModel::nishita(const Vec3 &d) const {
  const float longitude = wrap_angle(std::atan2(d.y, d.x) - sun_azimuth());
  if (d.z < 0.0f) {  // the ground: the horizon fading to black at z = -0.4
    if (d.z < -0.4f) return Vec3(0.0f);
    const float fade = 1.0f + 2.5f * d.z;
    return nishita_table(0.0f, longitude) * (fade * fade * fade);
  }
  if (s_.sun_disc) {
    const float angle = angle_between(d, sun_dir_);
    if (angle < 0.5f * s_.sun_size) return nishita_sun(d, angle);
  }
  return nishita_table(std::asin(std::min(d.z, 1.0f)), longitude);
}

Vec3 SkyModel::radiance(const Vec3 &dir) const {
  const float len = length(dir);
  if (!(len > 0.0f) || !std::isfinite(len)) return Vec3(0.0f);
  const Vec3 d = dir / len;
  if (s_.type == Type::Nishita) return xyz_to_scene_linear(nishita(d));
  return preetham(d);
}

bool SkyModel::has_sun_disc() const {
  return s_.type == Type::Nishita && s_.sun_disc && s_.sun_elevation + 0.5f * s_.sun_size > 0.0f;
}

// Blender 3.4: sun_rotation turns the sun clockwise (seen from above) from +y; measured against its
// Cycles (tests/addon/test_cycles_parity.py, scene `sky`: a 10 degree error shows in every quadrant).
float SkyModel::sun_azimuth() const { return 0.5f * kPi - s_.sun_rotation; }

SunDisc SkyModel::sun_disc() const { return {sun_dir_, 0.5f * s_.sun_size}; }

}  // namespace glimmer::render::nodes
