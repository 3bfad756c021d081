// Pieces shared by the streaming point readers: reopening an input, little-
// endian loads, batch sizing and the 16-bit colour rule. Internal to lib/io.
#pragma once

#include <algorithm>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "io/byte_source.h"
#include "relief/io.h"

namespace relief {

// Where a reader's bytes come from. Kept by the readers because some need the
// input a second time (the colour sample, LAS extended VLRs after the points).
struct InputSpec {
  std::string name;  // the path, or for memory input the name used in messages
  std::optional<std::span<const std::uint8_t>> memory;

  Result<ByteSource> open() const {
    if (memory) return ByteSource::from_memory(*memory);
    return ByteSource::open_file(name);
  }
};

// Reads a little-endian scalar from possibly unaligned bytes.
template <typename T>
T load_le(const std::uint8_t* p) {
  T v;
  if constexpr (std::endian::native == std::endian::little) {
    std::memcpy(&v, p, sizeof(T));
  } else {
    std::uint8_t b[sizeof(T)];
    for (std::size_t i = 0; i < sizeof(T); ++i) b[i] = p[sizeof(T) - 1 - i];
    std::memcpy(&v, b, sizeof(T));
  }
  return v;
}

// Sizes the arrays of `out` to `n` points: positions always, colours and
// intensities when wanted, else empty. A batch reused at the same size costs
// nothing, which matters when a reader is called a few hundred times per file.
inline void size_batch(PointCloud& out, std::size_t n, bool colors, bool intensity) {
  out.positions.resize(n);
  out.colors.resize(colors ? n : 0);
  out.intensities.resize(intensity ? n : 0);
}

// ---- 16-bit colours
//
// LAS stores 16-bit colour levels, and so do some PLY files, but plenty of
// writers put 8-bit levels (0..255) into those 16-bit fields. The rule, shared
// with the whole-file PLY reader: shift every level right by 8 when the file
// has a level above 255, else keep the levels as they are. A stream cannot see
// the whole file first, so streaming readers decide once per file from a
// sample: the first kColorSamplePoints points (or the whole file when smaller).
// The sample does not depend on the caller's batch size: when the first batch
// is smaller than the sample, the reader reads the sample through a second
// reader over the same input (only a pipe, which cannot be read twice, falls
// back to the first batch). When the sample decided "keep", a later level
// above 255 is split by split_8bit_level (relief/types.h) where the low bytes
// are kept (LAS, wide PLY colours: exact), and saturates at 255 where they are
// not; either way the reader warns once (note_level_above_255).
inline constexpr std::uint64_t kColorSamplePoints = std::uint64_t{1} << 20;

inline int color_shift_for(std::uint16_t max_level) { return max_level > 255 ? 8 : 0; }

inline std::uint8_t narrow_level(std::uint16_t v, int shift) {
  return static_cast<std::uint8_t>(std::min(v >> shift, 255));
}

// A level's colour and the low byte kept beside it (LasAttributes::color_low)
// so that las_color_level (relief/types.h) gives the level back exactly: with
// shift 8 its two bytes, with shift 0 (8-bit levels stored in the 16-bit
// fields) split_8bit_level: the level itself twice when it is at most 255.
inline void split_level(std::uint16_t v, int shift, std::uint8_t& colour, std::uint8_t& low) {
  if (shift != 0) {
    colour = static_cast<std::uint8_t>(v >> 8);
    low = static_cast<std::uint8_t>(v & 0xFF);
  } else {
    split_8bit_level(v, colour, low);
  }
}
inline Rgb8 split_levels(std::uint16_t r, std::uint16_t g, std::uint16_t b, int shift, Rgb8& low) {
  Rgb8 c;
  split_level(r, shift, c.r, low.r);
  split_level(g, shift, c.g, low.g);
  split_level(b, shift, c.b, low.b);
  return c;
}

inline std::uint16_t max_level(const std::uint16_t* levels, std::size_t count) {
  std::uint16_t m = 0;
  for (std::size_t i = 0; i < count; ++i) m = std::max(m, levels[i]);
  return m;
}

// `wide` holds r, g, b per point.
inline void narrow_colors(const std::uint16_t* wide, std::size_t n, int shift, Rgb8* out) {
  for (std::size_t i = 0; i < n; ++i) {
    out[i] = Rgb8{narrow_level(wide[3 * i], shift), narrow_level(wide[3 * i + 1], shift),
                  narrow_level(wide[3 * i + 2], shift)};
  }
}

// The same, each level split with its low byte in `low` (split_level).
inline void narrow_colors(const std::uint16_t* wide, std::size_t n, int shift, Rgb8* out, Rgb8* low) {
  for (std::size_t i = 0; i < n; ++i) out[i] = split_levels(wide[3 * i], wide[3 * i + 1], wide[3 * i + 2], shift, low[i]);
}

// The first of `n` points (r, g, b each) with a level above 255, or n.
inline std::size_t first_level_above_255(const std::uint16_t* wide, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) {
    if ((wide[3 * i] | wide[3 * i + 1] | wide[3 * i + 2]) > 255) return i;
  }
  return n;
}

