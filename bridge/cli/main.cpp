// glimmer: the command-line host. Sub-commands are in cli/command_*.cpp.
#include <csignal>
#include <exception>
#include <new>
#include <string_view>

#include "cli/commands.h"
#include "host/closure_instance.h"
#include "host/log.h"

int main(int argc, char **argv) {
  using namespace glimmer;
  // A reader of our progress output that goes away must not kill the render:
  // writes to the closed pipe fail with EPIPE and are ignored.
  std::signal(SIGPIPE, SIG_IGN);
  for (int i = 1; i < argc; ++i)
    if (std::string_view(argv[i]) == "render") cli::install_render_interrupt_handlers();
  CLI::App app{"Glimmer: glint and rough-refraction closures in a Cycles-style path tracer"};
  app.require_subcommand(1);
  // Global options such as --plugin may also follow the sub-command
  // (`glimmer describe --plugin PATH`); sub-commands inherit this setting.
  app.fallthrough();
  cli::CliContext ctx;
  app.add_option("--plugin", ctx.plugin_path, "path of libglimmer_closures.so (or its folder)");

  cli::add_describe_command(app, ctx);
  cli::add_lab_command(app, ctx);
  cli::add_render_command(app, ctx);
  cli::add_precompute_command(app, ctx);
  cli::add_bench_command(app, ctx);
  cli::add_merge_command(app, ctx);
  cli::add_farm_command(app, ctx);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError &e) {
    // --help exits 0; every malformed command line is bad input (exit 1).
    return app.exit(e) == 0 ? cli::kExitOk : cli::kExitBadInput;
  } catch (const host::PluginError &e) {
    host::log_error(e.what());
    return cli::kExitPlugin;
  } catch (const cli::CliError &e) {
    host::log_error(e.what());
    return e.code();
  } catch (const host::ClosureError &e) {
    host::log_error(e.what());
    return cli::kExitBadInput;
  } catch (const std::bad_alloc &) {
    host::log_error("out of memory");
    return cli::kExitBadInput;
  } catch (const std::exception &e) {
    host::log_error(e.what());
    return cli::kExitBadInput;
  }
  return ctx.exit_code;
}
