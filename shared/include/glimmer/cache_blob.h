// One authenticated cache file: the payload followed by its HMAC-SHA256 keyed
// by the cache folder's secret (cache_key.h), written atomically into a
// private folder (atomic_file.h). Readers get the payload back only when the
// MAC verifies (a corrupt or crafted file is refused, saying why); junk at the
// path (a directory, a FIFO, a symlink) is removed so a rebuilt entry can take
// its place. The payload's own format and validation are the caller's.
#pragma once

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

// Returns "" and the payload, "missing", or why the file cannot be trusted.
inline std::string read_cache_blob(const std::string &path, std::vector<unsigned char> &payload) {
  std::error_code ec;
  const auto status = std::filesystem::symlink_status(path, ec);
  if (!ec && std::filesystem::exists(status) && !std::filesystem::is_regular_file(status)) {
    std::filesystem::remove_all(path, ec);
    return "not a regular file; removed";
  }
  std::ifstream f(path, std::ios::binary);
  if (!f) return "missing";
  payload.assign(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
  Digest256 mac{};
  if (payload.size() < mac.size()) return "truncated";
  const size_t data_size = payload.size() - mac.size();
  std::copy(payload.begin() + std::ptrdiff_t(data_size), payload.end(), mac.begin());
  CacheKey secret;
  if (std::string problem = cache_secret_key(std::filesystem::path(path).parent_path().string(), secret);
      !problem.empty())
    return problem;
  if (mac != hmac_sha256(secret.data(), secret.size(), payload.data(), data_size))
    return "MAC mismatch (corrupt or crafted file)";
  payload.resize(data_size);
  return "";
}

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
};

}  // namespace glimmer
