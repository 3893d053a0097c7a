#include "render/shader_system.h"

#include <algorithm>
#include <filesystem>

#include "render/principled.h"
#include "scene/xml_loader.h"

namespace glimmer::render {

using scene::SceneError;
using scene::ShaderGraph;
using scene::ShaderNode;

namespace {

bool is_volume_node(const std::string &type) {
  return type.find("volume") != std::string::npos;
}

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

// Cycles' distribution names -> the DSO enum "ggx|beckmann|multi_ggx|sharp".
std::string map_distribution(const std::string &value, bool &approximated) {
  const std::string v = lower(value);
  approximated = false;
  if (v == "ggx") return "ggx";
  if (v == "beckmann") return "beckmann";
  if (v == "sharp") return "sharp";
  if (v == "multi_ggx" || v == "multiscatter_ggx" || v == "multiscatter ggx" || v == "multi-ggx") return "multi_ggx";
  approximated = true;  // ashikhmin_shirley and unknown names
  return "ggx";
}

}  // namespace

ShaderSystem::ShaderSystem(const scene::Scene &scene, const host::PluginLibrary &plugin,
                           const GlimmerHostServices *host, std::vector<std::string> &warnings,
                           FeatureSet &features)
    : scene_(scene), plugin_(plugin), host_(host), warnings_(warnings), features_(features) {}

void ShaderSystem::warn(const scene::SourceLocation &where, const std::string &message) {
  const std::string line = where.str() + ": warning: " + message;
  if (std::find(warnings_.begin(), warnings_.end(), line) == warnings_.end()) warnings_.push_back(line);
}

const host::ClosureInstance *ShaderSystem::instantiate(const GlimmerClosureType &type, const host::ParamList &params,
                                                       const scene::SourceLocation &where) {
  try {
    instances_.push_back(std::make_unique<host::ClosureInstance>(type, params, host_));
  } catch (const host::ClosureError &e) {
    throw SceneError(where, e.what());
  }
  features_.closures.insert(type.name);
  return instances_.back().get();
}

const ImageTexture *ShaderSystem::load_image(const ShaderNode &n) {
  auto it = n.attributes.find("filename");
  if (it == n.attributes.end() || it->second.empty()) {
    warn(n.where, "<" + n.type + "> has no filename; it reads as black");
    return nullptr;
  }
  std::filesystem::path path(it->second);
  if (path.is_relative()) path = std::filesystem::path(n.where.file).parent_path() / path;
  const std::string key = path.lexically_normal().string();
  auto found = images_.find(key);
  if (found != images_.end()) return found->second.get();
  if (!std::filesystem::exists(path)) throw SceneError(n.where, "<" + n.type + "> image not found: '" + key + "'");
  bool linear = false;
  if (auto cs = n.attributes.find("colorspace"); cs != n.attributes.end()) {
    const std::string c = lower(cs->second);
    linear = c == "non-color" || c == "raw" || c == "linear" || c == "__builtin_raw";
  }
  try {
    images_[key] = ImageTexture::load(key, linear);
  } catch (const std::exception &e) {
    throw SceneError(n.where, e.what());
  }
  features_.textures.insert(key);
  return images_[key].get();
}

Spectrum ShaderSystem::read_constant(const ShaderNode &n, const std::string &socket, const std::string *text,
                                     Spectrum fallback) {
  if (!text) return fallback;
  const auto v = scene::parse_floats(*text, n.where, "<" + n.type + "> " + socket);
  if (v.size() == 1) return Spectrum(v[0]);
  if (v.size() >= 3) return Spectrum(v[0], v[1], v[2]);
  throw SceneError(n.where, "<" + n.type + "> " + socket + ": expected 1 or 3 numbers");
}

Input ShaderSystem::read_input(const ShaderGraph &g, const ShaderNode &n, const std::string &socket, Spectrum fallback,
                               VectorSource default_vector) {
  Input in;
  const auto it = n.attributes.find(socket);
  in.constant = read_constant(n, socket, it != n.attributes.end() ? &it->second : nullptr, fallback);
  const scene::ShaderLink *link = g.link_to(n.name, socket);
  if (!link) return in;
  const ShaderNode *src = g.find(link->from_node);
  TextureNode tex;
  const std::string &type = src->type;
  if (type == "checker_texture") {
    tex.kind = TextureNode::Kind::Checker;
    tex.color1 = read_input(g, *src, "color1", Spectrum(0.8f), default_vector).constant;
    tex.color2 = read_input(g, *src, "color2", Spectrum(0.2f), default_vector).constant;
    tex.scale = read_input(g, *src, "scale", Spectrum(5.0f), default_vector).constant.x;
    tex.vector = VectorSource::Generated;
    if (g.link_to(src->name, "color1") || g.link_to(src->name, "color2") || g.link_to(src->name, "scale"))
      warn(src->where, "checker_texture: linked color1/color2/scale inputs are not supported; their constants are used");
  } else if (type == "image_texture" || type == "environment_texture") {
    tex.kind = type == "image_texture" ? TextureNode::Kind::Image : TextureNode::Kind::Environment;
    tex.vector = type == "image_texture" ? VectorSource::UV : VectorSource::Direction;
    tex.image = load_image(*src);
    if (auto it = src->attributes.find("interpolation"); it != src->attributes.end()) {
      const std::string mode = lower(it->second);
      tex.closest = mode == "closest";
      if (mode != "closest" && mode != "linear")
        warn(src->where, type + ": interpolation '" + it->second + "' is not supported; linear is used");
    }
    if (auto p = src->attributes.find("projection"); p != src->attributes.end() && lower(p->second) != "equirectangular" &&
                                                      lower(p->second) != "flat")
      warn(src->where, type + ": projection '" + p->second + "' is not supported; equirectangular/flat is used");
  } else if (nodes::find_node(type)) {
    in.program = compile_program(g, *link);
    return in;
  } else {
    warn(src->where, "node <" + type + "> is not supported; input '" + socket + "' of '" + n.name +
                         "' uses its constant value instead of this link");
    return in;
  }
  // A texture_coordinate node on the vector input picks the coordinates; other table nodes run as a program.
  if (const scene::ShaderLink *vlink = g.link_to(src->name, "vector")) {
    const ShaderNode *vn = g.find(vlink->from_node);
    const std::string s = lower(vlink->from_socket);
    if (vn->type != "texture_coordinate" && nodes::find_node(vn->type)) {
      tex.vector_program = compile_program(g, *vlink);
    } else if (vn->type == "texture_coordinate" && (s == "uv" || s == "generated" || s == "object" || s == "normal")) {
      tex.vector = s == "uv" ? VectorSource::UV
                   : s == "generated" ? VectorSource::Generated
                   : s == "object" ? VectorSource::Object
                                   : VectorSource::Normal;
    } else {
      warn(vlink->where, "vector input from <" + vn->type + "> '" + vlink->from_socket +
                             "' is not supported; the texture's default coordinates are used");
    }
  }
  const std::string out = lower(link->from_socket);
  in.fac_output = out == "fac" || out == "alpha";
  in.texture = static_cast<int>(textures_.size());
  textures_.push_back(tex);
  return in;
}

bool ShaderSystem::bind_varying(ClosureLeaf &leaf, const ShaderGraph &g, const ShaderNode &n, const std::string &socket,
                                const std::string &param) {
  const scene::ShaderLink *link = g.link_to(n.name, socket);
  if (!link) return false;
  const GlimmerParamSpec *spec = leaf.type ? host::find_param(*leaf.type, param) : nullptr;
  if (!spec || !(host::param_flags(*leaf.type, *spec) & GLIMMER_PARAM_VARYING) ||
      leaf.varying.size() >= static_cast<size_t>(ClosureLeaf::kMaxVarying)) {
    warn(link->where, "<" + n.type + "> linked input '" + socket + "' is not supported (closure '" +
                          (leaf.type ? leaf.type->name : "?") + "' has no varying parameter '" + param +
                          "'); its constant value is used");
    return false;
  }
  const Spectrum fallback(spec->default_value[0], spec->default_value[1], spec->default_value[2]);
  ClosureLeaf::VaryingInput v;
  v.input = read_input(g, n, socket, fallback, VectorSource::Generated);
  if (!v.input.varies()) return false;  // read_input warned: an unsupported source node
  v.param = host::param_index(*leaf.type, *spec);
  v.color = spec->type == GLIMMER_PARAM_COLOR || spec->type == GLIMMER_PARAM_VECTOR;
  if (param == "roughness") leaf.varying_roughness = static_cast<int>(leaf.varying.size());
  leaf.varying.push_back(v);
  return true;
}

void ShaderSystem::warn_unsupported_links(const ShaderGraph &g, const ShaderNode &n,
                                          std::initializer_list<const char *> supported) {
  for (const auto &l : g.links) {
    if (l.to_node != n.name) continue;
    if (std::any_of(supported.begin(), supported.end(), [&](const char *s) { return l.to_socket == s; })) continue;
    warn(l.where, "<" + n.type + "> linked input '" + l.to_socket + "' is not supported; its constant value is used");
  }
}

int ShaderSystem::compile_program(const ShaderGraph &g, const scene::ShaderLink &link) {
  nodes::BuildHooks hooks;
  hooks.warn = [this](const scene::SourceLocation &where, const std::string &message) { warn(where, message); };
  hooks.external = [&](const scene::ShaderLink &l, nodes::SocketType &type) {
    const Input in = read_input(g, *g.find(l.to_node), l.to_socket, Spectrum(0.0f), VectorSource::Generated);
    if (!in.varies()) return -1;
    type = in.fac_output ? nodes::SocketType::Float : nodes::SocketType::Color;
    program_externals_.push_back(in);
    return static_cast<int>(program_externals_.size()) - 1;
  };
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) hooks.camera_to_world[4 * r + c] = scene_.camera.camera_to_world.m[r][c];
  programs_.push_back(nodes::compile_program(g, link, hooks));
  return static_cast<int>(programs_.size()) - 1;
}

