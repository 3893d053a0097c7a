#include "scene/graph_checks.h"

#include <algorithm>
#include <cctype>
#include <map>
#include <set>
#include <string_view>
#include <vector>

#include "render/closure_nodes.h"

namespace glimmer::scene {

namespace {

// Inputs and outputs of the Cycles nodes the renderer interprets (Cycles 3.4
// socket names, lower case): the closure nodes' from their rows in
// render/closure_nodes.cpp, the others below. Other node types (plugin
// closures, nodes the renderer ignores with a warning) are not checked here.
struct NodeSockets {
  std::vector<std::string> inputs, outputs;
};

std::string lower(std::string_view s);

const std::map<std::string, NodeSockets, std::less<>> &known_sockets() {
  static const std::map<std::string, NodeSockets, std::less<>> table = [] {
    std::map<std::string, NodeSockets, std::less<>> t = {
        {"output", {{"surface", "volume", "displacement", "normal"}, {}}},
        {"background", {{"color", "strength", "surface_mix_weight"}, {"background"}}},
        {"mix_closure", {{"fac", "closure1", "closure2"}, {"closure"}}},
        {"add_closure", {{"closure1", "closure2"}, {"closure"}}},
        {"checker_texture", {{"vector", "color1", "color2", "scale"}, {"color", "fac"}}},
        {"image_texture", {{"vector"}, {"color", "alpha"}}},
        {"environment_texture", {{"vector"}, {"color", "alpha"}}},
        {"texture_coordinate", {{}, {"generated", "normal", "uv", "object", "camera", "window", "reflection"}}},
    };
    for (const render::ClosureNodeRow &row : render::closure_node_rows()) {
      if (row.schema || (row.kind != render::NodeKind::Closure && row.kind != render::NodeKind::Transparent &&
                         row.kind != render::NodeKind::Composite))
        continue;
      NodeSockets &sockets = t[row.node];
      for (const render::SocketRow &socket : row.sockets)
        for (const char *name : {socket.socket, socket.alias})
          if (name && std::find(sockets.inputs.begin(), sockets.inputs.end(), lower(name)) == sockets.inputs.end())
            sockets.inputs.push_back(lower(name));
      sockets.outputs = {row.output};
    }
    return t;
  }();
  return table;
}

std::string lower(std::string_view s) {
  std::string out(s);
  std::transform(out.begin(), out.end(), out.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return out;
}

std::string join(const std::vector<std::string> &names) {
  std::string out;
  for (const auto &n : names) out += (out.empty() ? "" : ", ") + n;
  return out.empty() ? "none" : out;
}

void check_socket(const ShaderLink &link, const std::string &graph, const std::string &node_type,
                  const std::string &node, const std::string &socket, bool input) {
  const auto &table = known_sockets();
  const auto it = table.find(node_type);
  if (it == table.end()) return;
  const auto &names = input ? it->second.inputs : it->second.outputs;
  const std::string s = lower(socket);
  if (std::find(names.begin(), names.end(), s) != names.end()) return;
  throw SceneError(link.where, "<connect> " + std::string(input ? "to" : "from") + " unknown socket '" + socket +
                                   "' of node '" + node + "' (" + node_type + ") in shader '" + graph + "'; its " +
                                   (input ? "inputs" : "outputs") + ": " + join(names));
}

}  // namespace

void validate_shader_graph(const ShaderGraph &g) {
  std::map<std::string, const ShaderNode *> by_name;
  for (const auto &n : g.nodes) {
    const auto [it, fresh] = by_name.emplace(n.name, &n);
    if (!fresh)
      throw SceneError(n.where, "duplicate node name '" + n.name + "' in shader '" + g.name + "' (first defined at " +
                                    it->second->where.str() + ")");
  }
  // Index the links by target node: inputs[i] = the source node indices feeding node i.
  std::map<std::string, size_t> index;
  for (size_t i = 0; i < g.nodes.size(); ++i) index[g.nodes[i].name] = i;
  std::vector<std::vector<std::pair<size_t, const ShaderLink *>>> sources(g.nodes.size());
  for (const auto &l : g.links) {
    const auto from = index.find(l.from_node);
    if (from == index.end())
      throw SceneError(l.where, "<connect> from unknown node '" + l.from_node + "' in shader '" + g.name + "'");
    check_socket(l, g.name, g.nodes[from->second].type, l.from_node, l.from_socket, false);
    if (l.to_node == "output" && !index.count("output")) {
      check_socket(l, g.name, "output", "output", l.to_socket, true);
      continue;
    }
    const auto to = index.find(l.to_node);
    if (to == index.end())
      throw SceneError(l.where, "<connect> to unknown node '" + l.to_node + "' in shader '" + g.name + "'");
    check_socket(l, g.name, g.nodes[to->second].type, l.to_node, l.to_socket, true);
    sources[to->second].push_back({from->second, &l});
  }
  // Iterative depth-first search over the links (no recursion: the input
  // controls the depth). state: 0 unvisited, 1 on the current path, 2 done;
  // depth[i] = the longest chain of nodes ending at node i.
  std::vector<int> state(g.nodes.size(), 0), depth(g.nodes.size(), 1);
  struct Frame {
    size_t node, next_source;
  };
  for (size_t root = 0; root < g.nodes.size(); ++root) {
    if (state[root]) continue;
    std::vector<Frame> stack{{root, 0}};
    state[root] = 1;
    while (!stack.empty()) {
      Frame &top = stack.back();
      if (top.next_source < sources[top.node].size()) {
        const size_t src = sources[top.node][top.next_source].first;
        const ShaderLink *link = sources[top.node][top.next_source++].second;
        if (state[src] == 1) {
          // Read as "a <- b <- a": a's input comes from b, b's from a.
          std::string cycle;
          for (auto it = std::find_if(stack.begin(), stack.end(), [&](const Frame &f) { return f.node == src; });
               it != stack.end(); ++it)
            cycle += g.nodes[it->node].name + " <- ";
          cycle += g.nodes[src].name;
          throw SceneError(link->where, "shader '" + g.name + "': links form a cycle (" + cycle + ")");
        }
        if (state[src] == 0) {
          state[src] = 1;
          stack.push_back({src, 0});
        }
        continue;
      }
      int d = 1;
      for (const auto &[src, link] : sources[top.node]) d = std::max(d, depth[src] + 1);
      if (d > kMaxShaderGraphDepth)
        throw SceneError(g.nodes[top.node].where, "shader '" + g.name + "': a chain of " + std::to_string(d) +
                                                      " linked nodes ends at '" + g.nodes[top.node].name +
                                                      "'; at most " + std::to_string(kMaxShaderGraphDepth));
      depth[top.node] = d;
      state[top.node] = 2;
      stack.pop_back();
    }
  }
}

}  // namespace glimmer::scene
