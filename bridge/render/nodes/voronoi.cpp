// Voronoi Texture (Cycles 3.4 svm_node_tex_voronoi, Worley's cellular noise): one
// jittered feature point per unit cell (position = cell + hash * randomness), the
// nearest (F1), second nearest (F2) or smoothly blended nearest (Smooth F1) point
// under the Euclidean, Manhattan, Chebychev or Minkowski metric, the distance to the
// nearest cell edge and the n-sphere radius, in 1-4 dimensions.
#include <limits>

#include "render/nodes/families.h"
#include "render/nodes/perlin.h"

namespace glimmer::render::nodes {

namespace {

using perlin::hash_to_float;
using perlin::Point;

enum Metric { kEuclidean, kManhattan, kChebychev, kMinkowski };
enum Feature { kF1, kF2, kSmoothF1, kDistanceToEdge, kNSphereRadius };

// The feature point's offset inside cell `c` (Cycles' hash_floatN_to_floatN), in [0, 1]^N.
template <int N>
Point<N> point_hash(const Point<N> &c) {
  if constexpr (N == 1) return {hash_to_float(c[0])};
  else if constexpr (N == 2) return {hash_to_float(c[0], c[1]), hash_to_float(c[0], c[1], 1.0f)};
  else if constexpr (N == 3)
    return {hash_to_float(c[0], c[1], c[2]), hash_to_float(c[0], c[1], c[2], 1.0f),
            hash_to_float(c[0], c[1], c[2], 2.0f)};
  else
    return {hash_to_float(c[0], c[1], c[2], c[3]), hash_to_float(c[3], c[0], c[1], c[2]),
            hash_to_float(c[2], c[3], c[0], c[1]), hash_to_float(c[1], c[2], c[3], c[0])};
}

struct Params {
  int metric, feature;
  float exponent, randomness, smoothness;
};

template <int N>
float distance(const Point<N> &a, const Point<N> &b, const Params &p) {
  if constexpr (N == 1) {
    return std::fabs(b[0] - a[0]);
  } else {
    float sum = 0.0f, largest = 0.0f;
    for (int i = 0; i < N; ++i) {
      const float d = std::fabs(a[i] - b[i]);
      switch (p.metric) {
        case kEuclidean: sum += d * d; break;
        case kManhattan: sum += d; break;
        case kChebychev: largest = std::fmax(largest, d); break;
        default: sum += std::pow(d, p.exponent); break;
      }
    }
    if (p.metric == kEuclidean) return std::sqrt(sum);
    if (p.metric == kManhattan) return sum;
    if (p.metric == kChebychev) return largest;
    return std::pow(sum, 1.0f / p.exponent);
  }
}

template <int N>
float euclidean(const Point<N> &a, const Point<N> &b) {
  float sum = 0.0f;
  for (int i = 0; i < N; ++i) sum += (a[i] - b[i]) * (a[i] - b[i]);
  return std::sqrt(sum);
}

// Visits the (2r+1)^N cell offsets in Cycles' order (the last axis outermost).
template <int N, typename F>
void for_each_offset(int r, F &&visit) {
  int index[N];
  for (int &i : index) i = -r;
  while (true) {
    Point<N> o{};
    for (int i = 0; i < N; ++i) o[i] = static_cast<float>(index[i]);
    visit(o);
    int axis = 0;
    while (axis < N && ++index[axis] > r) index[axis++] = -r;
    if (axis == N) return;
  }
}

struct Result {
  float distance = 0.0f;
  Vec3 color{0.0f};
  Vec3 position{0.0f};
  float w = 0.0f;
  float radius = 0.0f;
};

template <int N>
void set_position(Result &r, const Point<N> &p) {
  if constexpr (N == 1) {
    r.w = p[0];
  } else {
    r.position = Vec3(p[0], p[1], N > 2 ? p[2] : 0.0f);
    if constexpr (N == 4) r.w = p[3];
  }
}

// The lattice cell around a point and its jittered feature points (Cycles' voronoi_* share this set-up).
template <int N>
struct VoronoiCell {
  Point<N> cell{}, local{};
  const Params &p;
  VoronoiCell(const Point<N> &coord, const Params &params) : p(params) {
    for (int i = 0; i < N; ++i) {
      cell[i] = std::floor(coord[i]);
      local[i] = coord[i] - cell[i];
    }
  }
  // The feature point of the neighbour cell at `offset`, relative to this cell's corner.
  Point<N> feature_point(const Point<N> &offset) const {
    Point<N> q = point_hash<N>(perlin::plus<N>(cell, offset));
    for (int i = 0; i < N; ++i) q[i] = offset[i] + q[i] * p.randomness;
    return q;
  }
};

// F1 / F2: the nearest and second-nearest feature points.
template <int N>
Result voronoi_f1_f2(const VoronoiCell<N> &vc) {
  const Params &p = vc.p;
  float d1 = 8.0f, d2 = 8.0f;
  Point<N> o1{}, o2{}, q1{}, q2{};
  for_each_offset<N>(1, [&](const Point<N> &offset) {
    const Point<N> q = vc.feature_point(offset);
    const float d = distance<N>(q, vc.local, p);
    if (d < d1) {
      d2 = d1; o2 = o1; q2 = q1;
      d1 = d; o1 = offset; q1 = q;
    } else if (d < d2) {
      d2 = d; o2 = offset; q2 = q;
    }
  });
  const bool second = p.feature == kF2;
  Result r;
  r.distance = second ? d2 : d1;
  r.color = perlin::cell_color<N>(perlin::plus<N>(vc.cell, second ? o2 : o1));
  set_position<N>(r, perlin::plus<N>(vc.cell, second ? q2 : q1));
  return r;
}

// Smooth F1: distance, colour and position blended over the 5^N neighbourhood.
template <int N>
Result voronoi_smooth_f1(const VoronoiCell<N> &vc) {
  const Params &p = vc.p;
  float d_smooth = 8.0f;
  Vec3 color{0.0f};
  Point<N> position{};
  for_each_offset<N>(2, [&](const Point<N> &offset) {
    const Point<N> q = vc.feature_point(offset);
    const float d = distance<N>(q, vc.local, p);
    // smoothstep(0, 1, x); smoothness 0 is plain F1 (Cycles would divide by zero).
    const float x = p.smoothness > 0.0f ? 0.5f + 0.5f * (d_smooth - d) / p.smoothness : (d < d_smooth ? 1.0f : 0.0f);
    const float h = x <= 0.0f ? 0.0f : (x >= 1.0f ? 1.0f : x * x * (3.0f - 2.0f * x));
    float correction = p.smoothness * h * (1.0f - h);
    d_smooth = (1.0f - h) * d_smooth + h * d - correction;
    correction /= 1.0f + 3.0f * p.smoothness;
    color = (1.0f - h) * color + h * perlin::cell_color<N>(perlin::plus<N>(vc.cell, offset)) - Vec3(correction);
    for (int i = 0; i < N; ++i) position[i] = (1.0f - h) * position[i] + h * q[i] - correction;
  });
  Result r;
  r.distance = d_smooth;
  r.color = color;
  set_position<N>(r, perlin::plus<N>(vc.cell, position));
  return r;
}

// Distance to the nearest cell edge.
template <int N>
float voronoi_distance_to_edge(const VoronoiCell<N> &vc) {
  const Params &p = vc.p;
  if constexpr (N == 1) {
    const float mid = point_hash<1>(vc.cell)[0] * p.randomness;
    const float left = -1.0f + point_hash<1>({vc.cell[0] - 1.0f})[0] * p.randomness;
    const float right = 1.0f + point_hash<1>({vc.cell[0] + 1.0f})[0] * p.randomness;
    return std::fmin(std::fabs((mid + left) / 2.0f - vc.local[0]), std::fabs((mid + right) / 2.0f - vc.local[0]));
  } else {
    float nearest = 8.0f;
    Point<N> to_closest{};
    for_each_offset<N>(1, [&](const Point<N> &offset) {
      Point<N> v = vc.feature_point(offset);
      float d = 0.0f;
      for (int i = 0; i < N; ++i) {
        v[i] -= vc.local[i];
        d += v[i] * v[i];
      }
      if (d < nearest) {
        nearest = d;
        to_closest = v;
      }
    });
    float edge = 8.0f;
    for_each_offset<N>(1, [&](const Point<N> &offset) {
      Point<N> v = vc.feature_point(offset);
      float perp_len2 = 0.0f;
      for (int i = 0; i < N; ++i) {
        v[i] -= vc.local[i];
        perp_len2 += (v[i] - to_closest[i]) * (v[i] - to_closest[i]);
      }
      if (perp_len2 > 0.0001f) {
        const float inv = 1.0f / std::sqrt(perp_len2);
        float e = 0.0f;
        for (int i = 0; i < N; ++i) e += (to_closest[i] + v[i]) * 0.5f * (v[i] - to_closest[i]) * inv;
        edge = std::fmin(edge, e);
      }
    });
    return edge;
  }
}

// n-sphere radius: half the distance from the nearest point to its own nearest neighbour.
template <int N>
float voronoi_sphere_radius(const VoronoiCell<N> &vc) {
  float nearest = 8.0f;
  Point<N> closest{}, closest_offset{};
  for_each_offset<N>(1, [&](const Point<N> &offset) {
    const Point<N> q = vc.feature_point(offset);
    const float d = euclidean<N>(q, vc.local);
    if (d < nearest) {
      nearest = d;
      closest = q;
      closest_offset = offset;
    }
  });
  nearest = 8.0f;
  Point<N> neighbour{};
  for_each_offset<N>(1, [&](const Point<N> &offset) {
    bool centre = true;
    for (float c : offset) centre &= c == 0.0f;
    if (centre) return;
    const Point<N> q = vc.feature_point(perlin::plus<N>(offset, closest_offset));
    const float d = euclidean<N>(closest, q);
    if (d < nearest) {
      nearest = d;
      neighbour = q;
    }
  });
  return euclidean<N>(neighbour, closest) / 2.0f;
}

template <int N>
Result voronoi(const Point<N> &coord, const Params &p) {
  const VoronoiCell<N> vc(coord, p);
  if (p.feature == kF1 || p.feature == kF2) return voronoi_f1_f2<N>(vc);
  if (p.feature == kSmoothF1) return voronoi_smooth_f1<N>(vc);
  Result r;
  if (p.feature == kDistanceToEdge)
    r.distance = voronoi_distance_to_edge<N>(vc);
  else
    r.radius = voronoi_sphere_radius<N>(vc);
  return r;
}

}  // namespace

void configure_voronoi(const SettingsReader &r, NodeSettings &s) {
  s.mode[0] = 1 + r.choice("dimensions", {"1d", "2d", "3d", "4d"}, 2);
  s.mode[1] = r.choice("metric", {"euclidean", "manhattan", "chebychev", "minkowski"}, kEuclidean);
  s.mode[2] = r.choice("feature", {"f1", "f2", "smooth_f1", "distance_to_edge", "n_sphere_radius"}, kF1);
}

// in: vector, w, scale, smoothness, exponent, randomness; out: distance, color, position, w, radius.
void eval_voronoi(const NodeSettings &s, const ShadingPoint &, const Vec3 *in, Vec3 *out) {
  const float scale = in[2].x;
  const Vec3 v = in[0] * scale;
  const float w = in[1].x * scale;
  const Params p{s.mode[1], s.mode[2], in[4].x, saturate(in[5].x), clamp(in[3].x / 2.0f, 0.0f, 0.5f)};
  Result r;
  switch (s.mode[0]) {
    case 1: r = voronoi<1>({w}, p); break;
    case 2: r = voronoi<2>({v.x, v.y}, p); break;
    case 3: r = voronoi<3>({v.x, v.y, v.z}, p); break;
    default: r = voronoi<4>({v.x, v.y, v.z, w}, p); break;
  }
  const bool divide = scale != 0.0f;  // Cycles' safe_divide: 0 for a zero scale
  out[0] = Vec3(r.distance);
  out[1] = r.color;
  out[2] = divide ? r.position / scale : Vec3(0.0f);
  out[3] = Vec3(divide ? r.w / scale : 0.0f);
  out[4] = Vec3(r.radius);
}

}  // namespace glimmer::render::nodes
