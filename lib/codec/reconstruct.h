// Point reconstruction from the decoded maps (format-spec/chunk.md section 7),
// shared by the decoder (which emits the points) and the encoder (which
// computes the exact bounds of what a decoder will produce). Internal.
#pragma once

#include <cmath>
#include <cstdint>
#include <vector>

#include "codec/atlas.h"
#include "codec/chunk_format.h"
#include "codec/octree.h"
#include "codec/patch.h"

namespace relief::codec {

struct MapsView {
  const ChunkHeader* header = nullptr;
  const std::vector<Leaf>* leaves = nullptr;
  const std::uint8_t* records = nullptr;    // patches section, structure of arrays
  const std::uint8_t* occupancy = nullptr;  // atlas, one byte per pixel
  const std::uint8_t* height8 = nullptr;    // atlas heights (8-bit), or
  const std::uint16_t* height16 = nullptr;  // atlas heights (16-bit)
  std::uint32_t atlas_width = 0;
};

// Calls emit(atlas_index, position) for every point of patch p, at most
// `quota` of them: all occupied pixels row by row when quota equals the
// patch's occupied count, else the first `quota` in the level-of-detail order.
template <typename Emit>
void reconstruct_patch(const MapsView& m, std::uint32_t p, std::uint32_t quota, std::uint32_t occupied, Emit&& emit) {
  const ChunkHeader& h = *m.header;
  const int r = h.map_resolution;
  const std::size_t np = h.patch_count;
  const std::size_t aw = m.atlas_width;
  const Leaf& leaf = (*m.leaves)[p];
  const double edge = std::ldexp(h.grid_edge, -leaf.depth);
  const Vec3d center{h.grid_origin.x + (leaf.ix + 0.5) * edge, h.grid_origin.y + (leaf.iy + 0.5) * edge,
                     h.grid_origin.z + (leaf.iz + 0.5) * edge};
  const std::uint8_t* rec = m.records;
  const QuantizedPatch q{rec[p],          rec[np + p],     rec[2 * np + p], rec[3 * np + p],
                         rec[4 * np + p], rec[5 * np + p], rec[6 * np + p]};
  const PatchFrame f = make_frame(q, center, edge, r);
  std::uint32_t tx = 0, ty = 0;
  tile_position(p, tx, ty);
  const std::size_t tile0 = static_cast<std::size_t>(ty) * static_cast<std::size_t>(r) * aw +
                            static_cast<std::size_t>(tx) * static_cast<std::size_t>(r);
  const double levels = h.height_bits == 16 ? 65535.0 : 255.0;
  const double h_scale = edge * (h.height_max - h.height_min) / levels;
  // Point = origin + (umin + (x + .5) pu) e1 + (vmin + (y + .5) pv) e2 + h n.
  const Vec3d base = f.origin + (f.umin + 0.5 * f.pixel_u) * f.e1 + (f.vmin + 0.5 * f.pixel_v) * f.e2 +
                     (edge * h.height_min) * f.n;
  const Vec3d du = f.pixel_u * f.e1, dv = f.pixel_v * f.e2, dh = h_scale * f.n;
  const auto point = [&](int x, int y) {
    const std::size_t a = tile0 + static_cast<std::size_t>(y) * aw + static_cast<std::size_t>(x);
    const double hq = m.height16 != nullptr ? m.height16[a] : m.height8[a];
    emit(a, Vec3d{base.x + x * du.x + y * dv.x + hq * dh.x, base.y + x * du.y + y * dv.y + hq * dh.y,
                  base.z + x * du.z + y * dv.z + hq * dh.z});
  };
  if (quota == occupied) {
    for (int y = 0; y < r; ++y) {
      const std::uint8_t* row = m.occupancy + tile0 + static_cast<std::size_t>(y) * aw;
      for (int x = 0; x < r; ++x) {
        if (row[x]) point(x, y);
      }
    }
    return;
  }
  std::uint32_t left = quota;
  for (std::uint16_t pix : lod_pixel_order(r)) {
    if (left == 0) break;
    const int x = pix % r, y = pix / r;
    if (!m.occupancy[tile0 + static_cast<std::size_t>(y) * aw + static_cast<std::size_t>(x)]) continue;
    point(x, y);
    --left;
  }
}

}  // namespace relief::codec
