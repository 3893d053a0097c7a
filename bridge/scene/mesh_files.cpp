#include "scene/mesh_files.h"

#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>

#include "scene/input_file.h"
#include "scene/parse_number.h"

namespace glimmer::scene {

namespace {

// Lines or elements read between two polls of the cancel flag.
constexpr size_t kCancelPollInterval = 4096;

void poll_cancel(const std::atomic<bool> *cancel, size_t counter, const std::string &path) {
  if (cancel && counter % kCancelPollInterval == 0 && cancel->load())
    throw LoadCancelled(path + ": loading interrupted");
}

// The next `count` whitespace-separated tokens of `s` as floats (strict).
template <size_t N>
bool read_floats(std::istringstream &s, float (&out)[N]) {
  std::string token;
  for (size_t i = 0; i < N; ++i) {
    if (!(s >> token)) return false;
    out[i] = parse_float(token);
  }
  return true;
}

RawMesh read_obj(std::istringstream &in, const std::string &path, const SourceLocation &where,
                 const std::atomic<bool> *cancel) {
  RawMesh m;
  std::vector<float> vt;
  std::string line;
  int line_no = 0;
  bool any_uv = false;
  std::vector<float> corner_uv;
  while (std::getline(in, line)) {
    ++line_no;
    poll_cancel(cancel, static_cast<size_t>(line_no), path);
    std::istringstream s(line);
    std::string tag;
    if (!(s >> tag) || tag[0] == '#') continue;
    auto bad = [&](const std::string &what) {
      return SceneError(where, path + ":" + std::to_string(line_no) + ": " + what);
    };
    try {
      if (tag == "v") {
        float xyz[3];
        if (!read_floats(s, xyz)) throw bad("vertex needs 3 numbers");
        m.P.insert(m.P.end(), xyz, xyz + 3);
      } else if (tag == "vt") {
        float uv[2];
        if (!read_floats(s, uv)) throw bad("texture coordinate needs 2 numbers");
        vt.insert(vt.end(), uv, uv + 2);
      } else if (tag == "f") {
        std::string corner;
        int n = 0;
        while (s >> corner) {
          // v, v/vt, v//vn or v/vt/vn: each index a whole integer (1-based, negative = from the end).
          const size_t slash = corner.find('/');
          int vi = parse_int(std::string_view(corner).substr(0, slash));
          int ti = 0;
          if (slash != std::string::npos) {
            const size_t slash2 = corner.find('/', slash + 1);
            const std::string_view t = std::string_view(corner).substr(
                slash + 1, slash2 == std::string::npos ? std::string::npos : slash2 - slash - 1);
            if (!t.empty()) ti = parse_int(t);
            if (slash2 != std::string::npos) parse_int(std::string_view(corner).substr(slash2 + 1));  // vn: checked, unused
          }
          const int vcount = static_cast<int>(m.P.size() / 3), tcount = static_cast<int>(vt.size() / 2);
          if (vi == 0) throw bad("face vertex index 0 (OBJ indices start at 1)");
          vi = vi < 0 ? vcount + vi : vi - 1;
          if (vi < 0 || vi >= vcount) throw bad("face vertex index out of range");
          m.verts.push_back(vi);
          if (ti != 0) {
            ti = ti < 0 ? tcount + ti : ti - 1;
            if (ti < 0 || ti >= tcount) throw bad("face texture index out of range");
            corner_uv.insert(corner_uv.end(), {vt[2 * ti], vt[2 * ti + 1]});
            any_uv = true;
          } else {
            corner_uv.insert(corner_uv.end(), {0.0f, 0.0f});
          }
          ++n;
        }
        if (n < 3) throw bad("face with fewer than 3 corners");
        m.nverts.push_back(n);
      }
    } catch (const NumberError &e) {
      throw bad(std::string("'") + tag + "' line: " + e.what());
    }
    // vn, o, g, s, usemtl, mtllib: ignored (normals are recomputed for smooth shading)
  }
  if (any_uv) m.uv = std::move(corner_uv);
  m.uv_per_corner = true;
  return m;
}

// Byte size of a PLY scalar type; 0 for an unknown type (float128, typos).
size_t ply_type_size(const std::string &type) {
  if (type == "char" || type == "int8" || type == "uchar" || type == "uint8") return 1;
  if (type == "short" || type == "int16" || type == "ushort" || type == "uint16") return 2;
  if (type == "int" || type == "int32" || type == "uint" || type == "uint32" || type == "float" || type == "float32")
    return 4;
  if (type == "double" || type == "float64") return 8;
  return 0;
}

bool ply_integer_type(const std::string &type) {
  return ply_type_size(type) != 0 && type.find("float") == std::string::npos && type != "double";
}

RawMesh read_ply(std::istringstream &in, const std::string &path, const SourceLocation &where,
                 const std::atomic<bool> *cancel) {
  auto bad = [&](const std::string &what) { return SceneError(where, path + ": PLY: " + what); };
  std::string line, format;
  struct Property { std::string name, type, count_type; bool list = false; };
  struct Element { std::string name; size_t count = 0; std::vector<Property> props; };
  std::vector<Element> elements;
  bool header_done = false;
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream s(line);
    std::string tag;
    s >> tag;
    if (tag == "format") s >> format;
    else if (tag == "element") {
      Element e;
      std::string count;
      if (!(s >> e.name >> count)) throw bad("element needs a name and a count");
      try {
        e.count = static_cast<size_t>(parse_integer(count, 0, std::numeric_limits<int32_t>::max()));
      } catch (const NumberError &err) {
        throw bad("element '" + e.name + "' count: " + err.what());
      }
      elements.push_back(e);
    } else if (tag == "property") {
      if (elements.empty()) throw bad("property before element");
      Property p;
      s >> p.type;
      if (p.type == "list") {
        p.list = true;
        s >> p.count_type >> p.type;
        if (!ply_integer_type(p.count_type)) throw bad("list count type '" + p.count_type + "' is not an integer type");
      }
      if (ply_type_size(p.type) == 0) throw bad("property type '" + p.type + "' not supported");
      if (!(s >> p.name)) throw bad("property without a name");
      elements.back().props.push_back(p);
    } else if (tag == "end_header") {
      header_done = true;
      break;
    }
  }
  if (!header_done) throw bad("no end_header");
  for (const auto &e : elements)
    if (e.props.empty() && e.count > 0) throw bad("element '" + e.name + "' has no properties");
  if (format != "ascii" && format != "binary_little_endian") throw bad("format '" + format + "' not supported");
  const bool ascii = format == "ascii";
  auto read_value = [&](const std::string &type) -> double {
    if (ascii) {
      std::string token;
      if (!(in >> token)) throw bad("truncated data");
      try {
        return parse_double(token);
      } catch (const NumberError &e) {
        throw bad(e.what());
      }
    }
    auto rd = [&](auto v) { in.read(reinterpret_cast<char *>(&v), sizeof(v)); if (!in) throw bad("truncated data"); return static_cast<double>(v); };
    if (type == "float" || type == "float32") return rd(float{});
    if (type == "double" || type == "float64") return rd(double{});
    if (type == "uchar" || type == "uint8") return rd(uint8_t{});
    if (type == "char" || type == "int8") return rd(int8_t{});
    if (type == "ushort" || type == "uint16") return rd(uint16_t{});
    if (type == "short" || type == "int16") return rd(int16_t{});
    if (type == "uint" || type == "uint32") return rd(uint32_t{});
    if (type == "int" || type == "int32") return rd(int32_t{});
    throw bad("property type '" + type + "' not supported");
  };
  RawMesh m;
  m.uv_per_corner = false;
  std::vector<float> uv;
  size_t items = 0;
  for (const auto &e : elements) {
    for (size_t i = 0; i < e.count; ++i) {
      poll_cancel(cancel, ++items, path);
      float xyz[3] = {0, 0, 0}, n[3] = {0, 0, 0}, t[2] = {0, 0};
      bool has_n = false, has_t = false;
      for (const auto &p : e.props) {
        if (p.list) {
          const double list_length = read_value(p.count_type);
          if (!(list_length >= 0.0 && list_length <= (1 << 20)) || list_length != std::floor(list_length))
            throw bad("bad list length");
          const int count = static_cast<int>(list_length);
          for (int k = 0; k < count; ++k) {
            const double v = read_value(p.type);
            if (e.name == "face" && (p.name == "vertex_indices" || p.name == "vertex_index")) {
              if (v != std::floor(v) || v < 0.0 || v > std::numeric_limits<int>::max())
                throw bad("face vertex index " + std::to_string(v) + " is not a non-negative integer");
              m.verts.push_back(static_cast<int>(v));
            }
          }
          if (e.name == "face" && (p.name == "vertex_indices" || p.name == "vertex_index")) {
            if (count < 3) throw bad("face with fewer than 3 corners");
            m.nverts.push_back(count);
          }
          continue;
        }
        const double value = read_value(p.type);
        if (std::fabs(value) > std::numeric_limits<float>::max()) throw bad("value overflows a 32-bit float");
        const float v = static_cast<float>(value);
        if (e.name != "vertex") continue;
        if (p.name == "x") xyz[0] = v; else if (p.name == "y") xyz[1] = v; else if (p.name == "z") xyz[2] = v;
        else if (p.name == "nx") { n[0] = v; has_n = true; } else if (p.name == "ny") n[1] = v; else if (p.name == "nz") n[2] = v;
        else if (p.name == "u" || p.name == "s" || p.name == "texture_u") { t[0] = v; has_t = true; }
        else if (p.name == "v" || p.name == "t" || p.name == "texture_v") t[1] = v;
      }
      if (e.name == "vertex") {
        m.P.insert(m.P.end(), xyz, xyz + 3);
        if (has_n) m.N.insert(m.N.end(), n, n + 3);
        if (has_t) uv.insert(uv.end(), t, t + 2);
      }
    }
  }
  if (uv.size() == 2 * (m.P.size() / 3)) m.uv = std::move(uv);
  if (m.N.size() != m.P.size()) m.N.clear();
  return m;
}

}  // namespace

