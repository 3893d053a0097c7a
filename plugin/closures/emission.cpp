// Lambertian surface emission, as Cycles' emission closure
// (kernel/closure/emissive.h): constant radiance color * strength toward every
// direction on both sides of the surface.
//
// emit() returns that radiance toward ctx->wi. eval()/sample() describe the
// normalized directional distribution of the emitted power, |cos| / (2 pi)
// over both hemispheres (it integrates to 1), so the closure laboratory
// can check its sampler like any other closure.
#include <array>

#include "core/closure.h"
#include "glimmer/sampling.h"

namespace glimmer::plugin {

class EmissionClosure {
 public:
  static constexpr const char *kName = "emission";
  static constexpr const char *kDoc =
      "Lambertian emitter: radiance = color * strength toward every direction, both sides (Cycles' emission).";
  static constexpr uint32_t kFlags = GLIMMER_CLOSURE_EMISSIVE;

  static std::span<const GlimmerParamSpec> params() {
    static const std::array<GlimmerParamSpec, 2> schema{{
        {"color", GLIMMER_PARAM_COLOR, {1.0f, 1.0f, 1.0f}, 0.0f, 1e6f, nullptr, nullptr,
         "emitted colour (linear RGB)", 0},
        {"strength", GLIMMER_PARAM_FLOAT, {1.0f, 0.0f, 0.0f}, 0.0f, 1e9f, nullptr, nullptr,
         "radiance multiplier (Cycles units: strength 1 white renders as 1.0)", 0},
    }};
    return schema;
  }

  static std::unique_ptr<EmissionClosure> create(const ParamReader &p) {
    auto c = std::make_unique<EmissionClosure>();
    c->radiance_ = p.get_color("color") * p.get_float("strength");
    return c;
  }

  // Normalized emitted-power distribution |cos| / (2 pi) over the sphere.
  LocalEval eval(const ShadingPoint &, const Vec3 &wo) const {
    const float density = std::fabs(wo.z) * kInvPi * 0.5f;
    return {Spectrum(density), density};
  }

  bool sample(const ShadingPoint &, const Vec3 &rand, LocalSample &out) const {
    // Pick a side with rand.z, then a cosine-weighted direction on it.
    Vec3 wo = sample_cosine_hemisphere(rand.x, rand.y);
    if (!(wo.z > 0.0f)) return false;
    if (rand.z >= 0.5f) wo.z = -wo.z;
    out.wo = wo;
    out.pdf = std::fabs(wo.z) * kInvPi * 0.5f;
    out.f_cos = Spectrum(out.pdf);
    out.roughness = 1.0f;
    out.label = (wo.z > 0.0f ? GLIMMER_LABEL_REFLECT : GLIMMER_LABEL_TRANSMIT) | GLIMMER_LABEL_DIFFUSE;
    return true;
  }

  Spectrum emit(const ShadingPoint &) const { return radiance_; }

 private:
  Spectrum radiance_{1.0f};
};

GLIMMER_REGISTER_CLOSURE(EmissionClosure)

}  // namespace glimmer::plugin
