// The Cycles node -> closure table (bridge/render/closure_nodes.cpp): every
// socket of every row, linked to a texture, is either honoured (the weight, or a
// parameter the closure declares varying: no warning at the <connect>) or warns
// at the <connect>'s file:line naming the socket; `glimmer describe --json`
// lists every row. Images of the table-driven builder are compared bit for bit
// with the previous hand-written one in the commit that introduced it (see
// docs/scene-format.md, "Shader nodes").
#include <nlohmann/json.hpp>
#include <regex>

#include "render/closure_nodes.h"
#include "render_test_util.h"

namespace glimmer::test {
namespace {

using render::ClosureNodeRow;
using render::NodeKind;
using render::SocketRole;

// Line 6 is the <connect> into `socket` of node "g".
std::vector<std::string> warnings_for_link(const ClosureNodeRow &row, const std::string &socket) {
  const std::string output = row.output;
  const std::string name = std::string(row.node) + "_" + socket + ".xml";
  const std::string path = write_file(
      name, "<cycles>\n<camera width=\"8\" height=\"8\" />\n<shader name=\"s\">\n<checker_texture name=\"c\" />\n<" +
                std::string(row.node) + " name=\"g\" />\n<connect from=\"c fac\" to=\"g " + socket +
                "\" />\n<connect from=\"g " + output +
                "\" to=\"output surface\" />\n</shader>\n<state shader=\"s\"><mesh P=\"-1 -1 3  1 -1 3  0 1 3\" "
                "nverts=\"3\" verts=\"0 1 2\" /></state>\n</cycles>\n");
  const scene::Scene scene = scene::load_scene(path);
  render::RenderOptions opt;
  opt.samples = 1;
  render::Renderer renderer(scene, plugin(), opt);  // compiles the shader (warnings), no render needed
  return renderer.warnings();
}

bool supported(const ClosureNodeRow &row, const render::SocketRow &s) {
  if (s.role == SocketRole::Weight || s.role == SocketRole::ParamOrWeight) return true;
  // The closure's own frame, per shading point (render/nodes/normal_nodes.cpp, ShaderSystem::shading_frame).
  if (s.role == SocketRole::Normal || s.role == SocketRole::Tangent || s.role == SocketRole::Rotation) return true;
  if (s.role != SocketRole::Param && s.role != SocketRole::SchemaParam) return false;
  const GlimmerClosureType *type = plugin().find(row.closure);
  const GlimmerParamSpec *spec = type ? host::find_param(*type, s.param) : nullptr;
  return spec && (host::param_flags(*type, *spec) & GLIMMER_PARAM_VARYING);
}

TEST(ClosureNodes, EveryLinkedSocketIsSupportedOrWarnedWithFileAndLine) {
  int checked = 0, warned = 0;
  for (const ClosureNodeRow &table_row : render::closure_node_rows()) {
    if (table_row.kind != NodeKind::Closure && table_row.kind != NodeKind::Transparent) continue;
    const GlimmerClosureType *type = table_row.closure ? plugin().find(table_row.closure) : nullptr;
    if (table_row.closure) {
      ASSERT_NE(type, nullptr) << table_row.closure << " is not in the plugin";
    }
    const ClosureNodeRow row = table_row.schema ? render::schema_row(*type, table_row.node) : table_row;
    for (const render::SocketRow &s : row.sockets) {
      std::vector<std::string> names = {s.socket};
      if (s.alias) names.push_back(s.alias);
      for (const std::string &socket : names) {
        SCOPED_TRACE(std::string(row.node) + " <- " + socket);
        const auto warnings = warnings_for_link(row, socket);
        const std::regex at_connect(".*" + std::string(row.node) + "_" + socket + "\\.xml:6: warning: .*'" + socket +
                                    "'.*not supported.*constant.*");
        const bool warned_here = std::any_of(warnings.begin(), warnings.end(),
                                             [&](const std::string &w) { return std::regex_match(w, at_connect); });
        EXPECT_NE(supported(row, s), warned_here)
            << (warned_here ? "a supported socket warned" : "an unsupported link did not warn at line 6")
            << (warnings.empty() ? "" : "; first warning: " + warnings.front());
        ++checked;
        warned += warned_here;
      }
    }
  }
  EXPECT_GT(checked, 40);  // every socket of the 9 closure rows
  EXPECT_GT(warned, 10);   // the test sees both outcomes
  EXPECT_LT(warned, checked);
}

// Unsupported closure nodes warn at their own line and still render (grey diffuse / black).
TEST(ClosureNodes, FallbackAndHoldoutRowsWarnAtTheNode) {
  for (const ClosureNodeRow &row : render::closure_node_rows()) {
    if (row.kind != NodeKind::Fallback && row.kind != NodeKind::Holdout) continue;
    SCOPED_TRACE(row.node);
    const auto warnings = warnings_for_link(row, "surface_mix_weight_unused");
    const std::regex at_node(".*" + std::string(row.node) + "_surface_mix_weight_unused\\.xml:5: warning: .*");
    EXPECT_TRUE(std::any_of(warnings.begin(), warnings.end(),
                            [&](const std::string &w) { return std::regex_match(w, at_node); }));
  }
}

TEST(ClosureNodes, DescribeListsEveryRow) {
  std::string out;
  ASSERT_EQ(0, run_cli("describe --json", out)) << out;
  const auto nodes = nlohmann::json::parse(out.substr(out.find('{')))["nodes"];
  ASSERT_EQ(nodes.size(), render::closure_node_rows().size());
  for (size_t i = 0; i < nodes.size(); ++i) {
    const ClosureNodeRow &row = render::closure_node_rows()[i];
    EXPECT_EQ(nodes[i]["node"], row.node);
    if (!row.schema) EXPECT_EQ(nodes[i]["sockets"].size(), row.sockets.size()) << row.node;
    else EXPECT_FALSE(nodes[i]["sockets"].empty()) << row.node << ": the plugin's parameters";
  }
}

}  // namespace
}  // namespace glimmer::test
