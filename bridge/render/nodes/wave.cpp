// Wave Texture (Cycles 3.4 svm_wave): bands or rings along an axis, a sine, saw or
// triangle profile, optionally distorted by fBM noise.
#include "render/nodes/families.h"
#include "render/nodes/perlin.h"

namespace glimmer::render::nodes {

namespace {
enum WaveType { kBands, kRings };
enum Profile { kSine, kSaw, kTriangle };
}  // namespace

void configure_wave(const SettingsReader &r, NodeSettings &s) {
  s.mode[0] = r.choice("wave_type", {"bands", "rings"}, kBands);
  s.mode[1] = r.choice("bands_direction", {"x", "y", "z", "diagonal"}, 0);
  s.mode[2] = r.choice("rings_direction", {"x", "y", "z", "spherical"}, 0);
  s.mode[3] = r.choice("profile", {"sine", "saw", "tri"}, kSine);
}

// in: vector, scale, distortion, detail, detail_scale, detail_roughness, phase_offset; out: color, fac.
void eval_wave(const NodeSettings &s, const ShadingPoint &, const Vec3 *in, Vec3 *out) {
  Vec3 p = in[0] * in[1].x;
  const float distortion = in[2].x, detail = in[3].x, detail_scale = in[4].x, detail_roughness = in[5].x;
  // Cycles nudges the point off exact lattice values.
  p = (p + Vec3(0.000001f)) * 0.999999f;
  float n;
  if (s.mode[0] == kBands) {
    n = s.mode[1] == 3 ? (p.x + p.y + p.z) * 10.0f : p[s.mode[1]] * 20.0f;
  } else {
    Vec3 rp = p;
    if (s.mode[2] < 3) rp[s.mode[2]] = 0.0f;  // rings around that axis
    n = length(rp) * 20.0f;
  }
  n += in[6].x;
  if (distortion != 0.0f)
    n += distortion * (perlin::fractal_noise<3>({p.x * detail_scale, p.y * detail_scale, p.z * detail_scale}, detail,
                                                detail_roughness) * 2.0f - 1.0f);
  float f;
  if (s.mode[3] == kSine) {
    f = 0.5f + 0.5f * std::sin(n - 0.5f * kPi);
  } else {
    n *= kInv2Pi;
    f = s.mode[3] == kSaw ? n - std::floor(n) : std::fabs(n - std::floor(n + 0.5f)) * 2.0f;
  }
  out[0] = Vec3(f);
  out[1] = Vec3(f);
}

}  // namespace glimmer::render::nodes
