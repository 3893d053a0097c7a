#include "scene/settings.h"

#include <charconv>
#include <cmath>
#include <cstdlib>

#include "cli/json_number.h"  // floats in their shortest decimal form

namespace glimmer::scene {

namespace {

constexpr double kIntMin = std::numeric_limits<int>::min();
constexpr double kIntMax = std::numeric_limits<int>::max();
constexpr double kMaxBounces = 1024;  // every bounce limit; the kernel limit is setting + 1

using ST = SettingType;

nlohmann::json json_bound(double value, SettingType type) {
  if (!std::isfinite(value)) return nullptr;
  if (type == ST::Int) return static_cast<long long>(value);
  return cli::shortest_double(value);
}

std::string number_text(double value) {
  if (std::isinf(value)) return value > 0 ? "inf" : "-inf";
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), static_cast<float>(value));
  std::string s(buffer, result.ptr);
  if (auto e = s.find("e+"); e != std::string::npos) s.erase(e + 1, 1);  // 1e+06 -> 1e06
  if (auto e = s.find("e0"); e != std::string::npos) s.erase(e + 1, 1);  // 1e06 -> 1e6
  return s;
}

const char *type_name(SettingType t) {
  switch (t) {
    case ST::Int: return "int";
    case ST::Float: return "float";
    case ST::Bool: return "bool";
    case ST::Color: return "color";
    case ST::Vector: return "vector";
    case ST::Enum: return "enum";
    case ST::String: return "string";
    case ST::Matrix: return "matrix";
  }
  return "?";
}

// A default-constructed element (out of line: GCC's -Warray-bounds otherwise follows the
// member-pointer alternatives of rows an element does not have into its storage).
template <class T>
[[gnu::noinline]] const T &default_element() {
  static const T element{};
  return element;
}

template <class T>
nlohmann::json default_of(const Setting<T> &s) {
  const T &defaults = default_element<T>();
  const std::vector<std::string> choices = split_choices(s.choices);
  return std::visit(
      [&](const auto &member) -> nlohmann::json {
        using M = std::decay_t<decltype(member)>;
        if constexpr (std::is_same_v<M, std::monostate>) return nullptr;
        else if constexpr (std::is_same_v<M, int T::*>) return defaults.*member;
        else if constexpr (std::is_same_v<M, float T::*>) return cli::shortest_double(defaults.*member);
        else if constexpr (std::is_same_v<M, bool T::*>) return defaults.*member;
        else if constexpr (std::is_same_v<M, Vec3 T::*>) {
          const Vec3 v = defaults.*member;
          return {cli::shortest_double(v.x), cli::shortest_double(v.y), cli::shortest_double(v.z)};
        } else {
          return choices.at(static_cast<size_t>(member.get(defaults)));
        }
      },
      s.member);
}

template <class T>
nlohmann::json describe_element(const ElementSettings<T> &table) {
  nlohmann::json rows = nlohmann::json::array();
  for (const auto &s : table.settings) {
    nlohmann::json j;
    j["name"] = s.xml;
    j["type"] = type_name(s.type);
    j["default"] = default_of(s);
    if (s.type == ST::Int || s.type == ST::Float || s.type == ST::Color || s.type == ST::Vector) {
      j["min"] = json_bound(s.min, s.type);
      j["max"] = json_bound(s.max, s.type);
      j["min_exclusive"] = s.min_open;
      j["max_exclusive"] = s.max_open;
    }
    if (s.choices) j["choices"] = split_choices(s.choices);
    if (s.alias_of) j["alias_of"] = s.alias_of;
    if (s.lights) j["lights"] = split_choices(s.lights);
    if (s.blender_default) j["blender_default"] = nlohmann::json::parse(s.blender_default);
    j["doc"] = s.doc;
    rows.push_back(std::move(j));
  }
  nlohmann::json ignored = nlohmann::json::array();
  for (const char *name : table.ignored) ignored.push_back(name);
  return {{"attributes", rows}, {"ignored", ignored}};
}

