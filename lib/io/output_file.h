// Buffered output for the streaming point writers. A file destination is
// written under a temporary name beside it (`<path>.tmp-<host>-<pid>`, same directory
// so the final rename() cannot be a cross-device move) and renamed into place
// by commit(); until then readers never see a half-written file, and
// discarding (explicitly or by destruction) removes the temporary file and
// leaves whatever was at the destination untouched. The destination "-" is
// standard output: written through the same buffer, never renamed, and it
// cannot be patched (only formats without a trailer-dependent header go
// there). Internal to lib/io.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "relief/status.h"

namespace relief {

class OutputFile {
 public:
  // Size of the write() calls: large enough that system call overhead is
  // negligible next to encoding, small enough to stay in cache.
  static constexpr std::size_t kBlockSize = std::size_t{1} << 20;

  // Creates the temporary file for `path` (or adopts stdout for "-"). Errors
  // are kIoError starting with "<path>: ".
  static Result<std::unique_ptr<OutputFile>> create(const std::string& path);

  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;
  ~OutputFile();

  // The destination for messages: the path, or "stdout" for "-".
  const std::string& path() const { return path_; }
  bool is_stdout() const { return stdout_; }
  // Bytes appended so far (buffered or written).
  std::uint64_t position() const { return flushed_ + used_; }

  // Free space in the block buffer, at least `n` bytes: the buffer is
  // written out first when it has less, and grows when n exceeds a block (a
  // text line of thousands of columns). Encoders fill a prefix of the span
  // and report it with advance().
  Status room(std::size_t n, std::span<std::uint8_t>& out);
  void advance(std::size_t n) { used_ += n; }

  Status append(const void* data, std::size_t n);
  Status flush();
  // Overwrites bytes already appended (headers patched at the end). Not for
  // stdout.
  Status patch(std::uint64_t offset, const void* data, std::size_t n);
  // Reads back bytes already appended (records rewritten at the end). Not for
  // stdout.
  Status read_at(std::uint64_t offset, void* data, std::size_t n);

  // Flushes, closes and renames the temporary file onto the destination (for
  // stdout only flushes). On failure the temporary file is removed.
  Status commit();
  // Closes and removes the temporary file now; later calls fail.
  void discard();

 private:
  OutputFile(std::string path, std::string tmp_path, int fd, bool is_stdout);
  Status write_all(const std::uint8_t* data, std::size_t n);

  std::string path_;
  std::string tmp_path_;  // empty for stdout
  int fd_ = -1;
  bool stdout_ = false;
  bool done_ = false;  // committed or discarded
  std::vector<std::uint8_t> buf_;
  std::size_t used_ = 0;
  std::uint64_t flushed_ = 0;
};

}  // namespace relief
