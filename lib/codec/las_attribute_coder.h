// LAS per-point attributes of the error-bounded layer (chunk formats 3, 5 and
// 6, format-spec/chunk.md §11.7): one arithmetic-coded section per carried
// LasAttributes vector, lossless, in the canonical point order (format 6: GPS
// times in time order, §11.7.1, and with them the attributes that follow
// acquisition order, §11.7.2). Mirror pair in one file
// (las_attribute_coder.cpp). Internal to the codec.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "codec/attribute_coder.h"  // CellXyz
#include "relief/status.h"
#include "relief/types.h"

namespace relief::codec {

// LasAttributeBits in use (bits 0..11); the rest are reserved.
inline constexpr int kLasAttributeCount = 12;
inline constexpr std::uint32_t kKnownLasAttributes = (1u << kLasAttributeCount) - 1;
// The attribute's name in messages ("classification", "GPS time", ...).
const char* las_attribute_name(std::uint32_t bit);

// LAS point records are at most 65535 bytes, so are their extra bytes.
inline constexpr std::uint32_t kMaxExtraBytesSize = 65535;

// Format 6 GPS time: the largest bucket shift (buckets of 2^21 cells hold a
// whole chunk, whose local coordinates are < 2^21).
inline constexpr int kMaxBucketShift = 21;

// Format 6: the attributes that follow acquisition order (return number,
// number of returns, scan flags, scan angle, user data, point source ID) are
// coded in time order when the chunk carries GPS times (§11.7.2).
inline constexpr std::uint32_t kLasTimeOrdered = kLasReturnNumber | kLasNumberOfReturns | kLasScanFlags |
                                                 kLasScanAngle | kLasUserData | kLasPointSourceId;

// The points' time order: indices into `gps_time` by increasing bit pattern
// of the time as a u64, equal times in index order.
std::vector<std::uint32_t> las_time_order(const std::vector<double>& gps_time);

// Codes attribute `bit` (one LasAttributeBits value) of the n points of `las`,
// which are in canonical order. Attributes with a lower bit may serve as
// context, so sections are coded and decoded in increasing bit order (format
// 6 with GPS times: GPS time first). In chunk format 6 (`version` >= 6) GPS
// times are coded in time order, which needs the points' cells (`cells`, n of
// them); other formats and attributes ignore `cells`. `time_order` (format 6,
// the chunk carries GPS times: las_time_order of its times, n entries; else
// empty) makes the attributes of kLasTimeOrdered code in that order, with
// las.gps_time as context. `colors`: in chunk format 7 the colour low bytes
// start with a decision "every triplet equals the point's colour" (sources
// that store 8-bit levels, or levels v * 257), so the colours the point
// colour section decodes to (n of them; empty: not equal).
std::vector<std::uint8_t> encode_las_attribute(std::uint32_t bit, const LasAttributes& las, std::size_t n,
                                               int version = 5, std::span<const CellXyz> cells = {},
                                               std::span<const std::uint32_t> time_order = {},
                                               std::span<const Rgb8> colors = {});

// Decodes attribute `bit` of n points into `las` (resizing its vector; for
// extra bytes las.extra_bytes_size must be set). Attributes with a lower bit
// (and, given a time order, GPS time) must already be decoded. A stream too
// short to hold n points is refused before anything is allocated. `version`,
// `cells`, `time_order` and `colors` (the decoded point colours) as for the
// encoder.
Status decode_las_attribute(std::uint32_t bit, std::span<const std::uint8_t> data, std::size_t n, LasAttributes& las,
                            int version = 5, std::span<const CellXyz> cells = {},
                            std::span<const std::uint32_t> time_order = {}, std::span<const Rgb8> colors = {});

// The pulse kind of each position k of a time order (`order` lists indices
// into `gps`; §11.7.2): 0 the next pulse, 1 another return of the previous
// point's pulse (the same time), 2 a gap (more than twice the last step).
std::vector<std::uint8_t> las_pulse_kinds(const std::vector<double>& gps, std::span<const std::uint32_t> order);

// Format 8 blobs whose geometry is in time order (§11.3.3): the GPS time
// section holds the times alone, in that order (§11.7.1 without the ranks).
// `times` are the points' times in the geometry's order, non-decreasing by
// bit pattern. The decoder fills las.gps_time in the same order.
// `any_order` (format 14, a layer in the encoder's own order): the times may
// decrease from one point to the next; else they must not (time order).
std::vector<std::uint8_t> encode_gps_in_order(std::span<const double> times, bool any_order = false);
Status decode_gps_in_order(std::span<const std::uint8_t> data, std::size_t n, LasAttributes& las,
                           bool any_order = false);

// Attribute `bit` of `from` copied to `to` in another order: kGather makes
// point j of `to` point positions[j] of `from` (any points of `from`, so a
// subset too), kScatter makes point j of `from` point positions[j] of `to`
// (`positions` a permutation of 0..n-1). `to`'s vector of the attribute is
// resized to n = positions.size() points.
enum class Permute { kGather, kScatter };
void permute_las_attribute(std::uint32_t bit, const LasAttributes& from, LasAttributes& to,
                           std::span<const std::uint32_t> positions, Permute how);

// Orders two points of `las` by every carried attribute, in bit order
// (gps_time by bit pattern, extra bytes as unsigned byte strings): the
// tie-break that makes a cell's point order independent of the input order.
// Returns <0, 0 or >0.
int compare_las_points(const LasAttributes& las, std::size_t a, std::size_t b);

}  // namespace relief::codec
