// Render options that cut one render into parts for a farm (docs/farm.md):
// --sample-range a,b / --sample-split k/N (samples), --tile k/N (rows), and
// checkpoint files for --checkpoint-every / --resume.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "render/film.h"

namespace glimmer::cli {

// --frames "1-10,12" -> 1..10, 12; throws CliError on a malformed spec.
std::vector<int> parse_frames(const std::string &spec);

// "a,b" -> [a, b); throws CliError unless 0 <= a < b.
std::pair<int, int> parse_sample_range(const std::string &text);

// "k/N" (0 <= k < N) for --tile and --sample-split; `option` names the flag in the error.
std::pair<int, int> parse_split(const std::string &option, const std::string &text);

// Part k of N of [0, total): [k*total/N, (k+1)*total/N). Throws CliError when N > total.
std::pair<int, int> split_range(const std::string &option, int k, int n, int total);

// out.exr -> out.checkpoint.exr (beside the output; always EXR: the film sums must be exact floats).
std::string checkpoint_path(const std::string &output);

// Writes the film (raw sums) atomically with the part's metadata.
void write_checkpoint(const std::string &path, const render::Film &film, const render::PartInfo &part);

// Writes the film's image so far (means x exposure, alpha) for a viewer: render::write_display_image.
void write_display(const std::string &path, const render::Film &film, const render::PartInfo &part, float exposure);

// Reads a checkpoint and checks it belongs to `part` (same scene hash, resolution, seed,
// samples, strategy, sample range, window); throws CliError saying what differs.
render::Film read_checkpoint(const std::string &path, const render::PartInfo &part);

}  // namespace glimmer::cli
