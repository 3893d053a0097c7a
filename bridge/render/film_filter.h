// The film's pixel reconstruction filter, applied by importance sampling the
// film position (Cycles' filter table idea: the filter's inverse CDF).
#pragma once

#include <vector>

#include "scene/scene.h"

namespace glimmer::render {

class FilmFilter {
 public:
  FilmFilter() = default;
  FilmFilter(scene::FilterType type, float width);
  float offset(float u) const;  // pixel offset from the centre

 private:
  scene::FilterType type_ = scene::FilterType::Box;
  float width_ = 1.0f;
  std::vector<float> inverse_cdf_;
};

}  // namespace glimmer::render
