#include "render/shader_system.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <thread>

#include "render/nodes/shading_normal.h"
#include "render/displacement_bump.h"
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

const ImageTexture *ShaderSystem::load_image(const ShaderNode &n, bool &missing) {
  missing = false;
  auto it = n.attributes.find("filename");
  if (it == n.attributes.end() || it->second.empty()) {
    warn(n.where, "<" + n.type + "> has no filename; it reads as black");
    return nullptr;
  }
  std::filesystem::path path(it->second);
  if (path.is_relative()) path = std::filesystem::path(n.where.file).parent_path() / path;
  const std::string key = path.lexically_normal().string();
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    warn(n.where, "<" + n.type + "> image not found: '" + key + "'; it renders magenta, as in Cycles");
    missing = true;
    return nullptr;
  }
  bool linear = false;
  if (auto cs = n.attributes.find("colorspace"); cs != n.attributes.end()) {
    const std::string c = lower(cs->second);
    linear = c == "non-color" || c == "raw" || c == "linear" || c == "__builtin_raw";
  }
  if (!texture_cache_) texture_cache_ = std::make_unique<TextureCache>();
  try {
    const ImageTexture *image = texture_cache_->load(key, linear);
    features_.textures.insert(key);
    return image;
  } catch (const std::exception &e) {
    throw SceneError(n.where, e.what());
  }
}

namespace {
// An enum attribute of an image node among `names` (several spellings per value); a
// missing one is `fallback`, an unknown one warns and is `fallback`.
template <typename Enum>
Enum image_setting(const ShaderNode &n, const char *attribute,
                   std::initializer_list<std::pair<const char *, Enum>> names, Enum fallback,
                   const std::function<void(const std::string &)> &warn) {
  auto it = n.attributes.find(attribute);
  if (it == n.attributes.end()) return fallback;
  const std::string value = lower(it->second);
  for (const auto &[name, e] : names)
    if (value == name) return e;
  warn(n.type + ": " + attribute + " '" + it->second + "' is not supported; the default is used");
  return fallback;
}
}  // namespace

void ShaderSystem::configure_image(const ShaderNode &n, TextureNode &tex) {
  const bool environment = n.type == "environment_texture";
  tex.kind = environment ? TextureNode::Kind::Environment : TextureNode::Kind::Image;
  tex.vector = environment ? VectorSource::Direction : VectorSource::UV;
  tex.image = load_image(n, tex.missing);
  const auto warn_here = [&](const std::string &message) { warn(n.where, message); };
  tex.sampling.interpolation = image_setting<Interpolation>(
      n, "interpolation",
      {{"closest", Interpolation::Closest}, {"linear", Interpolation::Linear}, {"cubic", Interpolation::Cubic},
       {"smart", Interpolation::Smart}},
      Interpolation::Linear, warn_here);
  if (environment) {
    tex.projection = image_setting<Projection>(
        n, "projection", {{"equirectangular", Projection::Equirectangular}, {"mirror_ball", Projection::MirrorBall}},
        Projection::Equirectangular, warn_here);
    // Around the horizon u repeats; v stops at the poles (a mirror ball's rim).
    tex.sampling.extension = tex.projection == Projection::MirrorBall ? Extension::Extend : Extension::Repeat;
    tex.sampling.vertical = Extension::Extend;
    return;
  }
  tex.sampling.extension = image_setting<Extension>(
      n, "extension",
      {{"periodic", Extension::Repeat}, {"repeat", Extension::Repeat}, {"extend", Extension::Extend},
       {"clip", Extension::Clip}, {"mirror", Extension::Mirror}},
      Extension::Repeat, warn_here);
  tex.sampling.vertical = tex.sampling.extension;
  tex.projection = image_setting<Projection>(
      n, "projection",
      {{"flat", Projection::Flat}, {"box", Projection::Box}, {"sphere", Projection::Sphere}, {"tube", Projection::Tube}},
      Projection::Flat, warn_here);
  if (auto b = n.attributes.find("projection_blend"); b != n.attributes.end())
    tex.projection_blend = std::clamp(read_constant(n, "projection_blend", &b->second, Spectrum(0.0f)).x, 0.0f, 1.0f);
}