namespace {

enum class MeshFormat { Obj, Ply };

MeshFormat mesh_format(const std::string &path, const SourceLocation &where) {
  const auto dot = path.rfind('.');
  const std::string ext = dot == std::string::npos ? "" : path.substr(dot + 1);
  if (ext == "obj" || ext == "OBJ") return MeshFormat::Obj;
  if (ext == "ply" || ext == "PLY") return MeshFormat::Ply;
  throw SceneError(where, "<mesh> src '" + path + "': only .obj and .ply files are supported");
}

}  // namespace

RawMesh parse_mesh_text(const std::string &text, const std::string &path, const SourceLocation &where,
                        const std::atomic<bool> *cancel) {
  const MeshFormat format = mesh_format(path, where);
  std::istringstream in(text);
  return format == MeshFormat::Obj ? read_obj(in, path, where, cancel) : read_ply(in, path, where, cancel);
}

RawMesh read_mesh_file(const std::string &path, const SourceLocation &where, const std::atomic<bool> *cancel) {
  mesh_format(path, where);  // the extension is checked before the file is read
  std::string text;
  try {
    text = read_regular_file(path, kMaxMeshFileBytes, "<mesh> src");
  } catch (const InputFileError &e) {
    throw SceneError(where, e.what());
  }
  return parse_mesh_text(text, path, where, cancel);
}

}  // namespace glimmer::scene
