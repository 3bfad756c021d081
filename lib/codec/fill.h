// Smooth filling of unoccupied map pixels before image coding. Filled pixels
// never become points; smooth fills only make the image cheaper to code.
// Internal to the codec.
#pragma once

#include <cstdint>
#include <vector>

namespace relief::codec {

// Scratch buffers reused across tiles so filling allocates once per chunk.
struct FillScratch {
  std::vector<float> values;
  std::vector<float> weights;
};

// Fills the unoccupied pixels of one r x r tile of `channels` interleaved
// float channels (1 or 3). `occupied` holds r*r flags; at least one must be set.
// Push-pull (Gortler et al. 1996): a weighted pyramid is built down to 1x1 and
// pulled back up with bilinear interpolation; occupied pixels keep their values.
void fill_push_pull(float* tile, const std::uint8_t* occupied, int r, int channels,
                    FillScratch& scratch);

// Makes every partly empty B x B block (B = 8 or 16, aligned to the tile) as
// cheap as possible for a block-DCT coder: alternating projections between
// "the block holds only its DC and first horizontal/vertical cosines" and "the
// occupied pixels keep their values"; an empty block becomes flat. Run after
// push-pull, which gives it a smooth start.
void project_blocks_low_frequency(float* tile, const std::uint8_t* occupied, int r, int channels, int block);

// The paper's fill: unoccupied pixels start at the tile mean, then three passes
// of a 5x5 box filter update them.
void fill_box(float* tile, const std::uint8_t* occupied, int r, int channels, FillScratch& scratch);

}  // namespace relief::codec
