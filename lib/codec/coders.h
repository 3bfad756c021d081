// Wrappers around the third-party coders the chunk format uses. Internal to the
// codec module: no third-party header appears here. Every decoder takes the
// dimensions the chunk header promises and rejects a stream that disagrees, so
// no allocation is sized by a field inside the third-party stream.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "relief/status.h"

namespace relief::codec {

// 8-bit image, channels interleaved, rows top to bottom, no padding.
struct Image8 {
  std::uint32_t width = 0;
  std::uint32_t height = 0;
  std::uint32_t channels = 1;  // 1 or 3
  std::vector<std::uint8_t> pixels;
};

// 16-bit single-channel image.
struct Image16 {
  std::uint32_t width = 0;
  std::uint32_t height = 0;
  std::vector<std::uint16_t> pixels;
};

// Largest image side the coders accept (JPEG's own limit is 65500).
inline constexpr std::uint32_t kMaxImageSide = 65500;

// ---- JPEG (TurboJPEG). quality 1..100. 3-channel images are RGB; with
// `subsample_chroma` they are coded 4:2:0, else 4:4:4.
Result<std::vector<std::uint8_t>> jpeg_encode(const Image8& image, int quality, bool subsample_chroma);
Result<Image8> jpeg_decode(std::span<const std::uint8_t> data, std::uint32_t width,
                           std::uint32_t height, std::uint32_t channels);

// ---- JPEG 2000 (OpenJPEG, raw J2K codestream, in-memory). quality 1..99 maps
// to a target PSNR (j2k_quality_to_psnr); 100 = lossless (reversible 5/3).
double j2k_quality_to_psnr(int quality);
Result<std::vector<std::uint8_t>> j2k_encode8(const Image8& image, int quality);
Result<std::vector<std::uint8_t>> j2k_encode16(const Image16& image, int quality);
Result<Image8> j2k_decode8(std::span<const std::uint8_t> data, std::uint32_t width,
                           std::uint32_t height, std::uint32_t channels);
Result<Image16> j2k_decode16(std::span<const std::uint8_t> data, std::uint32_t width,
                             std::uint32_t height);

// ---- Bilevel (JBIG-KIT, ITU-T T.85 / JBIG1). `bits` is width x height pixels,
// one byte per pixel (0 or 1), rows top to bottom.
Result<std::vector<std::uint8_t>> bilevel_encode(std::span<const std::uint8_t> bits,
                                                 std::uint32_t width, std::uint32_t height);
Result<std::vector<std::uint8_t>> bilevel_decode(std::span<const std::uint8_t> data,
                                                 std::uint32_t width, std::uint32_t height);

// ---- LZMA (liblzma, raw LZMA2 stream). The encoder's dictionary is sized to the
// input (4 KiB..1 MiB); the decoder always uses 1 MiB, the format's maximum.
// The decoder must produce exactly `expected_size` bytes.
Result<std::vector<std::uint8_t>> lzma_compress(std::span<const std::uint8_t> data);
Result<std::vector<std::uint8_t>> lzma_decompress(std::span<const std::uint8_t> data,
                                                  std::size_t expected_size);
// Most bytes an LZMA2 stream of `coded_size` bytes can decode to, from the
// format alone: a compressed chunk is at least 6 bytes (control, unpacked and
// packed sizes, one payload byte) and unpacks to at most 2 MiB; a stored chunk
// unpacks to less than its own size. Lets a decoder bound a declared size by
// the bytes actually present before it allocates.
std::uint64_t lzma_max_decoded_size(std::size_t coded_size);

// CRC-32 (IEEE 802.3, as zlib and liblzma compute it).
std::uint32_t crc32(std::span<const std::uint8_t> data);

}  // namespace relief::codec
