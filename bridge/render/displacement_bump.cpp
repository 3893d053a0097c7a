#include "render/displacement_bump.h"

#include <set>

#include "render/closure_nodes.h"
#include "render/nodes/node.h"

namespace glimmer::render {

namespace {

constexpr const char *kGeometry = "__displacement_geometry";
constexpr const char *kHeight = "__displacement_height";
constexpr const char *kBump = "__displacement_bump";

// Every node `link` depends on (the displacement's own graph, evaluated with the unbumped normal).
std::set<std::string> upstream_of(const scene::ShaderGraph &g, const std::string &node) {
  std::set<std::string> seen;
  std::vector<std::string> todo{node};
  while (!todo.empty()) {
    const std::string n = todo.back();
    todo.pop_back();
    if (!seen.insert(n).second) continue;
    for (const auto &l : g.links)
      if (l.to_node == n) todo.push_back(l.from_node);
  }
  return seen;
}

// The normal inputs of node `n` that take the shading normal when unlinked.
std::vector<std::string> implicit_normal_inputs(const scene::ShaderNode &n) {
  if (const ClosureNodeRow *row = find_closure_node(n.type); row && row->find("normal")) return {"normal"};
  std::vector<std::string> names;
  if (const nodes::NodeDef *def = nodes::find_node(n.type))
    for (const auto &in : def->inputs)
      if (in.implicit == nodes::Implicit::Normal) names.emplace_back(in.name);
  return names;
}

}  // namespace

bool is_displacement_bump(const std::string &node) { return node == kBump; }

bool expand_displacement_as_bump(const scene::ShaderGraph &g, scene::ShaderGraph &expanded,
                                 const DisplacementWarn &warn) {
  const scene::ShaderLink *displacement = g.link_to("output", "displacement");
  if (!displacement) return false;
  const scene::SourceLocation at = displacement->where;
  if (g.displacement_method != "bump")
    warn(g.where, "shader '" + g.name + "': displacement_method '" + g.displacement_method +
                      "': the surface is not moved (no true displacement); the displacement renders as bump");
  const std::set<std::string> height_graph = upstream_of(g, displacement->from_node);
  expanded = g;
  expanded.links.clear();
  for (const auto &l : g.links)
    if (!(l.to_node == "output" && l.to_socket == "displacement")) expanded.links.push_back(l);
  for (const auto &n : g.nodes) {
    if (height_graph.count(n.name)) continue;
    for (const std::string &socket : implicit_normal_inputs(n))
      if (!g.link_to(n.name, socket) && !n.attributes.count(socket))
        expanded.links.push_back({kBump, "normal", n.name, socket, at});
  }
  expanded.nodes.push_back({"geometry", kGeometry, {}, at});
  expanded.nodes.push_back({"vector_math", kHeight, {{"math_type", "dot_product"}}, at});
  expanded.nodes.push_back({"bump", kBump, {{"distance", "1"}}, at});
  expanded.links.push_back({displacement->from_node, displacement->from_socket, kHeight, "vector1", at});
  expanded.links.push_back({kGeometry, "normal", kHeight, "vector2", at});
  expanded.links.push_back({kHeight, "value", kBump, "height", at});
  return true;
}

}  // namespace glimmer::render
