#include "codec/atlas.h"

#include <algorithm>
#include <array>
#include <bit>
#include <mutex>

namespace relief::codec {

namespace {

// Keeps the even bits of v, packed.
std::uint32_t compact_even_bits(std::uint32_t v) {
  v &= 0x55555555u;
  v = (v | (v >> 1)) & 0x33333333u;
  v = (v | (v >> 2)) & 0x0f0f0f0fu;
  v = (v | (v >> 4)) & 0x00ff00ffu;
  v = (v | (v >> 8)) & 0x0000ffffu;
  return v;
}

std::uint32_t spread_bits(std::uint32_t v) {
  v &= 0x0000ffffu;
  v = (v | (v << 8)) & 0x00ff00ffu;
  v = (v | (v << 4)) & 0x0f0f0f0fu;
  v = (v | (v << 2)) & 0x33333333u;
  v = (v | (v << 1)) & 0x55555555u;
  return v;
}

}  // namespace

void tile_position(std::uint32_t index, std::uint32_t& tx, std::uint32_t& ty) {
  tx = compact_even_bits(index);
  ty = compact_even_bits(index >> 1);
}

AtlasLayout atlas_layout(std::uint32_t patch_count) {
  AtlasLayout layout;
  if (patch_count == 0) return layout;
  std::uint32_t side = 1;
  while (static_cast<std::uint64_t>(side) * side < patch_count) side <<= 1;
  layout.tiles_x = side;
  // tiles_y is 1 + the largest row among indices 0..last. Computed in closed
  // form, not by visiting every index: a hostile header may claim 2^32 - 1
  // patches and this runs before any section is read. The row is the odd bits
  // of the index; the best index <= last clears last's highest set even (x)
  // bit b and sets every bit below b, which keeps the odd bits above b and
  // sets all odd bits below it. Without a set even bit, last itself is best.
  const std::uint32_t last = patch_count - 1;
  std::uint32_t best = last;
  const std::uint32_t x_bits = last & 0x55555555u;
  if (x_bits != 0) {
    const std::uint32_t b = 31u - static_cast<std::uint32_t>(std::countl_zero(x_bits));
    const std::uint32_t below = (std::uint32_t{1} << b) - 1;
    best = (last & ~below & ~(std::uint32_t{1} << b)) | below;
  }
  std::uint32_t tx = 0, ty = 0;
  tile_position(best, tx, ty);
  layout.tiles_y = ty + 1;
  return layout;
}

const std::vector<std::uint16_t>& lod_pixel_order(int map_resolution) {
  // One table per resolution (multiples of 8 up to 64), built once.
  static std::array<std::vector<std::uint16_t>, 9> tables;
  static std::once_flag once[9];
  const int slot = map_resolution / 8;
  std::call_once(once[slot], [map_resolution, slot] {
    const auto r = static_cast<std::uint32_t>(map_resolution);
    int bits = 0;
    while ((1u << bits) < r) ++bits;
    struct Entry {
      std::uint32_t key;
      std::uint16_t pixel;
    };
    std::vector<Entry> entries;
    entries.reserve(r * r);
    for (std::uint32_t y = 0; y < r; ++y) {
      for (std::uint32_t x = 0; x < r; ++x) {
        const std::uint32_t morton = spread_bits(x) | (spread_bits(y) << 1);
        std::uint32_t reversed = 0;
        for (int b = 0; b < 2 * bits; ++b) reversed |= ((morton >> b) & 1u) << (2 * bits - 1 - b);
        entries.push_back({reversed, static_cast<std::uint16_t>(y * r + x)});
      }
    }
    std::sort(entries.begin(), entries.end(),
              [](const Entry& a, const Entry& b) { return a.key < b.key; });
    auto& table = tables[slot];
    table.reserve(entries.size());
    for (const Entry& e : entries) table.push_back(e.pixel);
  });
  return tables[slot];
}

}  // namespace relief::codec