Spectrum ShaderSystem::read_constant(const ShaderNode &n, const std::string &socket, const std::string *text,
                                     Spectrum fallback) {
  if (!text) return fallback;
  const auto v = scene::parse_floats(*text, n.where, "<" + n.type + "> " + socket);
  if (v.size() == 1) return Spectrum(v[0]);
  if (v.size() == 3) return Spectrum(v[0], v[1], v[2]);
  // Strict as the closures' parameters and <light>/<transform> vectors: a 4th number (RGBA, a typo) is refused.
  throw SceneError(n.where,
                   "<" + n.type + "> " + socket + ": expected 1 or 3 numbers, got " + std::to_string(v.size()));
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
    configure_image(*src, tex);
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
  if (spec->type != GLIMMER_PARAM_VECTOR) v.clamped = clamped_count(g, n, *link, param, *spec);
  if (param == "roughness") leaf.varying_roughness = static_cast<int>(leaf.varying.size());
  leaf.varying.push_back(v);
  return true;
}

ClampedParameterCount *ShaderSystem::clamped_count(const ShaderGraph &g, const ShaderNode &n,
                                                   const scene::ShaderLink &link, const std::string &param,
                                                   const GlimmerParamSpec &spec) {
  // A composite's part (principled_bsdf's "pb__diffuse", "pb__specular": one link into several closures) is
  // reported as the artist's node, once: the first part bound counts, the others read the same texture value.
  const ShaderNode *owner = &n;
  if (const size_t cut = n.name.rfind("__"); cut != std::string::npos)
    if (const ShaderNode *o = g.find(n.name.substr(0, cut))) owner = o;
  const std::string what = "<" + owner->type + "> '" + owner->name + "' parameter '" + param + "'";
  for (const auto &c : clamped_)
    if (c->where.str() == link.where.str() && c->what == what) return nullptr;
  auto count = std::make_unique<ClampedParameterCount>();
  count->where = link.where;
  count->what = what;
  count->min_value = spec.min_value;
  count->max_value = spec.max_value;
  clamped_.push_back(std::move(count));
  return clamped_.back().get();
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
  Vec3 co, dco_dx(0.0f), dco_dy(0.0f);  // the coordinate and its change per pixel step (zero: unknown)
  switch (t.vector) {
    case VectorSource::UV:
      co = Vec3(tc.uv[0], tc.uv[1], 0.0f);
      dco_dx = Vec3(tc.duv_dx[0], tc.duv_dx[1], 0.0f);
      dco_dy = Vec3(tc.duv_dy[0], tc.duv_dy[1], 0.0f);
      break;
    case VectorSource::Generated:
      co = tc.generated;
      dco_dx = tc.dgenerated_dx;
      dco_dy = tc.dgenerated_dy;
      break;
    case VectorSource::Object:
      co = tc.P;
      dco_dx = tc.dPdx;
      dco_dy = tc.dPdy;
      break;
    case VectorSource::Normal: co = tc.N; break;
    case VectorSource::Direction: co = tc.direction; break;
  }
  if (t.vector_program >= 0) {
    co = eval_input(Input{Spectrum(0.0f), -1, false, t.vector_program}, tc);
    dco_dx = dco_dy = Vec3(0.0f);
  }
  switch (t.kind) {
    case TextureNode::Kind::Checker: {
      const float f = checker(co * t.scale);
      if (in.fac_output) return Spectrum(f);
      return f == 1.0f ? t.color1 : t.color2;
    }
    case TextureNode::Kind::Image:
    case TextureNode::Kind::Environment:
      return lookup_image(t, co, dco_dx, dco_dy, tc.N, in.fac_output);
  }
  return in.constant;
}

namespace {
// The change of a projected (u, v) over one pixel step, by differencing the projection
// (sphere, tube, environment): u wraps, so a step across the seam is the short way round.
template <typename Project>
void projected_footprint(const Project &project, const Vec3 &co, const Vec3 &dco_dx, const Vec3 &dco_dy,
                         UvFootprint &at) {
  project(co, at.u, at.v);
  auto step = [&](const Vec3 &d, float &du, float &dv) {
    if (!is_finite(d) || is_zero(d)) return;
    float u, v;
    project(co + d, u, v);
    du = u - at.u;
    du -= std::round(du);
    dv = v - at.v;
  };
  step(dco_dx, at.dudx, at.dvdx);
  step(dco_dy, at.dudy, at.dvdy);
}
}  // namespace

