#include "render/merge.h"

#include <algorithm>
#include <map>
#include <stdexcept>
#include <tuple>

namespace glimmer::render {

namespace {

std::string window_text(const int w[4]) {
  return "[" + std::to_string(w[0]) + "," + std::to_string(w[1]) + " - " + std::to_string(w[2]) + "," +
         std::to_string(w[3]) + ")";
}

std::string range_text(const PartInfo &p) {
  return "[" + std::to_string(p.sample_begin) + ", " + std::to_string(p.sample_end) + ")";
}

// Every field that must be equal for parts of one render, named for the error message.
void check_same_render(const RenderResult &a, const std::string &an, const RenderResult &b, const std::string &bn) {
  auto differ = [&](const std::string &what, const std::string &va, const std::string &vb) {
    if (va != vb)
      throw std::runtime_error("parts '" + an + "' and '" + bn + "' come from different renders: " + what + " " + va +
                               " vs " + vb);
  };
  const PartInfo &p = a.part, &q = b.part;
  differ("scene hash", p.scene_hash.empty() ? "unknown" : p.scene_hash,
         q.scene_hash.empty() ? "unknown" : q.scene_hash);
  differ("resolution", std::to_string(p.full_width) + "x" + std::to_string(p.full_height),
         std::to_string(q.full_width) + "x" + std::to_string(q.full_height));
  differ("seed", std::to_string(p.seed), std::to_string(q.seed));
  differ("samples per pixel", std::to_string(p.samples_total), std::to_string(q.samples_total));
  differ("strategy", p.strategy, q.strategy);
  differ("AOV passes", a.albedo.empty() ? "no" : "yes", b.albedo.empty() ? "no" : "yes");
}

bool windows_overlap(const int a[4], const int b[4]) {
  return a[0] < b[2] && b[0] < a[2] && a[1] < b[3] && b[1] < a[3];
}

// Sample-count-weighted mean of `parts` over `window` into `out` (one part: an exact copy).
void combine_window(const std::vector<const RenderResult *> &parts, const int window[4], int samples_total,
                    RenderResult &out) {
  const int width = out.width;
  auto blend = [&](std::vector<float> RenderResult::*channel, int nc) {
    std::vector<float> &dst = out.*channel;
    for (int y = window[1]; y < window[3]; ++y)
      for (int x = window[0]; x < window[2]; ++x)
        for (int k = 0; k < nc; ++k) {
          const size_t i = (static_cast<size_t>(y) * width + x) * nc + k;
          if (parts.size() == 1) {
            dst[i] = (parts[0]->*channel)[i];
            continue;
          }
          double sum = 0.0;
          for (const RenderResult *p : parts)
            sum += static_cast<double>(p->part.sample_end - p->part.sample_begin) * (p->*channel)[i];
          dst[i] = static_cast<float>(sum / samples_total);
        }
  };
  blend(&RenderResult::combined, 4);
  if (out.albedo.empty()) return;
  blend(&RenderResult::albedo, 3);
  blend(&RenderResult::normal, 3);
  blend(&RenderResult::depth, 1);
}

// The parts of one pixel window (indices `in_window`) in sample order; their sample ranges must tile [0, N)
// exactly (no overlap, no duplicate, no gap).
std::vector<const RenderResult *> parts_tiling_samples(const std::vector<RenderResult> &parts,
                                                       const std::vector<std::string> &names,
                                                       const std::vector<size_t> &in_window, int N) {
  const int *w = parts[in_window.front()].part.window;
  std::vector<size_t> order = in_window;
  std::sort(order.begin(), order.end(),
            [&](size_t a, size_t b) { return parts[a].part.sample_begin < parts[b].part.sample_begin; });
  int next = 0;
  size_t previous = order.front();
  std::vector<const RenderResult *> window_parts;
  for (size_t k : order) {
    const PartInfo &p = parts[k].part;
    if (p.sample_begin < next) {
      const PartInfo &q = parts[previous].part;
      const bool duplicate = p.sample_begin == q.sample_begin && p.sample_end == q.sample_end;
      throw std::runtime_error(std::string(duplicate ? "duplicate parts" : "sample ranges overlap") + ": '" +
                               names[previous] + "' renders samples " + range_text(q) + " and '" + names[k] +
                               "' samples " + range_text(p) + " of pixels " + window_text(w));
    }
    if (p.sample_begin > next)
      throw std::runtime_error("samples [" + std::to_string(next) + ", " + std::to_string(p.sample_begin) +
                               ") of pixels " + window_text(w) + " are missing (no part renders them)");
    next = p.sample_end;
    previous = k;
    window_parts.push_back(&parts[k]);
  }
  if (next != N)
    throw std::runtime_error("samples [" + std::to_string(next) + ", " + std::to_string(N) + ") of pixels " +
                             window_text(w) + " are missing (no part renders them)");
  return window_parts;
}

}  // namespace

RenderResult merge_parts(const std::vector<RenderResult> &parts, const std::vector<std::string> &names) {
  if (parts.empty()) throw std::runtime_error("merge: no parts given");
  for (size_t k = 0; k < parts.size(); ++k) {
    const RenderResult &p = parts[k];
    if (p.film_sums)
      throw std::runtime_error("'" + names[k] + "' is a checkpoint, not a finished part (finish it with --resume)");
    if (p.interrupted || p.samples_done != p.part.sample_end - p.part.sample_begin)
      throw std::runtime_error("'" + names[k] + "' is incomplete: " + std::to_string(p.samples_done) + " of its " +
                               std::to_string(p.part.sample_end - p.part.sample_begin) +
                               " samples were rendered (interrupted or time-limited)");
    if (k > 0) check_same_render(parts[0], names[0], p, names[k]);
  }
  // Group the parts by window; distinct windows must not overlap.
  using Window = std::tuple<int, int, int, int>;
  std::map<Window, std::vector<size_t>> by_window;
  for (size_t k = 0; k < parts.size(); ++k) {
    const int *w = parts[k].part.window;
    by_window[{w[0], w[1], w[2], w[3]}].push_back(k);
  }
  const int N = parts[0].part.samples_total;
  RenderResult out;
  out.width = parts[0].width;
  out.height = parts[0].height;
  out.combined.assign(parts[0].combined.size(), 0.0f);
  out.albedo.assign(parts[0].albedo.size(), 0.0f);
  out.normal.assign(parts[0].normal.size(), 0.0f);
  out.depth.assign(parts[0].depth.size(), 0.0f);
  long long covered = 0;
  for (auto it = by_window.begin(); it != by_window.end(); ++it) {
    const size_t first = it->second.front();
    const int *w = parts[first].part.window;
    for (auto jt = std::next(it); jt != by_window.end(); ++jt) {
      const int *v = parts[jt->second.front()].part.window;
      if (windows_overlap(w, v))
        throw std::runtime_error("parts '" + names[first] + "' (pixels " + window_text(w) + ") and '" +
                                 names[jt->second.front()] + "' (pixels " + window_text(v) + ") overlap");
    }
    const std::vector<const RenderResult *> window_parts = parts_tiling_samples(parts, names, it->second, N);
    combine_window(window_parts, w, N, out);
    covered += static_cast<long long>(w[2] - w[0]) * (w[3] - w[1]);
    for (const RenderResult *p : window_parts) {
      out.nan_samples += p->nan_samples;
      out.paths += p->paths;
      // Different pixels, or different samples of the same pixels: different shading points, so the counts add.
      add_clamped_records(out.clamped_parameters, p->clamped_parameters);
    }
  }
  const long long total = static_cast<long long>(out.width) * out.height;
  if (covered != total)
    throw std::runtime_error("the parts cover " + std::to_string(covered) + " of the " + std::to_string(total) +
                             " pixels of the " + std::to_string(out.width) + "x" + std::to_string(out.height) +
                             " image: some tiles are missing");
  out.part = parts[0].part;
  out.part.sample_begin = 0;
  out.part.sample_end = N;
  out.part.window[0] = out.part.window[1] = 0;
  out.part.window[2] = out.width;
  out.part.window[3] = out.height;
  out.samples_requested = out.samples_done = N;
  out.warnings = clamped_parameter_warnings(out.clamped_parameters);
  return out;
}

}  // namespace glimmer::render
