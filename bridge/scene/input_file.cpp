#include "scene/input_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <new>

namespace glimmer::scene {

namespace {

// Owns a file descriptor.
struct Fd {
  int fd = -1;
  ~Fd() {
    if (fd >= 0) ::close(fd);
  }
};

std::string kind_of(mode_t mode) {
  if (S_ISDIR(mode)) return "is a directory";
  if (S_ISFIFO(mode)) return "is a FIFO (named pipe)";
  if (S_ISCHR(mode)) return "is a character device";
  if (S_ISBLK(mode)) return "is a block device";
  if (S_ISSOCK(mode)) return "is a socket";
  return "is not a regular file";
}

// Opens `path` read-only without blocking and checks the descriptor is a
// regular file; returns the problem ("" when fine).
std::string open_regular(const std::string &path, Fd &fd, uint64_t &size) {
  fd.fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
  if (fd.fd < 0) return std::strerror(errno);
  struct stat st {};
  if (::fstat(fd.fd, &st) != 0) return std::strerror(errno);
  if (!S_ISREG(st.st_mode)) return kind_of(st.st_mode) + ", not a regular file";
  size = static_cast<uint64_t>(st.st_size);
  // Back to blocking reads for a regular file (O_NONBLOCK only guarded the open).
  const int flags = ::fcntl(fd.fd, F_GETFL);
  if (flags >= 0) ::fcntl(fd.fd, F_SETFL, flags & ~O_NONBLOCK);
  return {};
}

}  // namespace

std::string regular_file_problem(const std::string &path, uint64_t *size) {
  Fd fd;
  uint64_t bytes = 0;
  std::string problem = open_regular(path, fd, bytes);
  if (size) *size = bytes;
  return problem;
}

uint64_t require_regular_file(const std::string &path, const std::string &what) {
  uint64_t size = 0;
  const std::string problem = regular_file_problem(path, &size);
  if (!problem.empty()) throw InputFileError(what + " '" + path + "': " + problem);
  return size;
}

std::string read_regular_file(const std::string &path, uint64_t max_bytes, const std::string &what) {
  Fd fd;
  uint64_t size = 0;
  const std::string problem = open_regular(path, fd, size);
  if (!problem.empty()) throw InputFileError(what + " '" + path + "': " + problem);
  if (size > max_bytes)
    throw InputFileError(what + " '" + path + "': " + std::to_string(size) + " bytes is more than the limit of " +
                         std::to_string(max_bytes));
  std::string text;
  try {
    text.resize(static_cast<size_t>(size));
  } catch (const std::bad_alloc &) {
    throw InputFileError(what + " '" + path + "': out of memory for " + std::to_string(size) + " bytes");
  }
  size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::read(fd.fd, text.data() + done, text.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw InputFileError(what + " '" + path + "': read failed: " + std::strerror(errno));
    if (n == 0) break;  // the file shrank while reading
    done += static_cast<size_t>(n);
  }
  text.resize(done);
  return text;
}

}  // namespace glimmer::scene
