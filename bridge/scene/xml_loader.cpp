#include "scene/xml_loader.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <pugixml.hpp>
#include <set>
#include <sstream>

#include "scene/graph_checks.h"
#include "scene/input_file.h"
#include "scene/mesh_files.h"
#include "scene/parse_number.h"
#include "scene/settings.h"
#include "scene/uv_tangents.h"

namespace glimmer::scene {

namespace fs = std::filesystem;

std::vector<float> parse_floats(const std::string &text, const SourceLocation &where, const std::string &what) {
  try {
    return parse_float_list(text);
  } catch (const NumberError &e) {
    throw SceneError(where, what + ": " + e.what());
  }
}

namespace {

// One parsed XML file, kept alive for line lookups.
struct XmlFile {
  std::string path;
  std::string text;
  std::vector<size_t> line_starts;
  pugi::xml_document doc;

  int line_of(ptrdiff_t offset) const {
    if (offset < 0) return 0;
    auto it = std::upper_bound(line_starts.begin(), line_starts.end(), static_cast<size_t>(offset));
    return static_cast<int>(it - line_starts.begin());
  }
};

struct ReadState {
  Transform tfm;
  int shader = -1;
  bool smooth = false;
  std::string object;
};

class Loader {
 public:
  explicit Loader(Scene &scene) : scene_(scene) {}

  void load_file(const std::string &path, const SourceLocation *included_from, const ReadState &state) {
    std::string text;
    try {
      text = read_regular_file(path, kMaxSceneFileBytes, "scene file");
    } catch (const InputFileError &e) {
      if (included_from) throw SceneError(*included_from, e.what());
      throw SceneError(path + ":0: " + e.what());
    }
    load_text(path, std::move(text), state);
  }

  // `text` read as the content of the file at `path`.
  void load_text(const std::string &path, std::string text, const ReadState &state) {
    auto file = std::make_unique<XmlFile>();
    file->path = path;
    file->text = std::move(text);
    file->line_starts.push_back(0);
    for (size_t i = 0; i < file->text.size(); ++i)
      if (file->text[i] == '\n') file->line_starts.push_back(i + 1);
    const auto result =
        file->doc.load_buffer(file->text.data(), file->text.size(), pugi::parse_default | pugi::parse_ws_pcdata_single);
    if (!result) {
      throw SceneError(SourceLocation{path, file->line_of(result.offset)},
                       std::string("malformed XML: ") + result.description());
    }
    XmlFile *f = file.get();
    files_.push_back(std::move(file));
    const pugi::xml_node root = f->doc.child("cycles");
    if (!root) throw SceneError(SourceLocation{path, 1}, "the root element must be <cycles>");
    for (auto child = f->doc.first_child(); child; child = child.next_sibling())
      if (child.type() == pugi::node_element && std::string(child.name()) != "cycles")
        warn(*f, child, std::string("element <") + child.name() + "> outside <cycles> ignored");
    std::error_code ec;
    include_stack_.push_back(fs::weakly_canonical(path, ec).string());
    read_children(*f, root, state);
    include_stack_.pop_back();
  }

  const std::atomic<bool> *cancel = nullptr;

 private:
  Scene &scene_;
  std::vector<std::unique_ptr<XmlFile>> files_;
  std::set<std::string> objects_;
  // Input controls these depths; each has a limit (docs/scene-format.md, "Limits").
  std::vector<std::string> include_stack_;  // canonical paths of the files being read
  int transform_depth_ = 0, state_depth_ = 0;

  // Raises the depth counter for the scope of one nested element.
  struct DepthGuard {
    int &depth;
    DepthGuard(int &d, int limit, const SourceLocation &where, const char *element) : depth(d) {
      if (depth >= limit)
        throw SceneError(where, std::string("<") + element + "> nested more than " + std::to_string(limit) +
                                    " levels deep");
      ++depth;
    }
    ~DepthGuard() { --depth; }
    DepthGuard(const DepthGuard &) = delete;
    DepthGuard &operator=(const DepthGuard &) = delete;
  };

