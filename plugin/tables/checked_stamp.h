// The "checked" stamp beside a table's cache entry (the frosted SG table since session 32, the glint P table since
// session 39).
//
// A table's load-time validation (the frosted table re-fits 16 nodes; the glint table sums every LOD level's
// W-weighted energy) is a fixed cost of every render that uses the table, paid again at every start. Once it passes,
// <entry>.checked, an authenticated cache blob (cache_blob.h: HMAC-SHA256 with the cache folder's secret), records
// which plugin builds checked which bytes: the FNV-1a hash of bytes that bind the entry (the frosted table's payload;
// the glint table's verified HMAC, which binds its 14.5 MB) and the GNU build ids of the last four builds that
// checked them, newest first (the test binaries and the plugin DSO load the same entries in `make test`), after a
// header naming the table kind (magic, format, key). A later load by a listed build of the same bytes may skip the
// validation. Another build (the validation code may have changed without the key), other bytes, or a stamp that is
// missing, corrupt or crafted without the folder's secret mean: validate again. Without a build id (not Linux, or
// none linked in; the plugin links with --build-id) nothing is ever stamped.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace glimmer::plugin {

// The table kind a stamp is for (its header): one magic per table family, the stamp's format, the entry's key.
struct CheckedStampKind {
  char magic[8];
  uint32_t format;  // the stamp's layout: 2 since session 39 (a list of builds; 1 held one build)
  uint64_t key;
};

// This plugin build's GNU build id as hex (made once); "" where there is none.
const std::string &plugin_build_id();

// <entry_path>.checked
std::string checked_stamp_path(const std::string &entry_path);

// Whether the stamp beside `entry_path` lists `build_id` as a build that checked `entry_bytes` (false for an empty
// build id).
bool checked_stamp_matches(const std::string &entry_path, const CheckedStampKind &kind,
                           const std::vector<unsigned char> &entry_bytes, const std::string &build_id);

// Adds `build_id` to that stamp (first; the oldest of five is dropped; a stamp of other bytes is replaced). Best
// effort: a stamp that cannot be written only means the next load validates again. Returns "" when written (or when
// there is no build id, so nothing to write), else why not (e.g. a read-only cache folder), for the caller's log.
std::string write_checked_stamp(const std::string &entry_path, const CheckedStampKind &kind,
                                const std::vector<unsigned char> &entry_bytes, const std::string &build_id);

}  // namespace glimmer::plugin
