// Patch decomposition shared by the voxel grid and the octree: points are sorted
// by the Morton key of their finest cell, so every octree node is a contiguous
// run; a voxel grid is the octree that always splits down to the finest depth.
// Internal to the codec.
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "relief/status.h"

namespace relief::codec {

struct KeyedIndex {
  std::uint64_t key;
  std::uint32_t index;
};

// Spreads the low 21 bits of v so bit k moves to bit 3k.
inline std::uint64_t spread_bits3(std::uint32_t v) {
  std::uint64_t x = v & 0x1fffffu;
  x = (x | (x << 32)) & 0x1f00000000ffffULL;
  x = (x | (x << 16)) & 0x1f0000ff0000ffULL;
  x = (x | (x << 8)) & 0x100f00f00f00f00fULL;
  x = (x | (x << 4)) & 0x10c30c30c30c30c3ULL;
  x = (x | (x << 2)) & 0x1249249249249249ULL;
  return x;
}

// Interleaves x, y, z (21 bits each): bit 3k is x's bit k, 3k+1 y's, 3k+2 z's.
inline std::uint64_t morton_encode(std::uint32_t x, std::uint32_t y, std::uint32_t z) {
  return spread_bits3(x) | (spread_bits3(y) << 1) | (spread_bits3(z) << 2);
}

// Inverse of spread_bits3: gathers bits 0, 3, 6, ... into the low 21 bits.
inline std::uint32_t compact_bits3(std::uint64_t x) {
  x &= 0x1249249249249249ULL;
  x = (x | (x >> 2)) & 0x10c30c30c30c30c3ULL;
  x = (x | (x >> 4)) & 0x100f00f00f00f00fULL;
  x = (x | (x >> 8)) & 0x1f0000ff0000ffULL;
  x = (x | (x >> 16)) & 0x1f00000000ffffULL;
  x = (x | (x >> 32)) & 0x1fffffULL;
  return static_cast<std::uint32_t>(x);
}

// Stable LSD radix sort on the low `key_bits` bits of the keys.
void radix_sort(std::vector<KeyedIndex>& items, int key_bits);

struct Leaf {
  std::uint32_t begin = 0;  // range in the sorted order (encoder only)
  std::uint32_t end = 0;
  std::uint8_t depth = 0;
  std::uint32_t ix = 0, iy = 0, iz = 0;  // cell coordinates at `depth`
};

// Decides whether an octree node holding sorted[begin, end) is a leaf
// (encoder-side criterion: point count, normal cone).
using LeafPredicate = std::function<bool(std::uint32_t begin, std::uint32_t end)>;

// Builds the tree over keys sorted at depth `depth`. With a null predicate
// every node splits down to `depth` (voxel grid). Appends the DFS pre-order
// child masks (0 = leaf above the finest depth) to `masks`.
std::vector<Leaf> build_tree(std::span<const KeyedIndex> sorted, int depth,
                             const LeafPredicate& is_leaf, std::vector<std::uint8_t>& masks);

// Parses the masks written by build_tree. `allow_early_leaves` is false for a
// voxel grid. The stream must hold exactly `leaf_count` leaves and no extra byte.
Result<std::vector<Leaf>> parse_tree(std::span<const std::uint8_t> masks, int depth,
                                     bool allow_early_leaves, std::uint32_t leaf_count);

}  // namespace relief::codec