  SourceLocation loc(const XmlFile &f, const pugi::xml_node &node) const {
    return SourceLocation{f.path, f.line_of(node.offset_debug())};
  }
  void warn(const XmlFile &f, const pugi::xml_node &node, const std::string &message) {
    scene_.warnings.push_back(loc(f, node).str() + ": warning: " + message);
  }

  // Warn about every attribute not in `known` (and not in `ignored`, which are
  // recognised Cycles attributes without effect here).
  void check_attributes(const XmlFile &f, const pugi::xml_node &node, std::initializer_list<const char *> known,
                        std::initializer_list<const char *> ignored = {}) {
    for (auto a = node.first_attribute(); a; a = a.next_attribute()) {
      const std::string name = a.name();
      if (std::any_of(known.begin(), known.end(), [&](const char *k) { return name == k; })) continue;
      if (std::any_of(ignored.begin(), ignored.end(), [&](const char *k) { return name == k; })) {
        warn(f, node, std::string("<") + node.name() + "> attribute '" + name + "' is not supported; ignored");
        continue;
      }
      warn(f, node, std::string("<") + node.name() + "> unknown attribute '" + name + "' ignored");
    }
  }

  std::vector<float> floats(const XmlFile &f, const pugi::xml_node &node, const char *attr) {
    return parse_floats(node.attribute(attr).value(), loc(f, node), std::string("<") + node.name() + "> " + attr);
  }
  float read_float(const XmlFile &f, const pugi::xml_node &node, const char *attr, float fallback) {
    if (!node.attribute(attr)) return fallback;
    const auto v = floats(f, node, attr);
    if (v.size() != 1)
      throw SceneError(loc(f, node), std::string("<") + node.name() + "> " + attr + ": expected one number, got " +
                                         std::to_string(v.size()));
    return v[0];
  }
  // An integer attribute within [lo, hi] ("2.9", "1e10" for an int and junk are errors).
  int read_int(const XmlFile &f, const pugi::xml_node &node, const char *attr, int fallback, int lo = std::numeric_limits<int>::min(),
               int hi = std::numeric_limits<int>::max()) {
    if (!node.attribute(attr)) return fallback;
    const auto v = ints(f, node, attr, lo, hi);
    if (v.size() != 1)
      throw SceneError(loc(f, node), std::string("<") + node.name() + "> " + attr + ": expected one integer, got " +
                                         std::to_string(v.size()) + " numbers");
    return v[0];
  }
  std::vector<int> ints(const XmlFile &f, const pugi::xml_node &node, const char *attr, int lo, int hi) {
    try {
      return parse_int_list(node.attribute(attr).value(), lo, hi);
    } catch (const NumberError &e) {
      throw SceneError(loc(f, node), std::string("<") + node.name() + "> " + attr + ": " + e.what());
    }
  }
  Vec3 read_vec3(const XmlFile &f, const pugi::xml_node &node, const char *attr, Vec3 fallback) {
    if (!node.attribute(attr)) return fallback;
    const auto v = floats(f, node, attr);
    if (v.size() == 1) return Vec3(v[0]);
    if (v.size() != 3)
      throw SceneError(loc(f, node), std::string("<") + node.name() + "> " + attr + ": expected 3 numbers, got " +
                                         std::to_string(v.size()));
    return {v[0], v[1], v[2]};
  }
  bool read_bool(const XmlFile &f, const pugi::xml_node &node, const char *attr, bool fallback) {
    if (!node.attribute(attr)) return fallback;
    const std::string v = node.attribute(attr).value();
    if (v == "true" || v == "1" || v == "True") return true;
    if (v == "false" || v == "0" || v == "False") return false;
    throw SceneError(loc(f, node), std::string("<") + node.name() + "> " + attr + ": '" + v + "' is not a boolean");
  }

