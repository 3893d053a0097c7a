// Hostile and broken input (issue 14): every class of attack or clumsy input
// ends with a clear message and an exit code (or a documented fallback),
// never a crash, a hang, a silently wrong result or an overwritten file.
#include <OpenImageIO/imageio.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <fcntl.h>
#include <unistd.h>

#include <csignal>

#include <fstream>
#include <random>

#include "glimmer/atomic_file.h"
#include "lab/closure_lab.h"
#include "render/image_output.h"
#include "render/textures.h"
#include "render_test_util.h"
#include "scene/graph_checks.h"
#include "scene/parse_number.h"

namespace glimmer::test {
namespace {

namespace fs = std::filesystem;

const std::string kCamera = "<camera width=\"8\" height=\"8\" />\n";
const std::string kTriangle = "<mesh P=\"-1 -1 3  1 -1 3  0 1 3\" nverts=\"3\" verts=\"0 1 2\" />\n";

std::string quoted(const std::string &s) { return "'" + s + "'"; }

// Runs `glimmer render scene -o out.png`; returns the exit code, fills `out`.
int render_cli(const std::string &scene, std::string &out, const std::string &extra = "") {
  return run_cli("render " + quoted(scene) + " -o " + quoted((temp_dir() / "hostile_out.png").string()) +
                     " --samples 1 --quiet " + extra,
                 out);
}

// The scene must be refused: exit code 1 and `message` in the output.
void expect_refused(const std::string &scene, const std::string &message) {
  std::string out;
  EXPECT_EQ(1, render_cli(scene, out)) << out;
  EXPECT_NE(out.find(message), std::string::npos) << "expected '" << message << "' in: " << out;
}

// In-process loading must throw a SceneError containing `message`.
void expect_load_error(const std::string &scene, const std::string &message) {
  try {
    scene::load_scene(scene);
    ADD_FAILURE() << "loaded without error; expected '" << message << "'";
  } catch (const scene::SceneError &e) {
    EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << e.what();
  }
}

// Writes the mesh file `mesh_name` and a scene using it; loading must fail with `message`.
void expect_mesh_error(const std::string &mesh_name, const std::string &mesh, const std::string &message) {
  write_file(mesh_name, mesh);
  expect_load_error(write_file(mesh_name + ".xml", "<cycles>\n<mesh src=\"" + mesh_name + "\" />\n</cycles>\n"), message);
}

std::string nested(const std::string &open, const std::string &close, int depth, const std::string &inner) {
  std::string xml;
  xml.reserve(static_cast<size_t>(depth) * (open.size() + close.size() + 2) + inner.size());
  for (int i = 0; i < depth; ++i) xml += open + "\n";
  xml += inner;
  for (int i = 0; i < depth; ++i) xml += close;
  return xml;
}

// ---- Recursion: one documented limit each, a file:line error past it -------

TEST(HostileRecursion, SelfIncludeAndIncludeLoop) {
  const std::string self = write_file("self_include.xml", "<cycles>\n<include src=\"self_include.xml\" />\n</cycles>\n");
  expect_refused(self, "self_include.xml:2: <include> loop");
  write_file("loop_b.xml", "<cycles>\n\n<include src=\"loop_a.xml\" />\n</cycles>\n");
  const std::string a = write_file("loop_a.xml", "<cycles>\n<include src=\"loop_b.xml\" />\n</cycles>\n");
  expect_load_error(a, "loop_b.xml:3: <include> loop");
}

TEST(HostileRecursion, IncludeDepthLimit) {
  // A chain of distinct files one deeper than the limit.
  const int files = scene::kMaxIncludeDepth + 2;
  for (int i = 0; i < files; ++i)
    write_file("chain_" + std::to_string(i) + ".xml",
               "<cycles>\n" + (i + 1 < files ? "<include src=\"chain_" + std::to_string(i + 1) + ".xml\" />\n" : "") +
                   "</cycles>\n");
  expect_load_error((temp_dir() / "chain_0.xml").string(),
                    "<include> nested more than " + std::to_string(scene::kMaxIncludeDepth) + " files deep");
  // Exactly at the limit loads.
  write_file("chain_short.xml", "<cycles>\n<include src=\"chain_" + std::to_string(files - scene::kMaxIncludeDepth) +
                                    ".xml\" />\n</cycles>\n");
  EXPECT_NO_THROW(scene::load_scene((temp_dir() / "chain_short.xml").string()));
}

TEST(HostileRecursion, DeeplyNestedTransformsAndStates) {
  // 10,000 nested <transform> (the reported crash): refused at the limit with the line of the first element past it.
  const std::string transforms =
      write_file("deep_transform.xml", "<cycles>\n" + kCamera + nested("<transform translate=\"0 0 0\">", "</transform>", 10000, kTriangle) + "\n</cycles>\n");
  expect_refused(transforms, "deep_transform.xml:" + std::to_string(3 + scene::kMaxTransformDepth) +
                                 ": <transform> nested more than 256 levels deep");
  // 200,000 nested <state>.
  const std::string states =
      write_file("deep_state.xml", "<cycles>\n" + nested("<state>", "</state>", 200000, kTriangle) + "\n</cycles>\n");
  expect_load_error(states, "<state> nested more than 256 levels deep");
  // At the limit both load.
  const std::string ok = write_file(
      "ok_depth.xml", "<cycles>\n" + nested("<state>", "</state>", scene::kMaxStateDepth,
                                            nested("<transform>", "</transform>", scene::kMaxTransformDepth, kTriangle)) +
                          "</cycles>\n");
  EXPECT_EQ(scene::load_scene(ok).meshes.size(), 1u);
}

std::string checker_chain(int length) {
  std::string xml = "<cycles>\n" + kCamera + "<shader name=\"s\">\n<diffuse_bsdf name=\"d\" />\n";
  for (int i = 0; i < length; ++i) xml += "<checker_texture name=\"c" + std::to_string(i) + "\" />\n";
  for (int i = 0; i + 1 < length; ++i)
    xml += "<connect from=\"c" + std::to_string(i + 1) + " color\" to=\"c" + std::to_string(i) + " color1\" />\n";
  xml += "<connect from=\"c0 color\" to=\"d color\" />\n<connect from=\"d bsdf\" to=\"output surface\" />\n";
  xml += "</shader>\n<state shader=\"s\">" + kTriangle + "</state>\n</cycles>\n";
  return xml;
}

TEST(HostileRecursion, ShaderGraphDepthLimit) {
  // 50,000 textures in a chain (the reported stack overflow in read_input).
  expect_refused(write_file("texture_chain.xml", checker_chain(50000)), "linked nodes ends at");
  // The output <- diffuse <- 62 textures chain (64 nodes with the output) is accepted.
  EXPECT_NO_THROW(scene::load_scene(write_file("texture_chain_ok.xml", checker_chain(scene::kMaxShaderGraphDepth - 2))));
  expect_load_error(write_file("texture_chain_65.xml", checker_chain(scene::kMaxShaderGraphDepth)),
                    "at most " + std::to_string(scene::kMaxShaderGraphDepth));
}

// ---- Cycles in texture links -------------------------------------------------

TEST(HostileCycles, TwoTexturesLinkedInACycleAreRefused) {
  const std::string xml = "<cycles>\n" + kCamera +
                          "<shader name=\"s\">\n<diffuse_bsdf name=\"d\" />\n<checker_texture name=\"a\" />\n"
                          "<checker_texture name=\"b\" />\n<connect from=\"a color\" to=\"b color1\" />\n"
                          "<connect from=\"b color\" to=\"a color1\" />\n<connect from=\"a color\" to=\"d color\" />\n"
                          "<connect from=\"d bsdf\" to=\"output surface\" />\n</shader>\n<state shader=\"s\">" +
                          kTriangle + "</state>\n</cycles>\n";
  expect_refused(write_file("texture_cycle.xml", xml), "links form a cycle");
  // A closure loop through two mix nodes too.
  const std::string mix = "<cycles>\n<shader name=\"m\">\n<mix_closure name=\"x\" />\n<mix_closure name=\"y\" />\n"
                          "<connect from=\"x closure\" to=\"y closure1\" />\n"
                          "<connect from=\"y closure\" to=\"x closure1\" />\n"
                          "<connect from=\"x closure\" to=\"output surface\" />\n</shader>\n</cycles>\n";
  expect_load_error(write_file("mix_cycle.xml", mix), "links form a cycle");
}

// ---- Inputs must be regular files ---------------------------------------------

TEST(HostileFiles, FifoDeviceAndDirectoryAreRefusedWithoutHanging) {
  const fs::path fifo = temp_dir() / "mesh_fifo.obj";
  fs::remove(fifo);
  ASSERT_EQ(0, ::mkfifo(fifo.c_str(), 0600));
  const fs::path dir_mesh = temp_dir() / "dir_mesh.obj";
  fs::create_directories(dir_mesh);
  const fs::path dir_image = temp_dir() / "dir_image.png";
  fs::create_directories(dir_image);
  struct Case {
    std::string name, body, message;
  };
  const std::vector<Case> cases = {
      {"include_zero.xml", "<include src=\"/dev/zero\" />\n", "'/dev/zero': is a character device, not a regular file"},
      {"include_urandom.xml", "<include src=\"/dev/urandom\" />\n", "is a character device"},
      {"mesh_fifo.xml", "<mesh src=\"" + fifo.string() + "\" />\n", "is a FIFO (named pipe), not a regular file"},
      {"mesh_dir.xml", "<mesh src=\"" + dir_mesh.string() + "\" />\n", "is a directory, not a regular file"},
      {"mesh_zero.xml", "<mesh src=\"/dev/zero.obj\" />\n", "No such file"},
      {"image_dir.xml",
       "<shader name=\"s\"><image_texture name=\"t\" filename=\"" + dir_image.string() +
           "\" /><diffuse_bsdf name=\"d\" /><connect from=\"t color\" to=\"d color\" />"
           "<connect from=\"d bsdf\" to=\"output surface\" /></shader>\n<state shader=\"s\">" + kTriangle + "</state>\n",
       "is a directory, not a regular file"},
  };
  for (const auto &c : cases) {
    SCOPED_TRACE(c.name);
    const std::string path = write_file(c.name, "<cycles>\n" + kCamera + c.body + "</cycles>\n");
    std::string out;
    EXPECT_EQ(1, run_cli("render " + quoted(path) + " -o " + quoted((temp_dir() / "never.png").string()) +
                             " --quiet",
                         out))
        << out;
    EXPECT_NE(out.find(c.message), std::string::npos) << out;
    EXPECT_NE(out.find(c.name + ":"), std::string::npos) << "file:line expected: " << out;
  }
  // The scene file itself.
  std::string out;
  EXPECT_EQ(1, run_cli("render /dev/zero -o " + quoted((temp_dir() / "never.png").string()), out));
  EXPECT_NE(out.find("is a character device"), std::string::npos) << out;
  fs::remove(fifo);
}

TEST(HostileFiles, PlyElementWithoutPropertiesAndUnknownTypes) {
  expect_mesh_error("noprops.ply", "ply\nformat ascii 1.0\nelement vertex 1000000000\nend_header\n",
                    "element 'vertex' has no properties");
  expect_mesh_error("f128.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float128 x\nend_header\n0\n0\n0\n",
                    "property type 'float128' not supported");
  expect_mesh_error("badcount.ply", "ply\nformat ascii 1.0\nelement vertex 3x\nproperty float x\nend_header\n",
                    "'3x' is not a number");
}

// ---- Size-bomb image: the header is checked against the pixel budget -----------

TEST(HostileFiles, ImageHeaderOverThePixelBudgetIsRefusedBeforeAllocation) {
  // A 21-byte PPM claiming 30000 x 30000 (10.8 GB as float RGB).
  const std::string bomb = write_file("bomb.ppm", "P6\n30000 30000\n255\nxy");
  render::TextureCache cache;
  try {
    cache.load(bomb, false);
    ADD_FAILURE() << "size bomb accepted";
  } catch (const std::exception &e) {
    EXPECT_NE(std::string(e.what()).find("claims 30000x30000x3 values, more than the budget"), std::string::npos)
        << e.what();
  }
  const std::string xml =
      "<cycles>\n" + kCamera +
      "<shader name=\"s\"><image_texture name=\"t\" filename=\"bomb.ppm\" /><diffuse_bsdf name=\"d\" />"
      "<connect from=\"t color\" to=\"d color\" /><connect from=\"d bsdf\" to=\"output surface\" /></shader>\n"
      "<state shader=\"s\">" + kTriangle + "</state>\n</cycles>\n";
  expect_refused(write_file("bomb.xml", xml), "set GLIMMER_MAX_IMAGE_PIXELS to raise it");
  // The budget is configurable: a 4x4 image loads by default and is refused with a budget of 8 pixels.
  const std::string small = write_file("small4.ppm", "P6\n4 4\n255\n" + std::string(48, '\x40'));
  EXPECT_EQ(cache.load(small, false)->width(), 4);
  std::string small_xml = xml;
  small_xml.replace(small_xml.find("bomb.ppm"), 8, "small4.ppm");
  std::string out;
  EXPECT_EQ(0, run_cli("render " + quoted(write_file("small4.xml", small_xml)) + " -o " +
                           quoted((temp_dir() / "small4.png").string()) + " --quiet",
                       out))
      << out;
  const std::string cmd = "GLIMMER_MAX_IMAGE_PIXELS=8 '" + std::string(GLIMMER_TEST_CLI_PATH) + "' render " +
                          quoted((temp_dir() / "small4.xml").string()) + " -o " +
                          quoted((temp_dir() / "never.png").string()) + " --quiet > " +
                          quoted((temp_dir() / "budget.txt").string()) + " 2>&1";
  const int status = std::system(cmd.c_str());
  EXPECT_EQ(WEXITSTATUS(status), 1);
  std::ifstream log(temp_dir() / "budget.txt");
  const std::string text((std::istreambuf_iterator<char>(log)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("more than the budget of 8 pixels"), std::string::npos) << text;
}

// ---- Non-finite camera rays never reach Embree --------------------------------

TEST(HostileRender, HugeApertureRendersWithoutAbort) {
  const std::string scene = write_file(
      "aperture.xml", "<cycles>\n<camera width=\"16\" height=\"16\" aperturesize=\"1e19\" focaldistance=\"1e-30\" />\n"
                      "<background><background name=\"bg\" color=\"1 1 1\" strength=\"1\" />"
                      "<connect from=\"bg background\" to=\"output surface\" /></background>\n" +
                          kTriangle + "<light light_type=\"point\" co=\"0 0 0\" strength=\"10 10 10\" />\n</cycles>\n");
  std::string out;
  const auto png = (temp_dir() / "aperture.png").string();
  ASSERT_EQ(0, run_cli("render " + quoted(scene) + " -o " + quoted(png) + " --samples 4 --quiet", out)) << out;
  EXPECT_TRUE(fs::exists(png));
  render::RenderOptions opt;
  opt.samples = 4;
  const auto r = render_scene(scene, opt);
  for (float v : r.combined) ASSERT_TRUE(std::isfinite(v));
}

// ---- Film accumulation: sums that overflow are dropped and reported -----------

TEST(HostileRender, InfiniteAccumulationIsDroppedWithTheWarning) {
  const std::string scene = write_file(
      "hot.xml", "<cycles>\n<camera width=\"4\" height=\"4\" />\n"
                 "<background><background name=\"bg\" color=\"3e38 3e38 3e38\" strength=\"1\" />"
                 "<connect from=\"bg background\" to=\"output surface\" /></background>\n</cycles>\n");
  render::RenderOptions opt;
  opt.samples = 4;
  const auto r = render_scene(scene, opt);
  for (float v : r.combined) ASSERT_TRUE(std::isfinite(v));
  EXPECT_GT(r.nan_samples, 0u);
  std::string out;
  EXPECT_EQ(0, run_cli("render " + quoted(scene) + " -o " + quoted((temp_dir() / "hot.exr").string()) +
                           " --samples 4 --quiet",
                       out));
  EXPECT_NE(out.find("non-finite sample contributions were dropped"), std::string::npos) << out;
}

// ---- Strict numbers -------------------------------------------------------------

TEST(HostileNumbers, ParserRefusesJunkOverflowAndNonIntegers) {
  using scene::NumberError;
  EXPECT_EQ(scene::parse_int("3"), 3);
  EXPECT_EQ(scene::parse_int("3.0"), 3);
  EXPECT_FLOAT_EQ(scene::parse_float("-2.5e3"), -2500.0f);
  EXPECT_THROW(scene::parse_int("2.9"), NumberError);
  EXPECT_THROW(scene::parse_int("1e10"), NumberError);
  EXPECT_THROW(scene::parse_float("1e39"), NumberError);
  EXPECT_THROW(scene::parse_float("1abc"), NumberError);
  EXPECT_THROW(scene::parse_float("nan"), NumberError);
  EXPECT_THROW(scene::parse_float("inf"), NumberError);
  EXPECT_THROW(scene::parse_double("1e400"), NumberError);
  EXPECT_THROW(scene::parse_float(""), NumberError);
  EXPECT_EQ(scene::parse_float_list("1, 2\t3\n4").size(), 4u);
}

TEST(HostileNumbers, SceneNumbersAreStrict) {
  auto scene_with = [](const std::string &name, const std::string &body) {
    return write_file(name, "<cycles>\n" + body + "</cycles>\n");
  };
  expect_refused(scene_with("idx29.xml", "<mesh P=\"0 0 0 1 0 0 0 1 0\" nverts=\"3\" verts=\"0 1 2.9\" />\n"),
                 "idx29.xml:2: <mesh> verts: '2.9' is not an integer");
  expect_load_error(scene_with("seed.xml", "<integrator seed=\"1e10\" />\n"), "seed.xml:2: <integrator> seed: '1e10' is out of range");
  expect_load_error(scene_with("exposure.xml", "<film exposure=\"-100\" />\n"), "exposure.xml:2: <film> exposure must be in [0, 1e6]");
  expect_load_error(scene_with("junk.xml", "<transform translate=\"1abc 0 0\" />\n"), "'1abc' is not a number");
  expect_load_error(scene_with("overflow.xml", "<mesh P=\"1e39 0 0 1 0 0 0 1 0\" nverts=\"3\" verts=\"0 1 2\" />\n"),
                    "overflows a 32-bit float");
  expect_load_error(scene_with("inf_geometry.xml", "<transform scale=\"1e30 1e30 1e30\"><mesh P=\"1e10 0 0 1 0 0 0 1 0\" "
                                                   "nverts=\"3\" verts=\"0 1 2\" /></transform>\n"),
                    "vertex 0 is not finite after the transform");
  expect_load_error(scene_with("samples.xml", "<integrator samples=\"4.5\" />\n"), "'4.5' is not an integer");
}

TEST(HostileNumbers, ObjFaceIndicesAreStrict) {
  expect_mesh_error("junk_face.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1abc 2 3\n",
                    "junk_face.obj:4: 'f' line: '1abc' is not a number");
  expect_mesh_error("junk_vertex.obj", "v 0 0 0x\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
                    "junk_vertex.obj:1: 'v' line: '0x' is not a number");
  write_file("good.obj", "v 0 0 3\nv 1 0 3\nv 0 1 3\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2/1 -1//1\n");
  EXPECT_EQ(scene::load_scene(write_file("good_obj.xml", "<cycles>\n<mesh src=\"good.obj\" />\n</cycles>\n")).meshes.size(),
            1u);
}

TEST(HostileNumbers, ConnectSocketsAndNodeNamesAreChecked) {
  const std::string head = "<cycles>\n<shader name=\"s\">\n<diffuse_bsdf name=\"d\" />\n";
  expect_refused(write_file("bad_socket.xml", head + "<connect from=\"d bsdf\" to=\"output surfce\" />\n</shader>\n</cycles>\n"),
                 "bad_socket.xml:4: <connect> to unknown socket 'surfce' of node 'output'");
  expect_load_error(write_file("bad_from.xml", head + "<connect from=\"d bsdff\" to=\"output surface\" />\n</shader>\n</cycles>\n"),
                    "bad_from.xml:4: <connect> from unknown socket 'bsdff' of node 'd' (diffuse_bsdf)");
  expect_load_error(write_file("bad_input.xml", head + "<checker_texture name=\"c\" />\n"
                                                       "<connect from=\"c color\" to=\"d colour\" />\n</shader>\n</cycles>\n"),
                    "bad_input.xml:5: <connect> to unknown socket 'colour'");
  expect_load_error(write_file("dup_node.xml", head + "<diffuse_bsdf name=\"d\" />\n</shader>\n</cycles>\n"),
                    "dup_node.xml:4: duplicate node name 'd' in shader 's' (first defined at");
  // Socket names compare case-insensitively (the Cycles examples write "BSDF").
  EXPECT_NO_THROW(scene::load_scene(
      write_file("case_socket.xml", head + "<connect from=\"d BSDF\" to=\"output Surface\" />\n</shader>\n</cycles>\n")));
}

TEST(HostileNumbers, LabCommandLine) {
  std::string out;
  EXPECT_EQ(1, run_cli("lab furnace --closure diffuse --wi 1e30,1e30,0 --samples 100", out)) << out;
  EXPECT_NE(out.find("length must be in [1e-6, 1e6]"), std::string::npos) << out;
  EXPECT_EQ(1, run_cli("lab furnace --closure diffuse --wi 1e39,0,1 --samples 100", out)) << out;
  EXPECT_NE(out.find("overflows a 32-bit float"), std::string::npos) << out;
  EXPECT_EQ(1, run_cli("lab furnace --closure diffuse --wi nan,0,1 --samples 100", out)) << out;
  EXPECT_EQ(1, run_cli("lab furnace --closure diffuse --param color=1,1,1 --param color=0.5,0.5,0.5 --samples 100", out))
      << out;
  EXPECT_NE(out.find("--param color given more than once"), std::string::npos) << out;
  EXPECT_EQ(0, run_cli("lab furnace --closure diffuse --wi 0,3,4 --samples 100", out)) << out;
}

// ---- Overflowing chi2 bin counts ---------------------------------------------------

TEST(HostileLab, Chi2BinCountsWhoseProductOverflowsAreRefused) {
  std::string out;
  // 65536 x 65536 = 2^32 wraps to 0 in an int.
  EXPECT_EQ(1, run_cli("lab chi2 --closure diffuse --theta-bins 65536 --phi-bins 65536 --samples 100", out)) << out;
  EXPECT_NE(out.find("at most 4e6 cells"), std::string::npos) << out;
  lab::Chi2Options options;
  options.theta_bins = 65536;
  options.phi_bins = 65536;
  host::ClosureInstance diffuse(*plugin().find("diffuse"), host::ParamList{});
  EXPECT_THROW(lab::chi2_test(diffuse, host::make_local_context(Vec3(0, 0, 1)), options), std::invalid_argument);
}

// ---- Truncated plugin, bare plugin names --------------------------------------------

TEST(HostilePlugin, TruncatedPluginIsRefusedBeforeDlopen) {
  const fs::path truncated = temp_dir() / "libtruncated.so";
  fs::copy_file(GLIMMER_TEST_PLUGIN_PATH, truncated, fs::copy_options::overwrite_existing);
  fs::resize_file(truncated, fs::file_size(truncated) / 2);
  std::string out;
  EXPECT_EQ(2, run_cli("describe --plugin " + quoted(truncated.string()), out)) << out;
  EXPECT_NE(out.find("(truncated"), std::string::npos) << out;
  EXPECT_FALSE(host::elf_problem(truncated.string()).empty());
  EXPECT_EQ(host::elf_problem(GLIMMER_TEST_PLUGIN_PATH), "");
  // A few bytes, and a text file.
  fs::resize_file(truncated, 10);
  EXPECT_EQ(2, run_cli("describe --plugin " + quoted(truncated.string()), out)) << out;
  EXPECT_NE(out.find("too short"), std::string::npos) << out;
}

TEST(HostilePlugin, BareNameLoadsTheFileInTheCurrentFolderNotASystemLibrary) {
  // A junk file named like a system library in the current folder: the
  // checked file must be the loaded one (dlopen("libm.so.6") would load libm).
  const fs::path dir = temp_dir() / "bare_name";
  fs::create_directories(dir);
  std::ofstream(dir / "libm.so.6") << std::string(200, 'x');
  std::string out;
  EXPECT_EQ(2, run_cli("describe --plugin libm.so.6", out)) << out;  // cwd: no libm.so.6 there
  EXPECT_NE(out.find("not found"), std::string::npos) << out;
  const std::string cmd = "cd " + quoted(dir.string()) + " && '" + std::string(GLIMMER_TEST_CLI_PATH) +
                          "' describe --plugin libm.so.6 > out.txt 2>&1";
  const int status = std::system(cmd.c_str());
  EXPECT_EQ(WEXITSTATUS(status), 2);
  std::ifstream log(dir / "out.txt");
  const std::string text((std::istreambuf_iterator<char>(log)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find((dir / "libm.so.6").string() + ": not an ELF file"), std::string::npos) << text;
}

// ---- Signals ---------------------------------------------------------------------------

std::string sky_scene(const std::string &name, int size) {
  return write_file(name, "<cycles>\n<camera width=\"" + std::to_string(size) + "\" height=\"" + std::to_string(size) +
                              "\" />\n<background><background name=\"bg\" color=\"0.3 0.4 0.5\" strength=\"1\" />"
                              "<connect from=\"bg background\" to=\"output surface\" /></background>\n" +
                              kTriangle + "</cycles>\n");
}

TEST(HostileSignals, SigpipeOnProgressIsIgnored) {
  // The progress reader (`true`) exits at once; the render must finish and write its image.
  const auto png = (temp_dir() / "sigpipe.png").string();
  fs::remove(png);
  const std::string script =
      write_file("sigpipe.sh", "'" + std::string(GLIMMER_TEST_CLI_PATH) + "' render '" + sky_scene("sigpipe.xml", 16) +
                                   "' -o '" + png + "' --samples 64 2>/dev/null | true\nexit ${PIPESTATUS[0]}\n");
  const std::string cmd = "bash " + quoted(script);
  const int status = std::system(cmd.c_str());
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0);
  EXPECT_TRUE(fs::exists(png));
}

// The camera inside a closed white box, 100 bounces per path: one pass at
// 1000x1000 on one thread takes far longer than the 1 s before SIGINT. Half
// the box is glint, whose table precomputation (an empty cache) takes seconds.
std::string closed_box_scene() {
  const std::string quad = "nverts=\"4 4 4 4 4 4\" verts=\"0 1 2 3  4 5 6 7  0 1 5 4  2 3 7 6  1 2 6 5  0 3 7 4\"";
  return write_file("closed_box.xml",
                    "<cycles>\n<camera width=\"8\" height=\"8\" />\n"
                    "<integrator min_bounce=\"100\" max_bounce=\"100\" max_diffuse_bounce=\"100\" />\n"
                    "<shader name=\"white\"><diffuse_bsdf name=\"d\" color=\"0.9 0.9 0.9\" />"
                    "<glint_bsdf name=\"g\" roughness=\"0.45\" gamma=\"2.5\" /><mix_closure name=\"m\" fac=\"0.5\" />"
                    "<connect from=\"d bsdf\" to=\"m closure1\" /><connect from=\"g bsdf\" to=\"m closure2\" />"
                    "<connect from=\"m closure\" to=\"output surface\" /></shader>\n"
                    "<state shader=\"white\"><mesh P=\"-5 -5 -5  5 -5 -5  5 5 -5  -5 5 -5  -5 -5 5  5 -5 5  5 5 5  -5 5 5\" " +
                        quad + " /></state>\n<light light_type=\"point\" co=\"1 1 1\" strength=\"100 100 100\" />\n</cycles>\n");
}

TEST(HostileSignals, InterruptBeforeTheFirstSampleKeepsTheOldOutput) {
  // In-process: a cancelled render has no complete pass.
  std::atomic<bool> cancel{true};
  render::RenderOptions opt;
  opt.samples = 4;
  opt.cancel = &cancel;
  const auto r = render_scene(sky_scene("cancelled.xml", 8), opt);
  EXPECT_TRUE(r.interrupted);
  EXPECT_EQ(r.samples_done, 0);
  EXPECT_THROW(scene::load_scene(sky_scene("cancelled_load.xml", 8), &cancel), scene::LoadCancelled);

  // CLI: SIGINT once the process has installed its handler (seen in
  // /proc/PID/status, so a slow start-up cannot make this test flaky), then
  // 0.5 s later: in the glint table precomputation (empty cache: seconds) or
  // loading; the first pass alone takes far longer. Exit 3, old image untouched.
  const auto png = (temp_dir() / "keep.png").string();
  std::ofstream(png) << "the old good image";
  const fs::path empty_cache = temp_dir() / "empty_cache";
  fs::remove_all(empty_cache);
  const std::string scene = closed_box_scene(), log_path = (temp_dir() / "keep.txt").string();
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    const int fd = ::open(log_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    ::dup2(fd, 1);
    ::dup2(fd, 2);
    ::setenv("GLIMMER_CACHE_DIR", empty_cache.c_str(), 1);
    ::execl(GLIMMER_TEST_CLI_PATH, GLIMMER_TEST_CLI_PATH, "render", scene.c_str(), "-o", png.c_str(), "--width",
            "1000", "--height", "1000", "--samples", "4", "--threads", "1", static_cast<char *>(nullptr));
    ::_exit(127);
  }
  auto catches_sigint = [pid] {
    std::ifstream status("/proc/" + std::to_string(pid) + "/status");
    std::string line;
    while (std::getline(status, line))
      if (line.rfind("SigCgt:", 0) == 0) return ((std::stoull(line.substr(7), nullptr, 16) >> (SIGINT - 1)) & 1) != 0;
    return false;
  };
  for (int i = 0; i < 6000 && !catches_sigint(); ++i) ::usleep(10000);
  ::usleep(500000);
  ::kill(pid, SIGINT);
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status)) << "killed by signal " << WTERMSIG(status);
  EXPECT_EQ(WEXITSTATUS(status), 3);
  std::ifstream log(temp_dir() / "keep.txt");
  const std::string text((std::istreambuf_iterator<char>(log)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("left unchanged"), std::string::npos) << text;
  std::ifstream kept(png);
  const std::string content((std::istreambuf_iterator<char>(kept)), std::istreambuf_iterator<char>());
  EXPECT_EQ(content, "the old good image");
}

// ---- Output: validated before work, written through an unpredictable O_EXCL temporary ----

TEST(HostileOutput, BadOutputIsReportedBeforeRendering) {
  std::string out;
  const std::string scene = sky_scene("out_check.xml", 8);
  EXPECT_EQ(1, run_cli("render " + quoted(scene) + " -o /no/such/folder/x.png --samples 100000 --quiet", out));
  EXPECT_NE(out.find("output folder '/no/such/folder' does not exist"), std::string::npos) << out;
  EXPECT_EQ(1, run_cli("render " + quoted(scene) + " -o " + quoted((temp_dir() / "x.unknownext").string()) +
                           " --samples 100000 --quiet",
                       out));
  EXPECT_NE(out.find("no image format for extension '.unknownext'"), std::string::npos) << out;
  EXPECT_EQ(1, run_cli("render " + quoted(scene) + " -o " + quoted(temp_dir().string()) + "/ --quiet", out));
  // A folder access(W_OK) calls writable in which no file can be created (/proc for root; for other users access()
  // already refuses it): refused before the render (the probe's message), not at the write after it (the atomic
  // writer's "cannot create a temporary file").
  if (fs::is_directory("/proc/self") && ::access("/proc", W_OK | X_OK) == 0) {
    EXPECT_EQ(1, run_cli("render " + quoted(scene) + " -o /proc/x.png --samples 100000 --quiet", out));
    EXPECT_NE(out.find("cannot create a file in output folder '/proc'"), std::string::npos) << out;
  }
  // The probe leaves nothing behind in a folder that takes files.
  const fs::path clean = temp_dir() / "probe_clean";
  fs::create_directories(clean);
  const std::string ok = (clean / "ok.png").string();
  EXPECT_EQ(0, run_cli("render " + quoted(scene) + " -o " + quoted(ok) + " --samples 1 --quiet", out)) << out;
  std::vector<std::string> names;
  for (const auto &e : fs::directory_iterator(clean)) names.push_back(e.path().filename().string());
  EXPECT_EQ(names, std::vector<std::string>{"ok.png"});
}

TEST(HostileOutput, PlantedSymlinksAreNeitherFollowedNorOverwritten) {
  const fs::path dir = temp_dir() / "symlinks";
  fs::create_directories(dir);
  const fs::path victim = dir / "victim.txt";
  std::ofstream(victim) << "precious";
  // The old predictable temporary name (.STEM.tmp<PID>.EXT) planted as a symlink to the victim.
  const fs::path target = dir / "render.png";
  fs::remove(dir / (".render.tmp" + std::to_string(::getpid()) + ".png"));
  fs::create_symlink(victim, dir / (".render.tmp" + std::to_string(::getpid()) + ".png"));
  // The target itself a symlink to the victim: rename replaces the link, not the victim.
  fs::remove(target);
  fs::create_symlink(victim, target);
  render::RenderOptions opt;
  opt.samples = 1;
  render::write_image(target.string(), render_scene(sky_scene("symlink.xml", 8), opt));
  std::ifstream in(victim);
  const std::string content((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(content, "precious");
  EXPECT_TRUE(fs::is_regular_file(fs::symlink_status(target)));
  auto image = OIIO::ImageInput::open(target.string());
  ASSERT_TRUE(image);
  EXPECT_EQ(image->spec().width, 8);
  // Temporary names are random and not left behind.
  int leftovers = 0;
  for (const auto &e : fs::directory_iterator(dir))
    if (e.path().filename().string().find(".tmp") != std::string::npos && !fs::is_symlink(e.symlink_status()))
      ++leftovers;
  EXPECT_EQ(leftovers, 0);
  EXPECT_NE(random_hex16(), random_hex16());
  // A folder at the target is refused without touching it.
  fs::create_directories(dir / "folder.png");
  EXPECT_THROW(render::write_image((dir / "folder.png").string(), render_scene(sky_scene("symlink.xml", 8), opt)),
               std::runtime_error);
  EXPECT_TRUE(fs::is_directory(dir / "folder.png"));
}

// ---- The default cache folder: private, never a shared /tmp folder -------------------

TEST(HostileCache, DefaultCacheIsAPrivateFolderUnderXdgCacheHome) {
  const fs::path xdg = temp_dir() / "xdg";
  fs::remove_all(xdg);
  fs::create_directories(xdg / "glimmer");
  fs::permissions(xdg / "glimmer", fs::perms::all);  // a world-writable folder left by someone: made private
  const std::string run = "env -u GLIMMER_CACHE_DIR -u HOME XDG_CACHE_HOME=" + quoted(xdg.string()) + " '" +
                          std::string(GLIMMER_TEST_CLI_PATH) +
                          "' lab furnace --closure glint --param roughness=0.5 --param gamma=2 --samples 100 > " +
                          quoted((temp_dir() / "xdg.txt").string()) + " 2>&1";
  int status = std::system(run.c_str());
  EXPECT_EQ(WEXITSTATUS(status), 0);
  struct stat st {};
  ASSERT_EQ(0, ::stat((xdg / "glimmer").c_str(), &st));
  EXPECT_EQ(st.st_mode & 0777, 0700u);
  int tables = 0;
  for (const auto &e : fs::directory_iterator(xdg / "glimmer"))
    if (e.path().filename().string().rfind("glint_P_", 0) == 0) {
      ++tables;
      ASSERT_EQ(0, ::stat(e.path().c_str(), &st));
      EXPECT_EQ(st.st_mode & 0777, 0600u);
    }
  EXPECT_EQ(tables, 1);
  ASSERT_EQ(0, ::stat((xdg / "glimmer" / "secret.key").c_str(), &st));
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  // A symlink at the cache folder (someone else's folder): caching is off, with a warning; the run succeeds.
  fs::remove_all(xdg / "glimmer");
  fs::create_directories(xdg / "elsewhere");
  fs::create_directory_symlink(xdg / "elsewhere", xdg / "glimmer");
  status = std::system(run.c_str());
  EXPECT_EQ(WEXITSTATUS(status), 0);
  std::ifstream log(temp_dir() / "xdg.txt");
  const std::string text((std::istreambuf_iterator<char>(log)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("cache folder unusable"), std::string::npos) << text;
  EXPECT_TRUE(fs::is_empty(xdg / "elsewhere"));
}

}  // namespace
}  // namespace glimmer::test
