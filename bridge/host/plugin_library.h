// Loads libglimmer_closures.so with dlopen and checks its ABI version.
#pragma once

#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "glimmer/closure_abi.h"

namespace glimmer::host {

// Any problem finding or loading the DSO; the CLI exits with code 2.
class PluginError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class PluginLibrary {
 public:
  static constexpr const char *kLibraryFileName = "libglimmer_closures.so";

  // Loads the DSO at `path` (a file, or a folder holding kLibraryFileName;
  // a relative path is made absolute, so a bare name never loads a system
  // library). The file is validated (elf_problem) before dlopen.
  // Throws PluginError when it is missing, not a Glimmer plugin, or built for
  // another ABI version (the message names both versions).
  static std::unique_ptr<PluginLibrary> load(const std::string &path);

  // Search order: explicit --plugin path, $GLIMMER_PLUGIN_PATH, next to the
  // running executable. Throws PluginError listing every place tried.
  static std::unique_ptr<PluginLibrary> locate(const std::string &explicit_path);

  ~PluginLibrary();
  PluginLibrary(const PluginLibrary &) = delete;
  PluginLibrary &operator=(const PluginLibrary &) = delete;

  const GlimmerPluginInfo &info() const { return *info_; }
  const std::string &path() const { return path_; }
  std::vector<const GlimmerClosureType *> closures() const;
  // nullptr when the plugin has no closure of that name.
  const GlimmerClosureType *find(std::string_view name) const;

 private:
  PluginLibrary(void *handle, const GlimmerPluginInfo *info, std::string path)
      : handle_(handle), info_(info), path_(std::move(path)) {}
  void *handle_;
  const GlimmerPluginInfo *info_;
  std::string path_;
};

// "2.1" for a packed major.minor ABI version, "1" for the single-integer ABI 1.
std::string abi_version_name(uint32_t version);
// A plugin loads when its major version is the host's and its minor is the same or older.
bool abi_compatible(uint32_t plugin_version, uint32_t host_version);

// Why the file at `path` cannot be dlopen'ed safely ("" when it can): not a
// regular file, not a 64-bit ELF shared library for this CPU, or headers and
// loadable segments reaching past the end of the file (a truncated copy).
std::string elf_problem(const std::string &path);

// The directory holding the running executable ("" when unknown).
std::string executable_directory();

}  // namespace glimmer::host