Spectrum ShaderSystem::lookup_image(const TextureNode &t, const Vec3 &co, const Vec3 &dco_dx, const Vec3 &dco_dy,
                                    const Vec3 &N, bool alpha) const {
  if (t.missing) return alpha ? Spectrum(1.0f) : Spectrum(1.0f, 0.0f, 1.0f);  // Cycles' missing-texture magenta
  if (!t.image) return Spectrum(0.0f);
  float rgba[4] = {0, 0, 0, 0};
  UvFootprint at;
  const bool direction = t.kind == TextureNode::Kind::Environment || t.vector == VectorSource::Direction;
  if (direction && t.projection == Projection::MirrorBall) {
    projected_footprint([](const Vec3 &d, float &u, float &v) { direction_to_mirrorball(normalize(d), u, v); }, co,
                        dco_dx, dco_dy, at);
  } else if (direction) {
    projected_footprint([](const Vec3 &d, float &u, float &v) { direction_to_equirectangular(normalize(d), u, v); },
                        co, dco_dx, dco_dy, at);
  } else if (t.projection == Projection::Sphere) {
    projected_footprint(map_to_sphere, co, dco_dx, dco_dy, at);
  } else if (t.projection == Projection::Tube) {
    projected_footprint(map_to_tube, co, dco_dx, dco_dy, at);
  } else if (t.projection == Projection::Box) {
    // The world-space shading normal: meshes are stored in world space (Cycles uses the object's).
    box_lookup(*t.image, t.sampling, box_projection_weights(N, t.projection_blend), N, co, dco_dx, dco_dy, rgba);
  } else {
    at = {co.x, co.y, dco_dx.x, dco_dx.y, dco_dy.x, dco_dy.y};
  }
  if (t.projection != Projection::Box) t.image->lookup(at, t.sampling, rgba);
  if (alpha) return Spectrum(rgba[3]);
  return {rgba[0], rgba[1], rgba[2]};
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
      case SocketRole::Normal:
      case SocketRole::Tangent:
      case SocketRole::Rotation:
        read_frame_socket(g, n, row, s, text, leaf);
        break;
      case SocketRole::Ignored:
        break;
    }
  }
  return roughness;
}

void ShaderSystem::read_frame_socket(const ShaderGraph &g, const ShaderNode &n, const ClosureNodeRow &row,
                                     const SocketRow &s, const std::string *text, ClosureLeaf &leaf) {
  ClosureLeaf::Frame &f = leaf.frame;
  if (s.role == SocketRole::Rotation) {
    f.rotation = read_input(g, n, s.socket, read_constant(n, s.socket, text, Spectrum(s.default_value)),
                            VectorSource::Generated);
    if (f.rotation.varies() || f.rotation.constant.x != 0.0f) f.active = true;
    return;
  }
  if (!g.link_to(n.name, s.socket)) {  // unlinked: the point's normal, the UV tangent or Cycles' radial one
    if (s.role == SocketRole::Tangent && s.radial_default) {
      // Only an anisotropic lobe sees its tangent (an isotropic one keeps the point's frame, bit for bit).
      const SocketRow *anisotropy = row.find("anisotropy");
      const std::string *value = anisotropy ? attribute_of(n, *anisotropy) : nullptr;
      const bool linked = anisotropy && g.link_to(n.name, anisotropy->socket);
      if (linked || (anisotropy && read_constant(n, anisotropy->socket, value,
                                                 Spectrum(anisotropy->default_value)).x != 0.0f))
        f.radial_tangent = f.active = true;
      const GlimmerParamSpec *spec = linked && leaf.type ? host::find_param(*leaf.type, anisotropy->param) : nullptr;
      if (spec) f.anisotropy_param = host::param_index(*leaf.type, *spec);
      f.radial_only = spec != nullptr;
    }
    return;
  }
  Input &in = s.role == SocketRole::Normal ? f.normal : f.tangent;
  in = read_input(g, n, s.socket, Spectrum(0.0f), VectorSource::Generated);
  if (in.varies()) f.active = true;
}

