// The pane walk's resampled events (session 37, frostedwalk37; docs/history/frosted_glass_sessions.md "Session 37
// (frostedwalk37)"): FrostedGlassClosure::walk_event's level 1 and the walk / exit trials at that level, in a
// translation unit of their own so that frosted_glass.cpp's code (main's walk, level 0, and every inlining decision on
// the default path) is compiled as without them. FrostedGlassClosure::resampled_walk picks them (relative IOR >= 1.6
// since session 38; 1.9 before).
#include "closures/frosted_glass.h"

namespace glimmer::plugin {

bool FrostedGlassClosure::resampled_event(const DielectricLobe &lobe, const Vec3 &wi_in, mf::WalkRng &rng, bool control,
                                          LocalSample &s) {
  constexpr int kK = kPaneWalkCandidates;
  static_assert(kK == 4, "the candidates' visible normals are jittered on a 2 x 2 grid");
  const bool outside = wi_in.z > 0.0f;
  const float eta = outside ? lobe.ior : 1.0f / lobe.ior;
  const Vec3 wi = outside ? wi_in : mf::flip_z_local(wi_in);
  const float g1 = mf::G1(lobe.dist, wi, lobe.ax, lobe.ay);
  if (!(g1 > 0.0f)) return false;
  // wi's parts of the candidates' visible normals and shadowing, once per event (the same values bit for bit)
  const Vec3 wi_std = mf::ggx_stretched_incidence(wi, lobe.ax, lobe.ay);
  const float incidence = lobe.g2_incidence(wi);
  Vec3 dirs[2 * kK];
  float a[2 * kK];
  float total = 0.0f;
  for (int j = 0; j < kK; ++j) {
    const float u1 = (float(j & 1) + rng.next()) * 0.5f, u2 = (float(j >> 1) + rng.next()) * 0.5f;
    Vec3 m;
    float cos_t;
    const float F = lobe.visible_facet_at(wi, wi_std, eta, u1, u2, m, &cos_t);
    a[2 * j] = a[2 * j + 1] = 0.0f;
    dirs[2 * j] = normalize(mf::reflect_about(wi, m));
    if (F > 0.0f && dirs[2 * j].z > 0.0f) a[2 * j] = (control ? 1.0f : F) * lobe.g2_at(incidence, dirs[2 * j]) / g1;
    if (F < 1.0f) {  // mf::refract(wi, m, eta, ...) succeeds there; Fresnel's cos_t is its ct (session 39)
      dirs[2 * j + 1] = mf::refract_with_cos_t(wi, m, eta, cos_t);
      if (dirs[2 * j + 1].z < 0.0f)
        a[2 * j + 1] = (control ? 1.0f : 1.0f - F) * lobe.g2_at(incidence, dirs[2 * j + 1]) / g1;
    }
    total += a[2 * j] + a[2 * j + 1];
  }
  if (!(total > 0.0f) || !std::isfinite(total)) return false;
  float pick = rng.next() * total;
  int i = 0;
  while (i < 2 * kK - 1 && !(pick < a[i])) pick -= a[i++];
  while (a[i] == 0.0f) --i;  // rounding past the last branch: the last with a weight (total > 0: one exists)
  const bool reflect = (i & 1) == 0;
  s.wo = outside ? dirs[i] : mf::flip_z_local(dirs[i]);
  s.f_cos = Spectrum(total / (float(kK) * lobe.compensation(wi.z, eta)));
  s.pdf = 1.0f;
  s.roughness = std::sqrt(lobe.ax * lobe.ay);
  s.eta = reflect ? 1.0f : eta;
  s.label = (reflect ? GLIMMER_LABEL_REFLECT : GLIMMER_LABEL_TRANSMIT) | GLIMMER_LABEL_GLOSSY;
  return true;
}

FrostedGlassClosure::ResampledWalk FrostedGlassClosure::walk_to_exit_resampled(const ShadingPoint &sp,
                                                                               const DielectricLobe &lobe, Vec3 rand,
                                                                               Vec3 d, Spectrum throughput) const {
  ResampledWalk r;
  r.ok = walk_to_exit_at<kPaneWalkResampled>(sp, lobe, rand, d, throughput, r.leaving, &r.reflections, &r.before_exit);
  r.d = d, r.throughput = throughput;
  return r;
}

int FrostedGlassClosure::exit_trials_resampled(const ShadingPoint &sp, const DielectricLobe &lobe, Vec3 rand,
                                               Vec3 d) const {
  return exit_trials_at<kPaneWalkResampled>(sp, lobe, rand, d);
}

}  // namespace glimmer::plugin
