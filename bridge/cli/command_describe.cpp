// `glimmer describe [--json]`: the DSO's closures and their parameter schemas,
// and (JSON, key "scene") the attributes of the scene elements;
// `glimmer describe --nodes`: the shader-node support table (render/nodes/node_table.cpp).
// The JSON form is the one source the XML loader, docs and the Blender addon
// read parameters and settings from.
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>

#include "cli/commands.h"
#include "cli/json_number.h"
#include "host/closure_instance.h"
#include "render/closure_nodes.h"
#include "render/nodes/node.h"
#include "scene/settings.h"

namespace glimmer::cli {

namespace {

nlohmann::json describe_param(const GlimmerClosureType &type, const GlimmerParamSpec &p) {
  nlohmann::json j;
  j["name"] = p.name;
  j["type"] = host::param_type_name(p.type);
  j["doc"] = p.doc ? p.doc : "";
  j["varying"] = (host::param_flags(type, p) & GLIMMER_PARAM_VARYING) != 0;  // may be textured per shading point
  switch (p.type) {
    case GLIMMER_PARAM_COLOR:
    case GLIMMER_PARAM_VECTOR:
      j["default"] = json_floats(p.default_value, 3);
      j["min"] = json_float(p.min_value);
      j["max"] = json_float(p.max_value);
      break;
    case GLIMMER_PARAM_ENUM:
      j["default"] = p.default_string ? p.default_string : "";
      j["choices"] = scene::split_choices(p.enum_choices);
      break;
    case GLIMMER_PARAM_STRING:
      j["default"] = p.default_string ? p.default_string : "";
      break;
    case GLIMMER_PARAM_BOOL:
      j["default"] = p.default_value[0] != 0.0f;
      break;
    case GLIMMER_PARAM_INT:
      j["default"] = static_cast<int>(p.default_value[0]);
      j["min"] = json_float(p.min_value);
      j["max"] = json_float(p.max_value);
      break;
    case GLIMMER_PARAM_FLOAT:
      j["default"] = json_float(p.default_value[0]);
      j["min"] = json_float(p.min_value);
      j["max"] = json_float(p.max_value);
      break;
  }
  return j;
}

nlohmann::json flags_json(uint32_t flags) {
  nlohmann::json f = nlohmann::json::array();
  const std::pair<uint32_t, const char *> names[] = {
      {GLIMMER_CLOSURE_EMISSIVE, "emissive"},          {GLIMMER_CLOSURE_SINGULAR, "singular"},
      {GLIMMER_CLOSURE_TRANSMISSIVE, "transmissive"},  {GLIMMER_CLOSURE_NEEDS_TRACE, "needs_trace"},
      {GLIMMER_CLOSURE_NEEDS_ENVIRONMENT, "needs_environment"},
      {GLIMMER_CLOSURE_STOCHASTIC_EVAL, "stochastic_eval"}, {GLIMMER_CLOSURE_REFERENCE, "reference"}};
  for (const auto &[bit, name] : names)
    if (flags & bit) f.push_back(name);
  return f;
}

}  // namespace

namespace {
// "<name> <version> (ABI x.y) from <path>": `describe`'s first line and `--version`'s plugin line ("?" for a foreign
// plugin's missing name fields).
std::string plugin_summary(const host::PluginLibrary &plugin) {
  const auto &info = plugin.info();
  const auto text_or = [](const char *s) { return std::string(s != nullptr ? s : "?"); };
  return text_or(info.plugin_name) + " " + text_or(info.plugin_version) + " (ABI " +
         host::abi_version_name(info.abi_version) + ") from " + plugin.path();
}
}  // namespace

std::string version_text(CliContext &ctx) {
  std::string text = std::string("glimmer ") + GLIMMER_VERSION_STRING + " (closure ABI " +
                     host::abi_version_name(GLIMMER_ABI_VERSION) + ")\n";
  try {
    text += "plugin " + plugin_summary(ctx.plugin());
  } catch (const std::exception &e) {
    text += std::string("plugin: none loaded (") + e.what() + ")";
  }
  return text;
}

void add_describe_command(CLI::App &app, CliContext &ctx) {
  auto *cmd = app.add_subcommand("describe", "list the plugin's closures and their parameters");
  auto json = std::make_shared<bool>(false);
  auto nodes = std::make_shared<bool>(false);
  cmd->add_flag("--json", *json, "machine-readable output");
  cmd->add_flag("--nodes", *nodes, "the shader-node support table (Markdown, as in docs/scene-format.md)");
  cmd->callback([&ctx, json, nodes] {
    if (*nodes) {
      std::cout << render::nodes::support_table_markdown();
      return;
    }
    auto &plugin = ctx.plugin();
    const auto &info = plugin.info();
    if (*json) {
      nlohmann::json out;
      out["plugin"] = {{"name", info.plugin_name},
                       {"version", info.plugin_version},
                       {"abi_version", info.abi_version},
                       {"abi", host::abi_version_name(info.abi_version)},
                       {"path", plugin.path()}};
      out["closures"] = nlohmann::json::array();
      for (const auto *t : plugin.closures()) {
        nlohmann::json c;
        c["name"] = t->name;
        c["doc"] = t->doc ? t->doc : "";
        c["flags"] = flags_json(t->flags);
        c["params"] = nlohmann::json::array();
        for (uint32_t i = 0; i < t->param_count; ++i) c["params"].push_back(describe_param(*t, host::param_at(*t, i)));
        out["closures"].push_back(c);
      }
      out["nodes"] = render::describe_closure_nodes(plugin);  // Cycles closure nodes (render/closure_nodes.cpp)
      out["scene"] = scene::describe_scene_settings();  // scene element attributes (bridge/scene/settings.cpp)
      std::cout << out.dump(2) << "\n";
      return;
    }
    std::cout << plugin_summary(plugin) << "\n";
    for (const auto *t : plugin.closures()) {
      std::cout << "\n" << t->name << ": " << (t->doc ? t->doc : "") << "\n";
      for (uint32_t i = 0; i < t->param_count; ++i) {
        const GlimmerParamSpec &spec = host::param_at(*t, i);
        const auto j = describe_param(*t, spec);
        std::cout << "  " << spec.name << " (" << j["type"].get<std::string>() << ", default "
                  << j["default"].dump();
        if (j.contains("min")) {
          // An int's range as integers ("[0, 2147483648]", not "[0.0, 2147483648.0]"); JSON keeps the doubles.
          auto bound = [&j](const char *key) {
            return j["type"] == "int" ? std::to_string(static_cast<long long>(j[key].get<double>())) : j[key].dump();
          };
          std::cout << ", range [" << bound("min") << ", " << bound("max") << "]";
        }
        if (j.contains("choices")) std::cout << ", one of " << j["choices"].dump();
        std::cout << "): " << (spec.doc ? spec.doc : "") << (j["varying"].get<bool>() ? " [varying]" : "") << "\n";
      }
    }
  });
}

}  // namespace glimmer::cli
