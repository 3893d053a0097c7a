// The physics behind Cycles' Sky Texture node (Blender 3.4), written from the papers
// and the constants of Cycles' intern/sky (facts: wavelengths, coefficients, scale
// heights, the Gauss-Laguerre nodes of its optical depth):
//  - nishita: single scattering in a spherical atmosphere (Nishita et al. 1993, "Display
//    of the Earth taking into account atmospheric scattering", eq. 1-4: in-scattered
//    radiance = integral along the view ray of T(view) T(sun) sigma_s phase E_sun),
//    Rayleigh + Mie (Cornette-Shanks phase, g = 0.76) + ozone absorption, 21 wavelengths
//    380..780 nm integrated against the CIE 1931 matching functions, discretised as Cycles
//    3.4 does (a Cycles-compatible sky, not the converged integral): 32 equal view-ray
//    segments, each scattering at its midpoint with the transmittance of the whole segment,
//    the optical depth toward the sun by an 8-node Gauss-Laguerre rule. That is 1-3 % darker
//    overhead and up to ~60 % darker (blue) at the horizon than the converged integral
//    (tests/bridge/test_sky.cpp measures it). Precomputed once per node into Cycles' 512 x
//    128 table layout over (azimuth from the sun, elevation), the sun disc added
//    analytically (Beer-Lambert transmittance, limb darkening 0.6).
//  - preetham: the closed form of Preetham, Shirley & Smits 1999 (Perez et al. 1993
//    luminance distribution, appendix A.2 zenith values and distribution coefficients),
//    with Cycles' 0.06 luminance scale.
// Radiance is returned in Blender's scene linear (Rec.709 primaries): XYZ through the
// inverse of Blender's srgb_to_xyz.spimtx, negatives clamped (Cycles' xyz_to_rgb_clamped).
#pragma once

#include <vector>

#include "glimmer/math.h"

