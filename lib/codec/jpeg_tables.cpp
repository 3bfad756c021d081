#include "codec/jpeg_tables.h"

#include <algorithm>
#include <cstring>

namespace relief::codec {

namespace {

// T.81 Annex K, tables K.1 and K.2, in natural (row-major) order.
constexpr std::uint8_t kLumaQuant[64] = {
    16, 11, 10, 16, 24,  40,  51,  61,  12, 12, 14, 19, 26,  58,  60,  55,  14, 13, 16, 24, 40, 57,
    69, 56, 14, 17, 22,  29,  51,  87,  80, 62, 18, 22, 37,  56,  68,  109, 103, 77, 24, 35, 55, 64,
    81, 104, 113, 92, 49, 64, 78,  87,  103, 121, 120, 101, 72, 92, 95, 98, 112, 100, 103, 99};
constexpr std::uint8_t kChromaQuant[64] = {
    17, 18, 24, 47, 99, 99, 99, 99, 18, 21, 26, 66, 99, 99, 99, 99, 24, 26, 56, 99, 99, 99,
    99, 99, 47, 66, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99,
    99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99};
// Natural index of the k-th coefficient in zigzag order (DQT stores zigzag).
constexpr std::uint8_t kZigzag[64] = {0,  1,  8,  16, 9,  2,  3,  10, 17, 24, 32, 25, 18, 11, 4,  5,
                                      12, 19, 26, 33, 40, 48, 41, 34, 27, 20, 13, 6,  7,  14, 21, 28,
                                      35, 42, 49, 56, 57, 50, 43, 36, 29, 22, 15, 23, 30, 37, 44, 51,
                                      58, 59, 52, 45, 38, 31, 39, 46, 53, 60, 61, 54, 47, 55, 62, 63};
// T.81 Annex K.3: code counts by length (16) and values.
constexpr std::uint8_t kDcLumaBits[16] = {0, 1, 5, 1, 1, 1, 1, 1, 1, 0, 0, 0, 0, 0, 0, 0};
constexpr std::uint8_t kDcChromaBits[16] = {0, 3, 1, 1, 1, 1, 1, 1, 1, 1, 1, 0, 0, 0, 0, 0};
constexpr std::uint8_t kDcValues[12] = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11};
constexpr std::uint8_t kAcLumaBits[16] = {0, 2, 1, 3, 3, 2, 4, 3, 5, 5, 4, 4, 0, 0, 1, 0x7d};
constexpr std::uint8_t kAcLumaValues[162] = {
    0x01, 0x02, 0x03, 0x00, 0x04, 0x11, 0x05, 0x12, 0x21, 0x31, 0x41, 0x06, 0x13, 0x51, 0x61, 0x07, 0x22, 0x71,
    0x14, 0x32, 0x81, 0x91, 0xa1, 0x08, 0x23, 0x42, 0xb1, 0xc1, 0x15, 0x52, 0xd1, 0xf0, 0x24, 0x33, 0x62, 0x72,
    0x82, 0x09, 0x0a, 0x16, 0x17, 0x18, 0x19, 0x1a, 0x25, 0x26, 0x27, 0x28, 0x29, 0x2a, 0x34, 0x35, 0x36, 0x37,
    0x38, 0x39, 0x3a, 0x43, 0x44, 0x45, 0x46, 0x47, 0x48, 0x49, 0x4a, 0x53, 0x54, 0x55, 0x56, 0x57, 0x58, 0x59,
    0x5a, 0x63, 0x64, 0x65, 0x66, 0x67, 0x68, 0x69, 0x6a, 0x73, 0x74, 0x75, 0x76, 0x77, 0x78, 0x79, 0x7a, 0x83,
    0x84, 0x85, 0x86, 0x87, 0x88, 0x89, 0x8a, 0x92, 0x93, 0x94, 0x95, 0x96, 0x97, 0x98, 0x99, 0x9a, 0xa2, 0xa3,
    0xa4, 0xa5, 0xa6, 0xa7, 0xa8, 0xa9, 0xaa, 0xb2, 0xb3, 0xb4, 0xb5, 0xb6, 0xb7, 0xb8, 0xb9, 0xba, 0xc2, 0xc3,
    0xc4, 0xc5, 0xc6, 0xc7, 0xc8, 0xc9, 0xca, 0xd2, 0xd3, 0xd4, 0xd5, 0xd6, 0xd7, 0xd8, 0xd9, 0xda, 0xe1, 0xe2,
    0xe3, 0xe4, 0xe5, 0xe6, 0xe7, 0xe8, 0xe9, 0xea, 0xf1, 0xf2, 0xf3, 0xf4, 0xf5, 0xf6, 0xf7, 0xf8, 0xf9, 0xfa};
constexpr std::uint8_t kAcChromaBits[16] = {0, 2, 1, 2, 4, 4, 3, 4, 7, 5, 4, 4, 0, 1, 2, 0x77};
constexpr std::uint8_t kAcChromaValues[162] = {
    0x00, 0x01, 0x02, 0x03, 0x11, 0x04, 0x05, 0x21, 0x31, 0x06, 0x12, 0x41, 0x51, 0x07, 0x61, 0x71, 0x13, 0x22,
    0x32, 0x81, 0x08, 0x14, 0x42, 0x91, 0xa1, 0xb1, 0xc1, 0x09, 0x23, 0x33, 0x52, 0xf0, 0x15, 0x62, 0x72, 0xd1,
    0x0a, 0x16, 0x24, 0x34, 0xe1, 0x25, 0xf1, 0x17, 0x18, 0x19, 0x1a, 0x26, 0x27, 0x28, 0x29, 0x2a, 0x35, 0x36,
    0x37, 0x38, 0x39, 0x3a, 0x43, 0x44, 0x45, 0x46, 0x47, 0x48, 0x49, 0x4a, 0x53, 0x54, 0x55, 0x56, 0x57, 0x58,
    0x59, 0x5a, 0x63, 0x64, 0x65, 0x66, 0x67, 0x68, 0x69, 0x6a, 0x73, 0x74, 0x75, 0x76, 0x77, 0x78, 0x79, 0x7a,
    0x82, 0x83, 0x84, 0x85, 0x86, 0x87, 0x88, 0x89, 0x8a, 0x92, 0x93, 0x94, 0x95, 0x96, 0x97, 0x98, 0x99, 0x9a,
    0xa2, 0xa3, 0xa4, 0xa5, 0xa6, 0xa7, 0xa8, 0xa9, 0xaa, 0xb2, 0xb3, 0xb4, 0xb5, 0xb6, 0xb7, 0xb8, 0xb9, 0xba,
    0xc2, 0xc3, 0xc4, 0xc5, 0xc6, 0xc7, 0xc8, 0xc9, 0xca, 0xd2, 0xd3, 0xd4, 0xd5, 0xd6, 0xd7, 0xd8, 0xd9, 0xda,
    0xe2, 0xe3, 0xe4, 0xe5, 0xe6, 0xe7, 0xe8, 0xe9, 0xea, 0xf2, 0xf3, 0xf4, 0xf5, 0xf6, 0xf7, 0xf8, 0xf9, 0xfa};

constexpr std::uint8_t kMarker = 0xFF;
constexpr std::uint8_t kSoi = 0xD8;
constexpr std::uint8_t kSos = 0xDA;
constexpr std::uint8_t kDqt = 0xDB;
constexpr std::uint8_t kDht = 0xC4;
constexpr std::uint8_t kApp0 = 0xE0;

void append_segment(std::vector<std::uint8_t>& out, std::uint8_t marker, const std::vector<std::uint8_t>& payload) {
  const std::size_t len = payload.size() + 2;
  out.push_back(kMarker);
  out.push_back(marker);
  out.push_back(static_cast<std::uint8_t>(len >> 8));
  out.push_back(static_cast<std::uint8_t>(len & 0xff));
  for (const std::uint8_t b : payload) out.push_back(b);
}

// IJG jpeg_quality_scaling + jpeg_add_quant_table with force_baseline.
std::vector<std::uint8_t> dqt_payload(int table_id, const std::uint8_t* base, int quality) {
  const int q = std::clamp(quality, 1, 100);
  const long scale = q < 50 ? 5000 / q : 200 - q * 2;
  std::vector<std::uint8_t> p;
  p.push_back(static_cast<std::uint8_t>(table_id));  // 8-bit precision, table id
  for (int k = 0; k < 64; ++k) {
    long v = (static_cast<long>(base[kZigzag[k]]) * scale + 50) / 100;
    v = std::clamp(v, 1L, 255L);
    p.push_back(static_cast<std::uint8_t>(v));
  }
  return p;
}

std::vector<std::uint8_t> dht_payload(int klass, int table_id, const std::uint8_t* bits, const std::uint8_t* values,
                                      std::size_t count) {
  std::vector<std::uint8_t> p;
  p.reserve(1 + 16 + count);
  p.push_back(static_cast<std::uint8_t>((klass << 4) | table_id));
  for (int i = 0; i < 16; ++i) p.push_back(bits[i]);
  for (std::size_t i = 0; i < count; ++i) p.push_back(values[i]);
  return p;
}

// The canonical DQT/DHT segments, in the order libjpeg writes them.
std::vector<std::vector<std::uint8_t>> canonical_segments(int quality, std::uint32_t channels) {
  std::vector<std::vector<std::uint8_t>> s;
  const auto seg = [](std::uint8_t marker, const std::vector<std::uint8_t>& payload) {
    std::vector<std::uint8_t> out;
    append_segment(out, marker, payload);
    return out;
  };
  s.push_back(seg(kDqt, dqt_payload(0, kLumaQuant, quality)));
  if (channels == 3) s.push_back(seg(kDqt, dqt_payload(1, kChromaQuant, quality)));
  s.push_back(seg(kDht, dht_payload(0, 0, kDcLumaBits, kDcValues, sizeof kDcValues)));
  s.push_back(seg(kDht, dht_payload(1, 0, kAcLumaBits, kAcLumaValues, sizeof kAcLumaValues)));
  if (channels == 3) {
    s.push_back(seg(kDht, dht_payload(0, 1, kDcChromaBits, kDcValues, sizeof kDcValues)));
    s.push_back(seg(kDht, dht_payload(1, 1, kAcChromaBits, kAcChromaValues, sizeof kAcChromaValues)));
  }
  return s;
}

}  // namespace

