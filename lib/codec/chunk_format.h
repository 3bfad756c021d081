// Constants and header layout of the chunk blob, shared by the encoder and the
// decoder. format-spec/chunk.md is the normative description; keep them equal.
#pragma once

#include <bit>
#include <cstdint>
#include <span>
#include <vector>

#include "relief/codec.h"
#include "relief/status.h"

namespace relief::codec {

inline constexpr std::uint8_t kMagic[4] = {'R', 'L', 'F', 'C'};
inline constexpr std::uint16_t kHeaderSizeV1 = 88;
// Version 2 appends the error-bounded layer's fields (format-spec/chunk.md §2).
inline constexpr std::uint16_t kHeaderSizeV2 = 168;
// Version 3 appends the LAS attribute set and the extra-bytes width (§2).
inline constexpr std::uint16_t kHeaderSizeV3 = 176;
// Version 3 adds one section per carried LAS attribute: id kFirstLasSection +
// the attribute's bit index (LasAttributeBits), in increasing bit order.
inline constexpr std::uint8_t kFirstLasSection = 10;
inline constexpr std::uint8_t kLastLasSection = 21;
inline constexpr std::size_t kSectionEntrySize = 12;
inline constexpr std::size_t kChecksumSize = 4;

// Header flag bits; all others are reserved and must be 0.
inline constexpr std::uint8_t kFlagColors = 0x01;
inline constexpr std::uint8_t kFlagIntensity = 0x02;
// Versions 3 and 4: the maps carry a classification map (section 22).
inline constexpr std::uint8_t kFlagClassMap = 0x04;
inline constexpr std::uint8_t kKnownFlags = kFlagColors | kFlagIntensity;
inline constexpr std::uint8_t kKnownFlagsV3 = kFlagColors | kFlagIntensity | kFlagClassMap;

// Section ids, in the order they must appear.
enum class SectionId : std::uint8_t {
  kTree = 1,
  kPatches = 2,
  kOccupancy = 3,
  kHeight = 4,
  kColor = 5,
  kIntensity = 6,
  // Version 2: the error-bounded layer.
  kGeometry = 7,
  kPointColor = 8,
  kPointIntensity = 9,
  // Version 3: ids 10..21 are the LAS attributes (kFirstLasSection + bit).
  // Versions 3 and 4: the majority class of every occupied map pixel.
  kClassMap = 22,
};

// Section codec ids. Never reuse a value.
enum class SectionCodec : std::uint8_t {
  kStored = 0,
  kJpeg = 1,
  kJpeg2000 = 2,
  kLzma2 = 3,
  kJbig85 = 4,
  // JPEG without its tables: u8 quality, then the stream minus APP0/DQT/DHT
  // (jpeg_tables.h). The decoder re-inserts the standard tables.
  kJpegAbbreviated = 5,
  // Relief's adaptive binary range coder (range_coder.h), version 2 sections.
  kArithmetic = 6,
  // Geometry only (version 5): the range-coded octree with single-child
  // nodes coded as a flag and a 3-bit index (format-spec/chunk.md §11.3).
  kOctreeSingleChild = 7,
  // Geometry only (version 7): codec 7's octree with each bit's probability
  // mixed from two context models (format-spec/chunk.md §11.3.2).
  kOctreeMixed = 8,
  // Geometry only (version 8, blobs with GPS times): the points' cells in
  // time order, as predicted differences (format-spec/chunk.md §11.3.3).
  kScanOrder = 9,
  // Point colours only (version 9): codec 6's colour coding with each colour
  // predicted from its nearest previous points (format-spec/chunk.md §11.4.1).
  kNeighbourColor = 10,
  // Geometry only (version 10): codec 8 with chains, isolated one-cell
  // subtrees coded without flags or mixing (format-spec/chunk.md §11.3.4).
  kOctreeChains = 11,
  // Geometry only (version 13): codec 11 with a third model in each mix, by
  // the minus neighbours' children on the shared faces, and an adaptive
  // probability map after it (format-spec/chunk.md §11.3.5).
  kOctreeFaces = 12,
  // Geometry only (version 16): codec 12 with single children's and chains'
  // index bits told where a plane fitted to the nearby known cells crosses
  // the node (format-spec/chunk.md §11.3.6).
  kOctreePlanes = 13,
  // Geometry only (version 17): codec 13 with those index bits also told
  // which half of the node lies nearer the known points around it
  // (format-spec/chunk.md §11.3.7).
  kOctreeNearest = 14,
};

// How the error-bounded layer codes intensity (header byte 162).
enum class IntensityCoding : std::uint8_t { kNone = 0, kUInt16 = 1, kFloatBits = 2 };
inline constexpr int kMaxColorTolerance = 127;
// |quantised coordinate| stays below 2^62 so base + local never overflows.
inline constexpr std::int64_t kMaxQuantBase = std::int64_t{1} << 62;

inline constexpr int kMinMapResolution = 8;
inline constexpr int kMaxMapResolution = 64;
// 21 bits per axis keeps a Morton key in 63 bits.
inline constexpr int kMaxTreeDepth = 21;
// Bytes per patch in the patches section: oct_u, oct_v, offset, umin, umax, vmin, vmax.
inline constexpr std::size_t kPatchRecordSize = 7;
// A tree leaf is one bit of its parent's child mask (or an empty mask byte of
// its own), so n mask bytes describe at most 8 n leaves.
inline constexpr std::uint32_t kMaxLeavesPerTreeByte = 8;

struct SectionEntry {
  SectionId id{};
  SectionCodec codec{};
  std::uint32_t raw_size = 0;
  std::uint32_t coded_size = 0;
  std::span<const std::uint8_t> payload;  // filled by parse_blob
};

struct ChunkHeader {
  std::uint16_t version = 1;  // the maps-only format; the bounded encoder sets 2
  std::uint8_t flags = 0;
  Decomposition decomposition = Decomposition::kVoxelGrid;
  ImageCodec image_codec = ImageCodec::kJpeg;
  std::uint8_t map_resolution = 16;
  std::uint8_t tree_depth = 0;
  std::uint8_t height_bits = 8;
  std::uint32_t input_points = 0;
  std::uint32_t decoded_points = 0;
  std::uint32_t patch_count = 0;
  std::uint16_t tiles_x = 0;
  std::uint16_t tiles_y = 0;
  Vec3d grid_origin;
  double grid_edge = 0;
  double height_min = 0;  // heights are stored divided by the patch cell edge
  double height_max = 0;
  float intensity_min = 0;
  float intensity_max = 0;
  // Version 2 only: point i of the error-bounded layer is at
  // quant_origin + (quant_base + local_i) * quant_step, per axis.
  Vec3d quant_step;
  Vec3d quant_origin;
  std::int64_t quant_base[3] = {0, 0, 0};
  std::uint8_t geometry_depth = 0;  // local coordinates < 2^geometry_depth
  std::uint8_t color_tolerance = 0;
  IntensityCoding intensity_coding = IntensityCoding::kNone;
  // Version 12 on (header bytes 164-165): 0..32767, and 0 unless the
  // intensities are 16-bit integers.
  std::uint16_t intensity_tolerance = 0;
  // Versions 3, 5 and 6: the LasAttributeBits the layer carries (non-zero in
  // version 3) and the extra bytes per point (non-zero exactly when
  // kLasExtraBytes is set).
  std::uint32_t las_attributes = 0;
  std::uint32_t extra_bytes_size = 0;
};

// Versions 2, 3, 5 and 6 hold the error-bounded layer; 1 and 4 the maps alone
// (4: with a classification map).
inline bool has_bounded_layer(std::uint16_t version) { return version == 2 || version == 3 || version >= 5; }
// Versions 3, 5 and 6 have the LAS attribute fields (header bytes 168..175).
inline bool has_las_fields(std::uint16_t version) { return version == 3 || version >= 5; }
// Header size of a format version (1..6).
inline std::uint16_t header_size_for(std::uint16_t version) {
  return has_las_fields(version) ? kHeaderSizeV3 : (version == 2 ? kHeaderSizeV2 : kHeaderSizeV1);
}
inline bool is_las_section(SectionId id) {
  const auto v = static_cast<std::uint8_t>(id);
  return v >= kFirstLasSection && v <= kLastLasSection;
}
// The LasAttributeBits value of a LAS section id.
inline std::uint32_t las_section_bit(SectionId id) {
  return 1u << (static_cast<std::uint8_t>(id) - kFirstLasSection);
}
// The section of LAS attribute `bit` (one LasAttributeBits value).
inline SectionId las_section_id(std::uint32_t bit) {
  return static_cast<SectionId>(kFirstLasSection + std::countr_zero(bit));
}

struct ParsedBlob {
  ChunkHeader header;
  std::vector<SectionEntry> sections;
};

// Serialises header + sections + CRC. Section payloads are copied in order.
std::vector<std::uint8_t> write_blob(const ChunkHeader& header,
                                     const std::vector<SectionEntry>& sections);

// Validates magic, version, every header field, the section table and (when
// asked) the checksum. Payload spans point into `blob`.
Result<ParsedBlob> parse_blob(std::span<const std::uint8_t> blob, bool verify_checksum);
// The header and section table alone, from the first bytes of a blob of
// `blob_size` bytes (payloads left empty, no checksum): every check
// parse_blob makes of them, sizes included.
Result<ParsedBlob> parse_blob_head(std::span<const std::uint8_t> head, std::uint64_t blob_size);

// Which sections a header requires, in order.
std::vector<SectionId> required_sections(const ChunkHeader& header);

}  // namespace relief::codec
