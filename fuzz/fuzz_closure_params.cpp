// libFuzzer target: closure parameter parsing and validation. The first byte
// picks a closure type of the plugin; each following line is one
// "name=value" assignment (host::ParamList, as --param and the XML loader use
// it), then the plugin's create() validates the values (prepare is not called:
// it precomputes tables). Bad input must end in ClosureError or a create()
// failure with a message; anything else is a finding.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "host/closure_instance.h"
#include "host/plugin_library.h"

namespace {

glimmer::host::PluginLibrary &plugin() {
  static std::unique_ptr<glimmer::host::PluginLibrary> lib =
      glimmer::host::PluginLibrary::load(GLIMMER_FUZZ_PLUGIN_PATH);
  return *lib;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  if (size == 0) return 0;
  const auto closures = plugin().closures();
  const GlimmerClosureType &type = *closures[data[0] % closures.size()];
  std::istringstream lines(std::string(reinterpret_cast<const char *>(data) + 1, size - 1));
  glimmer::host::ParamList params;
  std::string line;
  std::vector<GlimmerParamValue> values;
  try {
    while (std::getline(lines, line)) params.set_assignment(type, line);
    values = params.values(type);
  } catch (const glimmer::host::ClosureError &) {
    return 0;
  }
  GlimmerInstance *instance = nullptr;
  char error[512] = {0};
  if (type.create(values.data(), static_cast<uint32_t>(values.size()), glimmer::host::default_host_services(),
                  &instance, error, sizeof(error)) &&
      instance != nullptr)
    type.destroy(instance);
  return 0;
}
