#include "render/shader_system.h"

#include <algorithm>
#include <filesystem>

#include "scene/xml_loader.h"

namespace glimmer::render {

using scene::SceneError;
using scene::ShaderGraph;
using scene::ShaderNode;

namespace {

const char *kCyclesClosureNodes[] = {"diffuse_bsdf", "glossy_bsdf", "anisotropic_bsdf", "glass_bsdf",
                                     "refraction_bsdf", "transparent_bsdf", "emission", "background",
                                     "mix_closure", "add_closure", "holdout"};

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

Input ShaderSystem::read_input(const ShaderGraph &g, const ShaderNode &n, const std::string &socket, Spectrum fallback,
                               VectorSource default_vector) {
  Input in;
  in.constant = fallback;
  if (auto it = n.attributes.find(socket); it != n.attributes.end()) {
    const auto v = scene::parse_floats(it->second, n.where, "<" + n.type + "> " + socket);
    if (v.size() == 1) in.constant = Spectrum(v[0]);
    else if (v.size() >= 3) in.constant = Spectrum(v[0], v[1], v[2]);
    else throw SceneError(n.where, "<" + n.type + "> " + socket + ": expected 1 or 3 numbers");
  }
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

int ShaderSystem::make_leaf(const ShaderGraph &g, const ShaderNode &n, CompiledShader &out) {
  auto leaf = std::make_unique<ClosureLeaf>();
  leaf->node = n.name;
  const std::string &t = n.type;
  auto check_known = [&](std::initializer_list<const char *> known) {
    for (const auto &attribute : n.attributes) {
      const std::string &name = attribute.first;  // not a structured binding: clang 14 cannot capture those
      if (std::none_of(known.begin(), known.end(), [&](const char *k) { return name == k; }))
        warn(n.where, "<" + t + "> attribute '" + name + "' is not supported; ignored");
    }
  };
  auto fallback_diffuse = [&](const std::string &why) -> const host::ClosureInstance * {
    warn(n.where, why);
    const GlimmerClosureType *diffuse = plugin_.find("diffuse");
    if (!diffuse) throw SceneError(n.where, "the plugin has no 'diffuse' closure");
    host::ParamList p;
    p.set_number("color", 1, 1, 1);
    leaf->type = diffuse;
    return instantiate(*diffuse, p, n.where);
  };
  const GlimmerClosureType *type = nullptr;
  host::ParamList params;

  if (t == "diffuse_bsdf") {
    check_known({"color", "roughness", "normal"});
    leaf->weight = read_input(g, n, "color", Spectrum(0.8f), VectorSource::Generated);
    if (auto r = n.attributes.find("roughness"); r != n.attributes.end()) {
      const auto v = scene::parse_floats(r->second, n.where, "<diffuse_bsdf> roughness");
      if (!v.empty() && v[0] != 0.0f) warn(n.where, "diffuse_bsdf: Oren-Nayar roughness is not supported; Lambertian is used");
    }
    type = plugin_.find("diffuse");
    if (!type) throw SceneError(n.where, "the plugin has no 'diffuse' closure");
    params.set_number("color", 1, 1, 1);
    leaf->type = type;
    leaf->instance = instantiate(*type, params, n.where);
    warn_unsupported_links(g, n, {"color"});
  } else if (t == "glossy_bsdf" || t == "anisotropic_bsdf" || t == "glass_bsdf" || t == "refraction_bsdf") {
    const bool dielectric = t == "glass_bsdf" || t == "refraction_bsdf";
    check_known({"color", "distribution", "roughness", "anisotropy", "rotation", "IOR", "ior", "normal", "tangent"});
    leaf->weight = read_input(g, n, "color", Spectrum(dielectric ? 1.0f : 0.8f), VectorSource::Generated);
    const char *dso_name = dielectric ? "microfacet_dielectric" : "microfacet_conductor";
    type = plugin_.find(dso_name);
    if (!type) {
      leaf->instance = fallback_diffuse(t + ": the plugin has no '" + dso_name +
                                        "' closure yet; falling back to diffuse");
    } else {
      leaf->type = type;
      bool approx = false;
      std::string distribution = "ggx";
      if (auto d = n.attributes.find("distribution"); d != n.attributes.end()) {
        distribution = map_distribution(d->second, approx);
        if (approx) warn(n.where, t + ": distribution '" + d->second + "' is not supported; GGX is used");
      }
      const float default_roughness = dielectric ? 0.0f : 0.5f;
      const float roughness = read_input(g, n, "roughness", Spectrum(default_roughness), VectorSource::Generated).constant.x;
      // Cycles (GlossyBsdfNode/GlassBsdfNode::simplify_settings): an unlinked roughness of 0 is the sharp closure.
      if (roughness <= 1e-4f && !g.link_to(n.name, "roughness")) distribution = "sharp";
      if (host::find_param(*type, "distribution")) params.set_string("distribution", distribution);
      if (host::find_param(*type, "roughness")) params.set_number("roughness", std::clamp(roughness, 0.0f, 1.0f), 0, 0);
      bind_varying(*leaf, g, n, "roughness", "roughness");
      if (!dielectric) {
        bind_varying(*leaf, g, n, "anisotropy", "anisotropy");
        warn_unsupported_links(g, n, {"color", "roughness", "anisotropy"});
        const float aniso = read_input(g, n, "anisotropy", Spectrum(t == "anisotropic_bsdf" ? 0.5f : 0.0f),
                                       VectorSource::Generated).constant.x;
        if (host::find_param(*type, "anisotropy")) params.set_number("anisotropy", std::clamp(aniso, -1.0f, 1.0f), 0, 0);
        if (host::find_param(*type, "f0")) params.set_number("f0", 1, 1, 1);
        // Cycles' Multiscatter GGX tints every bounce of its walk by the colour; the
        // weight applies it once, the closure the remaining powers (bounce_tint).
        if (distribution == "multi_ggx" && host::find_param(*type, "bounce_tint")) {
          if (leaf->weight.varies()) {
            warn(n.where, t + ": a textured colour with multi_ggx tints the multiple-scattering energy once "
                              "(Cycles tints each bounce); the walk's higher bounces are not darkened");
          } else {
            const Spectrum c = leaf->weight.constant;
            params.set_number("bounce_tint", std::clamp(c.x, 0.0f, 1.0f), std::clamp(c.y, 0.0f, 1.0f),
                              std::clamp(c.z, 0.0f, 1.0f));
          }
        }
      } else {
        float ior = 1.45f;
        if (n.attributes.count("IOR")) ior = read_input(g, n, "IOR", Spectrum(ior), VectorSource::Generated).constant.x;
        else if (n.attributes.count("ior")) ior = read_input(g, n, "ior", Spectrum(ior), VectorSource::Generated).constant.x;
        if (host::find_param(*type, "ior")) params.set_number("ior", ior, 0, 0);
        if (!bind_varying(*leaf, g, n, "IOR", "ior")) bind_varying(*leaf, g, n, "ior", "ior");
        warn_unsupported_links(g, n, {"color", "roughness", "IOR", "ior"});
        if (host::find_param(*type, "mode")) params.set_string("mode", t == "glass_bsdf" ? "glass" : "refraction");
      }
      if (n.attributes.count("rotation")) warn(n.where, t + ": rotation is not supported; ignored");
      leaf->instance = instantiate(*type, params, n.where);
      if (scene_.integrator.filter_glossy > 0.0f && host::find_param(*type, "roughness")) {
        // Cycles' bsdf_blur raises alpha to the blur roughness; alpha = roughness^2 here.
        leaf->blurred.assign(ClosureLeaf::kBlurLevels + 1, leaf->instance);
        for (int k = 1; k <= ClosureLeaf::kBlurLevels; ++k) {
          const float alpha = ClosureLeaf::kBlurStep * k;
          if (std::sqrt(alpha) <= roughness) continue;
          host::ParamList blurred = params;
          blurred.set_number("roughness", std::min(std::sqrt(alpha), 1.0f), 0, 0);
          if (distribution == "sharp" && host::find_param(*type, "distribution")) blurred.set_string("distribution", "ggx");
          leaf->blurred[k] = instantiate(*type, blurred, n.where);
        }
      }
      leaf->singular = (type->flags & GLIMMER_CLOSURE_SINGULAR) != 0;
    }
  } else if (t == "transparent_bsdf") {
    check_known({"color"});
    leaf->builtin = BuiltinClosure::Transparent;
    leaf->weight = read_input(g, n, "color", Spectrum(1.0f), VectorSource::Generated);
    warn_unsupported_links(g, n, {"color"});
    leaf->singular = true;
    out.has_transparent = true;
    features_.transparent = true;
  } else if (t == "emission") {
    check_known({"color", "strength"});
    leaf->weight = read_input(g, n, "color", Spectrum(0.8f), VectorSource::Generated);
    // Cycles' EmissionNode default strength is 10.
    leaf->strength = read_input(g, n, "strength", Spectrum(10.0f), VectorSource::Generated).constant.x;
    warn_unsupported_links(g, n, {"color"});
    type = plugin_.find("emission");
    if (!type) throw SceneError(n.where, "the plugin has no 'emission' closure");
    params.set_number("color", 1, 1, 1);
    params.set_number("strength", 1, 0, 0);
    leaf->type = type;
    leaf->instance = instantiate(*type, params, n.where);
    leaf->emissive = true;
    out.has_emission = true;
  } else {
    // Any closure the DSO lists, as `name` or `name_bsdf`.
    std::string dso = t;
    type = plugin_.find(dso);
    if (!type && t.size() > 5 && t.substr(t.size() - 5) == "_bsdf") {
      dso = t.substr(0, t.size() - 5);
      type = plugin_.find(dso);
    }
    if (!type) return -1;
    leaf->type = type;
    const bool has_color = host::find_param(*type, "color") != nullptr;
    for (const auto &[name, value] : n.attributes) {
      if (g.link_to(n.name, name)) continue;
      try {
        params.set_from_text(*type, name, value);
      } catch (const host::ClosureError &e) {
        throw SceneError(n.where, std::string("<") + t + ">: " + e.what());
      }
    }
    for (const auto &l : g.links) {
      if (l.to_node != n.name) continue;
      if (l.to_socket == "color" && has_color) {
        leaf->weight = read_input(g, n, "color", Spectrum(1.0f), VectorSource::Generated);
        leaf->weight.constant = Spectrum(1.0f);
        params.set_number("color", 1, 1, 1);
      } else {
        bind_varying(*leaf, g, n, l.to_socket, l.to_socket);
      }
    }
    if (leaf->weight.texture < 0) leaf->weight.constant = Spectrum(1.0f);
    leaf->instance = instantiate(*type, params, n.where);
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
  if (t == "holdout") {
    warn(n->where, "holdout is not supported; it renders as black (no closure)");
    return -1;
  }
  if (is_volume_node(t)) {
    features_.volumes = true;
    warn(n->where, "volume node <" + t + "> is not supported; ignored");
    return -1;
  }
  const int leaf = make_leaf(g, *n, out);
  if (leaf >= 0) return leaf;
  // Unknown closure-producing node (osl_shader, principled_bsdf, ...): grey diffuse.
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
      const bool known = std::any_of(std::begin(kCyclesClosureNodes), std::end(kCyclesClosureNodes),
                                     [&](const char *k) { return n.type == k; });
      (void)known;
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
