// Farm pieces (docs/farm.md): --tile/--region crops and --sample-range parts merged
// by `glimmer merge` equal the one-machine render (tiles bit for bit, sample ranges
// within float rounding), merge refuses parts of different renders, and a render
// killed with SIGKILL after a checkpoint resumes to the uninterrupted image.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <fstream>
#include <regex>
#include <thread>

#include "exr_compare.h"
#include "render/image_output.h"
#include "render_test_util.h"

namespace glimmer::test {
namespace {

namespace fs = std::filesystem;

// The demo scene, small: 48x32 pixels.
std::string demo_scene() { return std::string(GLIMMER_TEST_SOURCE_DIR) + "/examples/demo.xml"; }
const std::string kSmall = " --width 48 --height 32 --threads 2 --quiet";

std::string render_to(const std::string &name, const std::string &extra) {
  const std::string path = (temp_dir() / name).string();
  fs::remove(path);
  std::string out;
  EXPECT_EQ(0, run_cli("render '" + demo_scene() + "' -o '" + path + "'" + kSmall + " " + extra, out)) << out;
  return path;
}

std::string merge(const std::vector<std::string> &parts, const std::string &name, int &code) {
  std::string args = "merge";
  for (const auto &p : parts) args += " '" + p + "'";
  const std::string path = (temp_dir() / name).string();
  fs::remove(path);
  std::string out;
  code = run_cli(args + " -o '" + path + "'", out);
  return out;
}

TEST(Farm, TilesWriteCropsAndMergeBitIdentical) {
  const std::string full = render_to("full.exr", "--samples 4");
  std::vector<std::string> tiles;
  for (int k = 0; k < 4; ++k)
    tiles.push_back(render_to("tile" + std::to_string(k) + ".exr", "--samples 4 --tile " + std::to_string(k) + "/4"));
  // Each part holds just its band: data window 48x8 at y = 8k, display window 48x32.
  for (int k = 0; k < 4; ++k) {
    const Exr t = read_exr(tiles[k]);
    EXPECT_EQ(t.spec.width, 48);
    EXPECT_EQ(t.spec.height, 8);
    EXPECT_EQ(t.spec.y, 8 * k);
    EXPECT_EQ(t.spec.full_width, 48);
    EXPECT_EQ(t.spec.full_height, 32);
  }
  int code = -1;
  const std::string out = merge(tiles, "merged_tiles.exr", code);
  ASSERT_EQ(code, 0) << out;
  const Exr a = read_exr(temp_dir() / "merged_tiles.exr"), b = read_exr(full);
  EXPECT_TRUE(bit_identical(a, b));
  // --region parts too (uneven rectangles), and a missing tile is refused.
  const std::vector<std::string> regions = {render_to("rA.exr", "--samples 4 --region 0,0,30,32"),
                                            render_to("rB.exr", "--samples 4 --region 30,0,48,20"),
                                            render_to("rC.exr", "--samples 4 --region 30,20,48,32")};
  ASSERT_EQ(0, (merge(regions, "merged_regions.exr", code), code));
  const Exr c = read_exr(temp_dir() / "merged_regions.exr");
  EXPECT_TRUE(bit_identical(c, b));
  const std::string missing = merge({tiles[0], tiles[1], tiles[3]}, "missing.exr", code);
  EXPECT_EQ(code, 1);
  EXPECT_NE(missing.find("cover 1152 of the 1536 pixels"), std::string::npos) << missing;
  EXPECT_FALSE(fs::exists(temp_dir() / "missing.exr"));
}

TEST(Farm, SampleRangesMergeWithinFloatRounding) {
  const std::string full = render_to("full16.exr", "--samples 16");
  // Uneven ranges: an unweighted mean of the parts would be wrong (negative control below).
  const std::vector<std::string> parts = {render_to("s0.exr", "--samples 16 --sample-range 0,3"),
                                          render_to("s1.exr", "--samples 16 --sample-range 3,10"),
                                          render_to("s2.exr", "--samples 16 --sample-range 10,16")};
  int code = -1;
  const std::string out = merge(parts, "merged_samples.exr", code);
  ASSERT_EQ(code, 0) << out;
  const Exr merged = read_exr(temp_dir() / "merged_samples.exr"), ref = read_exr(full);
  ASSERT_EQ(merged.pixels.size(), ref.pixels.size());
  const double rel = max_relative_difference(merged, ref);
  EXPECT_LE(rel, 1e-6);
  std::printf("sample-range merge: max |merged - full| / max |full| = %.3g\n", rel);
  // Negative control: the unweighted mean of the three parts is far off.
  Exr unweighted = ref;
  const Exr p0 = read_exr(parts[0]), p1 = read_exr(parts[1]), p2 = read_exr(parts[2]);
  for (size_t i = 0; i < unweighted.pixels.size(); ++i)
    unweighted.pixels[i] = (p0.pixels[i] + p1.pixels[i] + p2.pixels[i]) / 3.0f;
  EXPECT_GT(max_relative_difference(unweighted, ref), 1e-3);
  // --sample-split k/N cuts [0, N) the same way (16/4 -> 4 samples each).
  std::vector<std::string> splits;
  for (int k = 0; k < 4; ++k)
    splits.push_back(
        render_to("split" + std::to_string(k) + ".exr", "--samples 16 --sample-split " + std::to_string(k) + "/4"));
  ASSERT_EQ(0, (merge(splits, "merged_splits.exr", code), code));
  EXPECT_LE(max_relative_difference(read_exr(temp_dir() / "merged_splits.exr"), ref), 1e-6);
  EXPECT_EQ(read_exr(splits[2]).spec.get_int_attribute("glimmer:sample_begin"), 8);
  EXPECT_EQ(read_exr(splits[2]).spec.get_int_attribute("glimmer:sample_end"), 12);
  // Tiles and sample ranges combine: band 0 whole, band 1 in two sample ranges.
  const std::vector<std::string> mixed = {render_to("m0.exr", "--samples 16 --tile 0/2"),
                                          render_to("m1a.exr", "--samples 16 --tile 1/2 --sample-range 0,5"),
                                          render_to("m1b.exr", "--samples 16 --tile 1/2 --sample-range 5,16")};
  ASSERT_EQ(0, (merge(mixed, "merged_mixed.exr", code), code));
  const Exr m = read_exr(temp_dir() / "merged_mixed.exr");
  EXPECT_LE(max_relative_difference(m, ref), 1e-6);
  const size_t band0 = m.pixels.size() / 2;  // rows 0-15 of 32: copied from one part, bit-identical
  EXPECT_EQ(0, std::memcmp(m.pixels.data(), ref.pixels.data(), band0 * sizeof(float)));
}

TEST(Farm, MergeRefusesPartsOfDifferentRenders) {
  const std::string a = render_to("a.exr", "--samples 4 --sample-range 0,2");
  const std::string b = render_to("b.exr", "--samples 4 --sample-range 2,4");
  int code = -1;
  auto refused = [&](const std::vector<std::string> &parts, const std::string &want) {
    const std::string out = merge(parts, "refused.exr", code);
    EXPECT_EQ(code, 1) << out;
    EXPECT_NE(out.find(want), std::string::npos) << out;
    EXPECT_FALSE(fs::exists(temp_dir() / "refused.exr"));
  };
  ASSERT_EQ(0, (merge({a, b}, "ok.exr", code), code));  // the positive control
  refused({a, render_to("seed.exr", "--samples 4 --sample-range 2,4 --seed 7")}, "seed 0 vs 7");
  const std::string res = (temp_dir() / "res.exr").string();
  std::string out;
  ASSERT_EQ(0, run_cli("render '" + demo_scene() + "' -o '" + res +
                           "' --width 40 --height 32 --samples 4 --sample-range 2,4 --quiet",
                       out))
      << out;
  refused({a, res}, "resolution 48x32 vs 40x32");
  refused({a, render_to("n.exr", "--samples 5 --sample-range 2,5")}, "samples per pixel 4 vs 5");
  refused({a, render_to("strategy.exr", "--samples 4 --sample-range 2,4 --strategy light")}, "strategy mis vs light");
  // The same scene with its mesh named by absolute path: the same picture, another scene hash.
  std::ifstream in(demo_scene());
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string mesh = "\"sphere.obj\"";
  ASSERT_NE(text.find(mesh), std::string::npos);
  for (auto at = text.find(mesh); at != std::string::npos; at = text.find(mesh))
    text.replace(at, mesh.size(), "\"" + std::string(GLIMMER_TEST_SOURCE_DIR) + "/examples/sphere.obj\"");
  const std::string other_scene = write_file("demo_moved.xml", text);
  const std::string other = (temp_dir() / "other.exr").string();
  ASSERT_EQ(
      0, run_cli("render '" + other_scene + "' -o '" + other + "'" + kSmall + " --samples 4 --sample-range 2,4", out));
  refused({a, other}, "scene hash");
  refused({a, render_to("overlap.exr", "--samples 4 --sample-range 1,4")}, "sample ranges overlap");
  refused({a, a, b}, "duplicate parts");
  refused({a}, "samples [2, 4) of pixels [0,0 - 48,32) are missing");
  refused(
      {render_to("t0.exr", "--samples 4 --region 0,0,48,20"), render_to("t1.exr", "--samples 4 --region 0,16,48,32")},
      "overlap");
  refused({a, b, (temp_dir() / "missing_part.exr").string()}, "missing_part.exr");
}

// Per-frame scenes scene_0001.xml, scene_0002.xml (the demo with its mesh by absolute path).
std::string write_frame_scenes() {
  std::ifstream in(demo_scene());
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string mesh = "\"sphere.obj\"";
  std::string absolute_mesh = "\"";
  absolute_mesh += GLIMMER_TEST_SOURCE_DIR;
  absolute_mesh += "/examples/sphere.obj\"";
  for (auto at = text.find(mesh); at != std::string::npos; at = text.find(mesh))
    text.replace(at, mesh.size(), absolute_mesh);
  write_file("scene_0001.xml", text);
  write_file("scene_0002.xml", text);
  return (temp_dir() / "scene_####.xml").string();
}

TEST(Farm, SlurmDryRunPrintsAnArrayAndADependentMerge) {
  const std::string scenes = write_frame_scenes();
  const std::string output = (temp_dir() / "anim_####.exr").string(), work = (temp_dir() / "anim_farm").string();
  std::string out;
  ASSERT_EQ(0, run_cli("farm slurm '" + scenes + "' --frames 1-2 --sample-splits 3 -o '" + output + "' --workdir '" +
                           work + "' --samples 6 --dry-run",
                       out))
      << out;
  for (const std::string &want :
       std::vector<std::string>{"#SBATCH --array=0-5\n", "FRAMES=(1 2)\nPARTS=3\n", "--sample-split \"$part/$PARTS\"",
                                " --samples 6 ", "--checkpoint-every 60 --resume", "--dependency=afterok:<id>",
                                "parts/part_0002_2.exr' -o '" + (temp_dir() / "anim_0002.exr").string() + "'"})
    EXPECT_NE(out.find(want), std::string::npos) << want << "\n" << out;
  EXPECT_FALSE(fs::exists(work)) << "--dry-run writes nothing";
  EXPECT_EQ(1, run_cli("farm slurm '" + scenes + "' --frames 1-3 --tiles 2 -o '" + output + "' --dry-run", out));
  EXPECT_NE(out.find("scene of frame 3 not found"), std::string::npos) << out;
  EXPECT_EQ(1, run_cli("farm slurm '" + demo_scene() + "' --frames 1-2 --tiles 2 -o '" + output + "' --dry-run", out));
  EXPECT_NE(out.find("scene_####.xml"), std::string::npos) << out;
  EXPECT_EQ(1, run_cli("farm slurm '" + demo_scene() + "' -o '" + output + "' --dry-run", out));
  EXPECT_NE(out.find("--tiles N or --sample-splits N"), std::string::npos) << out;
  // An output the merge job could not write is refused at submission, not after the whole array has rendered.
  const std::string bad_format = (temp_dir() / "farm_out.xyz").string();
  EXPECT_EQ(1, run_cli("farm slurm '" + demo_scene() + "' --tiles 2 -o '" + bad_format + "' --dry-run", out));
  EXPECT_NE(out.find("farm slurm: output '" + bad_format + "': no image format for extension '.xyz'"),
            std::string::npos)
      << out;
  const std::string no_extension = (temp_dir() / "farm_out").string();
  EXPECT_EQ(1, run_cli("farm slurm '" + demo_scene() + "' --tiles 2 -o '" + no_extension + "' --dry-run", out));
  EXPECT_NE(out.find("has no file extension"), std::string::npos) << out;
  ASSERT_EQ(0, run_cli("farm slurm '" + demo_scene() + "' --tiles 2 -o '" + (temp_dir() / "farm_out.png").string() +
                           "' --dry-run",
                       out))
      << out;
}

// Submission through a stand-in sbatch that records its arguments: the merge job
// depends on the array's id (afterok) and both ids are printed.
TEST(Farm, SlurmSubmitsTheMergeAfterTheArray) {
  const std::string log = (temp_dir() / "sbatch_calls.txt").string();
  fs::remove(log);
  const std::string fake = write_file(
      "fake_sbatch.sh", "#!/bin/sh\necho \"$@\" >> '" + log + "'\nn=$(wc -l < '" + log + "')\necho $((4000 + n))\n");
  fs::permissions(fake, fs::perms::owner_all);
  std::string out;
  ASSERT_EQ(
      0, run_cli("farm slurm '" + demo_scene() + "' --tiles 2 -o '" + (temp_dir() / "new_folder" / "sub.exr").string() +
                     "' --workdir '" + (temp_dir() / "sub_work").string() + "' --sbatch '" + fake + "'",
                 out))
      << out;
  EXPECT_NE(out.find("render job 4001 (array of 2 tasks)\nmerge job 4002 (runs after 4001 succeeds)"),
            std::string::npos)
      << out;
  std::ifstream in(log);
  std::string first, second;
  std::getline(in, first);
  std::getline(in, second);
  EXPECT_EQ(first, "--parsable " + (temp_dir() / "sub_work" / "render.sbatch").string());
  EXPECT_EQ(second, "--parsable --dependency=afterok:4001 " + (temp_dir() / "sub_work" / "merge.sbatch").string());
  EXPECT_TRUE(fs::exists(temp_dir() / "sub_work" / "parts"));
  EXPECT_TRUE(fs::is_directory(temp_dir() / "new_folder")) << "the merge job's output folder is created";
}

// Textured values clamped to a parameter's range (render/clamped_parameters.h) travel with the parts: a quad whose
// glossy roughness is a checker of 1.5 and -0.5 (outside [0, 1] both ways) under a point light, 32x32, in front of
// a diffuse wall that the camera sees around it: the paths bouncing off the wall onto the quad's back count too, so
// the counts depend on the paths (Russian roulette, sampled directions), not only on the pixels and samples.
std::string clamped_scene() {
  return write_file(
      "clamped_farm.xml",
      "<cycles>\n<camera width=\"32\" height=\"32\" fov=\"1.2\" />\n"
      "<integrator sample_clamp_direct=\"0\" sample_clamp_indirect=\"0\" />\n"
      "<state><light light_type=\"point\" co=\"2 0 0.5\" strength=\"300 300 300\" /></state>\n"
      "<shader name=\"s\">\n<texture_coordinate name=\"tc\" />\n"
      "<checker_texture name=\"c\" scale=\"2\" color1=\"1.5 1.5 1.5\" color2=\"-0.5 -0.5 -0.5\" />\n"
      "<connect from=\"tc uv\" to=\"c vector\" />\n<glossy_bsdf name=\"g\" distribution=\"ggx\" />\n"
      "<connect from=\"c color\" to=\"g roughness\" />\n<connect from=\"g bsdf\" to=\"output surface\" />\n"
      "</shader>\n<state shader=\"s\"><mesh P=\"-1.1 -1.1 3  1.1 -1.1 3  1.1 1.1 3  -1.1 1.1 3\" nverts=\"4\" "
      "verts=\"0 1 2 3\" UV=\"0 0 1 0 1 1 0 1\" /></state>\n"
      "<shader name=\"wall\"><diffuse_bsdf name=\"d\" color=\"0.8 0.8 0.8\" />\n"
      "<connect from=\"d bsdf\" to=\"output surface\" /></shader>\n"
      "<state shader=\"wall\"><mesh P=\"-9 -9 5  9 -9 5  9 9 5  -9 9 5\" nverts=\"4\" verts=\"0 1 2 3\" /></state>\n"
      "</cycles>\n");
}

// Renders the clamped scene with `extra` options to temp_dir()/name; `out` gets the CLI's output.
std::string render_clamped(const std::string &name, const std::string &extra, std::string &out, bool quiet = true) {
  const std::string path = (temp_dir() / name).string();
  fs::remove(path);
  EXPECT_EQ(
      0, run_cli("render '" + clamped_scene() + "' -o '" + path + "' --threads 2 " + (quiet ? "--quiet " : "") + extra,
                 out))
      << out;
  return path;
}

// The roughness counts of the warning lines in a CLI's output (-1: no such line) and the extreme values printed.
struct ClampedLines {
  long long below = -1, above = -1;
  std::string lowest, highest;
};
ClampedLines clamped_lines(const std::string &out) {
  ClampedLines c;
  const std::regex line(
      R"(clamped_farm\.xml:10: warning: <glossy_bsdf> 'g' parameter 'roughness': ([0-9]+) shading points had a )"
      R"(textured value (below the minimum, down to|above the maximum, up to) (\S+), clamped to [01] )"
      R"(\(its range is \[0, 1\]\))");
  for (std::sregex_iterator it(out.begin(), out.end(), line), end; it != end; ++it) {
    const bool below = (*it)[2].str()[0] == 'b';
    EXPECT_EQ(below ? c.below : c.above, -1) << "one line per direction: " << out;
    (below ? c.below : c.above) = std::stoll((*it)[1].str());
    (below ? c.lowest : c.highest) = (*it)[3].str();
  }
  return c;
}

// The record an EXR carries for the roughness (none: zero counts).
render::ClampedParameterRecord exr_record(const std::string &path) {
  const render::RenderResult r = render::read_image(path);
  EXPECT_LE(r.clamped_parameters.size(), 1u) << path;
  return r.clamped_parameters.empty() ? render::ClampedParameterRecord{} : r.clamped_parameters.front();
}

// The clamped scene rendered in two parts ("--sample-split" or "--tile" k/2, 8 samples) as `prefix`k.exr: the files
// and each part's warning lines (checked against the record its EXR carries).
struct ClampedParts {
  std::vector<std::string> files;
  std::vector<ClampedLines> lines;
};
ClampedParts render_clamped_parts(const std::string &prefix, const std::string &split_option) {
  ClampedParts p;
  std::string out;
  for (int k = 0; k < 2; ++k) {
    p.files.push_back(render_clamped(prefix + std::to_string(k) + ".exr",
                                     "--samples 8 " + split_option + " " + std::to_string(k) + "/2", out));
    p.lines.push_back(clamped_lines(out));
    EXPECT_EQ(static_cast<long long>(exr_record(p.files.back()).above), p.lines.back().above);
  }
  return p;
}

// A copy of `part` as a build before the record wrote it (no attribute), as temp_dir()/name.
std::string without_record(const std::string &part, const std::string &name) {
  render::RenderResult old = render::read_image(part);
  EXPECT_FALSE(old.clamped_parameters.empty()) << part;
  old.clamped_parameters.clear();
  const std::string path = (temp_dir() / name).string();
  render::write_image(path, old);
  EXPECT_FALSE(read_exr(path).spec.find_attribute("glimmer:clamped_parameters")) << path;
  return path;
}

// Checks that merging `parts` reports the sum of the parts' counts, as `single` (a one-machine render's output)
// does; the merged EXR carries the summed record. Returns the merged counts.
ClampedLines expect_merge_sums(const std::vector<std::string> &parts, const std::vector<ClampedLines> &part_lines,
                               const ClampedLines &single, const std::string &name) {
  int code = -1;
  const std::string out = merge(parts, name, code);
  EXPECT_EQ(code, 0) << out;
  EXPECT_NE(out.find("merged " + std::to_string(parts.size()) + " parts into"), std::string::npos) << out;
  const ClampedLines merged = clamped_lines(out);
  std::printf("%s: merged below %lld above %lld; one-machine below %lld above %lld\n", name.c_str(), merged.below,
              merged.above, single.below, single.above);
  long long below = 0, above = 0;
  for (const ClampedLines &p : part_lines) {
    // Negative control: every part saw some of them, so a merge that dropped or kept one part's would fail here.
    EXPECT_GT(p.below, 0);
    EXPECT_GT(p.above, 0);
    EXPECT_GT(merged.below, p.below) << out;
    EXPECT_GT(merged.above, p.above) << out;
    below += p.below;
    above += p.above;
  }
  EXPECT_EQ(merged.below, below) << out;
  EXPECT_EQ(merged.above, above) << out;
  // The paths of a pixel's sample do not depend on the part that traces it: the counts are the single render's.
  EXPECT_EQ(merged.below, single.below) << out;
  EXPECT_EQ(merged.above, single.above) << out;
  EXPECT_EQ(merged.lowest, single.lowest);
  EXPECT_EQ(merged.highest, single.highest);
  const render::ClampedParameterRecord r = exr_record((temp_dir() / name).string());
  EXPECT_EQ(static_cast<long long>(r.below), below);
  EXPECT_EQ(static_cast<long long>(r.above), above);
  return merged;
}

TEST(Farm, MergeReportsTheSummedClampedCountsOfSampleSplits) {
  std::string out;
  const std::string single = render_clamped("clamped_full.exr", "--samples 8", out);
  const ClampedLines full = clamped_lines(out);
  ASSERT_GT(full.below, 0) << out;
  ASSERT_GT(full.above, 0) << out;
  EXPECT_EQ(full.lowest, "-0.5");
  EXPECT_EQ(full.highest, "1.5");
  // The single render's EXR carries the record of its warning lines.
  EXPECT_TRUE(read_exr(single).spec.find_attribute("glimmer:clamped_parameters"));
  EXPECT_EQ(static_cast<long long>(exr_record(single).below), full.below);
  const ClampedParts parts = render_clamped_parts("clamped_split", "--sample-split");
  expect_merge_sums(parts.files, parts.lines, full, "clamped_merged_splits.exr");
  // A part written without the record (a build before it: no attribute) merges, adding nothing.
  const std::string old_part = without_record(parts.files[1], "clamped_split1_old.exr");
  int code = -1;
  const std::string mixed = merge({parts.files[0], old_part}, "clamped_merged_old.exr", code);
  ASSERT_EQ(code, 0) << mixed;
  EXPECT_EQ(clamped_lines(mixed).below, parts.lines[0].below) << mixed;
  EXPECT_EQ(clamped_lines(mixed).above, parts.lines[0].above) << mixed;
  // Neither part with the record: nothing to report, and the merged image has no record either.
  const std::string old_part0 = without_record(parts.files[0], "clamped_split0_old.exr");
  const std::string none = merge({old_part0, old_part}, "clamped_merged_none.exr", code);
  ASSERT_EQ(code, 0) << none;
  EXPECT_EQ(none.find("warning"), std::string::npos) << none;
  EXPECT_FALSE(read_exr(temp_dir() / "clamped_merged_none.exr").spec.find_attribute("glimmer:clamped_parameters"));
}

TEST(Farm, MergeReportsTheSummedClampedCountsOfTiles) {
  std::string out;
  render_clamped("clamped_full_t.exr", "--samples 8", out);
  const ClampedLines full = clamped_lines(out);
  const ClampedParts parts = render_clamped_parts("clamped_tile", "--tile");
  expect_merge_sums(parts.files, parts.lines, full, "clamped_merged_tiles.exr");
}

TEST(Farm, ResumedRenderReportsTheClampedCountsOfTheWholeRender) {
  std::string out;
  const std::string samples = " --samples 24";
  render_clamped("clamped_uninterrupted.exr", samples, out);
  const ClampedLines whole = clamped_lines(out);
  ASSERT_GT(whole.below, 0) << out;
  // Time-limited after its first pass: the checkpoint keeps one sample and its counts.
  const std::string checkpoint = (temp_dir() / "clamped_resumed.checkpoint.exr").string();
  fs::remove(checkpoint);
  render_clamped("clamped_resumed.exr", samples + " --checkpoint-every 0 --time-limit 0.000001", out);
  ASSERT_TRUE(fs::exists(checkpoint)) << out;
  const render::ClampedParameterRecord saved = exr_record(checkpoint);
  EXPECT_GT(saved.below, 0u);
  EXPECT_GT(saved.above, 0u);
  // Negative control: the samples after the checkpoint alone count fewer, so a resume that dropped the checkpoint's
  // counts would fail the equality below.
  EXPECT_LT(static_cast<long long>(saved.below), whole.below);
  const std::string output = render_clamped("clamped_resumed.exr", samples + " --resume", out, false);
  ASSERT_NE(out.find("Resuming " + checkpoint + " from sample 1/24"), std::string::npos) << out;
  const ClampedLines resumed = clamped_lines(out);
  std::printf("checkpoint below %llu; resumed below %lld; uninterrupted below %lld\n",
              static_cast<unsigned long long>(saved.below), resumed.below, whole.below);
  EXPECT_EQ(resumed.below, whole.below) << out;
  EXPECT_EQ(resumed.above, whole.above) << out;
  EXPECT_EQ(static_cast<long long>(exr_record(output).below), whole.below);
  EXPECT_EQ(static_cast<long long>(exr_record(output).above), whole.above);
}

// Runs the CLI in the background; returns its pid.
pid_t spawn_cli(const std::string &args) {
  const std::string cmd = std::string("exec '") + GLIMMER_TEST_CLI_PATH + "' " + args + " > /dev/null 2>&1";
  const pid_t pid = fork();
  if (pid == 0) {
    execl("/bin/sh", "sh", "-c", cmd.c_str(), static_cast<char *>(nullptr));
    _exit(127);
  }
  return pid;
}

TEST(Farm, KilledRenderResumesToTheUninterruptedImage) {
  const std::string samples = " --samples 300";
  const std::string reference = render_to("uninterrupted.exr", samples);
  const std::string output = (temp_dir() / "killed.exr").string(),
                    checkpoint = (temp_dir() / "killed.checkpoint.exr").string();
  fs::remove(output);
  fs::remove(checkpoint);
  const pid_t pid =
      spawn_cli("render '" + demo_scene() + "' -o '" + output + "'" + kSmall + samples + " --checkpoint-every 0");
  ASSERT_GT(pid, 0);
  // The checkpoint is renamed into place complete, so once it exists it can be read.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::minutes(2);
  while (!fs::exists(checkpoint) && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  ASSERT_EQ(0, ::kill(pid, SIGKILL));
  int status = 0;
  ::waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFSIGNALED(status)) << "the render finished before it could be killed";
  ASSERT_TRUE(fs::exists(checkpoint));
  EXPECT_FALSE(fs::exists(output));
  const Exr saved = read_exr(checkpoint);
  const int done = saved.spec.get_int_attribute("glimmer:samples");
  EXPECT_GE(done, 1);
  EXPECT_LT(done, 300);
  std::string out;
  ASSERT_EQ(0, run_cli("render '" + demo_scene() + "' -o '" + output + "' --width 48 --height 32 --threads 2" +
                           samples + " --checkpoint-every 1000 --resume",
                       out))
      << out;
  EXPECT_NE(out.find("Resuming " + checkpoint + " from sample "), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(checkpoint)) << "a finished render removes its checkpoint";
  const Exr a = read_exr(output), b = read_exr(reference);
  EXPECT_TRUE(bit_identical(a, b));
  // Negative control: the checkpoint alone (fewer samples) is not the final image.
  EXPECT_FALSE(bit_identical(saved, b));
}

TEST(Farm, ResumeRefusesACheckpointOfAnotherRender) {
  const std::string output = (temp_dir() / "ck.exr").string();
  const std::string checkpoint = (temp_dir() / "ck.checkpoint.exr").string();
  fs::remove(checkpoint);
  std::string out;
  // --time-limit 0 is "none"; interrupt after one pass via a tiny time limit instead, keeping the checkpoint.
  ASSERT_EQ(0, run_cli("render '" + demo_scene() + "' -o '" + output + "'" + kSmall +
                           " --samples 50 --checkpoint-every 0 --time-limit 0.000001",
                       out))
      << out;
  ASSERT_TRUE(fs::exists(checkpoint)) << "a time-limited render keeps its checkpoint";
  EXPECT_EQ(1, run_cli("render '" + demo_scene() + "' -o '" + output + "'" + kSmall + " --samples 50 --seed 3 --resume",
                       out));
  EXPECT_NE(out.find("belongs to another render (seed 0, this render 3)"), std::string::npos) << out;
}

TEST(Farm, BlenderStyleProgressLines) {
  std::string out;
  ASSERT_EQ(0, run_cli("render '" + demo_scene() + "' -o '" + (temp_dir() / "p.exr").string() +
                           "' --width 8 --height 8 --samples 2 --frames 5 --progress-format blender",
                       out))
      << out;
  const std::regex line(R"(Fra:5 Time:\d\d:\d\d\.\d\d \| Remaining:\d\d:\d\d\.\d\d \| Sample 2/2)");
  EXPECT_TRUE(std::regex_search(out, line)) << out;
}

}  // namespace
}  // namespace glimmer::test
