// The host's one logger: "glimmer: <level>: <message>" lines on stderr, whole
// lines even from many threads; debug messages only with $GLIMMER_DEBUG set.
// Levels are GlimmerLogLevel's, so the plugin's log service (GlimmerHostServices
// .log) is the same logger (log_callback).
#pragma once

#include <string_view>

#include "glimmer/closure_abi.h"

namespace glimmer::host {

void log(int level, std::string_view message);
inline void log_warning(std::string_view message) { log(GLIMMER_LOG_WARNING, message); }
inline void log_error(std::string_view message) { log(GLIMMER_LOG_ERROR, message); }

// GlimmerHostServices.log (host_data is not used).
void log_callback(void *host_data, int level, const char *message);

}  // namespace glimmer::host
