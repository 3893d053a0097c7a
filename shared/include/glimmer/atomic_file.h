// The one way Glimmer writes a file (images, plots, generated tables, the
// glint cache): the bytes go to a new temporary file in the target's folder,
// created with O_CREAT|O_EXCL|O_NOFOLLOW under a random name (so a planted
// file or symlink is never opened or followed), are fsync'ed, and the file is
// renamed over the target (rename replaces a symlink at the target itself,
// never the file it points to). Readers see the old or the new complete file.
#pragma once

#include <fcntl.h>
#include <sys/random.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>

namespace glimmer {

// 16 hex digits from the kernel's random source (not the PID, not an address).
inline std::string random_hex16() {
  uint64_t r = 0;
  size_t got = 0;
  while (got < sizeof(r)) {
    const ssize_t n = ::getrandom(reinterpret_cast<char *>(&r) + got, sizeof(r) - got, 0);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    got += static_cast<size_t>(n);
  }
  char hex[17];
  std::snprintf(hex, sizeof(hex), "%016llx", static_cast<unsigned long long>(r));
  return hex;
}

// Writes `size` bytes to `target` atomically with permission `mode` (before
// the umask). Returns "" on success, else a message naming the file and the
// reason; no temporary file is left behind on failure.
inline std::string write_file_atomically(const std::string &target, const void *data, size_t size,
                                         mode_t mode = 0644) {
  const size_t slash = target.rfind('/');
  const std::string dir = slash == std::string::npos ? "." : (slash == 0 ? "/" : target.substr(0, slash));
  const std::string base = slash == std::string::npos ? target : target.substr(slash + 1);
  if (base.empty()) return "'" + target + "' names a folder, not a file";
  std::string temp;
  int fd = -1;
  for (int attempt = 0; attempt < 16 && fd < 0; ++attempt) {
    temp = dir + "/." + base + "." + random_hex16() + ".tmp";
    fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, mode);
    if (fd < 0 && errno != EEXIST) break;
  }
  if (fd < 0) return "cannot create a temporary file in '" + dir + "' for '" + target + "': " + std::strerror(errno);
  auto fail = [&](const char *what) {
    const std::string why = std::strerror(errno);
    if (fd >= 0) ::close(fd);
    ::unlink(temp.c_str());
    return std::string("cannot write '") + target + "': " + what + ": " + why;
  };
  const auto *bytes = static_cast<const char *>(data);
  size_t done = 0;
  while (done < size) {
    const ssize_t n = ::write(fd, bytes + done, size - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return fail("write failed");
    done += static_cast<size_t>(n);
  }
  if (::fsync(fd) != 0) return fail("fsync failed");
  if (::close(fd) != 0) {
    fd = -1;
    return fail("close failed");
  }
  fd = -1;
  if (::rename(temp.c_str(), target.c_str()) != 0) return fail("rename failed");
  // Make the rename itself durable.
  const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd >= 0) {
    ::fsync(dfd);
    ::close(dfd);
  }
  return {};
}

inline std::string write_file_atomically(const std::string &target, const std::string &bytes, mode_t mode = 0644) {
  return write_file_atomically(target, bytes.data(), bytes.size(), mode);
}

// Makes `dir` a private folder for caches: missing folders are created with
// mode 0700; the last one must then be a real directory (not a symlink) owned
// by this user, and group/other permissions are removed. Returns "" when the
// folder is fit for use, else why not.
inline std::string ensure_private_directory(const std::string &dir) {
  if (dir.empty()) return "no folder given";
  for (size_t pos = 1; pos <= dir.size(); ++pos) {
    if (pos != dir.size() && dir[pos] != '/') continue;
    const std::string prefix = dir.substr(0, pos);
    if (::mkdir(prefix.c_str(), 0700) != 0 && errno != EEXIST)
      return "cannot create '" + prefix + "': " + std::strerror(errno);
  }
  struct stat st {};
  if (::lstat(dir.c_str(), &st) != 0) return "'" + dir + "': " + std::strerror(errno);
  if (!S_ISDIR(st.st_mode)) return "'" + dir + "' is not a directory (or is a symlink)";
  if (st.st_uid != ::geteuid()) return "'" + dir + "' belongs to another user";
  if ((st.st_mode & 077) != 0 && ::chmod(dir.c_str(), 0700) != 0)
    return "cannot make '" + dir + "' private: " + std::strerror(errno);
  return {};
}

}  // namespace glimmer
