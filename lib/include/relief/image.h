// Picture files for previews and other quick looks (not part of the archive
// format).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "relief/status.h"

namespace relief {

// Largest side encode_jpeg_rgb accepts: JPEG's 16-bit dimension fields.
inline constexpr int kMaxJpegSide = 65535;

// A baseline JFIF JPEG of an 8-bit RGB image (`rgb`: width x height x 3 bytes,
// rows from the top), at `quality` 1..100 with 4:2:0 chroma, through
// TurboJPEG. kInvalidArgument for a size mismatch or bad quality, kInternal
// when TurboJPEG fails.
Result<std::vector<std::uint8_t>> encode_jpeg_rgb(std::span<const std::uint8_t> rgb, int width, int height,
                                                  int quality);

}  // namespace relief
