// `glimmer lab ...`: the closure laboratory (furnace, chi2, bench, plot).
#include "cli/commands.h"

namespace glimmer::cli {

void add_lab_command(CLI::App &app, CliContext &ctx) {
  auto *lab = app.add_subcommand("lab", "closure laboratory: furnace, chi2, bench, plot");
  lab->require_subcommand(1);
  (void)ctx;
}

}  // namespace glimmer::cli
