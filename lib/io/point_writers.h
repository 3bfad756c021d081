// Streaming point writers: the constructors used by the dispatch in
// point_file.cpp and the batch bookkeeping they share (argument checks,
// sticky errors, commit). Internal to lib/io.
#pragma once

#include <algorithm>
#include <bit>
#include <charconv>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "io/output_file.h"
#include "relief/io.h"

namespace relief {

// Each creates its output (the temporary file, or stdout for XYZ "-") and
// writes what of the header it can, so a bad destination fails here.
Result<std::unique_ptr<PointWriter>> open_ply_writer(const std::string& path, const WriterOptions& options);
// `laz`: compress the points as LASzip does (a .laz file).
Result<std::unique_ptr<PointWriter>> open_las_writer(const std::string& path, const WriterOptions& options,
                                                     bool laz = false);
// `separator` goes between the columns: ' ' for .xyz/.txt/stdout, ',' for .csv.
Result<std::unique_ptr<PointWriter>> open_xyz_writer(const std::string& path, const WriterOptions& options,
                                                     char separator);

// Base of the writers: checks every batch against the options, counts points
// and makes the first error sticky. After an error the output is discarded at
// once (the temporary file is removed: it may be large) and every later call
// returns that error, so a caller that ignores one failure still cannot
// commit a file with a hole in it.
class StreamPointWriter : public PointWriter {
 public:
  Status write(const PointCloud& batch) final;
  Status finish() final;
  std::uint64_t points_written() const final { return count_; }
  std::vector<std::string> take_warnings() final { return std::exchange(warnings_, {}); }

 protected:
  StreamPointWriter(std::unique_ptr<OutputFile> out, const WriterOptions& options)
      : out_(std::move(out)), options_(options) {}

  // Encodes a batch that passed the checks; points_written() does not yet
  // include it, so the first point of the batch is point points_written().
  virtual Status write_points(const PointCloud& batch) = 0;
  // Completes the file before it is committed (counts, bounds, trailers).
  virtual Status complete() = 0;
  // True when write_points() itself rejects non-finite coordinates (the LAS
  // range check does), so the base skips its own pass over them.
  virtual bool checks_coordinates() const { return false; }

  // "<path>: point <index> <what>" as kInvalidArgument.
  Status point_error(std::uint64_t index, const std::string& what) const;

  std::unique_ptr<OutputFile> out_;
  WriterOptions options_;
  // For take_warnings(), filled by complete().
  std::vector<std::string> warnings_;

 private:
  Status check_batch(const PointCloud& batch) const;
  Status fail(Status status);

