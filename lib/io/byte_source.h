// Sequential input over a memory span or a file read in large blocks.
// Readers ask for "at least n contiguous bytes", decode straight out of the
// returned view and then consume what they used. Memory input costs no copy;
// file input costs one copy into a reusable block buffer and never holds the
// whole file. Internal to lib/io.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "relief/status.h"

namespace relief {

class ByteSource {
 public:
  // Reads `data`, which must outlive the source.
  static ByteSource from_memory(std::span<const std::uint8_t> data);
  // Opens `path` for reading; errors are kIoError naming the path and the reason.
  static Result<ByteSource> open_file(const std::string& path);

  ByteSource(ByteSource&& other) noexcept;
  ByteSource& operator=(ByteSource&& other) noexcept;
  ByteSource(const ByteSource&) = delete;
  ByteSource& operator=(const ByteSource&) = delete;
  ~ByteSource();

  // Sets `out` to every buffered, unconsumed byte after trying to make at
  // least `n` of them available; `out` is shorter than `n` only at the end of
  // the input. `out` stays valid until the next fill() or skip().
  Status fill(std::size_t n, std::span<const std::uint8_t>& out);
  // Marks the first `n` bytes of the last fill() view as used.
  void consume(std::size_t n);
  // Consumes up to `n` bytes, buffered or not; `skipped` is less than `n`
  // only when the input ended first.
  Status skip(std::uint64_t n, std::uint64_t& skipped);

  // What is left of the input, read to its end: its bytes, and its lines
  // holding anything but white space (a last line without a newline too).
  struct Rest {
    std::uint64_t bytes = 0;
    std::uint64_t lines = 0;
  };
  Result<Rest> read_rest();

  // Copies bytes [offset, offset + out.size()) of the input into `out`,
  // independently of the sequential position, for formats read out of order
  // (E57). `got` is less than out.size() only at the end of the input.
  // Memory and regular files only: a pipe is kUnsupported.
  Status read_at(std::uint64_t offset, std::span<std::uint8_t> out, std::size_t& got) const;

  // Bytes consumed since the start.
  std::uint64_t position() const { return base_ + begin_; }
  // Total input size when it is known in advance (memory, regular files).
  std::optional<std::uint64_t> size() const { return size_; }
  // Bytes left after position(), when the size is known.
  std::optional<std::uint64_t> remaining() const {
    if (!size_) return std::nullopt;
    return *size_ > position() ? *size_ - position() : 0;
  }

 private:
  ByteSource() = default;
  Status read_more(std::size_t want);
  void close_file();

  // Memory mode: data_ is the whole input and the "buffer" is data_ itself.
  // File mode: buf_ holds bytes [base_, base_ + end_) of the file.
  std::span<const std::uint8_t> data_;
  std::vector<std::uint8_t> buf_;
  std::size_t begin_ = 0;  // first unconsumed byte in the buffer
  std::size_t end_ = 0;    // one past the last buffered byte
  std::uint64_t base_ = 0;  // file offset of buffer byte 0
  std::optional<std::uint64_t> size_;
  int fd_ = -1;
  bool seekable_ = false;
  bool eof_ = false;
  std::string path_;
};

}  // namespace relief