  void read_children(const XmlFile &f, const pugi::xml_node &parent, const ReadState &state) {
    for (auto node = parent.first_child(); node; node = node.next_sibling()) {
      if (node.type() != pugi::node_element) continue;
      if (cancel && cancel->load()) throw LoadCancelled(loc(f, node).str() + ": loading interrupted");
      const std::string name = node.name();
      if (name == "camera") read_camera(f, node, state);
      else if (name == "film") read_film(f, node);
      else if (name == "integrator") read_integrator(f, node);
      else if (name == "background") read_background(f, node);
      else if (name == "shader") read_shader(f, node);
      else if (name == "mesh") read_mesh(f, node, state);
      else if (name == "light") read_light(f, node, state);
      else if (name == "transform") read_transform(f, node, state);
      else if (name == "state") read_state(f, node, state);
      else if (name == "object") read_object(f, node);
      else if (name == "include") read_include(f, node, state);
      else warn(f, node, "unknown element <" + name + "> ignored (with its children)");
    }
  }

  // Reads every attribute `table` declares into `target` (rows in table order), with a file:line error
  // for a value out of the row's range and a warning for any attribute not in the table.
  template <class T>
  void read_settings(const XmlFile &f, const pugi::xml_node &node, const ElementSettings<T> &table, T &target) {
    for (auto a = node.first_attribute(); a; a = a.next_attribute()) {
      const std::string name = a.name();
      if (table.find(name)) continue;
      std::string message = std::string("<") + table.element + "> ";
      if (table.is_ignored(name)) message += "attribute '" + name + "' is not supported; ignored";
      else message += "unknown attribute '" + name + "' ignored";
      warn(f, node, message);
    }
    for (const Setting<T> &s : table.settings) {
      if (!node.attribute(s.xml)) continue;
      const auto check = [&](double value) {
        if (!in_range(value, s.min, s.max, s.min_open, s.max_open))
          throw SceneError(loc(f, node), std::string("<") + table.element + "> " + s.xml + " " +
                                             range_text(s.min, s.max, s.min_open, s.max_open) + ", got " +
                                             node.attribute(s.xml).value());
      };
      std::visit(
          [&](const auto &member) {
            using M = std::decay_t<decltype(member)>;
            if constexpr (std::is_same_v<M, int T::*>) {
              target.*member = read_int(f, node, s.xml, 0);
              check(target.*member);
            } else if constexpr (std::is_same_v<M, float T::*>) {
              target.*member = read_float(f, node, s.xml, 0.0f);
              check(target.*member);
            } else if constexpr (std::is_same_v<M, bool T::*>) {
              target.*member = read_bool(f, node, s.xml, false);
            } else if constexpr (std::is_same_v<M, Vec3 T::*>) {
              target.*member = read_vec3(f, node, s.xml, Vec3(0.0f));
              for (int k = 0; k < 3; ++k) check((target.*member)[k]);
            } else if constexpr (std::is_same_v<M, EnumMember<T>>) {
              member.set(target, read_choice(f, node, table.element, s));
            }
          },
          s.member);
    }
  }

  template <class T>
  int read_choice(const XmlFile &f, const pugi::xml_node &node, const char *element, const Setting<T> &s) {
    const std::string value = node.attribute(s.xml).value();
    const std::vector<std::string> choices = split_choices(s.choices);
    const auto it = std::find(choices.begin(), choices.end(), value);
    if (it != choices.end()) return static_cast<int>(it - choices.begin());
    throw SceneError(loc(f, node), std::string("<") + element + "> " + s.xml + " '" + value + "' is not one of " +
                                       s.choices);
  }

  void read_camera(const XmlFile &f, const pugi::xml_node &node, const ReadState &state) {
    Camera &c = scene_.camera;
    read_settings(f, node, camera_settings(), c);
    c.where = loc(f, node);
    c.camera_to_world = state.tfm;
    if (!(c.farclip > c.nearclip)) throw SceneError(loc(f, node), "<camera> needs 0 <= nearclip < farclip");
    if (node.attribute("type") && std::string(node.attribute("type").value()) != "perspective")
      warn(f, node, std::string("camera type '") + node.attribute("type").value() +
                        "' is not supported; rendering with a perspective camera");
    if (std::fabs(state.tfm.determinant()) < 1e-12f) throw SceneError(loc(f, node), "<camera> transform is singular");
  }

