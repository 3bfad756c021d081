// Abbreviated JPEG streams: the quantisation and Huffman tables TurboJPEG
// writes into every stream are the JPEG standard's (ITU-T T.81 Annex K, the
// quantisation tables scaled by the IJG quality formula), so a chunk stores
// the stream without them plus its quality byte and the decoder puts them back.
// Saves ~330 bytes per grayscale and ~620 per colour image: per-chunk overhead
// that otherwise grows the archive as chunks get smaller. Internal to the codec.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "relief/status.h"

namespace relief::codec {

// The stream without its APP0, DQT and DHT segments, when every DQT and DHT
// segment it has equals the canonical tables for (quality, channels) in the
// canonical order; nullopt otherwise (the caller then keeps the full stream).
std::optional<std::vector<std::uint8_t>> jpeg_abbreviate(std::span<const std::uint8_t> full, int quality,
                                                         std::uint32_t channels);

// The full stream: the canonical DQT and DHT segments inserted after SOI.
Result<std::vector<std::uint8_t>> jpeg_restore(std::span<const std::uint8_t> abbreviated, int quality,
                                               std::uint32_t channels);

}  // namespace relief::codec
