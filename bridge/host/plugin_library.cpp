#include "host/plugin_library.h"

#include "host/closure_instance.h"

#include <dlfcn.h>
#include <elf.h>
#include <unistd.h>

#include <cstddef>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "scene/input_file.h"

namespace glimmer::host {

namespace fs = std::filesystem;

std::string executable_directory() {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  return ec ? std::string() : exe.parent_path().string();
}

std::string abi_version_name(uint32_t version) {
  if (version < 0x10000u) return std::to_string(version);  // ABI 1 numbered versions with one integer
  return std::to_string(GLIMMER_ABI_VERSION_MAJOR(version)) + "." + std::to_string(GLIMMER_ABI_VERSION_MINOR(version));
}

bool abi_compatible(uint32_t plugin_version, uint32_t host_version) {
  return plugin_version >= 0x10000u && GLIMMER_ABI_VERSION_MAJOR(plugin_version) == GLIMMER_ABI_VERSION_MAJOR(host_version) &&
         GLIMMER_ABI_VERSION_MINOR(plugin_version) <= GLIMMER_ABI_VERSION_MINOR(host_version);
}

std::string elf_problem(const std::string &path) {
  uint64_t size = 0;
  const std::string problem = scene::regular_file_problem(path, &size);
  if (!problem.empty()) return problem;
  constexpr uint64_t kMaxPluginBytes = uint64_t{1} << 31;
  if (size > kMaxPluginBytes)
    return std::to_string(size) + " bytes is more than the limit of " + std::to_string(kMaxPluginBytes);
  // Headers only: the ELF header, then the program headers it points to (not the whole file).
  std::ifstream file(path, std::ios::binary);
  auto read_at = [&file](uint64_t offset, void *out, size_t count) {
    file.clear();
    file.seekg(static_cast<std::streamoff>(offset));
    return static_cast<bool>(file.read(static_cast<char *>(out), static_cast<std::streamsize>(count)));
  };
  if (!file) return "cannot be opened";
  Elf64_Ehdr eh{};
  if (size < sizeof(eh) || !read_at(0, &eh, sizeof(eh)))
    return "too short to be a shared library (" + std::to_string(size) + " bytes)";
  if (std::memcmp(eh.e_ident, ELFMAG, SELFMAG) != 0) return "not an ELF file";
  if (eh.e_ident[EI_CLASS] != ELFCLASS64 || eh.e_ident[EI_DATA] != ELFDATA2LSB)
    return "not a 64-bit little-endian ELF file";
  if (eh.e_type != ET_DYN) return "not a shared library (ELF type " + std::to_string(eh.e_type) + ")";
#if defined(__x86_64__)
  if (eh.e_machine != EM_X86_64) return "built for another CPU (ELF machine " + std::to_string(eh.e_machine) + ")";
#elif defined(__aarch64__)
  if (eh.e_machine != EM_AARCH64) return "built for another CPU (ELF machine " + std::to_string(eh.e_machine) + ")";
#endif
  auto within = [&](uint64_t offset, uint64_t count, uint64_t entry) {
    return entry != 0 && offset <= size && count <= (size - offset) / entry;
  };
  if (eh.e_phentsize != sizeof(Elf64_Phdr) || !within(eh.e_phoff, eh.e_phnum, eh.e_phentsize))
    return "program headers lie outside the file (truncated?)";
  if (eh.e_shnum != 0 && !within(eh.e_shoff, eh.e_shnum, eh.e_shentsize))
    return "section headers lie outside the file (truncated?)";
  for (unsigned i = 0; i < eh.e_phnum; ++i) {
    Elf64_Phdr ph{};
    if (!read_at(eh.e_phoff + i * sizeof(ph), &ph, sizeof(ph))) return "cannot read its program headers";
    if (ph.p_type == PT_LOAD && (ph.p_offset > size || ph.p_filesz > size - ph.p_offset))
      return "a loadable segment lies outside the file (truncated: " + std::to_string(size) + " bytes)";
  }
  return {};
}

std::unique_ptr<PluginLibrary> PluginLibrary::load(const std::string &path_in) {
  fs::path path(path_in);
  std::error_code ec;
  if (fs::is_directory(path, ec)) path /= kLibraryFileName;
  if (!fs::exists(path, ec))
    throw PluginError("closure plugin not found: " + path.string());
  // An explicit path, never a bare name: dlopen("name.so") would search the
  // system library folders instead of the file checked here.
  path = fs::absolute(path, ec).lexically_normal();
  // dlopen maps the file: a truncated library faults (SIGBUS) inside the
  // loader, so the ELF headers are checked against the file size first.
  if (const std::string problem = elf_problem(path.string()); !problem.empty())
    throw PluginError("cannot load closure plugin " + path.string() + ": " + problem);

  void *handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (handle == nullptr) {
    const char *why = dlerror();
    throw PluginError("cannot load closure plugin " + path.string() + ": " + (why ? why : "unknown dlopen error"));
  }
  dlerror();
  void *symbol = dlsym(handle, GLIMMER_PLUGIN_ENTRY_SYMBOL);
  if (symbol == nullptr) {
    dlclose(handle);
    throw PluginError("not a Glimmer closure plugin (no " GLIMMER_PLUGIN_ENTRY_SYMBOL " symbol): " + path.string());
  }
  auto entry = reinterpret_cast<GlimmerPluginEntryFn>(symbol);
  const GlimmerPluginInfo *info = entry(GLIMMER_ABI_VERSION);
  if (info == nullptr) {
    dlclose(handle);
    throw PluginError("closure plugin " + path.string() + " returned no plugin info");
  }
  if (!abi_compatible(info->abi_version, GLIMMER_ABI_VERSION)) {
    std::ostringstream msg;
    msg << "closure plugin " << path.string() << " was built for Glimmer ABI version "
        << abi_version_name(info->abi_version) << ", but this host uses ABI version "
        << abi_version_name(GLIMMER_ABI_VERSION) << " (it loads plugins of ABI " << GLIMMER_ABI_MAJOR << ".0 to "
        << abi_version_name(GLIMMER_ABI_VERSION) << "); rebuild the plugin against this host's closure_abi.h";
    dlclose(handle);
    throw PluginError(msg.str());
  }
  auto refuse = [&](const std::string &why) {
    dlclose(handle);
    throw PluginError("closure plugin " + path.string() + ": " + why);
  };
  if (info->struct_size < offsetof(GlimmerPluginInfo, closures) + sizeof(info->closures))
    refuse("GlimmerPluginInfo.struct_size " + std::to_string(info->struct_size) + " is too small");
  for (uint32_t i = 0; i < info->closure_count; ++i) {
    const GlimmerClosureType *t = info->closures[i];
    if (t == nullptr || t->struct_size < offsetof(GlimmerClosureType, emit) + sizeof(t->emit) ||
        t->param_spec_size < offsetof(GlimmerParamSpec, doc) + sizeof(t->params->doc) || t->name == nullptr ||
        t->create == nullptr || t->destroy == nullptr || t->eval == nullptr || t->sample == nullptr ||
        (t->param_count > 0 && t->params == nullptr))
      refuse("lists an incomplete closure type (#" + std::to_string(i) + ")");
    if (const std::string problem = validate_schema(*t); !problem.empty()) refuse("invalid schema: " + problem);
  }
  return std::unique_ptr<PluginLibrary>(new PluginLibrary(handle, info, path.string()));
}

std::unique_ptr<PluginLibrary> PluginLibrary::locate(const std::string &explicit_path) {
  if (!explicit_path.empty()) return load(explicit_path);
  std::vector<std::string> tried;
  if (const char *env = std::getenv("GLIMMER_PLUGIN_PATH"); env != nullptr && *env != '\0') return load(env);
  tried.push_back("$GLIMMER_PLUGIN_PATH (unset)");
  const std::string dir = executable_directory();
  if (!dir.empty()) {
    const fs::path candidate = fs::path(dir) / kLibraryFileName;
    std::error_code ec;
    if (fs::exists(candidate, ec)) return load(candidate.string());
    tried.push_back(candidate.string());
  }
  std::string msg = "closure plugin " + std::string(kLibraryFileName) + " not found; tried: --plugin (not given)";
  for (const auto &t : tried) msg += ", " + t;
  msg += ". Pass --plugin PATH or set GLIMMER_PLUGIN_PATH.";
  throw PluginError(msg);
}

PluginLibrary::~PluginLibrary() {
  if (handle_ != nullptr) dlclose(handle_);
}

std::vector<const GlimmerClosureType *> PluginLibrary::closures() const {
  return {info_->closures, info_->closures + info_->closure_count};
}

const GlimmerClosureType *PluginLibrary::find(std::string_view name) const {
  for (uint32_t i = 0; i < info_->closure_count; ++i)
    if (name == info_->closures[i]->name) return info_->closures[i];
  return nullptr;
}

}  // namespace glimmer::host
