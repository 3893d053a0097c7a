// The checked stamp (checked_stamp.h).
#include "tables/checked_stamp.h"

#include <algorithm>
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

// The stamp: the kind's header, the FNV-1a hash of the entry's bytes, then the builds that checked them, newest first
// (a count and each id's length and bytes). Up to kRememberedBuilds: in `make test` the test binaries (the plugin's
// objects linked in) and the plugin DSO (the CLI, the bridge tests) load the same entries with different build ids,
// and a single slot made each overwrite the other's stamp.
constexpr size_t kRememberedBuilds = 4;
constexpr uint64_t kLongestBuildId = 128;  // hex digits (a GNU build id is 40)
struct Stamp {
  uint64_t entry_hash = 0;
  std::vector<std::string> builds;
};

uint64_t entry_hash(const std::vector<unsigned char> &entry_bytes) {
  return Fnv1a().add(entry_bytes.data(), entry_bytes.size()).h;
}

std::vector<unsigned char> stamp_bytes(const CheckedStampKind &kind, const Stamp &stamp) {
  ByteWriter out;
  out.put_header(kind.magic, kind.format, kind.key);
  out.put(stamp.entry_hash);
  out.put(uint64_t(stamp.builds.size()));
  for (const std::string &id : stamp.builds) {
    out.put(uint64_t(id.size()));
    out.bytes.insert(out.bytes.end(), id.begin(), id.end());
  }
  return std::move(out.bytes);
}

// The stamp beside `entry_path` for this kind, if its MAC holds and it parses.
bool read_stamp(const std::string &entry_path, const CheckedStampKind &kind, Stamp &stamp) {
  std::vector<unsigned char> bytes;
  if (!read_cache_blob(checked_stamp_path(entry_path), bytes).empty()) return false;
  ByteReader in{bytes};
  uint64_t count = 0;
  if (!in.get_header(kind.magic, kind.format, kind.key) || !in.get(&stamp.entry_hash, 8) || !in.get(&count, 8) ||
      count > kRememberedBuilds)
    return false;
  for (uint64_t k = 0; k < count; ++k) {
    uint64_t size = 0;
    std::string id;
    if (!in.get(&size, 8) || size == 0 || size > kLongestBuildId) return false;
    id.resize(size);
    if (!in.get(id.data(), size)) return false;
    stamp.builds.push_back(std::move(id));
  }
  return in.at_end();
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
  Stamp stamp;
  return !build_id.empty() && read_stamp(entry_path, kind, stamp) && stamp.entry_hash == entry_hash(entry_bytes) &&
         std::find(stamp.builds.begin(), stamp.builds.end(), build_id) != stamp.builds.end();
}

// This build first, then the builds the stamp already holds for the same bytes (a race between two writers loses one
// of them: that build checks once more).
std::string write_checked_stamp(const std::string &entry_path, const CheckedStampKind &kind,
                                const std::vector<unsigned char> &entry_bytes, const std::string &build_id) {
  if (build_id.empty()) return "";
  Stamp old, stamp;
  stamp.entry_hash = entry_hash(entry_bytes);
  stamp.builds.push_back(build_id);
  if (read_stamp(entry_path, kind, old) && old.entry_hash == stamp.entry_hash)
    for (const std::string &id : old.builds)
      if (id != build_id && stamp.builds.size() < kRememberedBuilds) stamp.builds.push_back(id);
  return write_cache_blob(checked_stamp_path(entry_path), stamp_bytes(kind, stamp));
}

}  // namespace glimmer::plugin
