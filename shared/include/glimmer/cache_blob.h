// One authenticated cache file: the payload followed by its HMAC-SHA256 keyed
// by the cache folder's secret (cache_key.h), written atomically into a
// private folder (atomic_file.h). Readers get the payload back only when the
// MAC verifies (a corrupt or crafted file is refused, saying why); junk at the
// path (a directory, a FIFO, a symlink) is removed so a rebuilt entry can take
// its place. The payload's own format and validation are the caller's; the
// pieces every table cache shares are here: the FNV-1a key chain that names
// the file, ByteWriter / ByteReader, and the header (8-byte magic, uint32
// format version, uint64 key) that starts every payload.
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "glimmer/atomic_file.h"
#include "glimmer/cache_key.h"
#include "glimmer/sha256.h"

namespace glimmer {

// Returns "" when written, else why not.
inline std::string write_cache_blob(const std::string &path, std::vector<unsigned char> payload) {
  const std::string dir = std::filesystem::path(path).parent_path().string();
  CacheKey secret;
  std::string problem = ensure_private_directory(dir);
  if (problem.empty()) problem = cache_secret_key(dir, secret);
  if (!problem.empty()) return problem;
  const Digest256 mac = hmac_sha256(secret.data(), secret.size(), payload.data(), payload.size());
  payload.insert(payload.end(), mac.begin(), mac.end());
  return write_file_atomically(path, payload.data(), payload.size(), 0600);
}

// Returns "" and the file's bytes, or "missing"; junk at the path is removed
// ("not a regular file; removed"). Nothing is verified yet (check_cache_mac).
inline std::string read_cache_file(const std::string &path, std::vector<unsigned char> &bytes) {
  std::error_code ec;
  const auto status = std::filesystem::symlink_status(path, ec);
  if (!ec && std::filesystem::exists(status) && !std::filesystem::is_regular_file(status)) {
    std::filesystem::remove_all(path, ec);
    return "not a regular file; removed";
  }
  std::ifstream f(path, std::ios::binary | std::ios::ate);
  if (!f) return "missing";
  // One read of the whole file (a byte-wise istreambuf_iterator copy cost ~28 M instructions per SG table load).
  const std::streamoff size = f.tellg();
  if (size < 0) return "unreadable (no size)";
  bytes.resize(size_t(size));
  f.seekg(0);
  if (size > 0 && !f.read(reinterpret_cast<char *>(bytes.data()), size)) return "unreadable (short read)";
  return "";
}

// Returns "" when `bytes` is exactly the data [0, data_end) followed by its
// HMAC-SHA256 under the secret of the folder of `path`, else why not. For
// loaders that parse the payload before the MAC (their "truncated" or "bad
// header" verdicts come first).
inline std::string check_cache_mac(const std::string &path, const std::vector<unsigned char> &bytes, size_t data_end) {
  CacheKey secret;
  if (std::string problem = cache_secret_key(std::filesystem::path(path).parent_path().string(), secret);
      !problem.empty())
    return problem;
  Digest256 mac{};
  if (data_end > bytes.size() || bytes.size() - data_end != mac.size()) return "MAC mismatch (corrupt or crafted file)";
  std::copy(bytes.begin() + std::ptrdiff_t(data_end), bytes.end(), mac.begin());
  if (mac != hmac_sha256(secret.data(), secret.size(), bytes.data(), data_end))
    return "MAC mismatch (corrupt or crafted file)";
  return "";
}

// Returns "" and the payload, "missing", or why the file cannot be trusted.
inline std::string read_cache_blob(const std::string &path, std::vector<unsigned char> &payload) {
  if (std::string problem = read_cache_file(path, payload); !problem.empty()) return problem;
  if (payload.size() < Digest256{}.size()) return "truncated";
  const size_t data_size = payload.size() - Digest256{}.size();
  if (std::string problem = check_cache_mac(path, payload, data_size); !problem.empty()) return problem;
  payload.resize(data_size);
  return "";
}

// `dir`/<prefix><key as 16 hex digits>.bin: a table's entry in the cache folder.
inline std::string cache_entry_path(const std::string &dir, const char *prefix, uint64_t key) {
  char name[96];
  std::snprintf(name, sizeof(name), "%s%016llx.bin", prefix, static_cast<unsigned long long>(key));
  return (std::filesystem::path(dir) / name).string();
}

// 64-bit FNV-1a, chained: the key that names a cache file (glint_*_<key>.bin).
// add(x) hashes the bytes of x (an object, a C array or a std::array). The
// start value is not FNV's published offset basis (14695981039346656037): a
// digit short since the first glint cache; kept, as it names existing files.
struct Fnv1a {
  uint64_t h = 1469598103934665603ull;
  Fnv1a &add(const void *data, size_t size) {
    const auto *p = static_cast<const unsigned char *>(data);
    for (size_t i = 0; i < size; ++i) {
      h ^= p[i];
      h *= 1099511628211ull;
    }
    return *this;
  }
  template <class T>
  Fnv1a &add(const T &value) {
    return add(&value, sizeof(T));
  }
};

// Appends bytes to a payload (native byte order, as the readers expect).
struct ByteWriter {
  std::vector<unsigned char> bytes;
  void put(const void *data, size_t size) {
    const auto *c = static_cast<const unsigned char *>(data);
    bytes.insert(bytes.end(), c, c + size);
  }
  template <class T>
  void put(const T &value) {
    put(&value, sizeof(T));
  }
  // The header every table cache starts with: magic, format version, key.
  void put_header(const char (&magic)[8], uint32_t version, uint64_t key) {
    put(magic);
    put(version);
    put(key);
  }
};

// Sequential reads from a payload; get() fails (false) past its end.
struct ByteReader {
  const std::vector<unsigned char> &bytes;
  size_t pos = 0;
  bool get(void *out, size_t n) {
    if (pos + n > bytes.size()) return false;
    std::memcpy(out, bytes.data() + pos, n);
    pos += n;
    return true;
  }
  bool at_end() const { return pos == bytes.size(); }
  // Reads the header ByteWriter::put_header wrote; false unless it has
  // exactly this magic, version and key.
  bool get_header(const char (&magic)[8], uint32_t version, uint64_t key) {
    char m[8];
    uint32_t v = 0;
    uint64_t k = 0;
    return get(m, 8) && std::memcmp(m, magic, 8) == 0 && get(&v, 4) && v == version && get(&k, 8) && k == key;
  }
};

}  // namespace glimmer
