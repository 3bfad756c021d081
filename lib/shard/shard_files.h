// Small file helpers of the sharded build: tab-separated text lines with
// escaped fields (plan files, manifests), atomic writes, and temporary names
// unique across hosts. Internal to lib/shard.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "relief/status.h"

namespace relief::shard {

// Backslash, tab, newline and carriage return as \\ \t \n \r: a field never
// holds a separator.
std::string escape_field(const std::string& text);

struct TextLine {
  std::string key;
  std::vector<std::string> fields;  // unescaped
};
// Splits text into lines of tab-separated fields (the first is the key).
// A bad escape is kFormatError naming `path` and the line.
Result<std::vector<TextLine>> split_lines(const std::string& path, const std::string& text);

// The whole file, refused (kLimitExceeded) when larger than `max_bytes`.
Result<std::string> read_text(const std::string& path, std::uint64_t max_bytes);
// Writes to core::temp_path_beside(path) (path + ".tmp-<host>-<pid>": two
// tasks writing the same file, even on two hosts sharing the directory, never
// write the same temporary file), flushes it to disk and renames it into place.
Status write_text_atomic(const std::string& path, const std::string& text);
// fsync(2) of a file, then a rename that replaces `to`.
Status sync_and_rename(int fd, const std::string& from, const std::string& to);

// FNV-1a, 64 bits: the identity of a plan's text.
std::uint64_t fnv1a64(const std::string& text);
std::string hex64(std::uint64_t v);

}  // namespace relief::shard
