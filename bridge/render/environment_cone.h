// The world's radiance averaged over a cone of directions (issue 12: the host
// service environment_lookup(direction, cone_angle) for frosted glass `sg`).
//
// cone_angle <= 0, or a constant world: the background shader itself (the
// point lookup, bit-identical to what the path loop sees). Otherwise, on the
// first such call, the background is baked once into an equirectangular map
// (512 x 256 cells, each the mean of a 2x2 grid of background evaluations) and a
// mip chain of it (each level the solid-angle weighted 2x2 mean of the one
// below, down to 2 x 1). A cone lookup is the mean over a fixed spiral of
// kConePoints directions spread uniformly over the spherical cap of half-angle
// cone_angle about `direction`, each read bilinearly from the mip level whose
// cell is as wide as the spacing of those points (linear between two levels),
// so the cap is covered without gaps: the radiance averaged uniformly over the
// cap's solid angle. Narrow cones (that level below 2, up to ~9 degrees) read the
// background at the spiral's points directly and build nothing. Thread-safe; the
// build is deterministic.
#pragma once

#include <mutex>
#include <vector>

#include "render/shader_system.h"

namespace glimmer::render {

class EnvironmentCone {
 public:
  static constexpr int kBaseWidth = 512, kBaseHeight = 256;
  static constexpr int kConePoints = 64;
  static constexpr float kLevelBias = 0.5f;  // levels coarser than the points' spacing: no gaps between them

  // Radiance around unit `direction`, averaged over the cone of half-angle `cone_angle` radians
  // (clamped to pi: the whole sphere). `points` (1..kConePoints) spiral points: fewer points read a coarser level
  // (the one as wide as their spacing), so the cap stays covered, blurred a little more (the exit lobe mixture
  // gives each lobe points in proportion to its weight, renderer.cpp ExitWorld).
  Spectrum lookup(const ShaderSystem &shaders, const Vec3 &direction, float cone_angle,
                  int points = kConePoints) const;
  // Whether the map has been built (it is built only by a cone lookup on a non-constant world).
  bool built() const { return !levels_.empty(); }

 private:
  struct Level {
    int width = 0, height = 0;
    std::vector<Spectrum> texels;  // row-major; row 0 is v = 0 (the -z pole)
    Spectrum at(int x, int y) const;
    Spectrum bilinear(float u, float v) const;
  };
  void build(const ShaderSystem &shaders) const;
  Spectrum filtered(const Vec3 &direction, float level) const;

  mutable std::once_flag once_;
  mutable std::vector<Level> levels_;
};

}  // namespace glimmer::render
