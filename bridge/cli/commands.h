// Each `glimmer` sub-command lives in its own cli/command_*.cpp and is added
// to the application by one add_*_command function listed in main.cpp.
#pragma once

#include <CLI/CLI.hpp>
#include <memory>
#include <string>

#include "host/plugin_library.h"

namespace glimmer::cli {

// Exit codes: 0 ok, 1 bad input (scene, parameters, arguments),
// 2 plugin missing/broken/ABI mismatch, 3 interrupted (partial image written).
enum ExitCode { kExitOk = 0, kExitBadInput = 1, kExitPlugin = 2, kExitInterrupted = 3 };

// An error already explained to the user; carries the exit code.
class CliError : public std::runtime_error {
 public:
  CliError(int code, const std::string &message) : std::runtime_error(message), code_(code) {}
  int code() const { return code_; }

 private:
  int code_;
};

// State shared by all sub-commands: global options and the lazily loaded DSO
// (a command that needs no closures never touches it).
struct CliContext {
  std::string plugin_path;  // --plugin
  int exit_code = kExitOk;  // set by a command that finishes with a non-zero status
  host::PluginLibrary &plugin() {
    if (!library) library = host::PluginLibrary::locate(plugin_path);
    return *library;
  }

 private:
  std::unique_ptr<host::PluginLibrary> library;
};

// SIGINT/SIGTERM set the render's cancel flag (a second signal terminates).
// main() installs them before parsing when the command line is a render, so
// an interrupt is honoured from the first instruction.
void install_render_interrupt_handlers();

void add_describe_command(CLI::App &app, CliContext &ctx);
// `glimmer --version`: the host's version and closure ABI, then the plugin it loads (name, version, ABI, path) or why
// none loads (a farm task's log records what rendered it).
std::string version_text(CliContext &ctx);
void add_lab_command(CLI::App &app, CliContext &ctx);
void add_render_command(CLI::App &app, CliContext &ctx);
void add_precompute_command(CLI::App &app, CliContext &ctx);
void add_bench_command(CLI::App &app, CliContext &ctx);
void add_merge_command(CLI::App &app, CliContext &ctx);
void add_farm_command(CLI::App &app, CliContext &ctx);

}  // namespace glimmer::cli