EnumMember<Film> film_filter() {
  return {[](const Film &f) { return static_cast<int>(f.filter); },
          [](Film &f, int choice) { f.filter = static_cast<FilterType>(choice); }};
}

// Choices in the order of light_type's `choices`; "distant" is Cycles' name of the sun.
constexpr LightType kLightChoices[] = {LightType::Point, LightType::Sun,  LightType::Sun,
                                       LightType::Spot,  LightType::Area, LightType::Background};
EnumMember<Light> light_type() {
  return {[](const Light &l) {
            for (int i = 0; i < 6; ++i)
              if (kLightChoices[i] == l.type) return i;
            return 0;
          },
          [](Light &l, int choice) { l.type = kLightChoices[choice]; }};
}

}  // namespace

std::vector<std::string> split_choices(const char *choices) {
  std::vector<std::string> out;
  std::string cur;
  for (const char *c = choices; c && *c; ++c) {
    if (*c == '|') {
      out.push_back(cur);
      cur.clear();
    } else {
      cur += *c;
    }
  }
  if (choices) out.push_back(cur);
  return out;
}

std::string range_text(double min, double max, bool min_open, bool max_open) {
  if (std::isinf(max)) return std::string("must be ") + (min_open ? "> " : ">= ") + number_text(min);
  if (std::isinf(min)) return std::string("must be ") + (max_open ? "< " : "<= ") + number_text(max);
  return "must be in " + std::string(min_open ? "(" : "[") + number_text(min) + ", " + number_text(max) +
         (max_open ? ")" : "]");
}

bool in_range(double value, double min, double max, bool min_open, bool max_open) {
  const double lo = static_cast<float>(min), hi = static_cast<float>(max);
  return (min_open ? value > lo : value >= lo) && (max_open ? value < hi : value <= hi);
}

const ElementSettings<IntegratorSettings> &integrator_settings() {
  using I = IntegratorSettings;
  static const ElementSettings<I> table{
      "integrator",
      {
          {.xml = "max_bounce", .type = ST::Int, .member = &I::max_bounce, .min = 0, .max = kMaxBounces,
           .doc = "total bounce limit (0: direct light only)", .blender_default = "12"},
          {.xml = "min_bounce", .type = ST::Int, .member = &I::min_bounce, .min = 0, .max = kMaxBounces,
           .doc = "bounces before Russian roulette starts"},
          {.xml = "max_diffuse_bounce", .type = ST::Int, .member = &I::max_diffuse_bounce, .min = 0,
           .max = kMaxBounces, .doc = "diffuse bounce limit", .blender_default = "4"},
          {.xml = "max_glossy_bounce", .type = ST::Int, .member = &I::max_glossy_bounce, .min = 0,
           .max = kMaxBounces, .doc = "glossy bounce limit", .blender_default = "4"},
          {.xml = "max_transmission_bounce", .type = ST::Int, .member = &I::max_transmission_bounce, .min = 0,
           .max = kMaxBounces, .doc = "transmission bounce limit", .blender_default = "12"},
          {.xml = "transparent_max_bounce", .type = ST::Int, .member = &I::transparent_max_bounce, .min = 0,
           .max = kMaxBounces, .doc = "transparent bounce limit", .blender_default = "8"},
          {.xml = "filter_glossy", .type = ST::Float, .member = &I::filter_glossy, .min = 0,
           .doc = "blur glossy closures after blurry bounces (0: off)", .blender_default = "1.0"},
          {.xml = "sample_clamp_direct", .type = ST::Float, .member = &I::sample_clamp_direct, .min = 0,
           .doc = "clamp of direct-light samples (0: off)"},
          {.xml = "sample_clamp_indirect", .type = ST::Float, .member = &I::sample_clamp_indirect, .min = 0,
           .doc = "clamp of indirect-light samples (0: off)"},
          {.xml = "seed", .type = ST::Int, .member = &I::seed, .min = kIntMin, .max = kIntMax,
           .doc = "seed of the sampling pattern"},
          {.xml = "aa_samples", .type = ST::Int, .member = &I::samples, .min = 1, .max = kIntMax,
           .doc = "samples per pixel (Cycles' older name)", .alias_of = "samples"},
          {.xml = "samples", .type = ST::Int, .member = &I::samples, .min = 1, .max = kIntMax,
           .doc = "samples per pixel (--samples overrides)"},
      },
      {"caustics_reflective", "caustics_refractive", "volume_step_size", "max_volume_bounce", "method",
       "sample_all_lights_direct", "sample_all_lights_indirect", "transparent_min_bounce", "ao_bounces",
       "light_sampling_threshold", "sampling_pattern", "use_light_tree", "volume_max_steps", "adaptive_threshold",
       "use_adaptive_sampling"}};
  return table;
}

