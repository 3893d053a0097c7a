// The checked stamp (checked_stamp.h). The stamp's payload: the kind's header, the build id's length and bytes, the
// entry bytes' FNV-1a hash.
#include "tables/checked_stamp.h"

#include <cstring>

#if defined(__linux__)
#include <link.h>
#endif

#include "glimmer/cache_blob.h"

namespace glimmer::plugin {
namespace {
#if defined(__linux__)
// The GNU build id's bytes in the PT_NOTE segments of the loaded module that holds `address`, as hex ("" if none).
struct BuildIdSearch {
  uintptr_t address;
  std::string id;
};
int find_build_id(dl_phdr_info *info, size_t, void *data) {
  auto &search = *static_cast<BuildIdSearch *>(data);
  bool holds = false;
  for (int i = 0; i < info->dlpi_phnum; ++i) {
    const ElfW(Phdr) &ph = info->dlpi_phdr[i];
    const uintptr_t start = info->dlpi_addr + ph.p_vaddr;
    holds |= ph.p_type == PT_LOAD && search.address >= start && search.address < start + ph.p_memsz;
  }
  if (!holds) return 0;
  for (int i = 0; i < info->dlpi_phnum; ++i) {
    const ElfW(Phdr) &ph = info->dlpi_phdr[i];
    if (ph.p_type != PT_NOTE) continue;
    const auto *at = reinterpret_cast<const unsigned char *>(info->dlpi_addr + ph.p_vaddr), *end = at + ph.p_memsz;
    while (at + sizeof(ElfW(Nhdr)) <= end) {
      ElfW(Nhdr) note;
      std::memcpy(&note, at, sizeof(note));
      const unsigned char *name = at + sizeof(note), *desc = name + ((note.n_namesz + 3u) & ~3u);
      if (desc + note.n_descsz > end) break;
      if (note.n_type == NT_GNU_BUILD_ID && note.n_namesz == 4 && std::memcmp(name, "GNU", 4) == 0) {
        static const char kHex[] = "0123456789abcdef";
        for (uint32_t k = 0; k < note.n_descsz; ++k) search.id += {kHex[desc[k] >> 4], kHex[desc[k] & 15]};
        return 1;
      }
      at = desc + ((note.n_descsz + 3u) & ~3u);
    }
  }
  return 1;  // the module, without a build id
}
#endif

std::vector<unsigned char> stamp_payload(const CheckedStampKind &kind, const std::vector<unsigned char> &entry_bytes,
                                         const std::string &build_id) {
  ByteWriter out;
  out.put_header(kind.magic, kind.format, kind.key);
  out.put(uint64_t(build_id.size()));
  out.bytes.insert(out.bytes.end(), build_id.begin(), build_id.end());
  out.put(Fnv1a().add(entry_bytes.data(), entry_bytes.size()).h);
  return std::move(out.bytes);
}
}  // namespace

const std::string &plugin_build_id() {
  static const std::string id = [] {
    std::string found;
#if defined(__linux__)
    BuildIdSearch search{reinterpret_cast<uintptr_t>(&find_build_id), ""};
    dl_iterate_phdr(&find_build_id, &search);
    found = search.id;
#endif
    return found;
  }();
  return id;
}

std::string checked_stamp_path(const std::string &entry_path) { return entry_path + ".checked"; }

bool checked_stamp_matches(const std::string &entry_path, const CheckedStampKind &kind,
                           const std::vector<unsigned char> &entry_bytes, const std::string &build_id) {
  if (build_id.empty()) return false;
  std::vector<unsigned char> stamp;
  return read_cache_blob(checked_stamp_path(entry_path), stamp).empty() &&
         stamp == stamp_payload(kind, entry_bytes, build_id);
}

void write_checked_stamp(const std::string &entry_path, const CheckedStampKind &kind,
                         const std::vector<unsigned char> &entry_bytes, const std::string &build_id) {
  if (!build_id.empty()) write_cache_blob(checked_stamp_path(entry_path), stamp_payload(kind, entry_bytes, build_id));
}

}  // namespace glimmer::plugin