  void read_film(const XmlFile &f, const pugi::xml_node &node) {
    Film &film = scene_.film;
    read_settings(f, node, film_settings(), film);
    // A smooth filter given without a width gets Cycles' usual 1.5 pixels.
    if (node.attribute("filter_type") && film.filter != FilterType::Box && !node.attribute("filter_width"))
      film.filter_width = 1.5f;
  }

  void read_integrator(const XmlFile &f, const pugi::xml_node &node) {
    read_settings(f, node, integrator_settings(), scene_.integrator);
  }

  // Shader graph nodes and <connect> links below `node`.
  ShaderGraph read_graph(const XmlFile &f, const pugi::xml_node &node, const std::string &name) {
    ShaderGraph g;
    g.name = name;
    g.where = loc(f, node);
    for (auto child = node.first_child(); child; child = child.next_sibling()) {
      if (child.type() != pugi::node_element) continue;
      const std::string type = child.name();
      if (type == "connect") {
        check_attributes(f, child, {"from", "to"});
        std::istringstream from(child.attribute("from").value()), to(child.attribute("to").value());
        ShaderLink link;
        link.where = loc(f, child);
        if (!(from >> link.from_node >> link.from_socket) || !(to >> link.to_node >> link.to_socket))
          throw SceneError(link.where, "<connect> needs from=\"node socket\" and to=\"node socket\"");
        g.links.push_back(link);
        continue;
      }
      ShaderNode n;
      n.type = type;
      n.where = loc(f, child);
      n.name = child.attribute("name").value();
      for (auto a = child.first_attribute(); a; a = a.next_attribute())
        if (std::string(a.name()) != "name") n.attributes[a.name()] = a.value();
      if (n.name.empty()) n.name = "__unnamed" + std::to_string(g.nodes.size());
      g.nodes.push_back(std::move(n));
    }
    validate_shader_graph(g);
    return g;
  }

  void read_shader(const XmlFile &f, const pugi::xml_node &node) {
    check_attributes(f, node, {"name", "displacement_method"},
                     {"use_mis", "use_transparent_shadow", "heterogeneous_volume", "volume_sampling_method",
                      "volume_interpolation_method"});
    const std::string name = node.attribute("name").value();
    if (name.empty()) throw SceneError(loc(f, node), "<shader> needs a name");
    ShaderGraph g = read_graph(f, node, name);
    if (const auto method = node.attribute("displacement_method")) {
      g.displacement_method = method.value();
      if (g.displacement_method != "bump" && g.displacement_method != "true" && g.displacement_method != "both")
        throw SceneError(loc(f, node), "<shader> displacement_method '" + g.displacement_method +
                                           "' is not one of bump, true, both");
    }
    const int existing = scene_.find_shader(name);
    if (existing >= 0) {
      warn(f, node, "shader '" + name + "' redefined; the later definition replaces the earlier one");
      scene_.shaders[existing] = std::move(g);
    } else {
      scene_.shaders.push_back(std::move(g));
    }
  }

  void read_background(const XmlFile &f, const pugi::xml_node &node) {
    read_settings(f, node, background_settings(), scene_.background);
    ShaderGraph g = read_graph(f, node, "__background");
    const int existing = scene_.find_shader("__background");
    if (existing >= 0) {
      scene_.shaders[existing] = std::move(g);
      scene_.background.shader = existing;
    } else {
      scene_.shaders.push_back(std::move(g));
      scene_.background.shader = static_cast<int>(scene_.shaders.size()) - 1;
    }
  }

