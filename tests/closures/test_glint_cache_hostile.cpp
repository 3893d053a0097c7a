// The glint table cache under attack (issue 14): a crafted table is rejected
// and rebuilt with a warning, whether the attacker recomputed the old FNV-1a
// checksum (the HMAC-SHA256 keyed by the private cache secret fails) or even
// knew the key (the energy validation fails for edited levels); junk at the
// entry path is replaced; the cache folder and key are private.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <vector>

#include "closures/cache_test_util.h"
#include "closures/closure_checks.h"
#include "glimmer/cache_blob.h"
#include "glimmer/sha256.h"
#include "tables/checked_stamp.h"
#include "tables/glint_aniso.h"
#include "tables/glint_tables.h"

namespace glimmer::test {
namespace {

namespace fs = std::filesystem;

// Scales the float values of LOD levels [first, last) by `factor`.
// Layout: magic 8, version 4, key 8, distribution 4, alpha 4, gamma 4, then
// per level: n_theta_o, n_phi (int32) and 91 * n_theta_o * n_phi floats; then the factored level 0's scales.
void scale_levels(std::vector<char> &bytes, int first, int last, float factor) {
  size_t pos = 32;
  for (int l = 0; l < 9 && pos + 8 <= bytes.size() - 32; ++l) {  // the 9 levels (the factored level's scales follow)
    int32_t n_to = 0, n_phi = 0;
    std::memcpy(&n_to, bytes.data() + pos, 4);
    std::memcpy(&n_phi, bytes.data() + pos + 4, 4);
    pos += 8;
    const size_t count = static_cast<size_t>(91) * n_to * n_phi;
    if (l >= first && l < last)
      for (size_t i = 0; i < count; ++i) {
        float v;
        std::memcpy(&v, bytes.data() + pos + 4 * i, 4);
        v *= factor;
        std::memcpy(bytes.data() + pos + 4 * i, &v, 4);
      }
    pos += 4 * count;
  }
}

// Scales the factored level 0's slice scales (the doubles after the 9 levels: a count, then the scales) by `factor`.
void scale_factored_scales(std::vector<char> &bytes, double factor) {
  size_t pos = 32;
  for (int l = 0; l < 9; ++l) {
    int32_t n_to = 0, n_phi = 0;
    std::memcpy(&n_to, bytes.data() + pos, 4);
    std::memcpy(&n_phi, bytes.data() + pos + 4, 4);
    pos += 8 + 4 * static_cast<size_t>(91) * n_to * n_phi;
  }
  int32_t n = 0;
  std::memcpy(&n, bytes.data() + pos, 4);
  ASSERT_GT(n, 0) << "the table must be factored";
  pos += 4;
  for (int32_t i = 0; i < n; ++i) {
    double v;
    std::memcpy(&v, bytes.data() + pos + 8 * i, 8);
    v *= factor;
    std::memcpy(bytes.data() + pos + 8 * i, &v, 8);
  }
}

// The MAC's building blocks against published test vectors (FIPS 180-4
// examples, RFC 4231 test case 2).
// A glint closure's parameters.
host::ParamList glint_params(const char *roughness, const char *gamma) {
  host::ParamList params;
  params.set_from_text(closure_type("glint"), "roughness", roughness);
  params.set_from_text(closure_type("glint"), "gamma", gamma);
  return params;
}

TEST(GlintCacheHostile, Sha256AndHmacMatchPublishedVectors) {
  EXPECT_EQ(to_hex(sha256("abc", 3)), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  const std::string million(1000000, 'a');  // FIPS 180-2 appendix B.3: many blocks
  EXPECT_EQ(to_hex(sha256(million.data(), million.size())),
            "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0");
  EXPECT_EQ(to_hex(sha256("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq", 56)),
            "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
  const std::string data = "what do ya want for nothing?";
  EXPECT_EQ(to_hex(hmac_sha256("Jefe", 4, data.data(), data.size())),
            "5bdcc146bf60754e6a042426089575c75a003f089d2739839dec58b964ec3843");
  // Negative control: one changed byte changes the digest.
  EXPECT_NE(to_hex(sha256("abd", 3)), to_hex(sha256("abc", 3)));
}

TEST(GlintCacheHostile, CraftedTablesAreRejectedAndJunkIsReplaced) {
  const fs::path root = fs::path(GLIMMER_TEST_BINARY_DIR) / "test_cache_glint_hostile";
  fs::remove_all(root);
  const std::string dir = (root / "nested" / "glimmer").string();
  const GlimmerHostServices host = host_caching_in(dir);
  const GlimmerClosureType &type = closure_type("glint");
  const host::ParamList params = glint_params("0.4", "2");
  const Vec3 wi = spherical_dir(30.0, 0.0), wo = spherical_dir(32.0, 175.0);
  const GlimmerShadingContext ctx = footprint_context(wi, 0.5, 0.5, 0.05, 0.0, 0.0, 0.05);
  auto eval_now = [&] {
    g_cache_log.clear();
    host::ClosureInstance c(type, params, &host);
    Spectrum f;
    float pdf = 0.0f;
    c.eval(ctx, wo, f, pdf);
    return f.x;
  };
  const float reference = eval_now();
  // The folders the cache created are private.
  struct stat st {};
  ASSERT_EQ(0, ::stat(dir.c_str(), &st));
  EXPECT_EQ(st.st_mode & 0777, 0700u);
  std::vector<fs::path> files;
  for (const auto &e : fs::directory_iterator(dir))
    if (e.path().filename() != "secret.key") files.push_back(e.path());
  ASSERT_EQ(files.size(), 1u);
  const fs::path entry = files[0];
  const std::vector<char> original = read_bytes(entry);

  const std::vector<char> key = read_bytes(fs::path(dir) / "secret.key");
  ASSERT_EQ(key.size(), 32u);
  ASSERT_EQ(0, ::stat((fs::path(dir) / "secret.key").c_str(), &st));
  EXPECT_EQ(st.st_mode & 0777, 0600u);

  // Control: the test's MAC of the unmodified content is the file's, and it loads silently.
  std::vector<char> same = original;
  rewrite_mac(same, key);
  ASSERT_EQ(same, original) << "the test's HMAC must match the file's";
  EXPECT_EQ(eval_now(), reference);
  EXPECT_FALSE(logged("recomputing"));
  EXPECT_FALSE(logged("precomputed"));

  struct Attack {
    const char *what;
    int first, last;
    float factor;
    bool knows_key;  // else the attacker recomputes the old unkeyed FNV-1a checksum
    const char *expected;
  };
  for (const Attack &a :
       {Attack{"x1000 brighter, FNV recomputed", 0, 9, 1000.0f, false, "MAC mismatch"},
        Attack{"x1.01, FNV recomputed", 0, 9, 1.01f, false, "MAC mismatch"},
        Attack{"level 0 doubled, MAC recomputed", 0, 1, 2.0f, true, "does not keep the energy"},
        Attack{"coarse levels x1.01, MAC recomputed", 1, 9, 1.01f, true, "does not keep the energy"},
        Attack{"factored level 0's scales x1.05, MAC recomputed", -1, -1, 1.05f, true, "slice scales differ"}}) {
    SCOPED_TRACE(a.what);
    std::vector<char> crafted = original;
    if (a.first < 0)
      scale_factored_scales(crafted, a.factor);
    else
      scale_levels(crafted, a.first, a.last, a.factor);
    if (a.knows_key) rewrite_mac(crafted, key);
    else rewrite_fnv(crafted);
    write_bytes(entry, crafted);
    EXPECT_EQ(eval_now(), reference);
    EXPECT_TRUE(logged("recomputing")) << "expected a warning";
    EXPECT_TRUE(logged(a.expected)) << (g_cache_log.empty() ? "" : g_cache_log[0]);
    EXPECT_EQ(read_bytes(entry), original) << "the rebuilt table replaces the crafted file";
  }

  // A directory (with content) at the entry path: removed with a warning, the table rebuilt and cached.
  fs::remove(entry);
  fs::create_directories(entry / "junk");
  EXPECT_EQ(eval_now(), reference);
  EXPECT_TRUE(logged("not a regular file; removed")) << (g_cache_log.empty() ? "" : g_cache_log[0]);
  EXPECT_TRUE(fs::is_regular_file(fs::symlink_status(entry)));
  EXPECT_EQ(read_bytes(entry), original);
  fs::remove_all(root);
}

// The cache files' names and headers as the files in users' folders have them
// (the keys are those of files main wrote before cache_blob.h's ByteWriter /
// Fnv1a replaced each table's own copy): a change of the key chain or of the
// header renames or orphans every cached table.
TEST(GlintCacheHostile, CacheKeysAndHeaderArePinned) {
  // The chain's start value and two strings, computed by hand (Python) with it.
  EXPECT_EQ(Fnv1a{}.h, 0x14650fb0739d0383ull);
  EXPECT_EQ(Fnv1a{}.add("a", 1).h, 0x44bd8ad473cd9906ull);
  EXPECT_EQ(Fnv1a{}.add("a", 1).h, Fnv1a{}.add('a').h);
  auto from_bits = [](uint32_t bits) {
    float f;
    std::memcpy(&f, &bits, 4);
    return f;
  };
  // glint_P_2c9b764e6df95301.bin: GGX, alpha 0x3d23d70b (0.04), gamma 2, format 7 (session 42: the factored level 0's
  // slice scales; format 5's key was 0x030cca93e58152cb). Both recomputed by hand (Python) from the chain.
  plugin::glint::TableSpec p;
  p.distribution = plugin::glint::BaseDistribution::GGX;
  p.alpha = from_bits(0x3d23d70bu);
  p.gamma_deg = 2.0f;
  EXPECT_EQ(plugin::glint::table_key(p), 0x2c9b764e6df95301ull);
  EXPECT_EQ(fs::path(plugin::glint::table_cache_path("/c", p)).filename().string(), "glint_P_2c9b764e6df95301.bin");
  // glint_A_c547ed6736770f18.bin: GGX, alpha 0.25 x 0.0625, gamma 2.
  plugin::glint::AnisoSpec a;
  a.distribution = microfacet::Distribution::GGX;
  a.alpha_x = 0.25f;
  a.alpha_y = 0.0625f;
  a.gamma_deg = 2.0f;
  EXPECT_EQ(plugin::glint::aniso_energy_key(a), 0xc547ed6736770f18ull);
  // Negative controls: any field changes the key.
  p.gamma_deg = std::nextafter(2.0f, 3.0f);
  EXPECT_NE(plugin::glint::table_key(p), 0x030cca93e58152cbull);
  a.alpha_y = 0.25f;
  EXPECT_NE(plugin::glint::aniso_energy_key(a), 0xc547ed6736770f18ull);

  // Header: 8-byte magic, uint32 version, uint64 key, little-endian, no padding.
  constexpr char magic[8] = {'G', 'L', 'M', 'G', 'L', 'N', 'T', 'A'};
  ByteWriter out;
  out.put_header(magic, 1u, 0xc547ed6736770f18ull);
  const std::vector<unsigned char> expected = {'G', 'L', 'M',  'G',  'L',  'N',  'T',  'A',  1,    0,
                                               0,   0,   0x18, 0x0f, 0x77, 0x36, 0x67, 0xed, 0x47, 0xc5};
  EXPECT_EQ(out.bytes, expected);
  ByteReader in{out.bytes};
  EXPECT_TRUE(in.get_header(magic, 1u, 0xc547ed6736770f18ull));
  EXPECT_TRUE(in.at_end());
  // Negative controls: another magic, version or key, or a header cut short, is refused.
  constexpr char other[8] = {'G', 'L', 'M', 'G', 'L', 'N', 'T', 'P'};
  EXPECT_FALSE((ByteReader{out.bytes}.get_header(other, 1u, 0xc547ed6736770f18ull)));
  EXPECT_FALSE((ByteReader{out.bytes}.get_header(magic, 2u, 0xc547ed6736770f18ull)));
  EXPECT_FALSE((ByteReader{out.bytes}.get_header(magic, 1u, 0xc547ed6736770f19ull)));
  const std::vector<unsigned char> cut(out.bytes.begin(), out.bytes.end() - 1);
  EXPECT_FALSE((ByteReader{cut}.get_header(magic, 1u, 0xc547ed6736770f18ull)));
}

// Found while interrupting renders: gamma in (2, 2.5] (and (1, 1.5]) gives an
// odd concentric disk grid whose centre point had NaN angles, and the table
// build read outside its slice (SIGSEGV). Now it builds, with finite values.
TEST(GlintCacheHostile, OddConeGridBuildsWithFiniteValues) {
  const std::string dir = GLIMMER_TEST_BINARY_DIR "/test_cache_glint_odd_grid";
  std::filesystem::remove_all(dir);
  const GlimmerHostServices host = host_caching_in(dir);
  for (const char *gamma : {"1.25", "2.5"}) {
    SCOPED_TRACE(gamma);
    host::ClosureInstance c(closure_type("glint"), glint_params("0.45", gamma), &host);
    Spectrum f;
    float pdf = 0.0f;
    c.eval(footprint_context(spherical_dir(30.0, 0.0), 0.5, 0.5, 0.05, 0.0, 0.0, 0.05), spherical_dir(30.0, 180.0), f,
           pdf);
    EXPECT_TRUE(std::isfinite(f.x) && std::isfinite(pdf));
  }
  std::filesystem::remove_all(dir);
}

// Session 39: the energy check's stamp (tables/checked_stamp.h; its own rules in test_checked_stamp.cpp). Loading a
// glint table re-sums every LOD level's W-weighted energy (~1 s of CPU, most of a small render's start); the first
// load of an entry runs it and writes <entry>.checked, the next load by the same build skips it and gives the same
// table bit for bit; another build checks once and is added (this build still skips); no build id always checks. A
// crafted entry (level 0 doubled, MAC recomputed with the folder's key) beside the good stamp is refused at every load,
// and the failed loads leave the stamp as it was.
// The roughness-0.2 glint table (GGX, alpha 0.04, gamma 2).
plugin::glint::TableSpec roughness_02_spec() {
  plugin::glint::TableSpec spec;
  spec.distribution = plugin::glint::BaseDistribution::GGX;
  spec.alpha = 0.2f * 0.2f;
  spec.gamma_deg = 2.0f;
  return spec;
}

// That table's entry in the suite's cache (built if missing), copied with the cache's key into the private folder
// `dir` (made anew); returns the copy's path, or "" when the suite's cache has no entry.
fs::path private_copy_of_roughness_02_table(const fs::path &dir) {
  const GlimmerHostServices *shared = host::default_host_services();
  if (shared->cache_dir == nullptr || shared->cache_dir[0] == '\0') return {};
  { host::ClosureInstance warm(closure_type("glint"), glint_params("0.2", "2"), shared); }
  const fs::path source = plugin::glint::table_cache_path(shared->cache_dir, roughness_02_spec());
  if (!fs::exists(source)) return {};
  fs::remove_all(dir);
  fs::create_directories(dir);
  fs::permissions(dir, fs::perms::owner_all, fs::perm_options::replace);
  const fs::path entry = dir / source.filename(), key_file = dir / "secret.key";
  fs::copy_file(source, entry);
  fs::copy_file(fs::path(shared->cache_dir) / "secret.key", key_file);
  fs::permissions(key_file, fs::perms::owner_read | fs::perms::owner_write, fs::perm_options::replace);
  return entry;
}

TEST(GlintCacheHostile, EnergyCheckedStampSkipsTheCheckOfTheSameBuildAndBytes) {
  const plugin::glint::TableSpec spec = roughness_02_spec();
  const fs::path dir = fs::path(GLIMMER_TEST_BINARY_DIR) / ("test_cache_glint_stamp_" + std::to_string(::getpid()));
  const fs::path entry = private_copy_of_roughness_02_table(dir), key_file = dir / "secret.key";
  ASSERT_FALSE(entry.empty()) << "the suite's cache has no roughness-0.2 table";
  const std::string stamp = plugin::checked_stamp_path(entry.string()), &id = plugin::plugin_build_id();
  ASSERT_FALSE(id.empty()) << "no GNU build id: the stamp is never used";
  auto load = [&](const std::string &build_id, bool expect_check) {
    std::string problem;
    auto table = plugin::glint::load_table(entry.string(), spec, problem, build_id);
    EXPECT_TRUE(table) << problem;
    if (table) {
      EXPECT_EQ(table->energy_checked, expect_check) << "build id '" << build_id << "'";
    }
    return table;
  };
  const auto first = load(id, true);
  EXPECT_TRUE(fs::exists(stamp));
  const auto second = load(id, false);
  ASSERT_TRUE(first && second);
  for (int l = 0; l < plugin::glint::kLodCount; ++l) {  // bit for bit
    EXPECT_EQ(first->levels[l].values, second->levels[l].values) << "level " << l;
    EXPECT_EQ(first->levels[l].halves, second->levels[l].halves) << "level " << l;
  }
  // Another build checks once and joins the stamp; this build still skips; no build id always checks.
  load(id + "00", true);
  load(id + "00", false);
  load(id, false);
  load("", true);
  // A crafted entry beside the good entry's stamp: refused by the check the stamp does not cover, at every load, and
  // the failed loads leave the stamp as it was (a stamp written before or regardless of the check would let the
  // second load through).
  const std::vector<char> stamp_before = read_bytes(stamp);
  const std::vector<char> key = read_bytes(key_file);
  std::vector<char> crafted = read_bytes(entry);
  scale_levels(crafted, 0, 1, 2.0f);
  rewrite_mac(crafted, key);
  write_bytes(entry, crafted);
  std::string problem;
  for (int attempt = 0; attempt < 2; ++attempt) {
    EXPECT_FALSE(plugin::glint::load_table(entry.string(), spec, problem, id)) << "attempt " << attempt;
    EXPECT_NE(problem.find("does not keep the energy"), std::string::npos) << problem;
  }
  EXPECT_EQ(read_bytes(stamp), stamp_before);
  std::printf(
      "[glint table cache] stamp: build %s; the second load skips the energy check; another build checks once and "
      "joins; no build id checks; a crafted entry beside the stamp refused twice, the stamp unchanged (%s)\n",
      id.c_str(), problem.c_str());
  fs::remove_all(dir);
}

// A cache folder that takes no more bytes (RLIMIT_FSIZE: a full disk or quota; root ignores a read-only mode, which
// fails the same way, at open()): the energy check's stamp cannot be written, so every start repeats the check. The
// closure still loads the cached table, the host's log says why the stamp is missing and what it costs, and no stamp
// (nor a temporary file) is left; once the folder is writable the next load checks, stamps, and says nothing.
TEST(GlintCacheHostile, UnwritableStampIsLoggedAndTheCheckRunsAgain) {
  const plugin::glint::TableSpec spec = roughness_02_spec();
  const fs::path dir = fs::path(GLIMMER_TEST_BINARY_DIR) / ("test_cache_glint_nostamp_" + std::to_string(::getpid()));
  const fs::path entry = private_copy_of_roughness_02_table(dir);
  ASSERT_FALSE(entry.empty()) << "the suite's cache has no roughness-0.2 table";
  const std::string stamp = plugin::checked_stamp_path(entry.string()), &id = plugin::plugin_build_id();
  ASSERT_FALSE(id.empty()) << "no GNU build id: the stamp is never used";
  const auto files_in_dir = [&] { return std::distance(fs::directory_iterator(dir), fs::directory_iterator()); };
  const auto files_before = files_in_dir();
  const std::string warning = "cannot record the table's energy check beside " + entry.string();
  const std::string dir_name = dir.string();  // host_caching_in keeps its c_str()
  g_cache_log.clear();
  {
    const FileSizeLimit limit(16);
    ASSERT_TRUE(limit.ok());
    const GlimmerHostServices host = host_caching_in(dir_name);
    host::ClosureInstance instance(closure_type("glint"), glint_params("0.2", "2"), &host);
    std::string problem;
    const auto table = plugin::glint::load_table(entry.string(), spec, problem, id);
    ASSERT_TRUE(table) << problem;
    EXPECT_TRUE(table->energy_checked);
    EXPECT_NE(table->stamp_not_written.find("File too large"), std::string::npos) << table->stamp_not_written;
  }
  EXPECT_TRUE(logged(warning)) << "the closure's load did not log the missing stamp";
  EXPECT_TRUE(logged("every start will repeat the check"));
  EXPECT_FALSE(logged("recomputing")) << "the cached table itself must still load";
  EXPECT_FALSE(fs::exists(stamp));
  EXPECT_EQ(files_in_dir(), files_before) << "a temporary file was left behind";
  g_cache_log.clear();
  {
    const GlimmerHostServices host = host_caching_in(dir_name);
    host::ClosureInstance instance(closure_type("glint"), glint_params("0.2", "2"), &host);
  }
  EXPECT_TRUE(fs::exists(stamp));
  EXPECT_FALSE(logged("cannot record")) << g_cache_log.size() << " messages";
  // (The closure ran in the plugin DSO, another build than this test binary: this build checks once, then skips.)
  std::string problem;
  for (const bool expect_check : {true, false}) {
    const auto table = plugin::glint::load_table(entry.string(), spec, problem, id);
    ASSERT_TRUE(table) << problem;
    EXPECT_EQ(table->energy_checked, expect_check);
    EXPECT_EQ(table->stamp_not_written, "");
  }
  std::printf("[glint table cache] unwritable folder: logged '%s'; stamped once writable\n", warning.c_str());
  fs::remove_all(dir);
}

}  // namespace
}  // namespace glimmer::test