Spectrum ShaderSystem::eval_input(const Input &in, const TexCoords &tc) const {
  if (in.program >= 0)
    return programs_[in.program].eval(
        tc, [this](int id, const TexCoords &at) { return eval_input(program_externals_[id], at); });
  if (in.texture < 0) return in.constant;
  const TextureNode &t = textures_[in.texture];
  Vec3 co;
  switch (t.vector) {
    case VectorSource::UV: co = Vec3(tc.uv[0], tc.uv[1], 0.0f); break;
    case VectorSource::Generated: co = tc.generated; break;
    case VectorSource::Object: co = tc.P; break;
    case VectorSource::Normal: co = tc.N; break;
    case VectorSource::Direction: co = tc.direction; break;
  }
  if (t.vector_program >= 0) co = eval_input(Input{Spectrum(0.0f), -1, false, t.vector_program}, tc);
  switch (t.kind) {
    case TextureNode::Kind::Checker: {
      const float f = checker(co * t.scale);
      if (in.fac_output) return Spectrum(f);
      return f == 1.0f ? t.color1 : t.color2;
    }
    case TextureNode::Kind::Image:
    case TextureNode::Kind::Environment: {
      if (!t.image) return Spectrum(0.0f);
      float u = co.x, v = co.y;
      if (t.kind == TextureNode::Kind::Environment || t.vector == VectorSource::Direction)
        direction_to_equirectangular(normalize(co), u, v);
      float rgba[4];
      t.image->lookup(u, v, rgba, t.closest);
      if (in.fac_output) return Spectrum(rgba[3]);
      return {rgba[0], rgba[1], rgba[2]};
    }
  }
  return in.constant;
}