  void read_transform(const XmlFile &f, const pugi::xml_node &node, const ReadState &state) {
    check_attributes(f, node, {"matrix", "translate", "rotate", "scale"});
    const DepthGuard guard(transform_depth_, kMaxTransformDepth, loc(f, node), "transform");
    ReadState s = state;
    if (node.attribute("matrix")) {
      const auto v = floats(f, node, "matrix");
      if (v.size() != 16) throw SceneError(loc(f, node), "<transform> matrix needs 16 numbers");
      // Cycles reads the 16 numbers column by column (transform_transposed).
      Transform m;
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c) m.m[r][c] = v[c * 4 + r];
      s.tfm = s.tfm * m;
    }
    if (node.attribute("translate")) s.tfm = s.tfm * Transform::translate(read_vec3(f, node, "translate", Vec3(0.0f)));
    if (node.attribute("rotate")) {
      const auto v = floats(f, node, "rotate");
      if (v.size() != 4) throw SceneError(loc(f, node), "<transform> rotate needs \"degrees x y z\"");
      const Vec3 axis(v[1], v[2], v[3]);
      if (length(axis) == 0.0f) throw SceneError(loc(f, node), "<transform> rotate axis is zero");
      s.tfm = s.tfm * Transform::rotate(v[0] * kPi / 180.0f, axis);
    }
    if (node.attribute("scale")) s.tfm = s.tfm * Transform::scale(read_vec3(f, node, "scale", Vec3(1.0f)));
    read_children(f, node, s);
  }

  void read_state(const XmlFile &f, const pugi::xml_node &node, const ReadState &state) {
    check_attributes(f, node, {"shader", "interpolation", "object"}, {"displacement_method", "dicing_rate"});
    const DepthGuard guard(state_depth_, kMaxStateDepth, loc(f, node), "state");
    ReadState s = state;
    if (node.attribute("shader")) {
      const std::string name = node.attribute("shader").value();
      s.shader = scene_.find_shader(name);
      if (s.shader < 0) throw SceneError(loc(f, node), "<state> unknown shader '" + name + "'");
    }
    if (node.attribute("interpolation")) {
      const std::string v = node.attribute("interpolation").value();
      if (v == "smooth") s.smooth = true;
      else if (v == "flat") s.smooth = false;
      else throw SceneError(loc(f, node), "<state> interpolation must be smooth or flat, got '" + v + "'");
    }
    if (node.attribute("object")) {
      s.object = node.attribute("object").value();
      if (!objects_.count(s.object)) warn(f, node, "<state> object '" + s.object + "' was not declared with <object>");
    }
    read_children(f, node, s);
  }

  void read_object(const XmlFile &f, const pugi::xml_node &node) {
    check_attributes(f, node, {"name"},
                     {"is_caustics_caster", "is_caustics_receiver", "is_shadow_catcher", "visibility", "asset_name",
                      "pass_id", "motion", "color", "random_id", "use_holdout", "hide_on_missing_motion"});
    objects_.insert(node.attribute("name").value());
  }

  void read_include(const XmlFile &f, const pugi::xml_node &node, const ReadState &state) {
    check_attributes(f, node, {"src"});
    const std::string src = node.attribute("src").value();
    if (src.empty()) throw SceneError(loc(f, node), "<include> needs src");
    const fs::path path = (fs::path(f.path).parent_path() / src).lexically_normal();
    const SourceLocation from = loc(f, node);
    std::error_code ec;
    if (!fs::exists(path, ec)) throw SceneError(from, "<include> file not found: '" + path.string() + "'");
    const std::string canonical = fs::weakly_canonical(path, ec).string();
    if (std::find(include_stack_.begin(), include_stack_.end(), canonical) != include_stack_.end()) {
      std::string chain;
      for (const auto &p : include_stack_) chain += p + " -> ";
      throw SceneError(from, "<include> loop: " + chain + canonical);
    }
    if (static_cast<int>(include_stack_.size()) > kMaxIncludeDepth)
      throw SceneError(from, "<include> nested more than " + std::to_string(kMaxIncludeDepth) + " files deep");
    if (files_.size() > kMaxIncludedFiles)
      throw SceneError(from, "<include>: more than " + std::to_string(kMaxIncludedFiles) + " files included");
    load_file(path.string(), &from, state);
  }

