// Scene settings declared once: each attribute of <integrator>, <film>,
// <camera>, <light> and <background> is one row {xml name, type, member,
// range, doc}. The XML loader reads, range-checks (file:line errors) and
// warns about unknown attributes from these rows; `glimmer describe --json`
// prints them (with the default read from the member of a default-constructed
// element, so each default is written once, in scene.h) and the Blender addon
// builds its properties, exporter and panels from that JSON.
#pragma once

#include <limits>
#include <nlohmann/json.hpp>
#include <string>
#include <variant>
#include <vector>

#include "scene/scene.h"

namespace glimmer::scene {

enum class SettingType { Int, Float, Bool, Color, Vector, Enum, String, Matrix };

// An enumerated attribute stored in a C++ enum: the value's index in `choices`.
template <class T>
struct EnumMember {
  int (*get)(const T &);
  void (*set)(T &, int choice);
};

inline constexpr double kUnbounded = std::numeric_limits<double>::infinity();

template <class T>
struct Setting {
  const char *xml;
  SettingType type;
  // Where the value goes; monostate: read by the element's own code (light tfm,
  // camera type) or accepted without effect (light name).
  std::variant<std::monostate, int T::*, float T::*, bool T::*, Vec3 T::*, EnumMember<T>> member;
  double min = -kUnbounded, max = kUnbounded;  // Int/Float, and each component of Color/Vector
  bool min_open = false, max_open = false;     // exclusive bounds
  const char *choices = nullptr;               // Enum: "a|b|c"
  const char *doc = "";
  const char *alias_of = nullptr;  // another name of the row `alias_of` (rows are read in table order)
  const char *lights = nullptr;    // <light> rows: the light types that read it ("point|spot"); null: all
  // Blender 3.4's UI default where it differs from Cycles' socket default (JSON text); the addon uses it.
  const char *blender_default = nullptr;
};

template <class T>
struct ElementSettings {
  const char *element;
  std::vector<Setting<T>> settings;
  // Cycles attributes of this element that have no effect here (warned as "not supported").
  std::vector<const char *> ignored;
  const Setting<T> *find(const std::string &xml) const {
    for (const auto &s : settings)
      if (xml == s.xml) return &s;
    return nullptr;
  }
  bool is_ignored(const std::string &xml) const {
    for (const char *name : ignored)
      if (xml == name) return true;
    return false;
  }
};

const ElementSettings<IntegratorSettings> &integrator_settings();
const ElementSettings<Film> &film_settings();
const ElementSettings<Camera> &camera_settings();
const ElementSettings<Light> &light_settings();
const ElementSettings<Background> &background_settings();

// "a|b|c" -> {"a", "b", "c"} (enum choices; null -> none).
std::vector<std::string> split_choices(const char *choices);

// "must be in [0, 1024]" / "must be in (0, 16]" / "must be >= 0".
std::string range_text(double min, double max, bool min_open, bool max_open);

// Whether `value` lies in the row's range (floats compared in single precision).
bool in_range(double value, double min, double max, bool min_open, bool max_open);

// {"integrator": {"attributes": [...], "ignored": [...]}, "film": ..., ...}
// for `glimmer describe --json` (key "scene").
nlohmann::json describe_scene_settings();

}  // namespace glimmer::scene