  std::uint64_t count_ = 0;
  Status error_;
  bool finished_ = false;
};

// ---- text output shared by ascii PLY and XYZ

// Longest line: three shortest doubles (<= 24 characters each), three colour
// levels, a shortest float (<= 15) and the separators.
inline constexpr std::size_t kMaxTextRecord = 128;

// Shortest text that parses back to exactly `v` (double or float): in fixed
// notation for magnitudes from 10^-4 to below 10^15 (coordinates, times:
// "4000000.5", not "4.0000005e+06"), else as to_chars' shortest picks. At
// most 24 characters either way.
template <typename T>
std::uint8_t* put_shortest(std::uint8_t* p, T v) {
  char* c = reinterpret_cast<char*>(p);
  const T m = v < 0 ? -v : v;
  const bool fixed = m >= static_cast<T>(1e-4) && m < static_cast<T>(1e15);
  // kMaxTextRecord leaves room for the longest value, so this cannot fail.
  return reinterpret_cast<std::uint8_t*>(
      (fixed ? std::to_chars(c, c + 32, v, std::chars_format::fixed) : std::to_chars(c, c + 32, v)).ptr);
}

// How text output prints each axis's coordinates: with `decimals[a]` digits
// after the point (0..9), or, when -1, as the shortest text that reads back
// to the same double. An error-bounded archive's grid whose step is 10^-k
// and whose origin is a multiple of it (a LAS source's scale and offset:
// 0.01 and 849000) gets k decimals, as las2txt prints LAS coordinates:
// 849017.32, not 849017.3200000001 (the double X * 0.01 + 849000 that every
// LAS reader computes). The text then reads back to the double nearest that
// decimal, which snaps to the same grid integer (README, "Output formats").
struct CoordinateText {
  int decimals[3] = {-1, -1, -1};
};

// k when `step` is 10^-k (k = 0..9, to 1e-9 relative) and `origin` a whole
// multiple of it (to 1e-6 of a step, below 2^52 steps); else -1.
int grid_decimals(double step, double origin);
// The options' grid (WriterOptions::grid_scale / grid_offset) per axis; all
// -1 without one.
CoordinateText coordinate_text(const WriterOptions& options);
// `v` with `decimals` digits after the point (-1: put_shortest), rounded to
// the nearest; a value too large for the digits (|v| * 10^decimals >= 2^53)
// or not finite prints as put_shortest. At most 24 characters.
std::uint8_t* put_coordinate(std::uint8_t* p, double v, int decimals);

// Point i of `batch` as "x y z [r g b] [i]" (colours and intensity when the
// options say) at `p`, columns separated by `sep`, no newline; returns the
// end. At most kMaxTextRecord - 1 bytes. With `colors16` the colours are the
// 16-bit levels (colors << 8 | las.color_low), else the 8-bit ones.
std::uint8_t* put_text_point(std::uint8_t* p, const PointCloud& batch, std::size_t i, const WriterOptions& options,
                             const CoordinateText& coords, std::uint8_t sep, bool colors16 = false);

// Lines "x y z [r g b] [i]" (colours and intensity when the options say),
// columns separated by `separator`.
Status write_text_points(OutputFile& out, const PointCloud& batch, const WriterOptions& options,
                         char separator);

// Room for one column: a shortest double (24 characters) or a 64-bit integer
// (20), and a separator.
inline constexpr std::size_t kMaxColumnText = 32;

template <typename T>
std::uint8_t* put_integer(std::uint8_t* p, T v) {
  char* c = reinterpret_cast<char*>(p);
  return reinterpret_cast<std::uint8_t*>(std::to_chars(c, c + kMaxColumnText, v).ptr);
}

// The little-endian value of type T at `p` (extra bytes are little endian).
template <typename T>
T load_le_value(const std::uint8_t* p) {
  std::uint8_t b[sizeof(T)];
  for (std::size_t k = 0; k < sizeof(T); ++k) b[k] = p[k];
  if constexpr (std::endian::native == std::endian::big) std::reverse(b, b + sizeof(T));
  T v;
  std::memcpy(&v, b, sizeof(T));
  return v;
}

// Lines as write_text_points() writes them, each point's core columns
// followed by what `put_tail(p, i)` writes for point i at p (its columns,
// each after a separator, at most `tail_room` bytes; it returns the end).
template <typename PutTail>
Status write_text_lines(OutputFile& out, const PointCloud& batch, const WriterOptions& options, char separator,
                        std::size_t tail_room, PutTail&& put_tail, bool colors16 = false) {
  const auto sep = static_cast<std::uint8_t>(separator);
  const std::size_t max_line = kMaxTextRecord + tail_room;
  const std::size_t n = batch.size();
  const CoordinateText coords = coordinate_text(options);
  std::size_t i = 0;
  while (i < n) {
    std::span<std::uint8_t> room;
    RELIEF_RETURN_IF_ERROR(out.room(max_line, room));
    std::uint8_t* const begin = room.data();
    std::uint8_t* p = begin;
    // Lines until the block may not hold another one.
    std::uint8_t* const last = begin + room.size() - max_line;
    for (; i < n && p <= last; ++i) {
      p = put_tail(put_text_point(p, batch, i, options, coords, sep, colors16), i);
      *p++ = '\n';
    }
    out.advance(static_cast<std::size_t>(p - begin));
  }
  return Status::ok();
}

}  // namespace relief
