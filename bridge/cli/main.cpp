// glimmer: the command-line host. Sub-commands are in cli/command_*.cpp.
#include <csignal>
#include <cstdio>
#include <exception>
#include <new>
#include <string>
#include <string_view>
#include <vector>

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
  app.set_version_flag(
      "--version", [&ctx] { return cli::version_text(ctx); },
      "print glimmer's version and closure ABI, and the plugin it loads");

  cli::add_describe_command(app, ctx);
  cli::add_lab_command(app, ctx);
  cli::add_render_command(app, ctx);
  cli::add_precompute_command(app, ctx);
  cli::add_bench_command(app, ctx);
  cli::add_merge_command(app, ctx);
  cli::add_farm_command(app, ctx);

  try {
    app.parse(argc, argv);
  } catch (const CLI::RequiredError &e) {
    // A typo leaves arguments nothing understood (`glimmer rendr ...`, `glimmer render --sampels 4`), and CLI11
    // reports only the requirement that is then unmet ("A subcommand is required"): name what was not understood.
    const std::vector<std::string> rest = app.remaining(true);
    if (rest.empty()) return app.exit(e) == 0 ? cli::kExitOk : cli::kExitBadInput;
    CLI::App *deepest = &app;  // the last sub-command given
    while (!deepest->get_subcommands().empty()) deepest = deepest->get_subcommands().front();
    const auto choices = deepest->get_subcommands([](CLI::App *) { return true; });
    std::string message;
    if (!choices.empty() && rest.front().rfind('-', 0) != 0) {
      message = "unknown sub-command '" + rest.front() + "' (one of:";
      for (const CLI::App *c : choices) message += " " + c->get_name();
      message += ")";
    } else {
      message = std::string(e.what()) + "; not understood:";
      for (const auto &r : rest) message += " '" + r + "'";
    }
    std::fprintf(stderr, "%s\nRun with --help for more information.\n", message.c_str());
    return cli::kExitBadInput;
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
