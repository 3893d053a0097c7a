// The checked stamp's rules (plugin/tables/checked_stamp.h; session 39), on a small entry in a private folder: a
// stamp lists the last four builds that checked the entry's bytes, newest first; it never matches other bytes,
// another table kind, an empty build id, a build it dropped, or a file whose MAC fails (a flipped bit, a MAC made
// with another key) or whose payload does not parse (cut short, too many builds) even under a valid MAC.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "closures/cache_test_util.h"
#include "glimmer/cache_blob.h"
#include "tables/checked_stamp.h"

namespace glimmer::test {
namespace {

namespace fs = std::filesystem;
using plugin::checked_stamp_matches;
using plugin::checked_stamp_path;
using plugin::CheckedStampKind;
using plugin::write_checked_stamp;

CheckedStampKind test_kind(uint64_t key) {
  CheckedStampKind kind{{'T', 'E', 'S', 'T', 'S', 'T', 'M', 'P'}, 2u, key};
  return kind;
}

TEST(CheckedStamp, ListsTheLastFourBuildsOfTheSameBytesAndRefusesForgedStamps) {
  const fs::path dir = fs::path(GLIMMER_TEST_BINARY_DIR) / ("test_cache_checked_stamp_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const std::string entry = (dir / "entry.bin").string(), stamp = checked_stamp_path(entry);
  const std::vector<unsigned char> bytes = {1, 2, 3, 4, 5, 6, 7, 8}, other_bytes = {1, 2, 3, 4, 5, 6, 7, 9};
  ASSERT_EQ(write_cache_blob(entry, bytes), "");  // the private folder and its secret
  const CheckedStampKind kind = test_kind(42), other_kind = test_kind(43);
  auto listed = [&](const std::string &id) { return checked_stamp_matches(entry, kind, bytes, id); };

  EXPECT_FALSE(listed("a"));  // no stamp yet
  write_checked_stamp(entry, kind, bytes, "a");
  EXPECT_TRUE(listed("a"));
  EXPECT_FALSE(listed("b"));
  EXPECT_FALSE(listed(""));
  EXPECT_FALSE(checked_stamp_matches(entry, kind, other_bytes, "a"));
  EXPECT_FALSE(checked_stamp_matches(entry, other_kind, bytes, "a"));
  write_checked_stamp(entry, kind, bytes, "");  // no build id: nothing written
  EXPECT_TRUE(listed("a"));
  // Four builds are remembered; a fifth drops the oldest; re-stamping a listed build moves it first.
  for (const char *id : {"b", "c", "d"}) write_checked_stamp(entry, kind, bytes, id);
  for (const char *id : {"a", "b", "c", "d"}) EXPECT_TRUE(listed(id)) << id;
  write_checked_stamp(entry, kind, bytes, "a");  // a first again: b is now the oldest
  write_checked_stamp(entry, kind, bytes, "e");
  EXPECT_FALSE(listed("b"));
  for (const char *id : {"a", "c", "d", "e"}) EXPECT_TRUE(listed(id)) << id;
  // A stamp of other bytes replaces the list.
  write_checked_stamp(entry, kind, other_bytes, "f");
  EXPECT_TRUE(checked_stamp_matches(entry, kind, other_bytes, "f"));
  EXPECT_FALSE(checked_stamp_matches(entry, kind, other_bytes, "a"));
  EXPECT_FALSE(listed("f"));
  write_checked_stamp(entry, kind, bytes, "a");
  ASSERT_TRUE(listed("a"));

  const std::vector<char> good = read_bytes(stamp), key = read_bytes(dir / "secret.key");
  ASSERT_EQ(key.size(), 32u);
  std::vector<char> forged = good;
  forged.back() ^= 1;  // a flipped MAC bit, the payload intact
  write_bytes(stamp, forged);
  EXPECT_FALSE(listed("a"));
  forged = good;
  rewrite_mac(forged, std::vector<char>(32, 'k'));  // the right payload under another key's MAC
  write_bytes(stamp, forged);
  EXPECT_FALSE(listed("a"));
  // Payloads that do not parse, under the folder's own MAC: cut short by one byte; a count of five builds.
  forged.assign(good.begin(), good.end() - 33);
  forged.resize(forged.size() + 32);
  rewrite_mac(forged, key);
  write_bytes(stamp, forged);
  EXPECT_FALSE(listed("a"));
  forged = good;
  const size_t count_at = 8 + 4 + 8 + 8;  // header (magic, format, key), entry hash
  uint64_t count = 0;
  std::memcpy(&count, forged.data() + count_at, 8);
  ASSERT_EQ(count, 1u);
  count = 5;
  std::memcpy(forged.data() + count_at, &count, 8);
  rewrite_mac(forged, key);
  write_bytes(stamp, forged);
  EXPECT_FALSE(listed("a"));
  // Control: the good stamp, written back, matches (so each refusal above was the forgery's).
  write_bytes(stamp, good);
  EXPECT_TRUE(listed("a"));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace glimmer::test