  void read_mesh(const XmlFile &f, const pugi::xml_node &node, const ReadState &state) {
    check_attributes(f, node, {"P", "verts", "nverts", "UV", "N", "src"}, {"motion_steps", "subdivision_type"});
    const SourceLocation where = loc(f, node);
    RawMesh raw;
    if (node.attribute("src")) {
      const fs::path path = fs::path(f.path).parent_path() / node.attribute("src").value();
      raw = read_mesh_file(path.string(), where, cancel);
    } else {
      raw.P = floats(f, node, "P");
      raw.verts = ints(f, node, "verts", std::numeric_limits<int>::min(), std::numeric_limits<int>::max());
      raw.nverts = ints(f, node, "nverts", std::numeric_limits<int>::min(), std::numeric_limits<int>::max());
      if (node.attribute("UV")) raw.uv = floats(f, node, "UV");
      if (node.attribute("N")) raw.N = floats(f, node, "N");
      raw.uv_per_corner = true;
    }
    Mesh mesh = build_mesh(raw, where, state);
    if (!mesh.triangles.empty()) scene_.meshes.push_back(std::move(mesh));
    else warn(f, node, "mesh has no triangles; ignored");
  }

  Mesh build_mesh(const RawMesh &raw, const SourceLocation &where, const ReadState &state) {
    if (raw.P.size() % 3 != 0) throw SceneError(where, "<mesh> P needs a multiple of 3 numbers");
    const size_t vertex_count = raw.P.size() / 3;
    size_t corners = 0;
    for (int n : raw.nverts) {
      if (n < 3) throw SceneError(where, "<mesh> nverts entries must be >= 3, got " + std::to_string(n));
      corners += static_cast<size_t>(n);
    }
    if (corners != raw.verts.size())
      throw SceneError(where, "<mesh> nverts sums to " + std::to_string(corners) + " but verts has " +
                                  std::to_string(raw.verts.size()) + " entries");
    for (int v : raw.verts)
      if (v < 0 || static_cast<size_t>(v) >= vertex_count)
        throw SceneError(where, "<mesh> vertex index " + std::to_string(v) + " out of range (" +
                                    std::to_string(vertex_count) + " vertices)");
    const bool uv_corner = raw.uv_per_corner ? raw.uv.size() == 2 * corners : false;
    const bool uv_vertex = !raw.uv_per_corner && raw.uv.size() == 2 * vertex_count;
    if (!raw.uv.empty() && !uv_corner && !uv_vertex)
      throw SceneError(where, "<mesh> UV needs 2 numbers per face corner (" + std::to_string(2 * corners) + "), got " +
                                  std::to_string(raw.uv.size()));
    if (!raw.N.empty() && raw.N.size() != 3 * vertex_count)
      throw SceneError(where, "<mesh> N needs 3 numbers per vertex");

    Mesh m;
    m.where = where;
    m.object_name = state.object;
    m.shader = state.shader;
    m.smooth = state.smooth;
    Vec3 lo(1e30f), hi(-1e30f);
    for (size_t i = 0; i < vertex_count; ++i) {
      const Vec3 p(raw.P[3 * i], raw.P[3 * i + 1], raw.P[3 * i + 2]);
      lo = min(lo, p);
      hi = max(hi, p);
    }
    const Vec3 extent = hi - lo;
    for (size_t i = 0; i < vertex_count; ++i) {
      const Vec3 p(raw.P[3 * i], raw.P[3 * i + 1], raw.P[3 * i + 2]);
      m.P.push_back(state.tfm.point(p));
      if (!is_finite(m.P.back()))
        throw SceneError(where, "<mesh> vertex " + std::to_string(i) +
                                    " is not finite after the transform (coordinates or scale overflow a float)");
      // Cycles' "generated" coordinates: object space normalised to the bounding box.
      m.generated.push_back(Vec3(extent.x > 0 ? (p.x - lo.x) / extent.x : 0.5f,
                                 extent.y > 0 ? (p.y - lo.y) / extent.y : 0.5f,
                                 extent.z > 0 ? (p.z - lo.z) / extent.z : 0.5f));
    }
    const bool flip = state.tfm.determinant() < 0.0f;
    size_t offset = 0;
    for (int n : raw.nverts) {
      for (int j = 1; j + 1 < n; ++j) {
        std::array<size_t, 3> c{offset, offset + j, offset + j + 1};
        if (flip) std::swap(c[1], c[2]);  // keep the geometric normal's side under mirroring
        m.triangles.push_back({static_cast<uint32_t>(raw.verts[c[0]]), static_cast<uint32_t>(raw.verts[c[1]]),
                               static_cast<uint32_t>(raw.verts[c[2]])});
        if (!raw.uv.empty()) {
          for (size_t k : c) {
            const size_t idx = uv_corner ? k : static_cast<size_t>(raw.verts[k]);
            m.uv.push_back({raw.uv[2 * idx], raw.uv[2 * idx + 1]});
          }
        }
      }
      offset += static_cast<size_t>(n);
    }
    if (m.smooth) {
      m.N.assign(vertex_count, Vec3(0.0f));
      if (!raw.N.empty()) {
        for (size_t i = 0; i < vertex_count; ++i)
          m.N[i] = normalize(state.tfm.normal(Vec3(raw.N[3 * i], raw.N[3 * i + 1], raw.N[3 * i + 2])));
      } else {
        // Area-weighted vertex normals, as Cycles computes them.
        for (const auto &t : m.triangles) {
          const Vec3 n = cross(m.P[t[1]] - m.P[t[0]], m.P[t[2]] - m.P[t[0]]);
          for (uint32_t v : t) m.N[v] += n;
        }
        for (auto &n : m.N) n = normalize(n);
      }
    }
    m.object_to_world = state.tfm;
    compute_uv_tangents(m);
    return m;
  }

