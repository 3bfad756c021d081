// Per-point attributes of the error-bounded layer, in the order the geometry
// section gives the points (format-spec/chunk.md, "Attribute sections"):
// DPCM from the previous point with context-adaptive binary arithmetic coding
// of the residuals. Internal to the codec.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "relief/status.h"
#include "relief/types.h"

namespace relief::codec {

// A point's local cell coordinates (x, y, z) in the error-bounded layer.
using CellXyz = std::array<std::uint32_t, 3>;

// Colours with every channel within `tolerance` levels (0 = exact): the
// residual of each channel is quantised with step 2 × tolerance + 1 (JPEG-LS
// style near-lossless coding). Red and blue are predicted with green's change.
// `reconstructed`, when given, receives what the decoder will return.
std::vector<std::uint8_t> encode_colors(std::span<const Rgb8> colors, int tolerance,
                                        std::vector<Rgb8>* reconstructed = nullptr);
Result<std::vector<Rgb8>> decode_colors(std::span<const std::uint8_t> data, std::size_t count, int tolerance);
// The same coding inside a stream another section has begun (fresh models):
// colour low bytes of chunk format 7 follow their "equal to the colours"
// decision. decode_colors_from returns false on a bad symbol.
class RangeEncoder;
class RangeDecoder;
void encode_colors_into(RangeEncoder& enc, std::span<const Rgb8> colors, int tolerance,
                        std::vector<Rgb8>* reconstructed = nullptr);
bool decode_colors_from(RangeDecoder& dec, std::size_t count, int tolerance, std::vector<Rgb8>& out);

// Format 9, section codec 10 (format-spec/chunk.md §11.4.1): the same
// near-lossless coding with each colour predicted from the previous
// kColorWindow points, weighted by inverse squared cell distance relative to
// the nearest one's (its square for exact colours, where the nearest point
// should dominate), and contexts from those points' residuals. cells[i] is
// point i's cell; the decoder has them from the geometry section.
inline constexpr std::size_t kColorWindow = 32;
std::vector<std::uint8_t> encode_colors_near(std::span<const Rgb8> colors, std::span<const CellXyz> cells,
                                             int tolerance, std::vector<Rgb8>* reconstructed = nullptr);
Result<std::vector<Rgb8>> decode_colors_near(std::span<const std::uint8_t> data, std::span<const CellXyz> cells,
                                             int tolerance);

// Integer values (16-bit intensities, or 32-bit float patterns), exact; or,
// with a tolerance t > 0 (format 12), 16-bit values 0..65535 each decoded
// within t, `reconstructed` receiving what the decoder will return.
inline constexpr std::int64_t kMaxUInt16Value = 65535;
std::vector<std::uint8_t> encode_values(std::span<const std::int64_t> values, int tolerance = 0,
                                        std::vector<std::int64_t>* reconstructed = nullptr);
Result<std::vector<std::int64_t>> decode_values(std::span<const std::uint8_t> data, std::size_t count,
                                                int tolerance = 0);

}  // namespace relief::codec
