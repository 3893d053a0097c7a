#include "render/image_output.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <stdexcept>

#include "glimmer/atomic_file.h"
#include "render/image_io.h"

namespace glimmer::render {

namespace fs = std::filesystem;

std::string frame_path(const std::string &pattern, int frame) {
  const auto start = pattern.find('#');
  if (start == std::string::npos) return pattern;
  auto end = start;
  while (end < pattern.size() && pattern[end] == '#') ++end;
  std::string number = std::to_string(std::abs(frame));
  const size_t pad = end - start;
  if (number.size() < pad) number = std::string(pad - number.size(), '0') + number;
  if (frame < 0) number = "-" + number;
  return pattern.substr(0, start) + number + pattern.substr(end);
}

namespace {

std::string lower_extension(const std::string &path) {
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

// The folder an output path is written into ("." for a bare file name).
fs::path output_folder(const std::string &path) {
  const fs::path target(path);
  return target.has_parent_path() ? target.parent_path() : fs::path(".");
}

}  // namespace

bool is_exr_path(const std::string &path) { return lower_extension(path) == ".exr"; }

bool known_writable_extension(const std::string &path) {
  const std::string ext = lower_extension(path);
  return std::find(kKnownWritableExtensions.begin(), kKnownWritableExtensions.end(), ext) !=
         kKnownWritableExtensions.end();
}

void check_output_format(const std::string &path) {
  if (!fs::path(path).has_extension())
    throw std::runtime_error("output '" + path + "' has no file extension (.exr or .png)");
  // Other extensions: ask the image module (this waits for it to load).
  if (!known_writable_extension(path)) image_io().check_output_format(path);
}

void check_output_path(const std::string &path) {
  check_output_format(path);
  const fs::path dir = output_folder(path);
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw std::runtime_error("output folder '" + dir.string() + "' does not exist");
  if (fs::is_directory(fs::path(path), ec)) throw std::runtime_error("output '" + path + "' is a folder");
  if (::access(dir.c_str(), W_OK | X_OK) != 0)
    throw std::runtime_error("output folder '" + dir.string() + "' is not writable");
}

void check_output_folder_takes_files(const std::string &path) {
  const fs::path dir = output_folder(path);
  // access(W_OK) passes where no file can be created (/proc for root, some FUSE and network mounts): try one. A short
  // fixed-length name (not the output's name + a suffix: the output's name may be near NAME_MAX).
  std::string name = ".glimmer-probe-";  // appended, not "." + ...: GCC 12's -Wrestrict misfires on insert
  name.append(random_hex16());
  const std::string probe = (dir / name).string();
  const int fd = ::open(probe.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0600);
  if (fd < 0) {
    const int error = errno;
    throw std::runtime_error("cannot create a file in output folder '" + dir.string() + "': " + std::strerror(error));
  }
  ::close(fd);
  if (::unlink(probe.c_str()) != 0) {
    const int error = errno;
    throw std::runtime_error("cannot remove the probe file '" + probe + "' in output folder '" + dir.string() +
                             "': " + std::strerror(error));
  }
}

void write_image(const std::string &path, const RenderResult &result) {
  check_output_path(path);
  if (is_exr_path(path)) exr_writer().write_image(path, result);
  else image_io().write_image(path, result);
}
void write_display_image(const std::string &path, const RenderResult &result) {
  check_output_path(path);
  if (is_exr_path(path)) exr_writer().write_display_image(path, result);
  else image_io().write_display_image(path, result);
}
void load_output_module(const std::string &path) {
  if (is_exr_path(path)) exr_writer();
  else image_io();
}
RenderResult read_image(const std::string &path) { return image_io().read_image(path); }
void write_8bit_image(const std::string &path, int width, int height, int channels, const unsigned char *pixels) {
  check_output_path(path);
  image_io().write_bytes(path, width, height, channels, pixels);
}

}  // namespace glimmer::render