std::optional<std::vector<std::uint8_t>> jpeg_abbreviate(std::span<const std::uint8_t> full, int quality,
                                                         std::uint32_t channels) {
  if (full.size() < 4 || full[0] != kMarker || full[1] != kSoi) return std::nullopt;
  const auto canonical = canonical_segments(quality, channels);
  std::size_t matched = 0;
  std::vector<std::uint8_t> out = {kMarker, kSoi};
  std::size_t pos = 2;
  for (;;) {
    if (pos + 4 > full.size() || full[pos] != kMarker) return std::nullopt;
    const std::uint8_t marker = full[pos + 1];
    const std::size_t len = (static_cast<std::size_t>(full[pos + 2]) << 8) | full[pos + 3];
    if (len < 2 || pos + 2 + len > full.size()) return std::nullopt;
    const std::span<const std::uint8_t> segment = full.subspan(pos, len + 2);
    if (marker == kSos) {
      // Scan header and entropy-coded data to the end, unchanged.
      out.insert(out.end(), full.begin() + static_cast<std::ptrdiff_t>(pos), full.end());
      break;
    }
    if (marker == kDqt || marker == kDht) {
      if (matched >= canonical.size() || canonical[matched].size() != segment.size() ||
          !std::equal(segment.begin(), segment.end(), canonical[matched].begin())) {
        return std::nullopt;
      }
      ++matched;
    } else if (marker != kApp0) {
      out.insert(out.end(), segment.begin(), segment.end());
    }
    pos += len + 2;
  }
  if (matched != canonical.size()) return std::nullopt;
  return out;
}

Result<std::vector<std::uint8_t>> jpeg_restore(std::span<const std::uint8_t> abbreviated, int quality,
                                               std::uint32_t channels) {
  if (quality < 1 || quality > 100) return corrupt_data("jpeg: abbreviated stream with quality " + std::to_string(quality));
  if (abbreviated.size() < 2 || abbreviated[0] != kMarker || abbreviated[1] != kSoi) {
    return corrupt_data("jpeg: abbreviated stream does not start with SOI");
  }
  std::vector<std::uint8_t> out = {kMarker, kSoi};
  for (const auto& seg : canonical_segments(quality, channels)) out.insert(out.end(), seg.begin(), seg.end());
  out.insert(out.end(), abbreviated.begin() + 2, abbreviated.end());
  return out;
}

}  // namespace relief::codec
