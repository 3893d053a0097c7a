// `glimmer merge parts... -o out.exr`: joins the parts of one render (tiles from
// --region/--tile, sample ranges from --sample-range/--sample-split) into the
// whole image; render/merge.h says what is checked and how pixels combine. Prints the summary, then the parts'
// summed warnings (textured values clamped to a parameter's range) as a one-machine render does.
#include <cstdio>

#include "cli/commands.h"
#include "render/image_output.h"
#include "render/merge.h"

namespace glimmer::cli {

void add_merge_command(CLI::App &app, CliContext &) {
  struct MergeArgs {
    std::vector<std::string> parts;
    std::string output;
    bool quiet = false;
  };
  auto args = std::make_shared<MergeArgs>();
  auto *cmd = app.add_subcommand("merge", "merge the EXR parts of one render (tiles and/or sample ranges)");
  cmd->add_option("parts", args->parts, "EXR parts written by glimmer render")->required();
  cmd->add_option("-o,--output", args->output, "merged image (.exr keeps every pass; .png the Combined pass)")
      ->required();
  cmd->add_flag("--quiet", args->quiet, "no summary line");
  cmd->callback([args] {
    std::vector<render::RenderResult> parts;
    for (const auto &path : args->parts) {
      try {
        parts.push_back(render::read_image(path));
      } catch (const std::exception &e) {
        throw CliError(kExitBadInput, e.what());
      }
    }
    render::RenderResult merged;
    try {
      merged = render::merge_parts(parts, args->parts);
      render::write_image(args->output, merged);
    } catch (const std::exception &e) {
      throw CliError(kExitBadInput, std::string("merge: ") + e.what());
    }
    if (!args->quiet)
      std::printf("merged %zu parts into %s: %dx%d, %d samples per pixel\n", parts.size(), args->output.c_str(),
                  merged.width, merged.height, merged.samples_done);
    std::fflush(stdout);
    // The parts' clamped textured values, summed: the lines a one-machine render prints after its last sample.
    for (const auto &w : merged.warnings) std::fprintf(stderr, "%s\n", w.c_str());
  });
}

}  // namespace glimmer::cli
