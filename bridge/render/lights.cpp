#include "render/lights.h"

#include <algorithm>
#include <cmath>

#include "glimmer/sampling.h"

namespace glimmer::render {

namespace {
constexpr float kInf = std::numeric_limits<float>::infinity();
}  // namespace

Distribution1D::Distribution1D(const std::vector<float> &weights) {
  cdf.assign(weights.size() + 1, 0.0f);
  double acc = 0.0;
  for (size_t i = 0; i < weights.size(); ++i) {
    acc += std::max(0.0f, std::isfinite(weights[i]) ? weights[i] : 0.0f);
    cdf[i + 1] = static_cast<float>(acc);
  }
  total = static_cast<float>(acc);
  if (acc > 0.0)
    for (auto &c : cdf) c = static_cast<float>(c / acc);
}

int Distribution1D::sample(float u, float &u_remapped) const {
  const int n = count();
  int i = static_cast<int>(std::upper_bound(cdf.begin(), cdf.end(), u) - cdf.begin()) - 1;
  i = std::clamp(i, 0, n - 1);
  while (i > 0 && cdf[i + 1] - cdf[i] <= 0.0f) --i;  // never land on an empty bin
  while (i < n - 1 && cdf[i + 1] - cdf[i] <= 0.0f) ++i;
  const float width = cdf[i + 1] - cdf[i];
  u_remapped = width > 0.0f ? std::clamp((u - cdf[i]) / width, 0.0f, 0.99999994f) : 0.5f;
  return i;
}

// ---- Film filter ----
FilmFilter::FilmFilter(scene::FilterType type, float width) : type_(type), width_(width) {
  if (type == scene::FilterType::Box) return;
  // Cycles' filter functions over [-width/2, width/2] (film.cpp).
  const int n = 1024;
  std::vector<float> w(n);
  for (int i = 0; i < n; ++i) {
    const float x = ((i + 0.5f) / n - 0.5f) * width;  // offset in pixels
    if (type == scene::FilterType::Gaussian) {
      const float v = x * 6.0f / width;
      w[i] = std::exp(-2.0f * v * v);
    } else {
      const float v = kTwoPi * (x / width + 0.5f);
      w[i] = 0.35875f - 0.48829f * std::cos(v) + 0.14128f * std::cos(2.0f * v) - 0.01168f * std::cos(3.0f * v);
    }
  }
  Distribution1D d(w);
  inverse_cdf_.resize(n);
  for (int i = 0; i < n; ++i) {
    float r;
    const int bin = d.sample((i + 0.5f) / n, r);
    inverse_cdf_[i] = ((bin + r) / n - 0.5f) * width;
  }
}

float FilmFilter::offset(float u) const {
  if (type_ == scene::FilterType::Box) return (u - 0.5f) * width_;
  const float x = u * (inverse_cdf_.size() - 1);
  const int i = std::min(static_cast<int>(x), static_cast<int>(inverse_cdf_.size()) - 2);
  const float t = x - i;
  return inverse_cdf_[i] * (1 - t) + inverse_cdf_[i + 1] * t;
}

// ---- Lights ----
ConstantWorld constant_world_sampling(const FeatureSet &features, bool light_only) {
  if (light_only) return ConstantWorld::AsLight;
  for (const std::string &closure : features.closures)
    if (closure != "diffuse" && closure != "emission") return ConstantWorld::AsLight;
  return ConstantWorld::BsdfOnly;
}

LightSet::LightSet(const scene::Scene &scene, ShaderSystem &shaders, const std::vector<int> &mesh_shader, Vec3 center,
                   float radius, ConstantWorld constant_world, FeatureSet &features, std::vector<std::string> &warnings)
    : scene_(scene), shaders_(shaders), mesh_shader_(mesh_shader) {
  (void)center;
  (void)warnings;
  std::vector<float> power;
  const float disk_area = kPi * radius * radius;
  for (const auto &l : scene.lights) {
    Entry e;
    e.strength = l.strength * shaders.light_emission(l.shader, l.where);
    if (is_zero(e.strength)) continue;
    e.co = l.co;
    e.dir = normalize(l.dir);
    e.radius = l.radius;
    e.use_camera = l.use_camera;
    float p = luminance(e.strength);
    switch (l.type) {
      case scene::LightType::Point:
        e.kind = Kind::Point;
        features.light_types.insert("point");
        break;
      case scene::LightType::Spot:
        e.kind = Kind::Spot;
        e.cos_half_spot = std::cos(0.5f * l.spot_angle);
        e.spot_smooth = (1.0f - e.cos_half_spot) * l.spot_smooth;
        features.light_types.insert("spot");
        break;
      case scene::LightType::Sun: {
        e.kind = Kind::Sun;
        // Cycles 3.4 (scene/light.cpp, kernel/light/distant.h): the sun is a disk of radius tan(angle / 2)
        // at unit distance, sampled uniformly by area: radiance = pdf = 1 / (pi tan^2(angle / 2) cos^3 theta)
        // (theta from the sun axis) times the strength, i.e. irradiance slightly below the strength.
        const float half = 0.5f * std::min(l.angle, 0.999f * kPi);
        e.cos_half_angle = std::cos(half);
        e.sun_tan_radius = std::tan(half);
        e.sun_inv_area = e.sun_tan_radius > 0.0f ? 1.0f / (kPi * e.sun_tan_radius * e.sun_tan_radius) : 1.0f;
        p *= disk_area;
        features.light_types.insert("sun");
        break;
      }
      case scene::LightType::Area:
        e.kind = Kind::Area;
        e.U = l.axisu * l.sizeu;
        e.V = l.axisv * l.sizev;
        e.round = l.round;
        e.area = length(cross(e.U, e.V)) * (l.round ? kPi * 0.25f : 1.0f);
        {
          // The emitting plane is spanned by axisu/axisv; `dir` only picks its emitting side.
          Vec3 n = normalize(cross(e.U, e.V));
          if (dot(n, e.dir) < 0.0f) n = -n;
          e.dir = n;
        }
        {
          // Cycles 3.4 spread: a soft-box grid of slats; attenuation (1 - tan(spread_angle) tan(a)) normalised by
          // 2 / (2 + (2 spread_angle - pi) tan(spread_angle)), spread_angle = (pi - max(spread, 1 deg)) / 2.
          const float spread_angle = 0.5f * (kPi - std::max(l.spread, kPi / 180.0f));
          e.tan_spread = std::tan(spread_angle);
          e.normalize_spread = 2.0f / (2.0f + (2.0f * spread_angle - kPi) * e.tan_spread);
        }
        p *= kPi * 0.25f;
        features.light_types.insert(l.round ? "area_disk" : "area_quad");
        break;
      case scene::LightType::Background:
        continue;  // the world shader is the background light (added below)
    }
    lights_.push_back(e);
    power.push_back(p);
  }
  // Emissive triangles.
  triangle_light_.resize(scene.meshes.size());
  for (size_t m = 0; m < scene.meshes.size(); ++m) {
    if (!shaders.shader(mesh_shader[m]).has_emission) continue;
    const auto &mesh = scene.meshes[m];
    triangle_light_[m].assign(mesh.triangles.size(), -1);
    for (size_t t = 0; t < mesh.triangles.size(); ++t) {
      const auto &tri = mesh.triangles[t];
      const float area = 0.5f * length(cross(mesh.P[tri[1]] - mesh.P[tri[0]], mesh.P[tri[2]] - mesh.P[tri[0]]));
      if (!(area > 0.0f)) continue;
      Entry e;
      e.kind = Kind::Triangle;
      e.mesh = static_cast<int>(m);
      e.prim = static_cast<int>(t);
      e.area = area;
      const Spectrum L = triangle_emission(e, mesh.surface_at(t, 1.0f / 3.0f, 1.0f / 3.0f), Vec3(0, 0, 1));
      if (is_zero(L)) continue;
      triangle_light_[m][t] = static_cast<int>(lights_.size());
      lights_.push_back(e);
      power.push_back(kPi * area * luminance(L));
      features.emissive_triangles++;
    }
  }
  // Background (a constant one only on request, see ConstantWorld).
  if (shaders.has_background() && (!shaders.background_is_constant() || constant_world == ConstantWorld::AsLight)) {
    Entry e;
    e.kind = Kind::Background;
    background_light_ = static_cast<int>(lights_.size());
    lights_.push_back(e);
    float avg = 0.0f;
    if (!shaders.background_is_constant()) {
      build_environment_map();
      avg = env_marginal_.total / static_cast<float>(env_w_ * env_h_);
    } else {
      avg = luminance(shaders.background(Vec3(0, 0, 1)));
    }
    power.push_back(kPi * avg * disk_area);
  }
  // Every light keeps at least a small share so that none is starved.
  float total = 0.0f;
  for (float p : power) total += p;
  for (float &p : power) p = std::max(p, 0.01f * total / std::max<size_t>(power.size(), 1));
  pick_ = Distribution1D(power);
}

void LightSet::build_environment_map() {
  env_w_ = 512;
  env_h_ = 256;
  std::vector<float> rows(env_h_);
  std::vector<std::vector<float>> weights(env_h_, std::vector<float>(env_w_));
  double sum = 0.0;
  for (int y = 0; y < env_h_; ++y) {
    for (int x = 0; x < env_w_; ++x) {
      float acc = 0.0f;
      for (int s = 0; s < 4; ++s) {  // 2x2 supersampling within the cell
        const float u = (x + 0.25f + 0.5f * (s & 1)) / env_w_, v = (y + 0.25f + 0.5f * (s >> 1)) / env_h_;
        acc += luminance(shaders_.background(equirectangular_to_direction(u, v)));
      }
      const float sin_theta = std::sin(kPi * (1.0f - (y + 0.5f) / env_h_));
      weights[y][x] = acc * 0.25f * sin_theta;
      sum += weights[y][x];
    }
  }
  // Floor: every direction keeps a non-zero density (unbiasedness for features finer than a cell).
  const float floor = static_cast<float>(sum / (env_w_ * env_h_)) * 0.01f + 1e-12f;
  env_rows_.clear();
  for (int y = 0; y < env_h_; ++y) {
    const float sin_theta = std::sin(kPi * (1.0f - (y + 0.5f) / env_h_));
    for (auto &w : weights[y]) w += floor * sin_theta;
    env_rows_.emplace_back(weights[y]);
    rows[y] = env_rows_.back().total;
  }
  env_marginal_ = Distribution1D(rows);
}

float LightSet::environment_pdf(const Vec3 &d) const {
  if (env_w_ == 0) return kInv4Pi;
  float u, v;
  direction_to_equirectangular(d, u, v);
  const int x = std::clamp(static_cast<int>((u - std::floor(u)) * env_w_), 0, env_w_ - 1);
  const int y = std::clamp(static_cast<int>(v * env_h_), 0, env_h_ - 1);
  const float p_uv = env_marginal_.probability(y) * env_rows_[y].probability(x) * env_w_ * env_h_;
  const float sin_theta = std::sin(kPi * (1.0f - v));
  if (!(sin_theta > 1e-6f)) return 0.0f;
  return p_uv / (2.0f * kPi * kPi * sin_theta);
}

float LightSet::background_pdf(const Vec3 &d) const {
  if (background_light_ < 0) return 0.0f;
  return pick_probability(background_light_) * environment_pdf(d);
}

float LightSet::spot_attenuation(const Entry &l, const Vec3 &dir_from_light) const {
  // Cycles 3.4 spot_attenuation: the cosine to the axis, zero outside the cone, smoothstep edge.
  float attenuation = dot(dir_from_light, l.dir);
  if (attenuation <= l.cos_half_spot) return 0.0f;
  const float t = attenuation - l.cos_half_spot;
  if (t < l.spot_smooth && l.spot_smooth != 0.0f) {
    const float s = t / l.spot_smooth;
    attenuation *= s * s * (3.0f - 2.0f * s);
  }
  return attenuation;
}

float LightSet::spread_attenuation(const Entry &l, float cos_to_normal) {
  // Cycles 3.4 light_spread_attenuation (kernel/light/light.h): the share of a soft-box grid cell not hidden by
  // its slats at angle a from the normal.
  if (l.tan_spread <= 0.0f) return 1.0f;
  const float sin_a = std::sqrt(std::max(0.0f, 1.0f - cos_to_normal * cos_to_normal));
  const float tan_a = sin_a / cos_to_normal;
  return std::max((1.0f - l.tan_spread * tan_a) * l.normalize_spread, 0.0f);
}

Spectrum LightSet::triangle_emission(const Entry &l, const scene::SurfacePoint &s, const Vec3 &wi_toward_viewer) const {
  TexCoords tc;
  tc.P = s.P;
  tc.generated = s.generated;
  const Vec3 Ng = s.Ng;
  tc.N = Ng;
  tc.uv[0] = s.uv[0];
  tc.uv[1] = s.uv[1];
  tc.direction = -wi_toward_viewer;
  tc.path.camera = false;  // Light Path node: Cycles evaluates sampled emission with PATH_RAY_EMISSION only
  ClosureSet cs;
  shaders_.evaluate(mesh_shader_[l.mesh], tc, cs);
  GlimmerShadingContext ctx{};
  ctx.struct_size = sizeof(GlimmerShadingContext);
  ctx.wi = wi_toward_viewer;
  ctx.P = tc.P;
  ctx.N = dot(Ng, wi_toward_viewer) >= 0.0f ? Ng : -Ng;
  ctx.Ng = ctx.N;
  ctx.T = Frame::from_normal(Vec3(ctx.N)).s;
  ctx.uv[0] = tc.uv[0];
  ctx.uv[1] = tc.uv[1];
  Spectrum L(0.0f);
  for (int i = 0; i < cs.count; ++i)
    if (cs.closures[i].leaf->emissive) L += cs.closures[i].leaf->instance->emit(ctx) * cs.closures[i].weight;
  return L;
}

bool LightSet::sample(float u, float v, const Vec3 &P, LightSample &out) const {
  if (lights_.empty()) return false;
  // u picks the light and is rescaled within its bin for the point on it (stratification kept).
  const int index = pick_.sample(u, u);
  const float pick = pick_probability(index);
  const Entry &l = lights_[index];
  switch (l.kind) {
    case Kind::Point:
    case Kind::Spot: {
      // Cycles 3.4 point/spot lamp (kernel/light/point.h, spot.h): with a radius, a disk of that radius
      // centred on co and facing the shading point, sampled uniformly by area; radiance
      // S / (4 pi) / (pi r^2) (eval_fac = 1/(4 pi) * invarea), pdf = t^2 / (cos * pi r^2).
      // Without a radius, a point of intensity S / (4 pi).
      const Vec3 to_center = l.co - P;
      const float d_center = length(to_center);
      if (!(d_center > 0.0f)) return false;
      if (l.radius > 0.0f) {
        const Vec3 lightN = -to_center / d_center;  // disk normal, toward P
        const Frame f = Frame::from_normal(lightN);
        float x, y;
        sample_uniform_disk_concentric(u, v, x, y);
        const Vec3 Pl = l.co + (f.s * x + f.t * y) * l.radius;
        const Vec3 to = Pl - P;
        const float d2 = length_squared(to), d = std::sqrt(d2);
        if (!(d > 0.0f)) return false;
        out.wi = to / d;
        const float cos_l = -dot(lightN, out.wi);
        if (cos_l <= 0.0f) return false;
        out.dist = d;
        const float area = kPi * l.radius * l.radius;
        out.pdf = pick * d2 / (cos_l * area);
        out.radiance = l.strength * (kInv4Pi / area);
        out.delta = false;
      } else {
        out.wi = to_center / d_center;
        out.dist = d_center;
        out.pdf = pick;
        out.radiance = l.strength * (kInv4Pi / (d_center * d_center));
        out.delta = true;
      }
      // Cycles evaluates the cone with the direction from the sampled lamp point to P.
      if (l.kind == Kind::Spot) out.radiance *= spot_attenuation(l, -out.wi);
      return !is_zero(out.radiance);
    }
    case Kind::Sun: {
      out.dist = kInf;
      if (l.sun_tan_radius > 0.0f) {
        const Frame f = Frame::from_normal(-l.dir);
        float x, y;
        sample_uniform_disk_concentric(u, v, x, y);
        out.wi = normalize(f.n + (f.s * x + f.t * y) * l.sun_tan_radius);
        const float cos_theta = dot(out.wi, f.n);
        const float density = l.sun_inv_area / (cos_theta * cos_theta * cos_theta);
        out.pdf = pick * density;
        out.radiance = l.strength * density;
        out.delta = false;
      } else {
        out.wi = -l.dir;
        out.pdf = pick;
        out.radiance = l.strength;
        out.delta = true;
      }
      return true;
    }
    case Kind::Area: {
      Vec3 offset;
      if (l.round) {
        float x, y;
        sample_uniform_disk_concentric(u, v, x, y);
        offset = l.U * (0.5f * x) + l.V * (0.5f * y);
      } else {
        offset = l.U * (u - 0.5f) + l.V * (v - 0.5f);
      }
      const Vec3 Pl = l.co + offset;
      const Vec3 to = Pl - P;
      const float d2 = length_squared(to), d = std::sqrt(d2);
      if (!(d > 0.0f)) return false;
      out.wi = to / d;
      const float cos_l = -dot(out.wi, l.dir);  // emits toward dir
      if (cos_l <= 0.0f) return false;
      out.dist = d;
      out.pdf = pick * d2 / (cos_l * l.area);
      out.radiance = l.strength * (0.25f / l.area * spread_attenuation(l, cos_l));
      out.delta = false;
      return !is_zero(out.radiance);
    }
    case Kind::Background: {
      out.dist = kInf;
      if (env_w_ == 0) {
        out.wi = sample_uniform_sphere(u, v);
      } else {
        float ur, vr;
        const int y = env_marginal_.sample(v, vr);
        const int x = env_rows_[y].sample(u, ur);
        out.wi = equirectangular_to_direction((x + ur) / env_w_, (y + vr) / env_h_);
      }
      out.pdf = pick * environment_pdf(out.wi);
      out.radiance = shaders_.background(out.wi);
      out.delta = false;
      return out.pdf > 0.0f;
    }
    case Kind::Triangle: {
      const scene::Mesh &m = scene_.meshes[l.mesh];
      float b1 = u, b2 = v;
      if (b1 + b2 > 1.0f) { b1 = 1.0f - b1; b2 = 1.0f - b2; }
      const scene::SurfacePoint surface = m.surface_at(l.prim, b1, b2);
      const Vec3 Pl = surface.P;
      const Vec3 Ng = surface.Ng;
      const Vec3 to = Pl - P;
      const float d2 = length_squared(to), d = std::sqrt(d2);
      if (!(d > 0.0f)) return false;
      out.wi = to / d;
      const float cos_l = std::fabs(dot(out.wi, Ng));
      if (cos_l <= 1e-7f) return false;
      out.dist = d;
      out.pdf = pick * d2 / (cos_l * l.area);
      out.radiance = triangle_emission(l, surface, -out.wi);
      out.delta = false;
      return !is_zero(out.radiance);
    }
  }
  return false;
}

void LightSet::intersect(const Vec3 &o, const Vec3 &d, float t_max, bool hit_surface, bool camera_ray,
                         LightHits &out) const {
  out.count = 0;
  for (size_t i = 0; i < lights_.size(); ++i) {
    const Entry &l = lights_[i];
    if (camera_ray && !l.use_camera) continue;
    const float pick = pick_probability(static_cast<int>(i));
    LightHit h;
    if ((l.kind == Kind::Point || l.kind == Kind::Spot) && l.radius > 0.0f) {
      // The disk of radius r at co facing the ray origin (Cycles' ray_disk_intersect with lightN = o - co).
      const Vec3 oc = o - l.co;
      const float dist_origin = length(oc);
      if (!(dist_origin > 0.0f)) continue;
      const Vec3 lightN = oc / dist_origin;
      const float cos_l = -dot(d, lightN);
      if (cos_l <= 0.0f) continue;
      const float t = dist_origin / cos_l;  // plane through co with normal lightN
      if (!(t > 0.0f && t < t_max)) continue;
      const Vec3 q = o + d * t - l.co;
      if (length_squared(q) > l.radius * l.radius) continue;
      const float area = kPi * l.radius * l.radius;
      h.radiance = l.strength * (kInv4Pi / area);
      if (l.kind == Kind::Spot) h.radiance *= spot_attenuation(l, -d);
      if (is_zero(h.radiance)) continue;
      h.pdf = pick * t * t / (cos_l * area);
      h.t = t;
      out.add(h);
    } else if (l.kind == Kind::Area) {
      const float denom = dot(d, l.dir);
      if (std::fabs(denom) < 1e-9f) continue;
      const float t = dot(l.co - o, l.dir) / denom;
      if (!(t > 0.0f && t < t_max)) continue;
      const Vec3 q = o + d * t - l.co;
      const float su = dot(q, l.U) / length_squared(l.U), sv = dot(q, l.V) / length_squared(l.V);
      const bool inside = l.round ? (4.0f * (su * su + sv * sv) <= 1.0f) : (std::fabs(su) <= 0.5f && std::fabs(sv) <= 0.5f);
      if (!inside) continue;
      const float cos_l = -denom;
      if (cos_l <= 0.0f) continue;  // back side: no emission
      h.radiance = l.strength * (0.25f / l.area * spread_attenuation(l, cos_l));
      if (is_zero(h.radiance)) continue;
      h.pdf = pick * t * t / (cos_l * l.area);
      h.t = t;
      out.add(h);
    } else if (l.kind == Kind::Sun && l.sun_tan_radius > 0.0f && !hit_surface) {
      const float cos_theta = dot(d, -l.dir);
      if (cos_theta < l.cos_half_angle) continue;
      const float density = l.sun_inv_area / (cos_theta * cos_theta * cos_theta);
      h.radiance = l.strength * density;
      h.pdf = pick * density;
      h.t = kInf;
      out.add(h);
    }
  }
}

float LightSet::triangle_pdf(int mesh, int prim, const Vec3 &from, const Vec3 &P, const Vec3 &Ng, const Vec3 &d) const {
  if (mesh < 0 || triangle_light_[mesh].empty()) return 0.0f;
  const int index = triangle_light_[mesh][prim];
  if (index < 0) return 0.0f;
  const float d2 = length_squared(P - from);
  const float cos_l = std::fabs(dot(d, Ng));
  if (cos_l <= 1e-7f) return 0.0f;
  return pick_probability(index) * d2 / (cos_l * lights_[index].area);
}

}  // namespace glimmer::render
