// The per-user secret that keys the MAC of every cache file (sha256.h):
// CACHE_DIR/secret.key, 32 bytes from the kernel's random source, mode 0600,
// in the private cache folder (atomic_file.h, ensure_private_directory).
// Created once, complete or not at all (a fully written temporary file is
// hard-linked into place; link() never replaces an existing key).
#pragma once

#include <fcntl.h>
#include <sys/random.h>
#include <sys/stat.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstdint>
#include <cstring>
#include <string>

#include "glimmer/atomic_file.h"

namespace glimmer {

using CacheKey = std::array<uint8_t, 32>;

// Reads (or creates) the key of `dir`; returns "" on success, else why the
// cache must not be trusted (a key that is not ours, not private, or malformed).
inline std::string cache_secret_key(const std::string &dir, CacheKey &key) {
  const std::string path = dir + "/secret.key";
  for (int attempt = 0; attempt < 3; ++attempt) {
    const int fd = ::open(path.c_str(), O_RDONLY | O_NOFOLLOW | O_CLOEXEC | O_NONBLOCK);
    if (fd >= 0) {
      struct stat st {};
      std::string problem;
      if (::fstat(fd, &st) != 0) problem = std::strerror(errno);
      else if (!S_ISREG(st.st_mode)) problem = "not a regular file";
      else if (st.st_uid != ::geteuid()) problem = "belongs to another user";
      else if ((st.st_mode & 077) != 0) problem = "readable or writable by others";
      else if (st.st_size != static_cast<off_t>(key.size())) problem = "not " + std::to_string(key.size()) + " bytes";
      else if (::read(fd, key.data(), key.size()) != static_cast<ssize_t>(key.size())) problem = "read failed";
      ::close(fd);
      return problem.empty() ? problem : "cache key '" + path + "': " + problem;
    }
    if (errno != ENOENT) return "cache key '" + path + "': " + std::strerror(errno);
    // Create: a complete private temporary file, then link() it into place.
    CacheKey fresh{};
    if (::getrandom(fresh.data(), fresh.size(), 0) != static_cast<ssize_t>(fresh.size()))
      return "no random bytes for the cache key";
    const std::string temp = dir + "/.secret.key." + random_hex16() + ".tmp";
    const int out = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0600);
    if (out < 0) return "cannot create the cache key in '" + dir + "': " + std::strerror(errno);
    const bool written = ::write(out, fresh.data(), fresh.size()) == static_cast<ssize_t>(fresh.size()) &&
                         ::fsync(out) == 0;
    ::close(out);
    const bool linked = written && ::link(temp.c_str(), path.c_str()) == 0;
    const int link_errno = errno;
    ::unlink(temp.c_str());
    if (linked) {
      key = fresh;
      return {};
    }
    if (!written || link_errno != EEXIST) return "cannot create the cache key '" + path + "'";
    // Another process created it first: read theirs.
  }
  return "cache key '" + path + "' keeps changing";
}

}  // namespace glimmer
