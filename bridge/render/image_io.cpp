#include "render/image_io.h"

#include <dlfcn.h>

#include <cstdlib>
#include <stdexcept>

#include "host/plugin_library.h"

namespace glimmer::render {

namespace {

std::string module_path() {
  const char *env = std::getenv("GLIMMER_IMAGE_IO_PATH");
  if (env != nullptr && *env != '\0') return env;
  const std::string dir = host::executable_directory();
  return dir.empty() ? std::string(kImageIoFileName) : dir + "/" + kImageIoFileName;
}

// dlopen + the entry point; the module stays loaded for the life of the process (no dlclose: its
// objects, e.g. the OIIO TextureSystem of a render, may outlive any owner here).
const ImageIo *load_module() {
  const std::string path = module_path();
  // RTLD_LAZY: the functions of OIIO's 260 libraries that are not built with BIND_NOW are bound on first
  // call, as they were when the executable linked OIIO (with RTLD_NOW a tiny render took 5 % more CPU time).
  void *handle = dlopen(path.c_str(), RTLD_LAZY | RTLD_LOCAL);
  if (handle == nullptr) {
    const char *why = dlerror();
    throw std::runtime_error("cannot load the image module '" + path + "': " + (why ? why : "unknown error"));
  }
  const auto entry = reinterpret_cast<ImageIoEntry>(dlsym(handle, kImageIoEntry));
  if (entry == nullptr) throw std::runtime_error("image module '" + path + "' has no " + kImageIoEntry + " entry");
  return entry();
}

}  // namespace

const ImageIo &image_io() {
  static const ImageIo *const module = load_module();  // once per process; a failed load is retried next call
  return *module;
}

}  // namespace glimmer::render
