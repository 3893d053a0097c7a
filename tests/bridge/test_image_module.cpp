// The image module (render/image_io.h): OpenImageIO is loaded with libglimmer_image_io.so on first use,
// not linked into the glimmer executable; the output extensions checked without the module are ones the
// module can write; a missing module is a clear error before any render work.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <string>

#include "render/image_io.h"
#include "render/image_output.h"
#include "render_test_util.h"

namespace glimmer::test {
namespace {

std::string ldd(const std::string &binary) {
  std::string text;
  FILE *p = popen(("ldd '" + binary + "' 2>&1").c_str(), "r");
  if (p == nullptr) return text;
  char buf[512];
  while (fgets(buf, sizeof(buf), p) != nullptr) text += buf;
  pclose(p);
  return text;
}

TEST(ImageModule, CliDoesNotLinkOpenImageIO) {
  EXPECT_EQ(ldd(GLIMMER_TEST_CLI_PATH).find("libOpenImageIO"), std::string::npos);
  // Control: the module links it (and this test binary, which reads images itself), so ldd shows it there.
  EXPECT_NE(ldd(std::string(GLIMMER_TEST_BINARY_DIR) + "/" + render::kImageIoFileName).find("libOpenImageIO"),
            std::string::npos);
}

// check_output_path accepts these without asking the module; the module must agree.
TEST(ImageModule, KnownWritableExtensionsAreWritable) {
  const render::ImageIo &io = render::image_io();
  for (const auto ext : render::kKnownWritableExtensions) {
    const std::string path = (temp_dir() / ("known" + std::string(ext))).string();
    EXPECT_NO_THROW(io.check_output_format(path)) << ext;
    EXPECT_TRUE(render::known_writable_extension(path)) << ext;
  }
  EXPECT_TRUE(render::known_writable_extension("a/B.EXR"));
  // Control: an unknown extension is not on the list and the module refuses it.
  EXPECT_FALSE(render::known_writable_extension("a/b.xyz"));
  EXPECT_THROW(io.check_output_format((temp_dir() / "unknown.xyz").string()), std::runtime_error);
  EXPECT_THROW(render::check_output_path((temp_dir() / "unknown.xyz").string()), std::runtime_error);
}

TEST(ImageModule, MissingModuleIsAClearErrorBeforeTheRender) {
  const std::string scene = write_file("module_scene.xml",
                                       "<cycles>\n<camera width=\"8\" height=\"8\" />\n"
                                       "<transform translate=\"0 0 -3\"><camera /></transform>\n"
                                       "<mesh P=\"-1 -1 0  1 -1 0  1 1 0  -1 1 0\" nverts=\"4\" verts=\"0 1 2 3\" />\n"
                                       "</cycles>\n");
  const auto out_path = temp_dir() / "module_missing.exr";
  std::filesystem::remove(out_path);
  ::setenv("GLIMMER_IMAGE_IO_PATH", "/no/such/libglimmer_image_io.so", 1);
  std::string out;
  const int code = run_cli("render '" + scene + "' -o '" + out_path.string() + "' --samples 1 --quiet", out);
  ::unsetenv("GLIMMER_IMAGE_IO_PATH");
  EXPECT_EQ(code, 2) << out;
  EXPECT_NE(out.find("cannot load the image module '/no/such/libglimmer_image_io.so'"), std::string::npos) << out;
  EXPECT_FALSE(std::filesystem::exists(out_path));
  // Control: with the module found next to the executable the same command renders.
  EXPECT_EQ(run_cli("render '" + scene + "' -o '" + out_path.string() + "' --samples 1 --quiet", out), 0) << out;
  EXPECT_TRUE(std::filesystem::exists(out_path));
}

}  // namespace
}  // namespace glimmer::test