// A node's closure row: the table's, or the schema of the DSO closure the node names
// (`name` or `name_bsdf`); nullptr when neither knows the node.
const ClosureNodeRow *ShaderSystem::row_for(const std::string &node_type, ClosureNodeRow &storage) {
  const ClosureNodeRow *row = find_closure_node(node_type);
  if (row && !row->schema) return row;
  const GlimmerClosureType *type = row ? plugin_.find(row->closure) : plugin_.find(node_type);
  if (!type && !row && node_type.size() > 5 && node_type.substr(node_type.size() - 5) == "_bsdf")
    type = plugin_.find(node_type.substr(0, node_type.size() - 5));
  if (!type) return nullptr;
  storage = schema_row(*type, row ? row->node : node_type.c_str());
  return &storage;
}

// The socket's attribute (or its alias's when the socket has none), for constants.
const std::string *ShaderSystem::attribute_of(const ShaderNode &n, const SocketRow &s) {
  if (auto it = n.attributes.find(s.socket); it != n.attributes.end()) return &it->second;
  if (s.alias)
    if (auto it = n.attributes.find(s.alias); it != n.attributes.end()) return &it->second;
  return nullptr;
}

// Attributes that are no socket of the row: a schema row hands them to the DSO (which
// names the unknown parameter in an error); a table row warns and ignores them.
void ShaderSystem::check_attributes(const ShaderNode &n, const ClosureNodeRow &row, const GlimmerClosureType *type,
                                    host::ParamList &params) {
  for (const auto &attribute : n.attributes) {
    const std::string &name = attribute.first;
    if (row.find(name) || (row.distribution && name == "distribution")) continue;
    if (!row.schema || !type) {
      warn(n.where, "<" + n.type + "> attribute '" + name + "' is not supported; ignored");
      continue;
    }
    try {
      params.set_from_text(*type, name, attribute.second);
    } catch (const host::ClosureError &e) {
      throw SceneError(n.where, "<" + n.type + ">: " + e.what());
    }
  }
}