// Every link into the node: a parameter socket is bound per shading point (or warns
// when the closure cannot vary it); weight sockets were read with their texture;
// any other linked socket renders with its constant and warns at the <connect>.
void ShaderSystem::bind_links(const ShaderGraph &g, const ShaderNode &n, const ClosureNodeRow &row, ClosureLeaf &leaf) {
  for (const auto &l : g.links) {
    if (l.to_node != n.name) continue;
    const SocketRow *s = row.find(l.to_socket);
    const SocketRole role = s ? s->role : SocketRole::Ignored;
    if (role == SocketRole::Weight || role == SocketRole::ParamOrWeight || role == SocketRole::Normal ||
        role == SocketRole::Tangent || role == SocketRole::Rotation)
      continue;
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
  const scene::ShaderLink *normal = g.link_to(n.name, "normal");
  leaf->frame.bump_shadowing = leaf->type && std::string(leaf->type->name) == "diffuse" &&
                               !(normal && is_displacement_bump(normal->from_node));
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
    const bool has_surface = g.link_to("output", "surface") != nullptr;
    const scene::ShaderLink *volume_only = nullptr;  // a volume's boundary: Cycles gives it no surface at all
    for (const auto &l : g.links) {
      if (l.to_node != "output") continue;
      if (l.to_socket == "volume") {
        features_.volumes = true;
        if (!has_surface) volume_only = &l;
        warn(l.where, "shader '" + g.name + "': volume output is not supported; ignored" +
                          (has_surface ? "" : " (the shader has no surface: its objects let light pass, unscattered)"));
      } else if (l.to_socket != "surface" && l.to_socket != "displacement") {
        warn(l.where, "shader '" + g.name + "': unknown output socket '" + l.to_socket + "'; ignored");
      }
    }
    auto bumped = std::make_unique<ShaderGraph>();
    const auto warn_at = [this](const scene::SourceLocation &where, const std::string &m) { warn(where, m); };
    if (volume_only != nullptr) {
      // Cycles (SD_HAS_ONLY_VOLUME) skips such a surface: rays cross it. Without volumes that is a clear boundary, not
      // the black no-closure surface an empty surface output means.
      ShaderNode boundary;
      boundary.type = "transparent_bsdf";
      boundary.name = g.name + "__volume_boundary";
      boundary.where = volume_only->where;
      boundary.attributes["color"] = "1 1 1";
      ShaderGraph empty;
      cs.root = make_leaf(empty, boundary, cs);
    } else if (expand_displacement_as_bump(g, *bumped, warn_at)) {
      expanded_graphs_.push_back(std::move(bumped));
      cs.root = compile_closure(*expanded_graphs_.back(), "output", "surface", cs, 0);
    } else {
      cs.root = compile_closure(g, "output", "surface", cs, 0);
    }
  }
  cs.reads_footprint = any_varying_input(cs);
  compiled_.push_back(std::move(cs));
  const int index = static_cast<int>(compiled_.size()) - 1;
  compiled_index_[shader_index] = index;
  return index;
}

bool ShaderSystem::any_varying_input(const CompiledShader &cs) const {
  for (const ClosureTreeNode &n : cs.tree) {
    if (n.kind != ClosureTreeNode::Kind::Leaf) {
      if (n.fac.varies()) return true;
      continue;
    }
    if (n.leaf < 0) continue;
    const ClosureLeaf &leaf = *leaves_[n.leaf];
    if (leaf.weight.varies() || leaf.frame.normal.varies() || leaf.frame.tangent.varies() ||
        leaf.frame.rotation.varies())
      return true;
    for (const ClosureLeaf::VaryingInput &v : leaf.varying)
      if (v.input.varies()) return true;
  }
  return false;
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
  // A constant world (every escaped ray of a white-furnace scene): eval_input would return the constant too,
  // without the texture coordinates built below.
  if (!background_.color.varies()) return background_.color.constant * background_.strength;
  TexCoords tc;
  tc.direction = direction;
  tc.P = direction;
  tc.N = direction;
  tc.generated = direction;
  return eval_input(background_.color, tc) * background_.strength;
}

std::vector<nodes::SunDisc> ShaderSystem::background_suns() const {
  if (!background_.active || background_.color.program < 0) return {};
  return programs_[background_.color.program].sun_discs();
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
  // Explicit stack: (tree node, accumulated weight), trivially constructed (with a Spectrum member all 64
  // entries were zeroed at every shading point: about half of this function's instructions for one closure).
  struct Item {
    int node;
    float w[3];
  };
  Item stack[64];
  int top = 0;
  const auto push = [&](int node, const Spectrum &w) { stack[top++] = Item{node, {w.x, w.y, w.z}}; };
  push(cs.root, Spectrum(1.0f));
  while (top > 0) {
    const Item &popped = stack[--top];
    const int node = popped.node;
    const Spectrum weight(popped.w[0], popped.w[1], popped.w[2]);
    if (node < 0 || is_zero(weight)) continue;
    const ClosureTreeNode &n = cs.tree[node];
    if (n.kind == ClosureTreeNode::Kind::Leaf) {
      const ClosureLeaf &leaf = *leaves_[n.leaf];
      Spectrum w = eval_input(leaf.weight, tc) * (leaf.strength * 1.0f);
      w = max(w, Spectrum(0.0f)) * weight;
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
        if (v.clamped) v.clamped->record(value.value, v.color ? 3 : 1);
      }
      if (leaf.frame.active) shading_frame(leaf, tc, active);
      out.add(active);
      continue;
    }
    if (top + 2 > 64) continue;
    if (n.kind == ClosureTreeNode::Kind::Mix) {
      const float fac = saturate(eval_input(n.fac, tc).x);
      push(n.b, weight * fac);
      push(n.a, weight * (1.0f - fac));
    } else {
      push(n.b, weight);
      push(n.a, weight);
    }
  }
}

