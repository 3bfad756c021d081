// The error-bounded layer's geometry: the set of occupied cells of a chunk's
// quantisation grid (side 2^depth per axis) and the number of points in each,
// coded as an octree, level by level, with context-adaptive binary arithmetic
// coding (format-spec/chunk.md, section "Geometry section"). Internal to the codec.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "relief/status.h"

namespace relief::codec {

// Distinct occupied cells in increasing Morton order (morton_encode of the
// cell's integer coordinates) and the number of points in each (>= 1).
inline constexpr int kMaxGeometryDepth = 21;  // Morton keys stay below 2^63

struct OccupiedCells {
  std::vector<std::uint64_t> keys;
  std::vector<std::uint32_t> counts;
};

// How the octree's child bytes are coded (the geometry section's codec id).
enum class OctreeCoding {
  // Codec 6 (format 2): 8 context-coded bits per node.
  kBitwise,
  // Codec 7 (format 5): a per-node flag "exactly one child"; a single child
  // is coded as its 3-bit index, other nodes as 8 bits (at least two set).
  // Smaller (sparse levels dominate fine grids) and fewer decisions.
  kSingleChild,
  // Codec 8 (format 7): as codec 7, the bits of multi-child nodes coded by
  // mixing three context models' predictions.
  kMixed,
  // Codec 11 (format 10): codec 8 plus chains: an isolated node (its
  // parent's only child, no face neighbour) says with one flag whether its
  // subtree holds one cell; if so, it and its descendants code their one
  // child's index with 3 plain decisions instead of a flag and 3 mixed ones.
  kChains,
  // Codec 12 (format 13): codec 11 with a third model for every mixed
  // decision, selected by the patterns of the minus face neighbours'
  // children on the faces they share with the node, and each mixed
  // probability refined by an adaptive probability map.
  kFacePatterns,
  // Codec 13 (format 16): codec 12 with the index bits of single children
  // and chains also told where a plane fitted to the nearby cells the
  // decoder knows crosses the node (format-spec/chunk.md §11.3.6).
  kPlanes,
  // Codec 14 (format 17): codec 13 with those index bits also told which
  // half of the node lies nearer the known points around it
  // (format-spec/chunk.md §11.3.7).
  kNearest,
};

// `cells.keys` must be strictly increasing and below 8^depth, with a count
// >= 1 each (at least one cell); depth <= 21. Input that breaks this gives an
// empty stream (no valid input does), never a stream of another octree.
std::vector<std::uint8_t> encode_geometry(const OccupiedCells& cells, int depth,
                                          OctreeCoding coding = OctreeCoding::kMixed);

// As encode_geometry, but gives up (nullopt) as soon as the stream is sure to
// exceed `max_bytes`: the encoder's way of trying the octree against a
// smaller alternative without paying for all of it. Refused input: an empty
// stream, as encode_geometry.
std::optional<std::vector<std::uint8_t>> encode_geometry_within(const OccupiedCells& cells, int depth,
                                                                OctreeCoding coding, std::size_t max_bytes);

// Decodes a stream made by encode_geometry with the same coding. The stream
// must describe exactly `point_count` points; the work done is bounded by the
// stream's size and by `point_count` (every octree node holds at least one point).
// `decisions`, when given, receives the number of binary decisions decoded.
Result<OccupiedCells> decode_geometry(std::span<const std::uint8_t> data, int depth, std::uint64_t point_count,
                                      OctreeCoding coding, std::uint64_t* decisions = nullptr);

}  // namespace relief::codec
