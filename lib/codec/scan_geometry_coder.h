// The error-bounded layer's geometry in acquisition order (section codec 9,
// chunk format 8, format-spec/chunk.md §11.3.3): each point's cell, in the
// order of its GPS time, as differences from the previous point predicted
// the way a scanner moves (the median of recent steps along the scan line,
// the height of the last return of the same level), with context from the
// return numbers and from whether the point is another return of the
// previous pulse. Internal to the codec.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "codec/las_attribute_coder.h"  // CellXyz
#include "relief/status.h"

namespace relief::codec {

// What the decoder knows of each position k of the time order before the
// geometry (decoded from sections 18, 12 and 13): the pulse kind (0 next
// pulse, 1 same pulse, 2 gap; las_pulse_kinds), the pulse multiple
// (scan_pulse_multiples) and, when the blob carries them, the return number
// and number of returns (empty spans: not carried).
struct ScanContext {
  std::span<const std::uint8_t> pulse_kind;
  std::span<const std::uint8_t> pulse_multiple;
  std::span<const std::uint8_t> return_number;
  std::span<const std::uint8_t> number_of_returns;
};

// The order mask, the geometry section's first byte (§11.3.3): bit s set =
// the section of slot s holds its points in cell order (the points sorted by
// the Morton code of their cells, stable), else in the layer's time order.
// Slots: 0 point colours (section 8), 1 point intensities (9), then the LAS
// attributes that do not follow acquisition order: 2 classification (10),
// 3 classification flags (11), 4 NIR (19), 5 colour low bytes (20), 6 extra
// bytes (21). Bit 7 is reserved, 0.
inline constexpr int kOrderSlotColors = 0;
inline constexpr int kOrderSlotIntensity = 1;
inline constexpr std::uint8_t kKnownOrderMask = 0x7F;
// The slot of LAS attribute `bit`, or -1 for one coded in time order (12-18).
int order_slot(std::uint32_t bit);

// How many pulse spacings each time step is (§11.3.3), from the times in
// time order: round(step / the last non-zero step) as bit patterns, 1 to 64
// (1 for the first point, a zero step, no step yet, or a step of more than
// 64 spacings: a new line rather than missed pulses).
std::vector<std::uint8_t> scan_pulse_multiples(std::span<const double> times);

// The median of five steps (§11.3.3's predictor), without branches: the
// median of the two pairs' inner values and the fifth, the value sorting the
// five would give.
inline std::int64_t median_of_five(const std::array<std::int64_t, 5>& v) {
  const std::int64_t lo = std::max(std::min(v[0], v[1]), std::min(v[2], v[3]));
  const std::int64_t hi = std::min(std::max(v[0], v[1]), std::max(v[2], v[3]));
  return std::max(std::min(lo, hi), std::min(std::max(lo, hi), v[4]));
}

// `cells` (local cell coordinates, each below 2^depth) in time order; the
// context spans have cells.size() entries or are empty (pulse_kind too: then
// every kind is 0).
std::vector<std::uint8_t> encode_scan_geometry(std::span<const CellXyz> cells, int depth, const ScanContext& context);

// Decodes n cells. Refuses, before allocating, a stream too short to hold n
// points; every decoded coordinate must lie below 2^depth.
Result<std::vector<CellXyz>> decode_scan_geometry(std::span<const std::uint8_t> data, int depth, std::size_t n,
                                                  const ScanContext& context);

}  // namespace relief::codec
