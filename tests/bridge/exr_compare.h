// Reading Glimmer EXRs back for the farm tests: the data window of every channel,
// and the relative difference the farm acceptance uses.
#pragma once

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <vector>

namespace glimmer::test {

struct Exr {
  OIIO::ImageSpec spec;
  std::vector<float> pixels;  // data window, all channels
};

inline Exr read_exr(const std::filesystem::path &path) {
  auto in = OIIO::ImageInput::open(path.string());
  EXPECT_TRUE(in) << path << ": " << OIIO::geterror();
  Exr e;
  if (!in) return e;
  e.spec = in->spec();
  e.pixels.resize(static_cast<size_t>(e.spec.width) * e.spec.height * e.spec.nchannels);
  EXPECT_TRUE(in->read_image(0, 0, 0, -1, OIIO::TypeDesc::FLOAT, e.pixels.data()));
  return e;
}

// Per channel: max over pixels of |a - b| / max over pixels of |b|; the largest over channels
// (the "relative" difference of the acceptance; per channel so that the 1e10 background
// depth does not hide a difference in the Combined pass).
inline double max_relative_difference(const Exr &a, const Exr &b) {
  const int nc = b.spec.nchannels;
  double worst = 0.0;
  for (int c = 0; c < nc; ++c) {
    double diff = 0.0, scale = 0.0;
    for (size_t i = c; i < b.pixels.size(); i += nc) {
      diff = std::max(diff, static_cast<double>(std::fabs(a.pixels[i] - b.pixels[i])));
      scale = std::max(scale, static_cast<double>(std::fabs(b.pixels[i])));
    }
    if (scale > 0.0)
      worst = std::max(worst, diff / scale);
    else if (diff > 0.0)
      return INFINITY;
  }
  return worst;
}

// Bit-for-bit equality of two images' pixels (same channels, same window).
inline bool bit_identical(const Exr &a, const Exr &b) {
  return a.spec.channelnames == b.spec.channelnames && a.pixels.size() == b.pixels.size() &&
         std::memcmp(a.pixels.data(), b.pixels.data(), a.pixels.size() * sizeof(float)) == 0;
}

}  // namespace glimmer::test
