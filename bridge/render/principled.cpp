#include "render/principled.h"

#include <algorithm>
#include <cctype>
#include <map>

#include "cli/json_number.h"
#include "scene/xml_loader.h"

namespace glimmer::render {

using scene::ShaderGraph;
using scene::ShaderLink;
using scene::ShaderNode;

namespace {

using R = SocketRole;

// Cycles 3.4 (and Disney) scale the clearcoat lobe by 0.25.
constexpr float kClearcoatWeight = 0.25f;

// Builds the composite's nodes into `out` (a copy of `g`), named after the principled node.
class Composite {
 public:
  Composite(const ShaderGraph &g, const ShaderNode &n, ShaderGraph &out, const ClosureNodeRow &row)
      : g_(g), n_(n), out_(out), row_(row) {}

  std::string add(const std::string &part, const std::string &type,
                  std::map<std::string, std::string> attributes = {}) {
    ShaderNode node;
    node.type = type;
    node.name = n_.name + "__" + part;
    node.attributes = std::move(attributes);
    node.where = n_.where;
    out_.nodes.push_back(std::move(node));
    return out_.nodes.back().name;
  }

  // The principled `socket` (its attribute, else its default, and its link) onto `node`.`target`.
  void carry(const char *socket, const std::string &node, const char *target) {
    const std::string *text = attribute(socket);
    set(node, target, text ? *text : cli::json_float(default_of(socket)).dump());
    if (const ShaderLink *l = link(socket)) out_.links.push_back({l->from_node, l->from_socket, node, target, l->where});
  }

  void set(const std::string &node, const char *attribute, const std::string &value) {
    node_named(node).attributes[attribute] = value;
  }

  void connect(const std::string &from, const char *from_socket, const std::string &to, const char *to_socket) {
    out_.links.push_back({from, from_socket, to, to_socket, n_.where});
  }

  bool linked(const char *socket) const { return link(socket) != nullptr; }

  // The socket's constant: its largest number (a colour's maximum component), else the default.
  float constant(const char *socket) const {
    const std::string *text = attribute(socket);
    if (!text) return default_of(socket);
    const auto v = scene::parse_floats(*text, n_.where, "<" + n_.type + "> " + socket);
    if (v.empty()) return default_of(socket);
    return *std::max_element(v.begin(), v.end());
  }

  // The term is present: the socket is linked, or its constant passes `matters`.
  bool active(const char *socket, bool (*matters)(float)) const { return linked(socket) || matters(constant(socket)); }

  // mix_closure(fac = the principled `fac_socket`, a, b); a constant fac of 1 is b alone.
  std::string mix(const char *part, const char *fac_socket, const std::string &a, const std::string &b) {
    if (!linked(fac_socket) && constant(fac_socket) >= 1.0f) return b;
    const std::string m = add(part, "mix_closure");
    carry(fac_socket, m, "fac");
    connect(a, output_of(a), m, "closure1");
    connect(b, output_of(b), m, "closure2");
    return m;
  }

  const char *output_of(const std::string &node) {
    const std::string &type = node_named(node).type;
    if (type == "mix_closure" || type == "add_closure") return "closure";
    return type == "emission" ? "emission" : "bsdf";
  }

 private:
  const ShaderGraph &g_;
  const ShaderNode &n_;
  ShaderGraph &out_;
  const ClosureNodeRow &row_;

