#include "render/nodes/node_program.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <map>
#include <set>

#include "scene/transform.h"
#include "scene/xml_loader.h"

namespace glimmer::render::nodes {

using scene::SceneError;
using scene::ShaderGraph;
using scene::ShaderLink;
using scene::ShaderNode;

std::string socket_key(const std::string &name) {
  std::string out;
  for (unsigned char c : name)
    if (c != '_' && c != ' ') out += static_cast<char>(std::tolower(c));
  return out;
}

namespace {

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

// Inverse of an affine 3x4 row-major transform (zero when singular).
std::array<float, 12> affine_inverse(const std::array<float, 12> &m) {
  scene::Transform t, inverse;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) t.m[r][c] = m[4 * r + c];
  std::array<float, 12> out{};
  if (!t.inverse(inverse)) return out;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) out[4 * r + c] = inverse.m[r][c];
  return out;
}

std::string socket_list(const std::vector<SocketDecl> &sockets) {
  std::string out;
  for (const auto &s : sockets) out += (out.empty() ? "" : ", ") + std::string(s.name);
  return out.empty() ? "none" : out;
}

int find_socket(const std::vector<SocketDecl> &sockets, const std::string &name) {
  const std::string key = socket_key(name);
  for (size_t i = 0; i < sockets.size(); ++i)
    if (socket_key(sockets[i].name) == key) return static_cast<int>(i);
  return -1;
}

// A node's attributes as settings; remembers which ones were read.
class AttributeReader final : public SettingsReader {
 public:
  AttributeReader(const ShaderNode &n, const BuildHooks &hooks) : n_(n), hooks_(hooks) {}
  int choice(const char *attribute, std::initializer_list<const char *> choices, int fallback) const override {
    const std::string *v = get(attribute);
    if (!v) return fallback;
    const std::string value = lower(*v);
    int i = 0;
    std::string names;
    for (const char *c : choices) {
      if (value == c) return i;
      names += (i++ ? ", " : "") + std::string(c);
    }
    fail(std::string(attribute) + " '" + *v + "' is not one of: " + names);
  }
  bool boolean(const char *attribute, bool fallback) const override {
    const std::string *v = get(attribute);
    if (!v) return fallback;
    const std::string value = lower(*v);
    if (value == "true" || value == "1") return true;
    if (value == "false" || value == "0") return false;
    fail(std::string(attribute) + " '" + *v + "' is not a boolean (true/false)");
  }
  std::vector<float> floats(const char *attribute) const override {
    const std::string *v = get(attribute);
    if (!v) return {};
    return scene::parse_floats(*v, n_.where, "<" + n_.type + "> " + attribute);
  }
  std::string text(const char *attribute) const override {
    const std::string *v = get(attribute);
    return v ? *v : std::string();
  }
  void warn(const std::string &message) const override { hooks_.warn(n_.where, "<" + n_.type + "> " + message); }
  [[noreturn]] void fail(const std::string &message) const override {
    throw SceneError(n_.where, "<" + n_.type + "> '" + n_.name + "': " + message);
  }
  const std::set<std::string> &read() const { return read_; }

 private:
  const std::string *get(const char *attribute) const {
    read_.insert(attribute);
    auto it = n_.attributes.find(attribute);
    return it == n_.attributes.end() ? nullptr : &it->second;
  }
  const ShaderNode &n_;
  const BuildHooks &hooks_;
  mutable std::set<std::string> read_;
};

}  // namespace

class ProgramBuilder {
 public:
  ProgramBuilder(const ShaderGraph &g, const BuildHooks &hooks) : g_(g), hooks_(hooks) {}

  NodeProgram build(const ShaderLink &link) {
    program_.world_to_camera_ = affine_inverse(hooks_.camera_to_world);
    program_.result_ = output_operand(link, SocketType::Color);
    return std::move(program_);
  }

 private:
  const ShaderGraph &g_;
  const BuildHooks &hooks_;
  NodeProgram program_;
  std::map<std::pair<std::string, int>, int> step_of_;  // (node name, offset point) -> step

  // The operand reading the output `link` comes from, converted to `to`, evaluated at offset point `at`.
  Operand output_operand(const ShaderLink &link, SocketType to, int at = 0) {
    const ShaderNode *src = g_.find(link.from_node);
    Operand o;
    o.to = to;
    const NodeDef *def = find_node(src->type);
    if (!def) {
      SocketType type = SocketType::Color;
      const int id = hooks_.external(link, type);
      if (id < 0) {
        o.kind = Operand::Kind::Constant;
        o.index = -1;  // unsupported source: the caller keeps the socket's constant
        return o;
      }
      o.kind = Operand::Kind::External;
      o.index = id;
      o.from = type;
      return o;
    }
    const int output = find_socket(def->outputs, link.from_socket);
    if (output < 0)
      throw SceneError(link.where, "<connect> from unknown socket '" + link.from_socket + "' of node '" + src->name +
                                       "' (" + src->type + ") in shader '" + g_.name +
                                       "'; its outputs: " + socket_list(def->outputs));
    if (const char *caveat = def->outputs[output].caveat)
      hooks_.warn(link.where, "<" + src->type + "> output '" + def->outputs[output].name + "': " + caveat);
    const int step = compile_node(*src, *def, at);
    o.kind = Operand::Kind::Register;
    o.index = program_.steps_[step].out_base + output;
    o.from = def->outputs[output].type;
    return o;
  }