// The one loop over a row's sockets: weight, strength and constant parameters.
// Returns the constant roughness (for sharp/filter_glossy), or -1 without one.
float ShaderSystem::apply_sockets(const ShaderGraph &g, const ShaderNode &n, const ClosureNodeRow &row,
                                  const GlimmerClosureType *type, ClosureLeaf &leaf, host::ParamList &params) {
  float roughness = -1.0f;
  for (const SocketRow &s : row.sockets) {
    const std::string *text = attribute_of(n, s);
    const bool linked = g.link_to(n.name, s.socket) != nullptr;
    switch (s.role) {
      case SocketRole::Weight:
        leaf.weight = read_input(g, n, s.socket, Spectrum(s.default_value), VectorSource::Generated);
        break;
      case SocketRole::Strength:
        leaf.strength = read_constant(n, s.socket, text, Spectrum(s.default_value)).x;
        break;
      case SocketRole::Param: {
        const float value = std::clamp(read_constant(n, s.socket, text, Spectrum(s.default_value)).x, s.min, s.max);
        if (type && host::find_param(*type, s.param)) params.set_number(s.param, value, 0, 0);
        if (std::string(s.param) == "roughness") roughness = value;
        break;
      }
      case SocketRole::ParamOrWeight:
        if (linked) {
          leaf.weight = read_input(g, n, s.socket, Spectrum(1.0f), VectorSource::Generated);
          leaf.weight.constant = Spectrum(1.0f);
          params.set_number(s.param, 1, 1, 1);
          break;
        }
        [[fallthrough]];
      case SocketRole::SchemaParam:
        if (text && !linked) {
          try {
            params.set_from_text(*type, s.param, *text);
          } catch (const host::ClosureError &e) {
            throw SceneError(n.where, "<" + n.type + ">: " + e.what());
          }
        }
        break;
      case SocketRole::Unsupported:
        if (text) {
          const auto v = scene::parse_floats(*text, n.where, "<" + n.type + "> " + s.socket);
          if (!v.empty() && v[0] != s.default_value) warn(n.where, n.type + ": " + s.note);
        }
        break;
      case SocketRole::Ignored:
        break;
    }
  }
  return roughness;
}

// Every link into the node: a parameter socket is bound per shading point (or warns
// when the closure cannot vary it); weight sockets were read with their texture;
// any other linked socket renders with its constant and warns at the <connect>.
void ShaderSystem::bind_links(const ShaderGraph &g, const ShaderNode &n, const ClosureNodeRow &row, ClosureLeaf &leaf) {
  for (const auto &l : g.links) {
    if (l.to_node != n.name) continue;
    const SocketRow *s = row.find(l.to_socket);
    const SocketRole role = s ? s->role : SocketRole::Ignored;
    if (role == SocketRole::Weight || role == SocketRole::ParamOrWeight) continue;
    if (role == SocketRole::Param || role == SocketRole::SchemaParam) {
      const GlimmerParamSpec *spec = leaf.type ? host::find_param(*leaf.type, s->param) : nullptr;
      const bool bound = spec && std::any_of(leaf.varying.begin(), leaf.varying.end(), [&](const auto &v) {
        return v.param == host::param_index(*leaf.type, *spec);
      });
      if (!bound) bind_varying(leaf, g, n, l.to_socket, s->param);
      continue;
    }
    warn(l.where, "<" + n.type + "> linked input '" + l.to_socket + "' is not supported; its constant value is used");
  }
}

