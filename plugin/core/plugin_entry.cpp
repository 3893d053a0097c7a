// The DSO's one exported symbol and the closure registry behind it.
#include <algorithm>
#include <cstring>
#include <mutex>
#include <vector>

#include "core/closure.h"
#include "glimmer/closure_abi.h"

#ifndef GLIMMER_PLUGIN_VERSION
#define GLIMMER_PLUGIN_VERSION "0.1.0"
#endif

namespace glimmer::plugin {
namespace {

std::vector<const GlimmerClosureType *> &registry() {
  static std::vector<const GlimmerClosureType *> types;
  return types;
}

}  // namespace

bool register_closure_type(const GlimmerClosureType *type) {
  registry().push_back(type);
  return true;
}

}  // namespace glimmer::plugin

extern "C" GLIMMER_EXPORT const GlimmerPluginInfo *glimmer_plugin_entry(uint32_t /*host_abi_version*/) {
  // Built once, after all static registrations ran (they precede any call).
  static const GlimmerPluginInfo info = [] {
    auto &types = glimmer::plugin::registry();
    std::sort(types.begin(), types.end(),
              [](const GlimmerClosureType *a, const GlimmerClosureType *b) { return std::strcmp(a->name, b->name) < 0; });
    GlimmerPluginInfo i{};
    i.abi_version = GLIMMER_ABI_VERSION;
    i.struct_size = sizeof(GlimmerPluginInfo);
    i.plugin_name = "glimmer_closures";
    i.plugin_version = GLIMMER_PLUGIN_VERSION;
    i.closure_count = static_cast<uint32_t>(types.size());
    i.closures = types.data();
    return i;
  }();
  return &info;
}
