// What every test folder shares: the DSO under test and the `make stress` scale.
#pragma once

#include <cstdint>
#include <cstdlib>
#include <memory>
#include <string>

#include "host/plugin_library.h"

namespace glimmer::test {

// The DSO under test (GLIMMER_TEST_PLUGIN_PATH), loaded once per test process.
inline host::PluginLibrary &plugin() {
  static const std::unique_ptr<host::PluginLibrary> library = host::PluginLibrary::load(GLIMMER_TEST_PLUGIN_PATH);
  return *library;
}

// Call-count factor of the stress tests: 100 under `make stress` (GLIMMER_STRESS
// set to anything but "" or "0", see tests/CMakeLists.txt), else 1.
inline uint64_t stress_scale() {
  const char *v = std::getenv("GLIMMER_STRESS");
  return (v != nullptr && *v != '\0' && std::string(v) != "0") ? 100 : 1;
}

}  // namespace glimmer::test
