// The glint eval queries shared by bench_glint.cpp (glint/eval_vs_ggx*, timed)
// and glint_eval_instructions.cpp (the callgrind driver), so the two measure
// the same inputs: 4096 queries from Pcg32(11), random positions, view and
// light directions around the lobe, and a footprint of the given uv area:
// a square, or a rectangle of the given aspect, rotated by a random angle.
#pragma once

#include <cmath>
#include <vector>

#include "glimmer/rng.h"
#include "host/closure_instance.h"

namespace glimmer::bench {

struct GlintQuery {
  GlimmerShadingContext ctx;
  Vec3 wo;
};

inline std::vector<GlintQuery> make_glint_queries(double area, double aspect = 1.0) {
  std::vector<GlintQuery> q(4096);
  Pcg32 rng(11);
  const float side = static_cast<float>(std::sqrt(area / aspect));
  for (auto &x : q) {
    const float ti = 1.4f * rng.next_float();
    x.ctx = host::make_local_context(Vec3(std::sin(ti), 0.0f, std::cos(ti)));
    x.ctx.uv[0] = rng.next_float();
    x.ctx.uv[1] = rng.next_float();
    // Rectangle side x (aspect side), rotated by a random angle.
    const float rot = 6.2831853f * rng.next_float(), c = std::cos(rot), s = std::sin(rot);
    x.ctx.duv_dx[0] = static_cast<float>(aspect) * side * c;
    x.ctx.duv_dx[1] = static_cast<float>(aspect) * side * s;
    x.ctx.duv_dy[0] = -side * s;
    x.ctx.duv_dy[1] = side * c;
    // wo: the mirror direction jittered by the lobe width (most light queries hit the lobe).
    const Vec3 mirror(-std::sin(ti), 0.0f, std::cos(ti));
    x.wo = normalize(mirror + Vec3(0.6f * (rng.next_float() - 0.5f), 0.6f * (rng.next_float() - 0.5f),
                                   0.3f * rng.next_float()));
    if (x.wo.z <= 0.05f) x.wo.z = 0.05f;
    x.wo = normalize(x.wo);
  }
  return q;
}

}  // namespace glimmer::bench