namespace glimmer::render::nodes {

// The atmosphere and observer of the nishita model (the node's settings).
struct Atmosphere {
  float altitude = 1.0f;  // m above sea level (Cycles clamps to [1, 59999])
  float air_density = 1.0f, dust_density = 1.0f, ozone_density = 1.0f;
};

// Physical constants of the model (Cycles' intern/sky values).
namespace atmosphere {
inline constexpr int kWavelengths = 21;  // 380, 400, ..., 780 nm
inline constexpr float kWavelengthStep = 20.0f;
inline constexpr float kEarthRadius = 6360e3f, kAtmosphereRadius = 6420e3f;  // m
inline constexpr float kRayleighScaleHeight = 8e3f, kMieScaleHeight = 1.2e3f;  // m
inline constexpr float kMieScattering = 2e-5f;   // m^-1
inline constexpr float kMieExtinctionRatio = 1.11f;  // Mie extinction / scattering
inline constexpr float kMieG = 0.76f;
inline constexpr int kViewSegments = 32;  // equal segments of the view ray (Cycles' `steps`)
inline constexpr int kDepthNodes = 8;     // Gauss-Laguerre nodes of the optical depth toward the sun
extern const float kSolarIrradiance[kWavelengths];  // top of the atmosphere, W m^-2 nm^-1
extern const float kRayleighScattering[kWavelengths];  // m^-1 at sea level
extern const float kOzoneAbsorption[kWavelengths];     // m^-1 at the ozone peak
extern const float kCieXyz[kWavelengths][3];           // CIE 1931 2-degree matching functions
// Relative densities at height h (m) above sea level: exp(-h / H) for air and dust; ozone a tent
// between 10 and 40 km peaking at 25 km.
double rayleigh_density(double h);
double mie_density(double h);
double ozone_density(double h);
double rayleigh_phase(double mu);  // 3 / (16 pi) (1 + mu^2)
double mie_phase(double mu);       // Cornette-Shanks with g = kMieG
}  // namespace atmosphere

// XYZ -> Blender 3.4 scene linear (Rec.709, D65), negative components clamped to 0.
Vec3 xyz_to_scene_linear(const Vec3 &xyz);
// Spectrum at the 21 wavelengths -> XYZ (sum of spectrum x matching function x 20 nm).
Vec3 spectrum_to_xyz(const float *spectrum);

// The sky's single-scattered radiance (XYZ) seen from the node's observer (on the +z axis at the
// atmosphere's altitude) along unit `dir`, lit by a sun in unit direction `sun_dir`: Cycles 3.4's
// discrete scheme (see the top of this file). One table texel.
Vec3 nishita_sky_xyz(const Vec3 &dir, const Vec3 &sun_dir, const Atmosphere &a);

// The sun disc's radiance (XYZ, before limb darkening) seen at `elevation`: the top-of-atmosphere
// irradiance spread over `solid_angle`, attenuated by Rayleigh and Mie extinction along the path
// (no ozone, as Cycles).
Vec3 nishita_sun_xyz(float elevation, float solid_angle, const Atmosphere &a);

// A cone of directions the background light samples explicitly (the sun disc).
struct SunDisc {
  Vec3 direction{0.0f, 0.0f, 1.0f};
  float half_angle = 0.0f;
};

// Blender 3.4's Sky Texture node, evaluated per direction.
class SkyModel {
 public:
  enum class Type { Preetham, HosekWilkie, Nishita };
  struct Settings {
    Type type = Type::Nishita;
    // preetham / hosek_wilkie
    Vec3 sun_direction{0.0f, 0.0f, 1.0f};
    float turbidity = 2.2f, ground_albedo = 0.3f;
    // nishita
    bool sun_disc = true;
    float sun_size = 0.009512f;  // angular diameter (rad)
    float sun_intensity = 1.0f;
    float sun_elevation = 0.2617994f;  // 15 degrees
    float sun_rotation = 0.0f;  // the sun's azimuth is 90 degrees - sun_rotation (counter-clockwise from +x)
    Atmosphere atmosphere;
  };
  static constexpr int kTableWidth = 512, kTableHeight = 128;
  // Where Cycles 3.4 computes texel (i, j) of its nishita table: row j at elevation
  // (pi/2 + pi/(4 H)) (j / H)^2, column i < W/2 at azimuth from the sun 2 pi i / W - pi, column
  // W-1-i its mirror. Its lookup puts texel centres at (i + 0.5) / W and (j + 0.5) / H over
  // (azimuth + pi) / 2 pi and sqrt(elevation / (pi/2)), half a texel from where they were computed.
  static float table_row_elevation(int j);
  static float table_column_azimuth(int i);

  explicit SkyModel(const Settings &s);  // nishita: precomputes the table (parallel rows, deterministic)
  Vec3 radiance(const Vec3 &dir) const;  // scene linear; `dir` need not be unit
  // The sun disc when the model draws one above the horizon (nishita with sun_disc).
  bool has_sun_disc() const;
  SunDisc sun_disc() const;
  const Settings &settings() const { return s_; }

 private:
  float sun_azimuth() const;  // counter-clockwise from +x
  Vec3 nishita(const Vec3 &dir) const;
  Vec3 nishita_table(float elevation, float longitude) const;  // bilinear, XYZ
  Vec3 nishita_sun(const Vec3 &dir, float angle) const;
  Vec3 preetham(const Vec3 &dir) const;
  void precompute_nishita();
  void precompute_preetham();

  Settings s_;
  Vec3 sun_dir_{0.0f, 0.0f, 1.0f};
  // nishita: rows of kTableWidth XYZ texels (table_row_elevation, table_column_azimuth); the sun's
  // bottom and top radiance.
  std::vector<Vec3> table_;
  Vec3 sun_bottom_{0.0f}, sun_top_{0.0f};
  // preetham: zenith values (Y, x, y) and Perez coefficients A..E per channel, sun zenith angle.
  float zenith_[3] = {0, 0, 0};
  float perez_[3][5] = {};
};

// The Perez et al. 1993 sky distribution F(theta, gamma) with coefficients A..E (Preetham eq. 3).
double perez(const double coefficients[5], double theta, double gamma);

}  // namespace glimmer::render::nodes