// `distribution` (Cycles' names) and the sharp closure for an unlinked roughness of 0;
// returns the distribution set.
std::string ShaderSystem::apply_distribution(const ShaderGraph &g, const ShaderNode &n, const GlimmerClosureType &type,
                                             float roughness, host::ParamList &params) {
  bool approx = false;
  std::string distribution = "ggx";
  if (auto d = n.attributes.find("distribution"); d != n.attributes.end()) {
    distribution = map_distribution(d->second, approx);
    if (approx) warn(n.where, n.type + ": distribution '" + d->second + "' is not supported; GGX is used");
  }
  // Cycles (GlossyBsdfNode/GlassBsdfNode::simplify_settings): an unlinked roughness of 0 is the sharp closure.
  if (roughness <= 1e-4f && !g.link_to(n.name, "roughness")) distribution = "sharp";
  if (host::find_param(type, "distribution")) params.set_string("distribution", distribution);
  return distribution;
}

// Cycles' Multiscatter GGX tints every bounce of its walk by the colour; the
// weight applies it once, the closure the remaining powers (bounce_tint).
void ShaderSystem::apply_bounce_tint(const ShaderNode &n, const GlimmerClosureType &type, const ClosureLeaf &leaf,
                                     host::ParamList &params) {
  if (!host::find_param(type, "bounce_tint")) return;
  if (leaf.weight.varies()) {
    warn(n.where, n.type + ": a textured colour with multi_ggx tints the multiple-scattering energy once "
                           "(Cycles tints each bounce); the walk's higher bounces are not darkened");
    return;
  }
  const Spectrum c = leaf.weight.constant;
  params.set_number("bounce_tint", std::clamp(c.x, 0.0f, 1.0f), std::clamp(c.y, 0.0f, 1.0f),
                    std::clamp(c.z, 0.0f, 1.0f));
}

// filter_glossy: variants with alpha >= kBlurStep * k, created only when the scene sets it.
void ShaderSystem::make_blurred_variants(const ShaderNode &n, const GlimmerClosureType &type,
                                         const std::string &distribution, float roughness,
                                         const host::ParamList &params, ClosureLeaf &leaf) {
  if (!(scene_.integrator.filter_glossy > 0.0f) || !host::find_param(type, "roughness")) return;
  // Cycles' bsdf_blur raises alpha to the blur roughness; alpha = roughness^2 here.
  leaf.blurred.assign(ClosureLeaf::kBlurLevels + 1, leaf.instance);
  for (int k = 1; k <= ClosureLeaf::kBlurLevels; ++k) {
    const float alpha = ClosureLeaf::kBlurStep * k;
    if (std::sqrt(alpha) <= roughness) continue;
    host::ParamList blurred = params;
    blurred.set_number("roughness", std::min(std::sqrt(alpha), 1.0f), 0, 0);
    if (distribution == "sharp" && host::find_param(type, "distribution")) blurred.set_string("distribution", "ggx");
    leaf.blurred[k] = instantiate(type, blurred, n.where);
  }
}

const host::ClosureInstance *ShaderSystem::diffuse_fallback(const ShaderNode &n, ClosureLeaf &leaf) {
  const GlimmerClosureType *diffuse = plugin_.find("diffuse");
  if (!diffuse) throw SceneError(n.where, "the plugin has no 'diffuse' closure");
  host::ParamList p;
  p.set_number("color", 1, 1, 1);
  leaf.type = diffuse;
  return instantiate(*diffuse, p, n.where);
}

