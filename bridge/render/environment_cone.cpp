#include "render/environment_cone.h"

#include <algorithm>
#include <cmath>

#include "render/textures.h"

namespace glimmer::render {

namespace {
constexpr float kGoldenAngle = 2.39996323f;  // pi (3 - sqrt 5): successive spiral points' azimuth step

// Solid angle of row y of an equirectangular grid of `height` rows, up to the factor 2 pi / width.
double row_solid_angle(int y, int height) {
  const double t0 = M_PI * (1.0 - double(y) / height), t1 = M_PI * (1.0 - double(y + 1) / height);
  return std::fabs(std::cos(t1) - std::cos(t0));
}
}  // namespace

Spectrum EnvironmentCone::Level::at(int x, int y) const {
  x %= width;
  if (x < 0) x += width;
  y = std::clamp(y, 0, height - 1);
  return texels[size_t(y) * size_t(width) + size_t(x)];
}

// Bilinear between cell centres; u wraps around the sphere, v clamps at the poles.
Spectrum EnvironmentCone::Level::bilinear(float u, float v) const {
  const float fx = (u - std::floor(u)) * width - 0.5f, fy = v * height - 0.5f;
  const int x0 = int(std::floor(fx)), y0 = int(std::floor(fy));
  const float tx = fx - x0, ty = fy - y0;
  return (at(x0, y0) * (1.0f - tx) + at(x0 + 1, y0) * tx) * (1.0f - ty) +
         (at(x0, y0 + 1) * (1.0f - tx) + at(x0 + 1, y0 + 1) * tx) * ty;
}

void EnvironmentCone::build(const ShaderSystem &shaders) const {
  Level base{kBaseWidth, kBaseHeight, std::vector<Spectrum>(size_t(kBaseWidth) * kBaseHeight)};
  for (int y = 0; y < base.height; ++y)
    for (int x = 0; x < base.width; ++x) {
      Spectrum acc(0.0f);
      for (int s = 0; s < 4; ++s) {  // 2x2 evaluations within the cell
        const float u = (x + 0.25f + 0.5f * (s & 1)) / base.width, v = (y + 0.25f + 0.5f * (s >> 1)) / base.height;
        acc += shaders.background(equirectangular_to_direction(u, v));
      }
      base.texels[size_t(y) * base.width + x] = acc * 0.25f;
    }
  std::vector<Level> levels{std::move(base)};
  while (levels.back().height > 1) {
    const Level &fine = levels.back();
    Level coarse{fine.width / 2, fine.height / 2, {}};
    coarse.texels.resize(size_t(coarse.width) * coarse.height);
    for (int y = 0; y < coarse.height; ++y) {
      // The two fine rows weighted by their solid angles (rows near a pole cover less of the sphere).
      const double w0 = row_solid_angle(2 * y, fine.height), w1 = row_solid_angle(2 * y + 1, fine.height);
      const float a = float(w0 / (w0 + w1)), b = 1.0f - a;
      for (int x = 0; x < coarse.width; ++x)
        coarse.texels[size_t(y) * coarse.width + x] =
            (fine.at(2 * x, 2 * y) + fine.at(2 * x + 1, 2 * y)) * (0.5f * a) +
            (fine.at(2 * x, 2 * y + 1) + fine.at(2 * x + 1, 2 * y + 1)) * (0.5f * b);
    }
    levels.push_back(std::move(coarse));
  }
  levels_ = std::move(levels);
}

// Trilinear: bilinear in the two levels around the fractional `level`, linear between them.
Spectrum EnvironmentCone::filtered(const Vec3 &direction, float level) const {
  float u, v;
  direction_to_equirectangular(direction, u, v);
  const float l = std::clamp(level, 0.0f, float(levels_.size() - 1));
  const int l0 = std::min(int(l), int(levels_.size()) - 1), l1 = std::min(l0 + 1, int(levels_.size()) - 1);
  const float t = l - float(l0);
  const Spectrum a = levels_[size_t(l0)].bilinear(u, v);
  return t > 0.0f ? a * (1.0f - t) + levels_[size_t(l1)].bilinear(u, v) * t : a;
}

Spectrum EnvironmentCone::lookup(const ShaderSystem &shaders, const Vec3 &direction, float cone_angle,
                                 int points) const {
  const int n = std::clamp(points, 1, kConePoints);
  const bool finite = std::isfinite(direction.x) && std::isfinite(direction.y) && std::isfinite(direction.z);
  if (!(cone_angle > 0.0f) || !finite || shaders.background_is_constant()) return shaders.background(direction);
  const float half = std::min(cone_angle, kPi);
  // 1 - cos(half) as 2 sin^2(half / 2): exact for the narrowest cones.
  const float one_minus_cos = 2.0f * std::pow(std::sin(0.5f * half), 2.0f);
  // Spacing of n points spread over the cap's solid angle 2 pi (1 - cos), and the level whose
  // cells (pi / height radians tall) are that wide.
  const float spacing = std::sqrt(kTwoPi * one_minus_cos / float(n));
  // Below level 2 the map's bilinear footprint would blur the cap's edge by more than a few percent of its width:
  // the background is then evaluated at the points themselves (cones up to ~9 degrees: kConePoints shader
  // evaluations at most).
  const float level = std::log2(spacing / (kPi / float(kBaseHeight))) + kLevelBias;
  const bool direct = level < 2.0f;
  if (!direct) std::call_once(once_, [&] { build(shaders); });
  const Frame frame = Frame::from_normal(direction);
  Spectrum sum(0.0f);
  for (int i = 0; i < n; ++i) {
    // Fibonacci spiral over the cap: equal solid angle per point (1 - cos uniform), azimuth by the golden angle.
    const float omc = (i + 0.5f) / float(n) * one_minus_cos;
    const float sin_t = std::sqrt(std::max(0.0f, omc * (2.0f - omc))), phi = kGoldenAngle * float(i);
    const Vec3 local(sin_t * std::cos(phi), sin_t * std::sin(phi), 1.0f - omc);
    const Vec3 d = normalize(frame.to_world(local));
    sum += direct ? shaders.background(d) : filtered(d, level);
  }
  return sum * (1.0f / float(n));
}

}  // namespace glimmer::render
