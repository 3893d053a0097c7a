#include "host/log.h"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <string>

namespace glimmer::host {

void log(int level, std::string_view message) {
  static const char *const names[] = {"debug", "info", "warning", "error"};
  const int l = std::clamp(level, 0, 3);
  if (l == GLIMMER_LOG_DEBUG && std::getenv("GLIMMER_DEBUG") == nullptr) return;
  const std::string line = std::string("glimmer: ") + names[l] + ": " + std::string(message) + "\n";
  static std::mutex mutex;
  const std::lock_guard<std::mutex> lock(mutex);
  std::fputs(line.c_str(), stderr);
}

void log_callback(void *, int level, const char *message) { log(level, message ? message : "(null)"); }

}  // namespace glimmer::host