// One closure leaf from a node, driven by its row (bridge/render/closure_nodes.cpp).
int ShaderSystem::make_leaf(const ShaderGraph &g, const ShaderNode &n, CompiledShader &out) {
  ClosureNodeRow storage;
  const ClosureNodeRow *row = row_for(n.type, storage);
  if (!row || row->kind == NodeKind::Fallback || row->kind == NodeKind::Holdout) return -1;
  auto leaf = std::make_unique<ClosureLeaf>();
  leaf->node = n.name;
  const GlimmerClosureType *type = row->kind == NodeKind::Closure ? plugin_.find(row->closure) : nullptr;
  host::ParamList params;
  check_attributes(n, *row, type, params);
  if (row->kind == NodeKind::Closure && !type) {
    if (!row->fallback_diffuse) throw SceneError(n.where, std::string("the plugin has no '") + row->closure + "' closure");
    leaf->weight = read_input(g, n, "color", Spectrum(row->find("color")->default_value), VectorSource::Generated);
    warn(n.where, n.type + ": the plugin has no '" + row->closure + "' closure yet; falling back to diffuse");
    leaf->instance = diffuse_fallback(n, *leaf);
  } else if (row->kind == NodeKind::Transparent) {
    apply_sockets(g, n, *row, nullptr, *leaf, params);
    bind_links(g, n, *row, *leaf);
    leaf->builtin = BuiltinClosure::Transparent;
    leaf->singular = true;
    out.has_transparent = true;
    features_.transparent = true;
  } else {
    leaf->type = type;
    if (row->schema) leaf->weight.constant = Spectrum(1.0f);  // unless apply_sockets finds a linked colour
    const float roughness = apply_sockets(g, n, *row, type, *leaf, params);
    const std::string distribution = row->distribution ? apply_distribution(g, n, *type, roughness, params) : "";
    if (row->bounce_tint && distribution == "multi_ggx") apply_bounce_tint(n, *type, *leaf, params);
    for (const auto &[name, value] : row->fixed)
      if (host::find_param(*type, name)) params.set_from_text(*type, name, value);
    bind_links(g, n, *row, *leaf);
    leaf->instance = instantiate(*type, params, n.where);
    if (row->filter_glossy) make_blurred_variants(n, *type, distribution, roughness, params, *leaf);
    leaf->singular = (type->flags & GLIMMER_CLOSURE_SINGULAR) != 0;
    leaf->emissive = (type->flags & GLIMMER_CLOSURE_EMISSIVE) != 0;
    if (leaf->emissive) out.has_emission = true;
  }
  if (!leaf->emissive && leaf->builtin == BuiltinClosure::None) out.has_bsdf = true;
  if (leaf->type && (leaf->type->flags & GLIMMER_CLOSURE_TRANSMISSIVE)) leaf->front_normal = true;
  ClosureTreeNode node;
  node.kind = ClosureTreeNode::Kind::Leaf;
  node.leaf = static_cast<int>(leaves_.size());
  leaves_.push_back(std::move(leaf));
  out.tree.push_back(node);
  return static_cast<int>(out.tree.size()) - 1;
}

int ShaderSystem::compile_closure(const ShaderGraph &g, const std::string &node_name, const std::string &socket,
                                  CompiledShader &out, int depth) {
  const scene::ShaderLink *link = g.link_to(node_name, socket);
  if (!link) return -1;
  if (depth > 64) throw SceneError(link->where, "shader '" + g.name + "': closure graph too deep (a cycle?)");
  const ShaderNode *n = g.find(link->from_node);
  const std::string &t = n->type;
  if (t == "mix_closure" || t == "add_closure") {
    ClosureTreeNode node;
    node.kind = t == "mix_closure" ? ClosureTreeNode::Kind::Mix : ClosureTreeNode::Kind::Add;
    if (node.kind == ClosureTreeNode::Kind::Mix) node.fac = read_input(g, *n, "fac", Spectrum(0.5f), VectorSource::Generated);
    warn_unsupported_links(g, *n, {"fac", "closure1", "closure2"});
    node.a = compile_closure(g, n->name, "closure1", out, depth + 1);
    node.b = compile_closure(g, n->name, "closure2", out, depth + 1);
    out.tree.push_back(node);
    return static_cast<int>(out.tree.size()) - 1;
  }
  if (const ClosureNodeRow *row = find_closure_node(t); row && row->kind == NodeKind::Holdout) {
    warn(n->where, "holdout is not supported; it renders as black (no closure)");
    return -1;
  }
  if (is_volume_node(t)) {
    features_.volumes = true;
    warn(n->where, "volume node <" + t + "> is not supported; ignored");
    return -1;
  }
  if (const ClosureNodeRow *row = find_closure_node(t); row && row->kind == NodeKind::Composite) {
    expanded_graphs_.push_back(std::make_unique<ShaderGraph>());
    ShaderGraph &expanded = *expanded_graphs_.back();
    const std::string output = expand_principled(
        g, *n, expanded, [this](const scene::SourceLocation &where, const std::string &message) { warn(where, message); });
    return compile_closure(expanded, output, "surface", out, depth + 1);
  }
  const int leaf = make_leaf(g, *n, out);
  if (leaf >= 0) return leaf;
  // Unknown closure-producing node (osl_shader, ...): grey diffuse.
  warn(n->where, "node <" + t + "> is not supported; the surface falls back to a grey (0.8) diffuse closure");
  ShaderNode grey;
  grey.type = "diffuse_bsdf";
  grey.name = n->name + "__fallback";
  grey.where = n->where;
  ShaderGraph empty;
  return make_leaf(empty, grey, out);
}