  void read_light(const XmlFile &f, const pugi::xml_node &node, const ReadState &state) {
    const SourceLocation where = loc(f, node);
    Light l;
    read_settings(f, node, light_settings(), l);
    l.where = where;
    l.shader = state.shader;
    if (node.attribute("type") && !node.attribute("light_type"))
      warn(f, node, "<light> attribute 'type' read as 'light_type' (Cycles' socket name)");
    // Cycles 2.x XML gave area lights one `size`; used when sizeu/sizev are absent.
    if (l.type == LightType::Area) {
      const float size = read_float(f, node, "size", 1.0f);
      if (!node.attribute("sizeu")) l.sizeu = size;
      if (!node.attribute("sizev")) l.sizev = size;
    }
    if (!node.attribute("dir")) l.dir = -cross(l.axisu, l.axisv);
    Transform tfm = state.tfm;
    if (node.attribute("tfm")) {
      const auto v = floats(f, node, "tfm");
      if (v.size() != 12 && v.size() != 16) throw SceneError(where, "<light> tfm needs 12 (3x4) or 16 numbers");
      Transform m;
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c) m.m[r][c] = v[r * 4 + c];
      tfm = tfm * m;
    }
    l.co = tfm.point(l.co);
    l.dir = normalize(tfm.vector(l.dir));
    l.axisu = tfm.vector(l.axisu);
    l.axisv = tfm.vector(l.axisv);
    if ((l.type == LightType::Sun || l.type == LightType::Spot || l.type == LightType::Area) && is_zero(l.dir))
      throw SceneError(where, "<light> dir is zero");
    if (l.type == LightType::Area && length(cross(l.axisu, l.axisv)) * l.sizeu * l.sizev <= 0.0f)
      throw SceneError(where, "<light> area light has zero area (axisu/axisv/sizeu/sizev)");
    scene_.lights.push_back(l);
  }
};

}  // namespace

namespace {

Scene load(const std::string &path, const std::atomic<bool> *cancel, const std::string *text) {
  Scene scene;
  scene.path = path;
  scene.directory = fs::path(path).parent_path().string();
  Loader loader(scene);
  loader.cancel = cancel;
  try {
    if (text) loader.load_text(path, *text, ReadState{});
    else loader.load_file(path, nullptr, ReadState{});
  } catch (const std::bad_alloc &) {
    throw SceneError(path + ":0: out of memory while loading the scene");
  }
  return scene;
}

}  // namespace

Scene load_scene(const std::string &path, const std::atomic<bool> *cancel) { return load(path, cancel, nullptr); }

Scene load_scene_text(const std::string &text, const std::string &path) { return load(path, nullptr, &text); }

}  // namespace glimmer::scene
