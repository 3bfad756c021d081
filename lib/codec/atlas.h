// Placement of patch tiles in the chunk atlas and the level-of-detail pixel
// order. Internal to the codec.
#pragma once

#include <cstdint>
#include <vector>

namespace relief::codec {

struct AtlasLayout {
  std::uint32_t tiles_x = 0;
  std::uint32_t tiles_y = 0;
};

// Tiles follow a Z-order curve in an atlas tiles_x wide, tiles_x the smallest
// power of two with tiles_x^2 >= patch_count, so patches that are neighbours in
// the (Morton-ordered) patch list are neighbours in the image.
AtlasLayout atlas_layout(std::uint32_t patch_count);
// Tile position of patch `index`.
void tile_position(std::uint32_t index, std::uint32_t& tx, std::uint32_t& ty);

// Pixels of an r x r tile ordered so that every prefix is spatially uniform
// (bit-reversed Morton order); entries are y * r + x.
const std::vector<std::uint16_t>& lod_pixel_order(int map_resolution);

}  // namespace relief::codec
