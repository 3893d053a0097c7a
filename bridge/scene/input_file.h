// Opening the files a scene names (XML, includes, meshes, textures) and the
// plugin: only regular files are accepted, checked on the open descriptor
// (open with O_NONBLOCK so a FIFO cannot block, then fstat), so a FIFO, a
// device such as /dev/zero, a socket or a directory is refused with a clear
// message instead of hanging or reading forever; reads are bounded by a size
// limit. Errors throw InputFileError naming the file and the reason.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>

namespace glimmer::scene {

class InputFileError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Size limits (bytes) per kind of input (docs/scene-format.md, "Limits").
constexpr uint64_t kMaxSceneFileBytes = uint64_t{256} << 20;  // one XML file
constexpr uint64_t kMaxMeshFileBytes = uint64_t{2} << 30;     // one OBJ/PLY file

// Why `path` is not a readable regular file, in a few words ("is a directory",
// "is a FIFO", "No such file or directory"); empty when it is one. `size`
// receives its size.
std::string regular_file_problem(const std::string &path, uint64_t *size = nullptr);

// Throws InputFileError ("<what> 'path': is a FIFO, not a regular file").
uint64_t require_regular_file(const std::string &path, const std::string &what);

// The whole content of a regular file of at most `max_bytes` bytes.
std::string read_regular_file(const std::string &path, uint64_t max_bytes, const std::string &what);

}  // namespace glimmer::scene