// Base of the readers that may see 16-bit colours (PLY, LAS): implements
// read() on top of read_into() and applies the colour rule above.
class BatchPointReader : public PointReader {
 public:
  const PointStreamInfo& info() const final { return info_; }
  Result<std::size_t> read(PointCloud& batch, std::size_t max_points) final;

  // ReaderOptions::color_sample_memory: with reads smaller than the colour
  // rule's sample, the sample is decoded once and held (at most `bytes`).
  void hold_sample_up_to(std::uint64_t bytes) { hold_bytes_ = bytes; }

  // Decodes up to `max_points` points into `out` from index `at` and returns
  // how many (0 at the end). On return every array info() announces holds
  // at + n entries and the others are empty. When `wide` is given and the file
  // has 16-bit colours, the levels go to (*wide)[3 * at ...] as r, g, b and
  // out.colors is left empty; otherwise colours are narrowed with
  // color_shift_.
  virtual Result<std::size_t> read_into(PointCloud& out, std::vector<std::uint16_t>* wide, std::size_t at,
                                        std::size_t max_points) = 0;

 protected:
  // A new reader at the first point of the same input, or null when the
  // input cannot be read twice (a pipe).
  virtual Result<std::unique_ptr<BatchPointReader>> reopen() const = 0;

  // Decides the 16-bit rule now, from at most `within` points read through
  // reopen(), for a reader that must say at open whether it keeps the
  // levels' low bytes (text declares no type): decided when a level above
  // 255 shows up among them (16-bit) or they are the rule's whole sample
  // (8-bit). False, deciding nothing, when neither holds or the input cannot
  // be read twice: read() then decides from its first batch.
  Result<bool> decide_color_shift_now(std::uint64_t within);

  // Once per input: a warning that point `point` (from 0; `label` "point" or
  // "line", numbered as the reader numbers them) has colour level `level`
  // above 255 although the rule's sample held none, saying what became of it
  // (kept exactly with the low bytes, else 255). Levels of points [0, n) of
  // `wide` (r, g, b each; point `first` is the first) are checked at once by
  // the second form. Both do nothing unless the rule decided 8-bit levels.
  void note_level_above_255(std::uint64_t point, std::uint16_t level, const char* label = "point");
  void note_levels_above_255(const std::uint16_t* wide, std::size_t n, std::uint64_t first);
  // A warning when the rule decided 16-bit levels for a reader that keeps no
  // low bytes (text whose first levels above 255 came after the look at open).
  void note_lost_low_bytes();

  PointStreamInfo info_;
  bool wide_colors_ = false;  // colours need the 16-bit rule
  bool color_low_ = false;    // also fill las.color_low (LAS colours, low_level)
  int color_shift_ = 0;       // valid once decided

 private:
  // The largest colour level of up to `sample` points from the current one
  // (stopping early at a level above 255 when `stop_when_wide`), how many
  // were read, and whether that was the whole input.
  struct LevelSample {
    std::uint16_t max = 0;
    std::uint64_t points = 0;
    bool whole = false;
  };
  Result<LevelSample> sample_levels(std::uint64_t sample, bool stop_when_wide);

  // Decodes the rule's `sample` points into held_ (whole points, colours
  // narrowed once the rule is decided from them): false, reading nothing,
  // when they would need more than hold_bytes_.
  Result<bool> hold_sample(std::uint64_t sample);
  // The rule for a sample whose largest level is `largest` (with
  // info().las_colors_8bit), and the colours (and low bytes) of `out`'s
  // first n points from their 16-bit levels by it.
  void settle_rule(std::uint16_t largest);
  void narrow_into(PointCloud& out, const std::uint16_t* wide, std::size_t n) const;

  bool shift_known_ = false;
  bool level_above_255_noted_ = false;
  std::uint64_t hold_bytes_ = 0;
  PointCloud held_;            // the sample's points not yet handed out ...
  std::size_t held_next_ = 0;  // ... from this one
};

}  // namespace relief
