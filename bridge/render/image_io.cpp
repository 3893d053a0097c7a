#include "render/image_io.h"

#include <dlfcn.h>

#include <cstdlib>
#include <stdexcept>

#include "host/plugin_library.h"

namespace glimmer::render {

namespace {

// $<env> if set, else file_name next to the executable.
std::string module_path(const char *env_name, const char *file_name) {
  const char *env = std::getenv(env_name);
  if (env != nullptr && *env != '\0') return env;
  const std::string dir = host::executable_directory();
  return dir.empty() ? std::string(file_name) : dir + "/" + file_name;
}

// dlopen + the entry point; the module stays loaded for the life of the process (no dlclose: its
// objects, e.g. the OIIO TextureSystem of a render, may outlive any owner here).
template <class Module>
const Module *load_module(const char *env_name, const char *file_name, const char *entry_name) {
  const std::string path = module_path(env_name, file_name);
  // RTLD_LAZY: the functions of OIIO's 260 libraries that are not built with BIND_NOW are bound on first
  // call, as they were when the executable linked OIIO (with RTLD_NOW a tiny render took 5 % more CPU time).
  void *handle = dlopen(path.c_str(), RTLD_LAZY | RTLD_LOCAL);
  if (handle == nullptr) {
    const char *why = dlerror();
    throw std::runtime_error("cannot load the image module '" + path + "': " + (why ? why : "unknown error"));
  }
  using Entry = const Module *(*)();
  const auto entry = reinterpret_cast<Entry>(dlsym(handle, entry_name));
  if (entry == nullptr) throw std::runtime_error("image module '" + path + "' has no " + entry_name + " entry");
  return entry();
}

}  // namespace

const ImageIo &image_io() {
  // once per process; a failed load is retried next call
  static const ImageIo *const module = load_module<ImageIo>("GLIMMER_IMAGE_IO_PATH", kImageIoFileName, kImageIoEntry);
  return *module;
}

const ExrWriter &exr_writer() {
  static const ExrWriter *const module =
      load_module<ExrWriter>("GLIMMER_EXR_IO_PATH", kExrWriterFileName, kExrWriterEntry);
  return *module;
}

}  // namespace glimmer::render