const ElementSettings<Film> &film_settings() {
  static const ElementSettings<Film> table{
      "film",
      {
          {.xml = "exposure", .type = ST::Float, .member = &Film::exposure, .min = 0, .max = 1e6,
           .doc = "multiplier of the image"},
          {.xml = "filter_type", .type = ST::Enum, .member = film_filter(), .choices = "box|gaussian|blackman_harris",
           .doc = "pixel filter (gaussian/blackman_harris without filter_width: 1.5 pixels)"},
          {.xml = "filter_width", .type = ST::Float, .member = &Film::filter_width, .min = 0, .max = 16,
           .min_open = true, .doc = "pixel filter width in pixels"},
      },
      {"pass_alpha_threshold", "mist_start", "mist_depth", "mist_falloff", "use_approximate_shadow_catcher"}};
  return table;
}

const ElementSettings<Camera> &camera_settings() {
  static const ElementSettings<Camera> table{
      "camera",
      {
          {.xml = "width", .type = ST::Int, .member = &Camera::width, .min = 1, .max = 65536,
           .doc = "image width in pixels"},
          {.xml = "height", .type = ST::Int, .member = &Camera::height, .min = 1, .max = 65536,
           .doc = "image height in pixels"},
          {.xml = "full_width", .type = ST::Int, .member = &Camera::width, .min = 1, .max = 65536,
           .doc = "image width in pixels", .alias_of = "width"},
          {.xml = "full_height", .type = ST::Int, .member = &Camera::height, .min = 1, .max = 65536,
           .doc = "image height in pixels", .alias_of = "height"},
          {.xml = "fov", .type = ST::Float, .member = &Camera::fov, .min = 0, .max = kPi, .min_open = true,
           .max_open = true, .doc = "field of view in radians, across the shorter image side"},
          {.xml = "nearclip", .type = ST::Float, .member = &Camera::nearclip, .min = 0,
           .doc = "near clipping distance (< farclip)"},
          {.xml = "farclip", .type = ST::Float, .member = &Camera::farclip, .min = 0, .min_open = true,
           .doc = "far clipping distance"},
          {.xml = "type", .type = ST::String, .member = std::monostate{}, .doc = "only perspective; other types warn and render perspective"},
          {.xml = "aperturesize", .type = ST::Float, .member = &Camera::aperture_size, .min = 0,
           .doc = "thin-lens aperture radius (0: pinhole)"},
          {.xml = "focaldistance", .type = ST::Float, .member = &Camera::focal_distance, .min = 0, .min_open = true,
           .doc = "distance of the plane in focus along the view axis"},
      },
      {"sensorwidth", "sensorheight", "shuttertime", "blades", "bladesrotation", "panorama_type", "fisheye_fov",
       "fisheye_lens", "offscreen_dicing_scale"}};
  return table;
}

