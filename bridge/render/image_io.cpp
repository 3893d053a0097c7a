#include "render/image_io.h"

#include <dlfcn.h>

#include <cstdlib>
#include <future>
#include <mutex>
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
  // call, as they were when the executable linked OIIO (RTLD_NOW cost 5 % more CPU for a tiny render).
  void *handle = dlopen(path.c_str(), RTLD_LAZY | RTLD_LOCAL);
  if (handle == nullptr) {
    const char *why = dlerror();
    throw std::runtime_error("cannot load the image module '" + path + "': " + (why ? why : "unknown error"));
  }
  const auto entry = reinterpret_cast<ImageIoEntry>(dlsym(handle, kImageIoEntry));
  if (entry == nullptr) throw std::runtime_error("image module '" + path + "' has no " + kImageIoEntry + " entry");
  return entry();
}

// The one load of the process: started by preload_image_io() on a thread, or by image_io() in place.
std::once_flag g_started;
std::shared_future<const ImageIo *> g_module;

void start(std::launch how) {
  std::call_once(g_started, [how] { g_module = std::async(how, load_module).share(); });
}

}  // namespace

void preload_image_io() { start(std::launch::async); }

const ImageIo &image_io() {
  start(std::launch::deferred);
  return *g_module.get();  // rethrows the load's error to every caller
}

}  // namespace glimmer::render
