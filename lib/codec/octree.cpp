#include "codec/octree.h"

#include <algorithm>
#include <string>
#include <utility>
#include <vector>

namespace relief::codec {

namespace {

struct TreeBuilder {
  TreeBuilder(std::span<const KeyedIndex> s, int d, const LeafPredicate& p, std::vector<std::uint8_t>& m)
      : sorted(s), depth(d), is_leaf(p), masks(m) {}

  std::span<const KeyedIndex> sorted;
  int depth;
  const LeafPredicate& is_leaf;
  std::vector<std::uint8_t>& masks;
  std::vector<Leaf> leaves;

  void node(std::uint32_t begin, std::uint32_t end, int level, std::uint32_t x, std::uint32_t y,
            std::uint32_t z) {
    const auto leaf = [&] {
      leaves.push_back({begin, end, static_cast<std::uint8_t>(level), x, y, z});
    };
    if (level == depth) {
      leaf();
      return;
    }
    // A run of identical keys cannot be separated by splitting: stop early
    // (e.g. a scanner standing still), whatever the point count.
    if (is_leaf && (is_leaf(begin, end) || sorted[begin].key == sorted[end - 1].key)) {
      masks.push_back(0);
      leaf();
      return;
    }
    const std::size_t mask_pos = masks.size();
    masks.push_back(0);
    const int shift = 3 * (depth - level - 1);
    std::uint32_t i = begin;
    while (i < end) {
      const auto digit = static_cast<std::uint32_t>((sorted[i].key >> shift) & 7u);
      // Keys are sorted, so the run of this digit ends at the first larger one.
      std::uint32_t lo = i + 1, hi = end;
      while (lo < hi) {
        const std::uint32_t mid = lo + (hi - lo) / 2;
        if (((sorted[mid].key >> shift) & 7u) == digit) {
          lo = mid + 1;
        } else {
          hi = mid;
        }
      }
      const std::uint32_t j = lo;
      masks[mask_pos] = static_cast<std::uint8_t>(masks[mask_pos] | (1u << digit));
      node(i, j, level + 1, 2 * x + (digit & 1u), 2 * y + ((digit >> 1) & 1u),
           2 * z + ((digit >> 2) & 1u));
      i = j;
    }
  }
};

}  // namespace

void radix_sort(std::vector<KeyedIndex>& items, int key_bits) {
  const std::size_t n = items.size();
  if (n < 2 || key_bits <= 0) return;
  key_bits = std::min(key_bits, 64);
  // Digits of 11 bits for large inputs (a 51-bit key in 5 passes instead of
  // 7; 2,048 buckets still fit the L2 cache), bytes for small ones, whose
  // passes the buckets' prefix sums would dominate. Stable either way, so
  // the order is the same.
  const int digit_bits = n >= 65536 ? 11 : 8;
  const std::size_t buckets = std::size_t{1} << digit_bits;
  const std::uint64_t digit_mask = buckets - 1;
  const int passes = (key_bits + digit_bits - 1) / digit_bits;
  // Every pass's histogram in one read of the items, then a pass per digit
  // that varies (one holding a single value everywhere moves nothing).
  std::vector<std::size_t> count(static_cast<std::size_t>(passes) * buckets, 0);
  for (const KeyedIndex& it : items) {
    for (int p = 0; p < passes; ++p) ++count[static_cast<std::size_t>(p) * buckets + ((it.key >> (digit_bits * p)) & digit_mask)];
  }
  std::vector<KeyedIndex> tmp;
  for (int p = 0; p < passes; ++p) {
    std::size_t* c = count.data() + static_cast<std::size_t>(p) * buckets;
    if (std::find(c, c + buckets, n) != c + buckets) continue;
    std::size_t sum = 0;
    for (std::size_t b = 0; b < buckets; ++b) sum += std::exchange(c[b], sum);  // bucket starts
    if (tmp.empty()) tmp.resize(n);
    const int shift = digit_bits * p;
    for (const KeyedIndex& it : items) tmp[c[(it.key >> shift) & digit_mask]++] = it;
    items.swap(tmp);
  }
}

std::vector<Leaf> build_tree(std::span<const KeyedIndex> sorted, int depth,
                             const LeafPredicate& is_leaf, std::vector<std::uint8_t>& masks) {
  TreeBuilder builder(sorted, depth, is_leaf, masks);
  if (!sorted.empty()) builder.node(0, static_cast<std::uint32_t>(sorted.size()), 0, 0, 0, 0);
  return std::move(builder.leaves);
}

namespace {

struct TreeParser {
  TreeParser(std::span<const std::uint8_t> m, int d, bool early, std::uint32_t count)
      : masks(m), depth(d), allow_early_leaves(early), leaf_count(count) {}

  std::span<const std::uint8_t> masks;
  int depth;
  bool allow_early_leaves;
  std::uint32_t leaf_count;
  std::size_t pos = 0;
  std::vector<Leaf> leaves;

  Status node(int level, std::uint32_t x, std::uint32_t y, std::uint32_t z) {
    if (level == depth) return add_leaf(level, x, y, z);
    if (pos >= masks.size()) {
      return corrupt_data("tree section: ends early after " + std::to_string(pos) + " bytes");
    }
    const std::uint8_t mask = masks[pos++];
    if (mask == 0) {
      if (!allow_early_leaves) {
        return corrupt_data("tree section: empty node mask at byte " + std::to_string(pos - 1) +
                            " in a voxel-grid chunk");
      }
      return add_leaf(level, x, y, z);
    }
    for (std::uint32_t digit = 0; digit < 8; ++digit) {
      if ((mask & (1u << digit)) == 0) continue;
      RELIEF_RETURN_IF_ERROR(node(level + 1, 2 * x + (digit & 1u), 2 * y + ((digit >> 1) & 1u),
                                  2 * z + ((digit >> 2) & 1u)));
    }
    return Status::ok();
  }

  Status add_leaf(int level, std::uint32_t x, std::uint32_t y, std::uint32_t z) {
    if (leaves.size() >= leaf_count) {
      return corrupt_data("tree section: more leaves than the " + std::to_string(leaf_count) +
                          " patches the header declares");
    }
    leaves.push_back({0, 0, static_cast<std::uint8_t>(level), x, y, z});
    return Status::ok();
  }
};

}  // namespace

Result<std::vector<Leaf>> parse_tree(std::span<const std::uint8_t> masks, int depth,
                                     bool allow_early_leaves, std::uint32_t leaf_count) {
  TreeParser parser(masks, depth, allow_early_leaves, leaf_count);
  parser.leaves.reserve(leaf_count);
  if (leaf_count > 0) RELIEF_RETURN_IF_ERROR(parser.node(0, 0, 0, 0));
  if (parser.leaves.size() != leaf_count) {
    return corrupt_data("tree section: " + std::to_string(parser.leaves.size()) +
                        " leaves, header declares " + std::to_string(leaf_count));
  }
  if (parser.pos != masks.size()) {
    return corrupt_data("tree section: " + std::to_string(masks.size() - parser.pos) +
                        " unused bytes after the last node");
  }
  return std::move(parser.leaves);
}

}  // namespace relief::codec
