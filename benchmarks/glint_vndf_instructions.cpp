// Instructions per Beckmann visible-normal sample (issue 10): the shared exact
// sampler (microfacet::sample_beckmann_visible_normal, libm) and glint's
// library-free one (draw_visible_normal, plugin/tables/glint_beckmann_vndf.cpp:
// the out-of-line function glint calls) over the same inputs,
// each in its own loop for callgrind (glint_vndf_instructions.sh counts
// `shared_loop` and `glint_loop`). Inputs: wi uniform over the hemisphere
// (cosine-distributed polar angle, any azimuth), alpha uniform in
// [0.05, 1] (isotropic), u1, u2 float uniform; 20000 samples. Prints the
// count, an XOR hash of each loop's normals' bits and the number of
// normals that differ.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <vector>

#include "glimmer/microfacet.h"
#include "tables/glint_beckmann_vndf.h"

namespace {
using glimmer::Vec3;
struct Input {
  Vec3 wi;
  float alpha, u1, u2;
};
std::uint32_t bits(float f) {
  std::uint32_t b;
  std::memcpy(&b, &f, 4);
  return b;
}
std::uint64_t hash_of(const std::vector<Vec3> &out) {
  std::uint64_t h = 1469598103934665603ull;
  for (const Vec3 &v : out)
    for (float f : {v.x, v.y, v.z}) h = (h ^ bits(f)) * 1099511628211ull;
  return h;
}
__attribute__((noinline)) void shared_loop(const std::vector<Input> &in, std::vector<Vec3> &out) {
  for (std::size_t i = 0; i < in.size(); ++i)
    out[i] = glimmer::microfacet::sample_beckmann_visible_normal(in[i].wi, in[i].alpha, in[i].alpha, in[i].u1,
                                                                 in[i].u2);
}
__attribute__((noinline)) void glint_loop(const std::vector<Input> &in, std::vector<Vec3> &out) {
  for (std::size_t i = 0; i < in.size(); ++i)
    out[i] = glimmer::plugin::glint::beckmann_vndf::draw_visible_normal(in[i].wi, in[i].alpha, in[i].alpha,
                                                                        in[i].u1, in[i].u2);
}
}  // namespace

int main() {
  constexpr int kSamples = 20000;
  std::uint64_t state = 0x9e3779b97f4a7c15ull;
  auto next = [&state] {  // splitmix64 -> float in [0, 1)
    state += 0x9e3779b97f4a7c15ull;
    std::uint64_t z = state;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return static_cast<float>((z ^ (z >> 31)) >> 40) * 0x1p-24f;
  };
  std::vector<Input> in(kSamples);
  for (Input &s : in) {
    const float cos_t = std::sqrt(next()), phi = 6.2831853f * next();
    const float sin_t = std::sqrt(std::max(0.0f, 1.0f - cos_t * cos_t));
    s.wi = Vec3(sin_t * std::cos(phi), sin_t * std::sin(phi), std::max(cos_t, 1e-6f));
    s.alpha = 0.05f + 0.95f * next();
    s.u1 = next();
    s.u2 = next();
  }
  // Warm the shared start table (both samplers use it) outside the counted loops.
  (void)glimmer::microfacet::detail::beckmann_slope_guess();
  std::vector<Vec3> a(kSamples), b(kSamples);
  shared_loop(in, a);
  glint_loop(in, b);
  int differ = 0;
  for (int i = 0; i < kSamples; ++i) differ += std::memcmp(&a[i], &b[i], sizeof(Vec3)) != 0;
  std::printf("samples %d shared_hash %016llx glint_hash %016llx differ %d\n", kSamples,
              static_cast<unsigned long long>(hash_of(a)), static_cast<unsigned long long>(hash_of(b)), differ);
  return 0;
}
