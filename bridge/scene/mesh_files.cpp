#include "scene/mesh_files.h"

#include <cstring>
#include <fstream>
#include <sstream>

namespace glimmer::scene {

namespace {

RawMesh read_obj(std::ifstream &in, const std::string &path, const SourceLocation &where) {
  RawMesh m;
  std::vector<float> vt;
  std::string line;
  int line_no = 0;
  bool any_uv = false;
  std::vector<float> corner_uv;
  while (std::getline(in, line)) {
    ++line_no;
    std::istringstream s(line);
    std::string tag;
    if (!(s >> tag) || tag[0] == '#') continue;
    auto bad = [&](const std::string &what) {
      return SceneError(where, path + ":" + std::to_string(line_no) + ": " + what);
    };
    if (tag == "v") {
      float x, y, z;
      if (!(s >> x >> y >> z)) throw bad("bad vertex");
      m.P.insert(m.P.end(), {x, y, z});
    } else if (tag == "vt") {
      float u, v;
      if (!(s >> u >> v)) throw bad("bad texture coordinate");
      vt.insert(vt.end(), {u, v});
    } else if (tag == "f") {
      std::string corner;
      int n = 0;
      while (s >> corner) {
        int vi = 0, ti = 0;
        char *end = nullptr;
        vi = static_cast<int>(std::strtol(corner.c_str(), &end, 10));
        if (end == corner.c_str()) throw bad("bad face corner '" + corner + "'");
        if (*end == '/' && end[1] != '/' && end[1] != '\0') ti = static_cast<int>(std::strtol(end + 1, nullptr, 10));
        const int vcount = static_cast<int>(m.P.size() / 3), tcount = static_cast<int>(vt.size() / 2);
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
    // vn, o, g, s, usemtl, mtllib: ignored (normals are recomputed for smooth shading)
  }
  if (any_uv) m.uv = std::move(corner_uv);
  m.uv_per_corner = true;
  return m;
}

RawMesh read_ply(std::ifstream &in, const std::string &path, const SourceLocation &where) {
  auto bad = [&](const std::string &what) { return SceneError(where, path + ": PLY: " + what); };
  std::string line, format;
  struct Property { std::string name, type, count_type; bool list = false; };
  struct Element { std::string name; size_t count = 0; std::vector<Property> props; };
  std::vector<Element> elements;
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream s(line);
    std::string tag;
    s >> tag;
    if (tag == "format") s >> format;
    else if (tag == "element") { Element e; s >> e.name >> e.count; elements.push_back(e); }
    else if (tag == "property") {
      if (elements.empty()) throw bad("property before element");
      Property p;
      s >> p.type;
      if (p.type == "list") { p.list = true; s >> p.count_type >> p.type; }
      s >> p.name;
      elements.back().props.push_back(p);
    } else if (tag == "end_header") break;
  }
  if (format != "ascii" && format != "binary_little_endian") throw bad("format '" + format + "' not supported");
  const bool ascii = format == "ascii";
  auto read_value = [&](const std::string &type) -> double {
    if (ascii) { double v; if (!(in >> v)) throw bad("truncated data"); return v; }
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
  for (const auto &e : elements) {
    for (size_t i = 0; i < e.count; ++i) {
      float xyz[3] = {0, 0, 0}, n[3] = {0, 0, 0}, t[2] = {0, 0};
      bool has_n = false, has_t = false;
      for (const auto &p : e.props) {
        if (p.list) {
          const int count = static_cast<int>(read_value(p.count_type));
          if (count < 0 || count > 1 << 20) throw bad("bad list length");
          for (int k = 0; k < count; ++k) {
            const double v = read_value(p.type);
            if (e.name == "face" && (p.name == "vertex_indices" || p.name == "vertex_index"))
              m.verts.push_back(static_cast<int>(v));
          }
          if (e.name == "face" && (p.name == "vertex_indices" || p.name == "vertex_index")) {
            if (count < 3) throw bad("face with fewer than 3 corners");
            m.nverts.push_back(count);
          }
          continue;
        }
        const float v = static_cast<float>(read_value(p.type));
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

RawMesh read_mesh_file(const std::string &path, const SourceLocation &where) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw SceneError(where, "<mesh> cannot open '" + path + "'");
  const auto dot = path.rfind('.');
  const std::string ext = dot == std::string::npos ? "" : path.substr(dot + 1);
  if (ext == "obj" || ext == "OBJ") return read_obj(in, path, where);
  if (ext == "ply" || ext == "PLY") return read_ply(in, path, where);
  throw SceneError(where, "<mesh> src '" + path + "': only .obj and .ply files are supported");
}

}  // namespace glimmer::scene
