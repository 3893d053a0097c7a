// Lobe picture: eval, pdf and the sampled density over the sphere in a
// latitude-longitude layout, written as PNG through OpenImageIO (the image module, render/image_io.h).
#include <tbb/enumerable_thread_specific.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <stdexcept>
#include <vector>

#include "lab/closure_lab.h"
#include "lab/lab_internal.h"
#include "render/image_output.h"

namespace glimmer::lab {

namespace {

// Perceptual colour map (matplotlib's "inferno" at 0, 1/4, 1/2, 3/4, 1),
// interpolated linearly in sRGB.
Vec3 colour_map(float t) {
  static const Vec3 stops[5] = {{0.0f, 0.0f, 0.016f},
                                {0.341f, 0.063f, 0.431f},
                                {0.737f, 0.216f, 0.329f},
                                {0.976f, 0.557f, 0.035f},
                                {0.988f, 1.0f, 0.643f}};
  t = saturate(t) * 4.0f;
  const int i = std::min(3, static_cast<int>(t));
  const float f = t - static_cast<float>(i);
  return stops[i] * (1.0f - f) + stops[i + 1] * f;
}

}  // namespace

void plot_lobe(const host::ClosureInstance &instance, const GlimmerShadingContext &ctx, const std::string &path,
               const PlotOptions &options) {
  const int w = std::max(8, options.width), h = std::max(4, options.height);
  const int panels = options.samples > 0 ? 3 : 2;
  const int gap = 2;
  const Frame frame = detail::shading_frame(ctx);
  const double theta_step = M_PI / h, phi_step = 2.0 * M_PI / w;

  // Panels 0 and 1: eval (mean over RGB) and pdf at each pixel's centre.
  std::vector<float> eval_image(size_t(w) * h), pdf_image(size_t(w) * h), density(size_t(w) * h, 0.0f);
  tbb::parallel_for(tbb::blocked_range<int>(0, h), [&](const tbb::blocked_range<int> &rows) {
    for (int y = rows.begin(); y != rows.end(); ++y)
      for (int x = 0; x < w; ++x) {
        const double theta = (y + 0.5) * theta_step, phi = -M_PI + (x + 0.5) * phi_step;
        Spectrum f;
        float pdf = 0.0f;
        instance.eval(ctx, frame.to_world(detail::spherical_direction(theta, phi)), f, pdf);
        eval_image[size_t(y) * w + x] = std::isfinite(average(f)) ? average(f) : 0.0f;
        pdf_image[size_t(y) * w + x] = std::isfinite(pdf) ? pdf : 0.0f;
      }
  });

  // Panel 2: histogram of sample() directions, divided by N * pixel solid angle.
  if (options.samples > 0) {
    tbb::enumerable_thread_specific<std::vector<uint32_t>> per_thread(
        [&] { return std::vector<uint32_t>(size_t(w) * h, 0u); });
    detail::for_each_block<char>(options.samples, [&](uint64_t begin, uint64_t end, char &) {
      auto &histogram = per_thread.local();
      for (uint64_t i = begin; i < end; ++i) {
        GlimmerSample s = glimmer_blank_sample();
        const uint32_t label = detail::sample_at(instance, ctx, options.seed, i, s);
        if (label == GLIMMER_LABEL_NONE || (label & GLIMMER_LABEL_SINGULAR) || !detail::is_unit_direction(Vec3(s.wo)))
          continue;
        const Vec3 local = frame.to_local(Vec3(s.wo));
        const double theta = std::acos(std::clamp(static_cast<double>(local.z), -1.0, 1.0));
        const double phi = std::atan2(static_cast<double>(local.y), static_cast<double>(local.x));
        const int y = std::clamp(static_cast<int>(theta / theta_step), 0, h - 1);
        const int x = std::clamp(static_cast<int>((phi + M_PI) / phi_step), 0, w - 1);
        ++histogram[size_t(y) * w + x];
      }
    });
    for (const auto &histogram : per_thread)
      for (size_t i = 0; i < histogram.size(); ++i) density[i] += static_cast<float>(histogram[i]);
    for (int y = 0; y < h; ++y) {
      const double solid_angle = (std::cos(y * theta_step) - std::cos((y + 1) * theta_step)) * phi_step;
      for (int x = 0; x < w; ++x)
        density[size_t(y) * w + x] =
            static_cast<float>(density[size_t(y) * w + x] / (static_cast<double>(options.samples) * solid_angle));
    }
  }

  // Common scale: the pdf's maximum (eval's if the pdf is zero everywhere).
  float scale = *std::max_element(pdf_image.begin(), pdf_image.end());
  if (!(scale > 0.0f)) scale = *std::max_element(eval_image.begin(), eval_image.end());
  if (!(scale > 0.0f)) scale = 1.0f;

  const int width = panels * w + (panels - 1) * gap;
  std::vector<unsigned char> pixels(size_t(width) * h * 3, 64);
  const std::vector<float> *sources[3] = {&eval_image, &pdf_image, &density};
  for (int p = 0; p < panels; ++p)
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const float v = (*sources[p])[size_t(y) * w + x];
        Vec3 c = colour_map(std::sqrt(std::max(0.0f, v) / scale));
        // Mark the horizon (theta = 90 degrees) with a grey line.
        if (y == h / 2 && (x / 4) % 2 == 0) c = Vec3(0.5f);
        unsigned char *out = &pixels[(size_t(y) * width + p * (w + gap) + x) * 3];
        for (int k = 0; k < 3; ++k) out[k] = static_cast<unsigned char>(std::lround(saturate(c[k]) * 255.0f));
      }

  render::write_8bit_image(path, width, h, 3, pixels.data());
}

}  // namespace glimmer::lab