  float default_of(const char *socket) const { return row_.find(socket)->default_value; }
  // The socket's attribute under its name or alias (`ior` / `IOR`), or nullptr.
  const std::string *attribute(const char *socket) const {
    const SocketRow *s = row_.find(socket);
    for (const char *name : {s->socket, s->alias})
      if (auto a = name ? n_.attributes.find(name) : n_.attributes.end(); a != n_.attributes.end()) return &a->second;
    return nullptr;
  }
  const ShaderLink *link(const char *socket) const {
    const SocketRow *s = row_.find(socket);
    const ShaderLink *l = g_.link_to(n_.name, s->socket);
    return l || !s->alias ? l : g_.link_to(n_.name, s->alias);
  }
  ShaderNode &node_named(const std::string &name) {
    for (ShaderNode &node : out_.nodes)
      if (node.name == name) return node;
    throw scene::SceneError(n_.where, "principled_bsdf: internal node '" + name + "' missing");
  }
};

bool positive(float v) { return v > 0.0f; }
bool below_one(float v) { return v < 1.0f; }

// Unsupported sockets: a non-default constant warns with the row's note, a link warns at the link.
void warn_unsupported(const ShaderGraph &g, const ShaderNode &n, const ClosureNodeRow &row,
                      const PrincipledWarn &warn) {
  for (const SocketRow &s : row.sockets) {
    if (s.role == R::Ignored) {
      if (const ShaderLink *l = g.link_to(n.name, s.socket))
        warn(l->where, "<principled_bsdf> linked input '" + std::string(s.socket) + "' is not supported; ignored");
      continue;
    }
    if (s.role != R::Unsupported) continue;
    const ShaderLink *l = g.link_to(n.name, s.socket);
    const auto a = n.attributes.find(s.socket);
    bool set = false;
    if (a != n.attributes.end())
      for (float v : scene::parse_floats(a->second, n.where, "<principled_bsdf> " + std::string(s.socket)))
        set = set || v != s.default_value;
    if (l || set) warn(l ? l->where : n.where, std::string("principled_bsdf: ") + s.note);
  }
}

}  // namespace

ClosureNodeRow principled_row() {
  return {
      .node = "principled_bsdf",
      .kind = NodeKind::Composite,
      .sockets =
          {{.socket = "base_color", .role = R::Weight, .default_value = 0.8f},
           {.socket = "metallic", .role = R::Param, .param = "mix fac (diffuse, glass off) and specular cspec0", .default_value = 0.0f,
            .min = 0, .max = 1},
           {.socket = "specular", .role = R::Param, .param = "principled_specular F0 = 0.08 * specular",
            .default_value = 0.5f},
           {.socket = "specular_tint", .role = R::Param, .param = "principled_specular tint of F0 toward the hue",
            .default_value = 0.0f, .min = 0, .max = 1},
           {.socket = "roughness", .role = R::Param, .param = "roughness (diffuse retro-reflection, specular, glass)",
            .default_value = 0.5f, .min = 0, .max = 1},
           {.socket = "transmission", .role = R::Param, .param = "mix fac (glass)", .default_value = 0.0f,
            .min = 0, .max = 1},
           {.socket = "ior", .role = R::Param, .param = "glass IOR", .default_value = 1.45f, .alias = "IOR"},
           {.socket = "clearcoat", .role = R::Param, .param = "clearcoat_bsdf weight 0.25 * clearcoat",
            .default_value = 0.0f, .min = 0, .max = 1},
           {.socket = "clearcoat_roughness", .role = R::Param, .param = "clearcoat_bsdf roughness (GTR1 alpha = r^2)",
            .default_value = 0.03f, .min = 0, .max = 1},
           {.socket = "alpha", .role = R::Param, .param = "mix fac (transparent)", .default_value = 1.0f,
            .min = 0, .max = 1},
           {.socket = "emission", .role = R::Param, .param = "emission colour", .default_value = 0.0f},
           {.socket = "emission_strength", .role = R::Param, .param = "emission strength", .default_value = 1.0f},
           {.socket = "sheen", .role = R::Param, .param = "principled_sheen amount", .default_value = 0.0f,
            .min = 0, .max = 1},
           {.socket = "sheen_tint", .role = R::Param, .param = "principled_sheen tint toward the base colour's hue",
            .default_value = 0.5f, .min = 0, .max = 1},
           {.socket = "subsurface", .role = R::Unsupported, .default_value = 0.0f,
            .note = "subsurface scattering is not supported; dropped"},
           {.socket = "anisotropic", .role = R::Unsupported, .default_value = 0.0f,
            .note = "anisotropic is not supported; the specular lobes are isotropic"},
           {.socket = "transmission_roughness", .role = R::Unsupported, .default_value = 0.0f,
            .note = "transmission_roughness is not supported; the glass uses roughness"},
           {.socket = "subsurface_color", .role = R::Ignored},
           {.socket = "subsurface_radius", .role = R::Ignored},
           {.socket = "subsurface_ior", .role = R::Ignored},
           {.socket = "subsurface_anisotropy", .role = R::Ignored},
           {.socket = "anisotropic_rotation", .role = R::Ignored},
           {.socket = "normal", .role = R::Ignored},
           {.socket = "clearcoat_normal", .role = R::Ignored},
           {.socket = "tangent", .role = R::Ignored},
           {.socket = "surface_mix_weight", .role = R::Ignored}},
      .distribution = true,
      .doc = "host composite (render/principled.cpp): mix(alpha, transparent, "
             "mix(metallic, mix(transmission, principled_diffuse + principled_specular [+ principled_sheen], glass), "
             "principled_specular) + "
             "clearcoat_bsdf(0.25 clearcoat, clearcoat_roughness) + emission)"};
}

std::string expand_principled(const ShaderGraph &g, const ShaderNode &n, ShaderGraph &expanded,
                              const PrincipledWarn &warn) {
  static const ClosureNodeRow row = principled_row();
  expanded = g;
  warn_unsupported(g, n, row, warn);
  Composite c(g, n, expanded, row);
  std::string distribution = "ggx";
  if (auto d = n.attributes.find("distribution"); d != n.attributes.end()) distribution = d->second;

  // Cycles 3.4's base (svm_closure.h): principled diffuse of weight (1 - metallic)(1 - transmission), glass of
  // weight (1 - metallic) transmission and the Fresnel-interpolated specular of weight 1 - transmission
  // (1 - metallic), which carries the metal through cspec0. As mixes:
  //   mix(metallic, mix(transmission, diffuse + specular, glass), specular)
  // gives the specular (1 - metallic)(1 - transmission) + metallic = 1 - transmission (1 - metallic).
  const std::string diffuse = c.add("diffuse", "principled_diffuse_bsdf");
  c.carry("base_color", diffuse, "color");
  c.carry("roughness", diffuse, "roughness");
  const std::string specular = c.add("specular", "principled_specular_bsdf");
  for (const char *socket : {"base_color", "metallic", "specular", "specular_tint", "roughness"})
    c.carry(socket, specular, socket);
  std::string lower = distribution;
  std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char ch) { return std::tolower(ch); });
  if (lower != "ggx")
    warn(n.where, "principled_bsdf: distribution '" + distribution +
                      "': the specular is single-scattering GGX (Cycles' multiscatter GGX with Fresnel is not "
                      "implemented); the glass uses the distribution");
  std::string result = c.add("dielectric", "add_closure");
  c.connect(diffuse, "bsdf", result, "closure1");
  c.connect(specular, "bsdf", result, "closure2");
  // Sheen as Cycles 3.4 adds it (svm_closure.h): the principled sheen lobe of weight (1 - metallic)(1 -
  // transmission), i.e. beside the diffuse, inside both mixes.
  if (c.active("sheen", positive)) {
    const std::string sheen = c.add("sheen", "principled_sheen_bsdf");
    for (const char *socket : {"base_color", "sheen", "sheen_tint"}) c.carry(socket, sheen, socket);
    const std::string sheened = c.add("sheen_layer", "add_closure");
    c.connect(result, "closure", sheened, "closure1");
    c.connect(sheen, "bsdf", sheened, "closure2");
    result = sheened;
  }

  if (c.active("transmission", positive)) {
    const std::string glass = c.add("glass", "glass_bsdf", {{"distribution", distribution}});
    c.carry("base_color", glass, "color");
    c.carry("roughness", glass, "roughness");
    c.carry("ior", glass, "IOR");
    result = c.mix("transmission", "transmission", result, glass);
  }
  if (c.active("metallic", positive)) result = c.mix("metallic", "metallic", result, specular);
  // Clearcoat as Cycles 3.4 adds it (svm_closure.h): its coat lobe (clearcoat_bsdf: GTR1, Fresnel 1.5 at the
  // microfacet) of weight 0.25 * clearcoat on top of the base, which it does not attenuate.
  if (c.active("clearcoat", positive)) {
    const std::string coat = c.add("clearcoat", "clearcoat_bsdf");
    c.carry("clearcoat_roughness", coat, "roughness");
    const std::string weight = c.add("clearcoat_weight", "math", {{"math_type", "multiply"}});
    c.carry("clearcoat", weight, "value1");
    c.set(weight, "value2", cli::json_float(kClearcoatWeight).dump());
    c.connect(weight, "value", coat, "color");
    const std::string coated = c.add("clearcoat_layer", "add_closure");
    c.connect(result, c.output_of(result), coated, "closure1");
    c.connect(coat, "bsdf", coated, "closure2");
    result = coated;
  }
  // Emission, then alpha over everything (as Cycles' PrincipledBsdfNode::expand).
  if (c.active("emission", positive) && c.active("emission_strength", positive)) {
    const std::string emit = c.add("emission", "emission");
    c.carry("emission", emit, "color");
    c.carry("emission_strength", emit, "strength");
    const std::string sum = c.add("emit", "add_closure");
    c.connect(result, c.output_of(result), sum, "closure1");
    c.connect(emit, "emission", sum, "closure2");
    result = sum;
  }
  if (c.active("alpha", below_one)) {
    const std::string transparent = c.add("transparent", "transparent_bsdf", {{"color", "1"}});
    result = c.mix("alpha", "alpha", transparent, result);
  }
  const std::string output = n.name + "__principled_output";
  c.connect(result, c.output_of(result), output, "surface");
  return output;
}

}  // namespace glimmer::render