  int compile_node(const ShaderNode &n, const NodeDef &def, int at) {
    if (auto it = step_of_.find({n.name, at}); it != step_of_.end()) return it->second;
    NodeProgram::Step step;
    step.def = &def;
    step.at = static_cast<uint8_t>(at);
    if (at != 0) program_.offsets_ = true;
    AttributeReader reader(n, hooks_);
    if (def.configure) def.configure(reader, step.settings);
    if (&def == find_node("texture_coordinate")) program_.reads_camera_ = true;
    // Links into this node must name its inputs.
    for (const auto &l : g_.links)
      if (l.to_node == n.name && find_socket(def.inputs, l.to_socket) < 0)
        throw SceneError(l.where, "<connect> to unknown socket '" + l.to_socket + "' of node '" + n.name + "' (" +
                                      n.type + ") in shader '" + g_.name + "'; its inputs: " + socket_list(def.inputs));
    std::set<std::string> known = reader.read();
    for (const SocketDecl &in : def.inputs) {
      known.insert(in.name);
      step.inputs.push_back(input_operand(n, in, at));
    }
    if (def.offset_input >= 0) {  // Bump: the height one footprint step along x and along y
      step.inputs.push_back(input_operand(n, def.inputs[def.offset_input], 1));
      step.inputs.push_back(input_operand(n, def.inputs[def.offset_input], 2));
    }
    for (const auto &[name, value] : n.attributes)
      if (!known.count(name)) hooks_.warn(n.where, "<" + n.type + "> attribute '" + name + "' is not supported; ignored");
    if (program_.registers_ + static_cast<int>(def.outputs.size()) > NodeProgram::kMaxRegisters)
      throw SceneError(n.where, "shader '" + g_.name + "': more than " + std::to_string(NodeProgram::kMaxRegisters) +
                                    " node outputs feed one input");
    step.out_base = program_.registers_;
    program_.registers_ += static_cast<int>(def.outputs.size());
    program_.steps_.push_back(std::move(step));
    const int index = static_cast<int>(program_.steps_.size()) - 1;
    step_of_[{n.name, at}] = index;
    return index;
  }

  Operand input_operand(const ShaderNode &n, const SocketDecl &in, int at) {
    Operand constant;
    constant.kind = Operand::Kind::Constant;
    constant.value = in.default_value;
    auto attribute = std::find_if(n.attributes.begin(), n.attributes.end(),
                                  [&](const auto &a) { return socket_key(a.first) == socket_key(in.name); });
    if (attribute != n.attributes.end()) {
      const auto v = scene::parse_floats(attribute->second, n.where, "<" + n.type + "> " + in.name);
      if (v.size() == 1) constant.value = Vec3(v[0]);
      else if (v.size() == 3 && in.type != SocketType::Float) constant.value = Vec3(v[0], v[1], v[2]);
      else
        throw SceneError(n.where, "<" + n.type + "> " + in.name + ": expected " +
                                      (in.type == SocketType::Float ? "1 number" : "1 or 3 numbers"));
    }
    const ShaderLink *link = nullptr;
    for (const auto &l : g_.links)
      if (l.to_node == n.name && socket_key(l.to_socket) == socket_key(in.name)) link = &l;
    if (link) {
      Operand o = output_operand(*link, in.type, at);
      if (!(o.kind == Operand::Kind::Constant && o.index < 0)) return o;
    } else if (in.implicit != Implicit::None && attribute == n.attributes.end()) {
      Operand o;
      o.kind = Operand::Kind::Implicit;
      o.implicit = in.implicit;
      o.from = o.to = SocketType::Vector;
      return o;
    }
    return constant;
  }
};

std::vector<SunDisc> NodeProgram::sun_discs() const {
  std::vector<SunDisc> suns;
  for (const Step &s : steps_)
    if (s.settings.sky && s.settings.sky->has_sun_disc() && s.inputs[0].kind == Operand::Kind::Implicit)
      suns.push_back(s.settings.sky->sun_disc());
  return suns;
}

NodeProgram compile_program(const ShaderGraph &g, const ShaderLink &link, const BuildHooks &hooks) {
  return ProgramBuilder(g, hooks).build(link);
}

}  // namespace glimmer::render::nodes
