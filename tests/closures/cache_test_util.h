// Pieces of the table-cache tests (test_glint_cache_hostile.cpp,
// test_glint_aniso_cache.cpp): host services that cache in a folder and
// capture the log, a cache file's bytes, and the edits an attacker can make
// to them (recompute the trailing HMAC with a stolen key, or the old unkeyed
// FNV-1a checksum).
#pragma once

#include <sys/resource.h>

#include <csignal>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "glimmer/sha256.h"
#include "host/closure_instance.h"

namespace glimmer::test {

// The messages logged through host_caching_in's services ("<level>: <text>").
inline std::vector<std::string> g_cache_log;
inline void capture_cache_log(void *, int level, const char *message) {
  g_cache_log.push_back(std::to_string(level) + ": " + message);
}
inline bool logged(const std::string &text) {
  for (const auto &m : g_cache_log)
    if (m.find(text) != std::string::npos) return true;
  return false;
}

// Host services caching in `dir` and logging to g_cache_log.
inline GlimmerHostServices host_caching_in(const std::string &dir) {
  GlimmerHostServices host = *host::default_host_services();
  host.cache_dir = dir.c_str();
  host.log = &capture_cache_log;
  return host;
}

// While alive, files this process writes cannot grow past `bytes` (RLIMIT_FSIZE; SIGXFSZ ignored, so write() fails
// with EFBIG): a cache write that fails after its file was created (a full disk or quota), also for root, whom a
// read-only mode does not stop. (A read-only folder fails earlier, at open(): the same "not written" path with
// another reason.) The limit is per process: keep the scope to the writes under test (gtest's own output goes to a
// pipe under ctest; redirected to a file inside the scope it would be cut too).
class FileSizeLimit {
 public:
  explicit FileSizeLimit(rlim_t bytes) {
    if (::getrlimit(RLIMIT_FSIZE, &old_) != 0) return;  // ok() false; nothing to restore
    old_handler_ = std::signal(SIGXFSZ, SIG_IGN);
    rlimit limit = old_;
    limit.rlim_cur = bytes;
    set_ = true;
    ok_ = old_handler_ != SIG_ERR && ::setrlimit(RLIMIT_FSIZE, &limit) == 0;
  }
  ~FileSizeLimit() {
    if (!set_) return;
    ::setrlimit(RLIMIT_FSIZE, &old_);
    if (old_handler_ != SIG_ERR) std::signal(SIGXFSZ, old_handler_);
  }
  bool ok() const { return ok_; }
  FileSizeLimit(const FileSizeLimit &) = delete;
  FileSizeLimit &operator=(const FileSizeLimit &) = delete;

 private:
  rlimit old_{};
  void (*old_handler_)(int) = SIG_DFL;
  bool set_ = false, ok_ = false;
};

inline std::vector<char> read_bytes(const std::filesystem::path &p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

inline void write_bytes(const std::filesystem::path &p, const std::vector<char> &bytes) {
  std::ofstream(p, std::ios::binary | std::ios::trunc).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

// Recomputes the file's trailing 32-byte HMAC-SHA256 with `key` (what an
// attacker who could read the key would do).
inline void rewrite_mac(std::vector<char> &bytes, const std::vector<char> &key) {
  const Digest256 mac = hmac_sha256(key.data(), key.size(), bytes.data(), bytes.size() - 32);
  std::memcpy(bytes.data() + bytes.size() - 32, mac.data(), 32);
}

// The old, unkeyed integrity check: FNV-1a over the content, which anyone can
// recompute; written over the first 8 bytes of the MAC.
inline void rewrite_fnv(std::vector<char> &bytes) {
  uint64_t h = 1469598103934665603ull;
  for (size_t i = 0; i + 32 < bytes.size(); ++i) {
    h ^= static_cast<unsigned char>(bytes[i]);
    h *= 1099511628211ull;
  }
  std::memcpy(bytes.data() + bytes.size() - 32, &h, 8);
}

}  // namespace glimmer::test
