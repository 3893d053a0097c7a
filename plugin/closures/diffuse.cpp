// Lambertian diffuse reflection: f = color / pi.
// Like Cycles (kernel/closure/bsdf_diffuse.h) only the side of wo is checked:
// the host orients N toward wi.
#include <array>

#include "core/closure.h"
#include "core/cosine_lobe.h"
#include "glimmer/sampling.h"

namespace glimmer::plugin {

class DiffuseClosure {
 public:
  static constexpr const char *kName = "diffuse";
  static constexpr const char *kDoc = "Lambertian diffuse reflection, f = color / pi.";
  static constexpr uint32_t kFlags = 0;

  static std::span<const GlimmerParamSpec> params() {
    static const std::array<GlimmerParamSpec, 1> schema{{
        {"color", GLIMMER_PARAM_COLOR, {0.8f, 0.8f, 0.8f}, 0.0f, 1.0f, nullptr, nullptr,
         "reflectance (albedo) per RGB channel, 0..1", GLIMMER_PARAM_VARYING},
    }};
    return schema;
  }

  static std::unique_ptr<DiffuseClosure> create(const ParamReader &p) {
    auto c = std::make_unique<DiffuseClosure>();
    c->color_ = p.get_color("color");
    c->color_param_ = p.index("color");
    return c;
  }

  // The reflectance at this point (color is varying).
  Spectrum color(const ShadingPoint &sp) const { return sp.param_color(color_param_, color_); }
  // f cos(wo) = color cos(wo) / pi, with the point's colour read once.
  auto f_cos(const ShadingPoint &sp) const {
    return [c = color(sp)](const Vec3 &wo) { return c * (wo.z * kInvPi); };
  }

  LocalEval eval(const ShadingPoint &sp, const Vec3 &wo) const { return cosine_lobe::eval(wo, f_cos(sp)); }

  bool sample(const ShadingPoint &sp, const Vec3 &rand, LocalSample &out) const {
    return cosine_lobe::sample(rand, f_cos(sp), out);
  }

  Spectrum albedo(const ShadingPoint &sp) const { return color(sp); }

 private:
  Spectrum color_{0.8f};
  uint32_t color_param_ = 0;
};

GLIMMER_REGISTER_CLOSURE(DiffuseClosure)

}  // namespace glimmer::plugin
