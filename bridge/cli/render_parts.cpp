#include "cli/render_parts.h"

#include <sstream>

#include "cli/commands.h"
#include "render/image_output.h"

namespace glimmer::cli {

namespace {

// Two integers separated by `sep`, nothing else.
bool parse_pair(const std::string &text, char sep, int &a, int &b) {
  std::istringstream in(text);
  char c = 0;
  std::string rest;
  return (in >> a >> c >> b) && c == sep && !(in >> rest);
}

}  // namespace

std::vector<int> parse_frames(const std::string &spec) {
  std::vector<int> frames;
  std::stringstream in(spec);
  std::string part;
  while (std::getline(in, part, ',')) {
    if (part.empty()) continue;
    try {
      const auto dash = part.find('-', 1);
      size_t used = 0;
      if (dash == std::string::npos) {
        frames.push_back(std::stoi(part, &used));
        if (used != part.size()) throw std::invalid_argument(part);
      } else {
        const int a = std::stoi(part.substr(0, dash)), b = std::stoi(part.substr(dash + 1), &used);
        if (used != part.size() - dash - 1 || b < a || b - a > 100000) throw std::invalid_argument(part);
        for (int f = a; f <= b; ++f) frames.push_back(f);
      }
    } catch (const std::exception &) {
      throw CliError(kExitBadInput, "--frames: '" + part + "' is not a frame or range (e.g. 1-10,12)");
    }
  }
  if (frames.empty()) throw CliError(kExitBadInput, "--frames: no frames in '" + spec + "'");
  return frames;
}

std::pair<int, int> parse_sample_range(const std::string &text) {
  int a = 0, b = 0;
  if (!parse_pair(text, ',', a, b) || a < 0 || b <= a)
    throw CliError(kExitBadInput, "--sample-range must be a,b with 0 <= a < b (samples a..b-1), got '" + text + "'");
  return {a, b};
}

std::pair<int, int> parse_split(const std::string &option, const std::string &text) {
  int k = 0, n = 0;
  if (!parse_pair(text, '/', k, n) || n < 1 || k < 0 || k >= n)
    throw CliError(kExitBadInput, option + " must be k/N with 0 <= k < N, got '" + text + "'");
  return {k, n};
}

std::pair<int, int> split_range(const std::string &option, int k, int n, int total) {
  if (n > total)
    throw CliError(kExitBadInput, option + " " + std::to_string(k) + "/" + std::to_string(n) + ": cannot cut " +
                                      std::to_string(total) + " into " + std::to_string(n) + " non-empty parts");
  const long long t = total;
  return {static_cast<int>(k * t / n), static_cast<int>((k + 1) * t / n)};
}

std::string checkpoint_path(const std::string &output) {
  const auto dot = output.find_last_of('.');
  const auto slash = output.find_last_of('/');
  const bool has_ext = dot != std::string::npos && (slash == std::string::npos || dot > slash);
  return (has_ext ? output.substr(0, dot) : output) + ".checkpoint.exr";
}

void write_checkpoint(const std::string &path, const render::Film &film, const render::PartInfo &part) {
  render::RenderResult r;
  film.store(r);
  r.part = part;
  r.samples_requested = part.sample_end - part.sample_begin;
  r.samples_done = film.passes();
  render::write_image(path, r);
}

void write_display(const std::string &path, const render::Film &film, const render::PartInfo &part, float exposure) {
  render::RenderResult r;
  film.resolve(exposure, r);
  r.width = film.width();
  r.height = film.height();
  r.part = part;
  r.samples_done = film.passes();
  render::write_display_image(path, r);
}

render::Film read_checkpoint(const std::string &path, const render::PartInfo &part) {
  render::RenderResult r;
  try {
    r = render::read_image(path);
  } catch (const std::exception &e) {
    throw CliError(kExitBadInput, std::string("--resume: ") + e.what());
  }
  const render::PartInfo &c = r.part;
  auto differ = [&](const std::string &what, const std::string &have, const std::string &want) {
    if (have != want)
      throw CliError(kExitBadInput, "--resume: checkpoint '" + path + "' belongs to another render (" + what + " " +
                                        have + ", this render " + want + "); delete it or drop --resume");
  };
  auto window = [](const render::PartInfo &p) {
    std::string s;
    for (int v : p.window) s += (s.empty() ? "" : ",") + std::to_string(v);
    return s;
  };
  if (!r.film_sums) throw CliError(kExitBadInput, "--resume: '" + path + "' is not a checkpoint");
  differ("scene hash", c.scene_hash, part.scene_hash);
  differ("resolution", std::to_string(c.full_width) + "x" + std::to_string(c.full_height),
         std::to_string(part.full_width) + "x" + std::to_string(part.full_height));
  differ("seed", std::to_string(c.seed), std::to_string(part.seed));
  differ("samples", std::to_string(c.samples_total), std::to_string(part.samples_total));
  differ("strategy", c.strategy, part.strategy);
  differ("sample range", std::to_string(c.sample_begin) + "," + std::to_string(c.sample_end),
         std::to_string(part.sample_begin) + "," + std::to_string(part.sample_end));
  differ("region", window(c), window(part));
  return render::Film::restore(r);
}

}  // namespace glimmer::cli