// Cycles' svm_node_closure_bsdf: N from the normal socket (the point's N unlinked), T from the tangent
// socket (unlinked: the UV map's dP/du, or the radial Z tangent of Cycles' anisotropic glossy), in N's plane
// and turned about N by rotation * 2 pi.
void ShaderSystem::shading_frame(const ClosureLeaf &leaf, const TexCoords &tc, ActiveClosure &out) const {
  const ClosureLeaf::Frame &f = leaf.frame;
  const bool radial_only = f.radial_only && !f.normal.varies() && !f.tangent.varies() && !f.rotation.varies() &&
                           f.rotation.constant.x == 0.0f;
  if (radial_only)
    for (uint32_t i = 0; i < out.varying_count; ++i)
      if (out.varying[i].param == f.anisotropy_param && out.varying[i].value[0] == 0.0f) return;
  Vec3 N = tc.N;
  if (f.normal.varies()) {
    const Vec3 n = eval_input(f.normal, tc);
    if (length_squared(n) > 0.0f) N = normalize(n);
  }
  Vec3 T = tc.dPdu;
  if (f.tangent.varies()) T = eval_input(f.tangent, tc);
  else if (f.radial_tangent) T = tc.object_normal_to_world(nodes::radial_tangent(tc.generated, 2));
  T = Frame::from_normal_tangent(N, T).s;
  const float rotation = eval_input(f.rotation, tc).x;
  if (rotation != 0.0f) {
    const float angle = rotation * 2.0f * kPi;
    T = T * std::cos(angle) + cross(N, T) * std::sin(angle);
  }
  out.own_frame = true;
  out.N = N;
  out.T = T;
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

void ClampedParameterCount::record(const float *value, int channels) {
  float lo = std::numeric_limits<float>::infinity(), hi = -lo;
  for (int c = 0; c < channels; ++c)
    if (std::isfinite(value[c])) lo = std::min(lo, value[c]), hi = std::max(hi, value[c]);
  const bool below = lo<min_value, above = hi> max_value;
  if (!below && !above) return;  // in range (or no finite channel): the common case, no shared write
  static thread_local const size_t slot = std::hash<std::thread::id>{}(std::this_thread::get_id()) % kSlots;
  Slot &s = slots_[slot];
  // a = min(a, v) (down) or max(a, v), lock-free.
  auto extend = [](std::atomic<float> &a, float v, bool down) {
    float cur = a.load(std::memory_order_relaxed);
    while ((down ? v < cur : v > cur) && !a.compare_exchange_weak(cur, v, std::memory_order_relaxed)) {
    }
  };
  if (below) s.below.fetch_add(1, std::memory_order_relaxed), extend(s.lowest, lo, true);
  if (above) s.above.fetch_add(1, std::memory_order_relaxed), extend(s.highest, hi, false);
}

ClampedParameterCount::Totals ClampedParameterCount::totals() const {
  Totals t;
  for (const Slot &s : slots_) {
    t.below += s.below.load();
    t.above += s.above.load();
    t.lowest = std::min(t.lowest, s.lowest.load());
    t.highest = std::max(t.highest, s.highest.load());
  }
  return t;
}

void ClampedParameterCount::reset() {
  for (Slot &s : slots_) {
    s.below = 0;
    s.above = 0;
    s.lowest = std::numeric_limits<float>::infinity();
    s.highest = -std::numeric_limits<float>::infinity();
  }
}

ClampedParameterRecords ShaderSystem::clamped_parameter_records() const {
  ClampedParameterRecords out;
  for (const auto &c : clamped_) {
    const ClampedParameterCount::Totals t = c->totals();
    if (t.below == 0 && t.above == 0) continue;
    out.push_back({c->where.str(), c->what, c->min_value, c->max_value, t.below, t.above, t.lowest, t.highest});
  }
  return out;
}

std::vector<std::string> ShaderSystem::clamped_parameter_warnings() const {
  return render::clamped_parameter_warnings(clamped_parameter_records());
}

void ShaderSystem::reset_clamped_parameter_counts() {
  for (auto &c : clamped_) c->reset();
}

}  // namespace glimmer::render