int ShaderSystem::compile(int shader_index) {
  if (auto it = compiled_index_.find(shader_index); it != compiled_index_.end()) return it->second;
  CompiledShader cs;
  if (shader_index < 0) {
    cs.name = "__default_surface";
    ShaderNode grey;  // Cycles' default surface: diffuse 0.8
    grey.type = "diffuse_bsdf";
    grey.name = "default";
    grey.where = scene::SourceLocation{scene_.path, 0};
    ShaderGraph empty;
    cs.root = make_leaf(empty, grey, cs);
  } else {
    const ShaderGraph &g = scene_.shaders[shader_index];
    cs.name = g.name;
    for (const auto &l : g.links) {
      if (l.to_node != "output") continue;
      if (l.to_socket == "volume") {
        features_.volumes = true;
        warn(l.where, "shader '" + g.name + "': volume output is not supported; ignored");
      } else if (l.to_socket == "displacement") {
        warn(l.where, "shader '" + g.name + "': displacement/bump output is not supported; ignored");
      } else if (l.to_socket != "surface") {
        warn(l.where, "shader '" + g.name + "': unknown output socket '" + l.to_socket + "'; ignored");
      }
    }
    for (const auto &n : g.nodes) {
      if (n.type == "bump" || n.type == "normal_map")
        warn(n.where, "<" + n.type + "> is not supported; the unperturbed normal is used");
    }
    cs.root = compile_closure(g, "output", "surface", cs, 0);
  }
  compiled_.push_back(std::move(cs));
  const int index = static_cast<int>(compiled_.size()) - 1;
  compiled_index_[shader_index] = index;
  return index;
}

void ShaderSystem::compile_background(int shader_index) {
  if (shader_index < 0) return;
  const ShaderGraph &g = scene_.shaders[shader_index];
  const scene::ShaderLink *link = g.link_to("output", "surface");
  for (const auto &l : g.links)
    if (l.to_node == "output" && l.to_socket == "volume") {
      features_.volumes = true;
      warn(l.where, "background volume is not supported; ignored");
    }
  if (!link) return;
  const ShaderNode *n = g.find(link->from_node);
  if (n->type != "background" && n->type != "emission") {
    warn(n->where, "background: node <" + n->type + "> on the surface output is not supported; the background is black");
    return;
  }
  background_.active = true;
  background_.color = read_input(g, *n, "color", Spectrum(0.8f), VectorSource::Direction);
  if (background_.color.texture >= 0) {  // image/checker directly on the colour
    TextureNode &t = textures_[background_.color.texture];
    if (t.kind == TextureNode::Kind::Image && t.vector == VectorSource::UV) t.vector = VectorSource::Direction;
    if (t.kind != TextureNode::Kind::Checker) features_.environment_map = true;
  }
  background_.strength =
      read_input(g, *n, "strength", Spectrum(n->type == "emission" ? 10.0f : 1.0f), VectorSource::Direction).constant.x;
  for (const auto &[name, value] : n->attributes)
    if (name != "color" && name != "strength") warn(n->where, "<" + n->type + "> attribute '" + name + "' ignored");
  if (max_component(background_.color.constant) * background_.strength <= 0.0f && !background_.color.varies())
    background_.active = false;
  features_.background = background_.active;
}