const ElementSettings<Light> &light_settings() {
  static const ElementSettings<Light> table{
      "light",
      {
          {.xml = "name", .type = ST::String, .member = std::monostate{}, .doc = "lamp name (not used)"},
          {.xml = "type", .type = ST::Enum, .member = light_type(),
           .choices = "point|sun|distant|spot|area|background", .doc = "read as light_type, with a warning",
           .alias_of = "light_type"},
          {.xml = "light_type", .type = ST::Enum, .member = light_type(),
           .choices = "point|sun|distant|spot|area|background", .doc = "light kind (distant = sun)"},
          {.xml = "strength", .type = ST::Color, .member = &Light::strength, .min = 0,
           .doc = "emission (times the state shader's color * strength); watts for point/spot"},
          {.xml = "co", .type = ST::Vector, .member = &Light::co, .doc = "position",
           .lights = "point|spot|area"},
          {.xml = "dir", .type = ST::Vector, .member = &Light::dir,
           .doc = "direction (default: -(axisu x axisv))", .lights = "sun|spot|area"},
          {.xml = "radius", .type = ST::Float, .member = &Light::radius, .min = 0, .doc = "point/spot radius",
           .alias_of = "size", .lights = "point|spot"},
          {.xml = "size", .type = ST::Float, .member = &Light::radius, .min = 0,
           .doc = "point/spot radius; area: sizeu and sizev when they are absent (default 1)",
           .lights = "point|spot|area"},
          {.xml = "angle", .type = ST::Float, .member = &Light::angle, .min = 0,
           .doc = "angular diameter in radians", .lights = "sun"},
          {.xml = "spot_angle", .type = ST::Float, .member = &Light::spot_angle, .min = 0, .max = kPi,
           .min_open = true, .doc = "cone angle in radians", .lights = "spot"},
          {.xml = "spot_smooth", .type = ST::Float, .member = &Light::spot_smooth, .min = 0, .max = 1,
           .doc = "softness of the cone's edge", .lights = "spot"},
          {.xml = "axisu", .type = ST::Vector, .member = &Light::axisu, .doc = "first axis", .lights = "area"},
          {.xml = "axisv", .type = ST::Vector, .member = &Light::axisv, .doc = "second axis", .lights = "area"},
          {.xml = "sizeu", .type = ST::Float, .member = &Light::sizeu, .min = 0, .doc = "size along axisu",
           .lights = "area"},
          {.xml = "sizev", .type = ST::Float, .member = &Light::sizev, .min = 0, .doc = "size along axisv",
           .lights = "area"},
          {.xml = "round", .type = ST::Bool, .member = &Light::round, .doc = "disk/ellipse instead of rectangle",
           .lights = "area"},
          {.xml = "use_camera", .type = ST::Bool, .member = &Light::use_camera, .doc = "visible to camera rays"},
          {.xml = "spread", .type = ST::Float, .member = &Light::spread, .min = 0, .max = kPi + 1e-6,
           .doc = "spread angle in radians (pi: Lambertian)", .lights = "area"},
          {.xml = "tfm", .type = ST::Matrix, .member = std::monostate{}, .doc = "3x4 or 4x4 row-major transform"},
      },
      {"use_mis", "cast_shadow", "use_caustics", "use_diffuse", "use_glossy", "use_transmission", "use_scatter",
       "max_bounces", "map_resolution", "is_portal", "samples", "random_id", "is_enabled", "shadow_soft_size",
       "normalize"}};
  return table;
}

const ElementSettings<Background> &background_settings() {
  static const ElementSettings<Background> table{
      "background",
      {
          {.xml = "transparent", .type = ST::Bool, .member = &Background::transparent,
           .doc = "film transparency: camera rays that escape give alpha 0"},
      },
      {"heterogeneous_volume", "volume_sampling_method", "volume_interpolation_method", "use_shader", "use_mis",
       "volume_step_size", "transparent_glass", "transparent_roughness_threshold"}};
  return table;
}

nlohmann::json describe_scene_settings() {
  return {{"integrator", describe_element(integrator_settings())},
          {"film", describe_element(film_settings())},
          {"camera", describe_element(camera_settings())},
          {"light", describe_element(light_settings())},
          {"background", describe_element(background_settings())}};
}

}  // namespace glimmer::scene
