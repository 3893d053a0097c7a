// Scene settings declared once (bridge/scene/settings.cpp): every row of the
// <integrator>, <film>, <camera>, <light> and <background> tables round-trips:
// `glimmer describe --json` lists it with its default and range, an in-range
// value reaches the member, an out-of-range or malformed value is a file:line
// error, and an attribute outside the table warns with file:line.
#include <iomanip>
#include <nlohmann/json.hpp>
#include <regex>

#include "render_test_util.h"
#include "scene/settings.h"

namespace glimmer::test {
namespace {

using scene::SettingType;

const nlohmann::json &described_scene() {
  static const nlohmann::json scene = [] {
    std::string out;
    EXPECT_EQ(0, run_cli("describe --json", out)) << out;
    return nlohmann::json::parse(out.substr(out.find('{')))["scene"];
  }();
  return scene;
}

const nlohmann::json *described_row(const std::string &element, const std::string &name) {
  for (const auto &row : described_scene().at(element).at("attributes"))
    if (row.at("name") == name) return &row;
  return nullptr;
}

// The loaded element of that kind (the light is the scene's only one).
const scene::IntegratorSettings &loaded(const scene::Scene &s, const scene::IntegratorSettings *) { return s.integrator; }
const scene::Film &loaded(const scene::Scene &s, const scene::Film *) { return s.film; }
const scene::Camera &loaded(const scene::Scene &s, const scene::Camera *) { return s.camera; }
const scene::Light &loaded(const scene::Scene &s, const scene::Light *) { return s.lights.at(0); }
const scene::Background &loaded(const scene::Scene &s, const scene::Background *) { return s.background; }

// A scene whose line 2 is <element attributes />.
scene::Scene load_element(const char *element, const std::string &attributes, const std::string &file) {
  const std::string text = std::string("<cycles>\n<") + element + " " + attributes + " />\n</cycles>\n";
  return scene::load_scene_text(text, (temp_dir() / file).string());
}

void expect_error(const char *element, const std::string &attributes, const std::string &expected) {
  SCOPED_TRACE(attributes);
  try {
    load_element(element, attributes, "bad.xml");
    ADD_FAILURE() << "no error for <" << element << " " << attributes << ">";
  } catch (const scene::SceneError &e) {
    EXPECT_NE(std::string(e.what()).find("bad.xml:2: <" + std::string(element) + "> " + expected), std::string::npos)
        << e.what();
  }
}

// A value inside [min, max] (a unit vector for vectors: light dir is normalised).
double inside(double min, double max, SettingType type) {
  const double lo = std::isfinite(min) ? min : 0.0;
  double v = std::isfinite(max) ? 0.5 * (lo + max) : lo + 1.5;
  if (type == SettingType::Int) v = std::isfinite(max) ? std::floor(v) : lo + 1;
  return v;
}

template <class T>
void check_table(const scene::ElementSettings<T> &table) {
  const T defaults{};
  ASSERT_TRUE(described_scene().contains(table.element)) << table.element;
  for (const auto &s : table.settings) {
    SCOPED_TRACE(std::string(table.element) + " " + s.xml);
    const nlohmann::json *row = described_row(table.element, s.xml);
    ASSERT_NE(row, nullptr) << "describe --json does not list it";
    EXPECT_TRUE(row->contains("default") && row->contains("doc") && !row->at("doc").get<std::string>().empty());
    const bool numeric = s.type == SettingType::Int || s.type == SettingType::Float || s.type == SettingType::Color ||
                         s.type == SettingType::Vector;
    if (numeric) {
      ASSERT_TRUE(row->contains("min") && row->contains("max"));
      if (std::isfinite(s.min)) EXPECT_NEAR(row->at("min").get<double>(), s.min, 1e-6 * (1 + std::fabs(s.min)));
      else EXPECT_TRUE(row->at("min").is_null());
      if (std::isfinite(s.max)) EXPECT_NEAR(row->at("max").get<double>(), s.max, 1e-6 * (1 + std::fabs(s.max)));
      else EXPECT_TRUE(row->at("max").is_null());
    }
    std::visit(
        [&](const auto &member) {
          using M = std::decay_t<decltype(member)>;
          if constexpr (std::is_same_v<M, std::monostate>) {
            EXPECT_TRUE(row->at("default").is_null());
          } else if constexpr (std::is_same_v<M, int T::*> || std::is_same_v<M, float T::*>) {
            EXPECT_NEAR(row->at("default").get<double>(), defaults.*member, 1e-6 * (1 + std::fabs(defaults.*member)));
            const double value = inside(s.min, s.max, s.type);
            std::ostringstream text;
            text << std::setprecision(10) << s.xml << "=\"" << static_cast<float>(value) << "\"";
            const scene::Scene ok = load_element(table.element, text.str(), "ok.xml");
            EXPECT_EQ(loaded(ok, static_cast<T *>(nullptr)).*member, static_cast<std::decay_t<decltype(defaults.*member)>>(value))
                << text.str();
            if (std::isfinite(s.min) && s.min > std::numeric_limits<int>::min()) {  // (seed: any int)
              std::ostringstream below;
              below << std::setprecision(12) << s.xml << "=\"" << (s.min_open ? s.min : s.min - 1) << "\"";
              expect_error(table.element, below.str(), std::string(s.xml) + " must be");
            }
            if (std::isfinite(s.max) && s.max < std::numeric_limits<int>::max()) {
              std::ostringstream above;
              above << s.xml << "=\"" << std::setprecision(9) << (s.max_open ? s.max : s.max + 1) << "\"";
              expect_error(table.element, above.str(), std::string(s.xml) + " must be");
            }
            expect_error(table.element, std::string(s.xml) + "=\"1x\"", s.xml);
          } else if constexpr (std::is_same_v<M, bool T::*>) {
            EXPECT_EQ(row->at("default").get<bool>(), defaults.*member);
            const scene::Scene ok = load_element(
                table.element, std::string(s.xml) + "=\"" + (defaults.*member ? "false" : "true") + "\"", "ok.xml");
            const T &t = loaded(ok, static_cast<T *>(nullptr));
            EXPECT_NE(t.*member, defaults.*member);
            expect_error(table.element, std::string(s.xml) + "=\"maybe\"", std::string(s.xml) + ": 'maybe' is not a boolean");
          } else if constexpr (std::is_same_v<M, Vec3 T::*>) {
            const Vec3 d = defaults.*member;
            ASSERT_EQ(row->at("default").size(), 3u);
            for (int k = 0; k < 3; ++k) EXPECT_NEAR(row->at("default")[k].get<double>(), d[k], 1e-6);
            const float v = static_cast<float>(inside(s.min, s.max, SettingType::Float));
            const Vec3 value = s.type == SettingType::Vector ? Vec3(0.0f, 0.0f, 1.0f) : Vec3(v, 0.5f * v, 0.25f * v);
            std::ostringstream text;
            text << std::setprecision(10) << s.xml << "=\"" << value.x << " " << value.y << " " << value.z << "\"";
            const scene::Scene ok = load_element(table.element, text.str(), "ok.xml");
            const Vec3 got = loaded(ok, static_cast<T *>(nullptr)).*member;
            for (int k = 0; k < 3; ++k) EXPECT_NEAR(got[k], value[k], 1e-6);
            if (std::isfinite(s.min)) {
              std::ostringstream below;
              below << s.xml << "=\"" << v << " " << (s.min_open ? s.min : s.min - 1) << " " << v << "\"";
              expect_error(table.element, below.str(), std::string(s.xml) + " must be");
            }
            expect_error(table.element, std::string(s.xml) + "=\"1 2\"", std::string(s.xml) + ": expected 3 numbers");
          } else {  // EnumMember
            const auto choices = row->at("choices").get<std::vector<std::string>>();
            ASSERT_FALSE(choices.empty());
            EXPECT_EQ(row->at("default").get<std::string>(), choices.at(member.get(defaults)));
            for (size_t i = 0; i < choices.size(); ++i) {
              const scene::Scene ok =
                  load_element(table.element, std::string(s.xml) + "=\"" + choices[i] + "\"", "ok.xml");
              const T &t = loaded(ok, static_cast<T *>(nullptr));
              T expected{};
              member.set(expected, static_cast<int>(i));
              EXPECT_EQ(member.get(t), member.get(expected)) << choices[i];
            }
            expect_error(table.element, std::string(s.xml) + "=\"bogus\"", std::string(s.xml) + " 'bogus' is not one of");
          }
        },
        s.member);
  }
  // Any attribute outside the table warns at the element's line; the listed Cycles
  // attributes without effect warn as "not supported".
  const scene::Scene unknown = load_element(table.element, "bogus_attribute=\"1\"", "unknown.xml");
  const std::regex warning(".*unknown\\.xml:2: warning: <" + std::string(table.element) +
                           "> unknown attribute 'bogus_attribute' ignored");
  EXPECT_TRUE(std::any_of(unknown.warnings.begin(), unknown.warnings.end(),
                          [&](const std::string &w) { return std::regex_match(w, warning); }))
      << table.element << ": " << (unknown.warnings.empty() ? "no warning" : unknown.warnings.front());
  for (const char *name : table.ignored) {
    const scene::Scene ignored = load_element(table.element, std::string(name) + "=\"1\"", "ignored.xml");
    const std::string expected = "ignored.xml:2: warning: <" + std::string(table.element) + "> attribute '" + name +
                                 "' is not supported; ignored";
    EXPECT_TRUE(std::any_of(ignored.warnings.begin(), ignored.warnings.end(),
                            [&](const std::string &w) { return w.find(expected) != std::string::npos; }))
        << expected;
  }
  // describe --json lists exactly the table's rows and ignored attributes.
  EXPECT_EQ(described_scene().at(table.element).at("attributes").size(), table.settings.size());
  EXPECT_EQ(described_scene().at(table.element).at("ignored").size(), table.ignored.size());
}

TEST(SettingsTable, IntegratorRowsRoundTrip) { check_table(scene::integrator_settings()); }
TEST(SettingsTable, FilmRowsRoundTrip) { check_table(scene::film_settings()); }
TEST(SettingsTable, CameraRowsRoundTrip) { check_table(scene::camera_settings()); }
TEST(SettingsTable, LightRowsRoundTrip) { check_table(scene::light_settings()); }
TEST(SettingsTable, BackgroundRowsRoundTrip) { check_table(scene::background_settings()); }

// The range check is not vacuous: a bounce limit past 1024 (which would overflow the kernel's
// setting + 1 near INT_MAX) and a negative exposure are refused with the element's line.
TEST(SettingsTable, RangeErrorsNameTheLimit) {
  expect_error("integrator", "max_diffuse_bounce=\"1025\"", "max_diffuse_bounce must be in [0, 1024], got 1025");
  expect_error("film", "exposure=\"-100\"", "exposure must be in [0, 1e6], got -100");
  expect_error("film", "filter_width=\"0\"", "filter_width must be in (0, 16], got 0");
  expect_error("camera", "fov=\"3.5\"", "fov must be in (0, 3.1415927), got 3.5");
  expect_error("light", "strength=\"1 -1 1\"", "strength must be >= 0, got 1 -1 1");
}

// Cycles 3.4's socket defaults (intern/cycles/scene/integrator.cpp, film.cpp, camera.cpp, light.cpp);
// the differences are documented in docs/scene-format.md.
TEST(SettingsTable, DefaultsAreCycles34) {
  const scene::IntegratorSettings i{};
  EXPECT_EQ(i.max_bounce, 7);
  EXPECT_EQ(i.min_bounce, 0);
  EXPECT_EQ(i.max_diffuse_bounce, 7);
  EXPECT_EQ(i.max_glossy_bounce, 7);
  EXPECT_EQ(i.max_transmission_bounce, 7);
  EXPECT_EQ(i.transparent_max_bounce, 7);
  EXPECT_EQ(i.filter_glossy, 0.0f);
  EXPECT_EQ(i.sample_clamp_direct, 0.0f);
  EXPECT_EQ(i.sample_clamp_indirect, 10.0f);
  EXPECT_EQ(i.seed, 0);
  const scene::Camera c{};
  EXPECT_EQ(c.width, 1024);
  EXPECT_EQ(c.height, 512);
  EXPECT_EQ(c.aperture_size, 0.0f);
  EXPECT_EQ(c.focal_distance, 10.0f);
  const scene::Light l{};
  EXPECT_TRUE(l.use_camera);
  EXPECT_FLOAT_EQ(l.spread, kPi);
  EXPECT_FLOAT_EQ(l.spot_angle, kPi / 4);
  const scene::Film f{};
  EXPECT_EQ(f.exposure, 1.0f);
}

}  // namespace
}  // namespace glimmer::test