Spectrum ShaderSystem::background(const Vec3 &direction) const {
  if (!background_.active) return Spectrum(0.0f);
  TexCoords tc;
  tc.direction = direction;
  tc.P = direction;
  tc.N = direction;
  tc.generated = direction;
  return eval_input(background_.color, tc) * background_.strength;
}

Spectrum ShaderSystem::light_emission(int shader_index, const scene::SourceLocation &where) {
  if (shader_index < 0) return Spectrum(1.0f);  // Cycles' default light shader: emission 1
  const ShaderGraph &g = scene_.shaders[shader_index];
  const scene::ShaderLink *link = g.link_to("output", "surface");
  if (!link) return Spectrum(0.0f);
  const ShaderNode *n = g.find(link->from_node);
  if (n->type != "emission") {
    warn(where, "light shader '" + g.name + "': only an emission node is supported on lights; the light is black");
    return Spectrum(0.0f);
  }
  const Input color = read_input(g, *n, "color", Spectrum(0.8f), VectorSource::Generated);
  const Input strength = read_input(g, *n, "strength", Spectrum(10.0f), VectorSource::Generated);
  if (color.varies() || strength.varies())
    warn(n->where, "textured light emission is not supported; constant values are used");
  return color.constant * strength.constant.x;
}

void ShaderSystem::evaluate(int compiled, const TexCoords &tc, ClosureSet &out) const {
  out.count = 0;
  out.sum_sample_weight = 0.0f;
  out.transparent = Spectrum(0.0f);
  const CompiledShader &cs = compiled_[compiled];
  if (cs.root < 0) return;
  // Explicit stack: (tree node, accumulated weight).
  struct Item { int node; Spectrum weight; };
  Item stack[64];
  int top = 0;
  stack[top++] = {cs.root, Spectrum(1.0f)};
  while (top > 0) {
    const Item item = stack[--top];
    if (item.node < 0 || is_zero(item.weight)) continue;
    const ClosureTreeNode &n = cs.tree[item.node];
    if (n.kind == ClosureTreeNode::Kind::Leaf) {
      const ClosureLeaf &leaf = *leaves_[n.leaf];
      Spectrum w = eval_input(leaf.weight, tc) * (leaf.strength * 1.0f);
      w = max(w, Spectrum(0.0f)) * item.weight;
      if (is_zero(w)) continue;
      if (leaf.builtin == BuiltinClosure::Transparent) {
        out.transparent += w;
        continue;
      }
      ActiveClosure active;
      active.leaf = &leaf;
      active.instance = leaf.instance;
      active.weight = w;
      active.sample_weight = leaf.emissive ? 0.0f : std::fabs(average(w));
      for (const ClosureLeaf::VaryingInput &v : leaf.varying) {
        GlimmerVaryingValue &value = active.varying[active.varying_count++];
        const Spectrum x = eval_input(v.input, tc);
        value.param = v.param;
        // A float socket reads a colour as its luminance (a grey exactly as its value).
        value.value[0] = v.color || (x.x == x.y && x.y == x.z) ? x.x : luminance(x);
        value.value[1] = v.color ? x.y : 0.0f;
        value.value[2] = v.color ? x.z : 0.0f;
      }
      out.add(active);
      continue;
    }
    if (top + 2 > 64) continue;
    if (n.kind == ClosureTreeNode::Kind::Mix) {
      const float fac = saturate(eval_input(n.fac, tc).x);
      stack[top++] = {n.b, item.weight * fac};
      stack[top++] = {n.a, item.weight * (1.0f - fac)};
    } else {
      stack[top++] = {n.b, item.weight};
      stack[top++] = {n.a, item.weight};
    }
  }
}

void ShaderSystem::apply_filter_glossy(ClosureSet &cs, int k) {
  if (k <= 0) return;
  k = std::min(k, ClosureLeaf::kBlurLevels);
  const float blur_roughness = std::sqrt(ClosureLeaf::kBlurStep * k);  // alpha = roughness^2
  for (int i = 0; i < cs.count; ++i) {
    ActiveClosure &c = cs.closures[i];
    if (c.leaf->blurred.empty()) continue;
    c.instance = c.leaf->blurred[k];
    if (c.leaf->varying_roughness >= 0) {
      float &r = c.varying[c.leaf->varying_roughness].value[0];
      r = std::max(r, blur_roughness);
    }
  }
}

}  // namespace glimmer::render
