#include <cmath>
#include <cstring>
#include <string>

#include "codec/atlas.h"
#include "codec/chunk_format.h"
#include "codec/coders.h"
#include "codec/las_attribute_coder.h"
#include "core/byte_io.h"

namespace relief {

const char* decomposition_name(Decomposition d) {
  switch (d) {
    case Decomposition::kVoxelGrid: return "voxel";
    case Decomposition::kOctree: return "octree";
  }
  return "unknown";
}

const char* image_codec_name(ImageCodec c) {
  switch (c) {
    case ImageCodec::kJpeg: return "jpeg";
    case ImageCodec::kJpeg2000: return "jpeg2000";
  }
  return "unknown";
}

namespace codec {

namespace {

const char* section_name(SectionId id) {
  if (is_las_section(id)) return las_attribute_name(las_section_bit(id));
  switch (id) {
    case SectionId::kTree: return "tree";
    case SectionId::kPatches: return "patches";
    case SectionId::kOccupancy: return "occupancy";
    case SectionId::kHeight: return "height";
    case SectionId::kColor: return "colour";
    case SectionId::kIntensity: return "intensity";
    case SectionId::kGeometry: return "geometry";
    case SectionId::kPointColor: return "point colour";
    case SectionId::kPointIntensity: return "point intensity";
    case SectionId::kClassMap: return "classification map";
  }
  return "unknown";
}

bool codec_allowed(SectionId id, SectionCodec c, ImageCodec image_codec, std::uint16_t version) {
  switch (id) {
    case SectionId::kTree:
    case SectionId::kPatches:
      return c == SectionCodec::kStored || c == SectionCodec::kLzma2;
    case SectionId::kOccupancy:
      return c == SectionCodec::kJbig85;
    case SectionId::kHeight:
    case SectionId::kColor:
    case SectionId::kIntensity:
      if (image_codec == ImageCodec::kJpeg) return c == SectionCodec::kJpeg || c == SectionCodec::kJpegAbbreviated;
      return c == SectionCodec::kJpeg2000;
    case SectionId::kGeometry:
      // One octree coding per version: codec 6 in versions 2 and 3, codec 7
      // in 5 and 6, codec 8 in 7 to 9, codec 11 in 10 to 12, codec 12 in 13
      // to 15, codec 13 from 16; version 8 adds codec 9 (time order).
      if (version >= 8 && c == SectionCodec::kScanOrder) return true;
      return c == (version >= 17   ? SectionCodec::kOctreeNearest
                   : version >= 16 ? SectionCodec::kOctreePlanes
                   : version >= 13 ? SectionCodec::kOctreeFaces
                   : version >= 10 ? SectionCodec::kOctreeChains
                   : version >= 7  ? SectionCodec::kOctreeMixed
                   : version >= 5  ? SectionCodec::kOctreeSingleChild
                                   : SectionCodec::kArithmetic);
    case SectionId::kPointColor:
      return c == SectionCodec::kArithmetic || (version >= 9 && c == SectionCodec::kNeighbourColor);
    case SectionId::kPointIntensity:
    case SectionId::kClassMap:
      return c == SectionCodec::kArithmetic;
  }
  return is_las_section(id) && c == SectionCodec::kArithmetic;
}

// The error-bounded layer's fields (version 2).
Status check_bounded_header(const ChunkHeader& h) {
  const auto bad = [](const std::string& m) { return corrupt_data("chunk header: " + m); };
  const Vec3d& s = h.quant_step;
  const Vec3d& o = h.quant_origin;
  if (!(std::isfinite(s.x) && std::isfinite(s.y) && std::isfinite(s.z) && s.x > 0 && s.y > 0 && s.z > 0)) {
    return bad("quantisation step must be finite and positive");
  }
  if (!(std::isfinite(o.x) && std::isfinite(o.y) && std::isfinite(o.z))) return bad("non-finite quantisation origin");
  if (h.geometry_depth > kMaxTreeDepth) return bad("geometry depth " + std::to_string(h.geometry_depth) + " > 21");
  const double far = std::ldexp(1.0, h.geometry_depth);
  const double steps[3] = {s.x, s.y, s.z};
  const double origins[3] = {o.x, o.y, o.z};
  for (int a = 0; a < 3; ++a) {
    if (h.quant_base[a] <= -kMaxQuantBase || h.quant_base[a] >= kMaxQuantBase) return bad("quantisation base out of range");
    // The farthest coordinate the layer can produce must be finite.
    const double lo = origins[a] + static_cast<double>(h.quant_base[a]) * steps[a];
    const double hi = origins[a] + (static_cast<double>(h.quant_base[a]) + far) * steps[a];
    if (!std::isfinite(lo) || !std::isfinite(hi)) return bad("coordinates of the error-bounded layer overflow");
  }
  if (h.color_tolerance > kMaxColorTolerance) return bad("colour tolerance above 127");
  const bool has_i = (h.flags & kFlagIntensity) != 0;
  const auto ic = static_cast<std::uint8_t>(h.intensity_coding);
  if (has_i ? (ic != 1 && ic != 2) : ic != 0) return bad("intensity coding " + std::to_string(ic) + " invalid");
  if ((h.flags & kFlagColors) == 0 && h.color_tolerance != 0) return bad("colour tolerance without colours");
  if (h.intensity_tolerance > kMaxIntensityTolerance) return bad("intensity tolerance above 32767");
  if (h.intensity_tolerance != 0 && h.intensity_coding != IntensityCoding::kUInt16) {
    return bad("intensity tolerance without 16-bit intensities");
  }
  if (h.input_points == 0 && (h.patch_count != 0 || h.geometry_depth != 0)) return bad("empty chunk with content");
  if (h.input_points > 0 && h.patch_count == 0) return bad("points without a base layer");
  if (has_las_fields(h.version)) {
    // Version 3 exists for the LAS attributes: a blob without any is version 2.
    // Version 5 (every bounded blob) may carry none.
    if ((h.version == 3 && h.las_attributes == 0) || (h.las_attributes & ~kKnownLasAttributes) != 0) {
      return bad("LAS attribute set " + std::to_string(h.las_attributes) + " invalid");
    }
    if (h.input_points == 0 && h.las_attributes != 0) return bad("LAS attributes in an empty chunk");
    const bool extra = (h.las_attributes & kLasExtraBytes) != 0;
    if (extra ? (h.extra_bytes_size == 0 || h.extra_bytes_size > kMaxExtraBytesSize) : h.extra_bytes_size != 0) {
      return bad("extra bytes size " + std::to_string(h.extra_bytes_size) + " invalid");
    }
    if ((h.las_attributes & kLasColorLow) != 0 && (h.flags & kFlagColors) == 0) {
      return bad("colour low bytes without colours");
    }
    // The base layer has a classification map exactly when the points carry classes.
    if (((h.flags & kFlagClassMap) != 0) != ((h.las_attributes & kLasClassification) != 0)) {
      return bad("classification map flag does not match the LAS attributes");
    }
  }
  return Status::ok();
}

Status check_header(const ChunkHeader& h) {
  const auto bad = [](const std::string& m) { return corrupt_data("chunk header: " + m); };
  if ((h.flags & ~(h.version >= 3 ? kKnownFlagsV3 : kKnownFlags)) != 0) return bad("reserved flag bits set");
  // Version 4 exists for the classification map: without one a blob is version 1.
  if (h.version == 4 && ((h.flags & kFlagClassMap) == 0 || h.patch_count == 0)) {
    return bad("version 4 without a classification map");
  }
  if (h.decomposition != Decomposition::kVoxelGrid && h.decomposition != Decomposition::kOctree) {
    return bad("unknown decomposition id " + std::to_string(static_cast<int>(h.decomposition)));
  }
  if (h.image_codec != ImageCodec::kJpeg && h.image_codec != ImageCodec::kJpeg2000) {
    return bad("unknown image codec id " + std::to_string(static_cast<int>(h.image_codec)));
  }
  if (h.map_resolution < kMinMapResolution || h.map_resolution > kMaxMapResolution ||
      h.map_resolution % 8 != 0) {
    return bad("map resolution " + std::to_string(h.map_resolution) + " is not a multiple of 8 in 8..64");
  }
  if (h.tree_depth > kMaxTreeDepth) return bad("tree depth " + std::to_string(h.tree_depth) + " > 21");
  if (h.height_bits != 8 && !(h.height_bits == 16 && h.image_codec == ImageCodec::kJpeg2000)) {
    return bad("height bits " + std::to_string(h.height_bits) + " invalid for this image codec");
  }
  if (h.decoded_points > h.input_points) return bad("more decoded points than input points");
  if (h.patch_count > h.decoded_points) return bad("more patches than decoded points");
  if (h.patch_count == 0) {
    if (h.decoded_points != 0 || h.tiles_x != 0 || h.tiles_y != 0) return bad("empty chunk with content");
    return Status::ok();
  }
  // 8^depth leaves at most.
  if (3 * h.tree_depth < 32 && h.patch_count > (std::uint64_t{1} << (3 * h.tree_depth))) {
    return bad("more patches than cells at depth " + std::to_string(h.tree_depth));
  }
  // Bound the counts by the atlas the header declares before anything uses
  // them: one tile per patch, one occupancy pixel per decoded point.
  if (static_cast<std::uint64_t>(h.tiles_x) * h.map_resolution > kMaxImageSide ||
      static_cast<std::uint64_t>(h.tiles_y) * h.map_resolution > kMaxImageSide) {
    return bad("atlas larger than " + std::to_string(kMaxImageSide) + " pixels");
  }
  const std::uint64_t tiles = static_cast<std::uint64_t>(h.tiles_x) * h.tiles_y;
  if (h.patch_count > tiles) {
    return bad(std::to_string(h.patch_count) + " patches do not fit an atlas of " +
               std::to_string(h.tiles_x) + "x" + std::to_string(h.tiles_y) + " tiles");
  }
  const std::uint64_t pixels = tiles * h.map_resolution * h.map_resolution;
  if (h.decoded_points > pixels) {
    return bad(std::to_string(h.decoded_points) + " decoded points do not fit an occupancy map of " +
               std::to_string(pixels) + " pixels");
  }
  const AtlasLayout layout = atlas_layout(h.patch_count);
  if (h.tiles_x != layout.tiles_x || h.tiles_y != layout.tiles_y) {
    return bad("atlas of " + std::to_string(h.tiles_x) + "x" + std::to_string(h.tiles_y) +
               " tiles does not match " + std::to_string(h.patch_count) + " patches");
  }
  const bool finite = std::isfinite(h.grid_origin.x) && std::isfinite(h.grid_origin.y) &&
                      std::isfinite(h.grid_origin.z) && std::isfinite(h.grid_edge) &&
                      std::isfinite(h.height_min) && std::isfinite(h.height_max) &&
                      std::isfinite(h.intensity_min) && std::isfinite(h.intensity_max);
  if (!finite) return bad("non-finite grid, height or intensity range");
  if (!(h.grid_edge > 0)) return bad("grid edge must be positive");
  if (h.height_max < h.height_min || h.intensity_max < h.intensity_min) return bad("inverted range");
  return Status::ok();
}

std::uint64_t expected_raw_size(SectionId id, const ChunkHeader& h) {
  const std::uint64_t pixels = static_cast<std::uint64_t>(h.tiles_x) * h.tiles_y *
                               h.map_resolution * h.map_resolution;
  switch (id) {
    case SectionId::kTree: return 0;  // variable, bounded separately
    case SectionId::kPatches: return static_cast<std::uint64_t>(h.patch_count) * kPatchRecordSize;
    case SectionId::kOccupancy: return pixels;
    case SectionId::kHeight: return pixels * (h.height_bits / 8u);
    case SectionId::kColor: return pixels * 3;
    case SectionId::kIntensity: return pixels;
    case SectionId::kGeometry:
    case SectionId::kPointColor:
    case SectionId::kPointIntensity: return h.input_points;
    case SectionId::kClassMap: return h.decoded_points;
  }
  return is_las_section(id) ? h.input_points : 0;
}

}  // namespace

std::vector<SectionId> required_sections(const ChunkHeader& header) {
  std::vector<SectionId> ids;
  if (header.patch_count == 0) return ids;
  ids = {SectionId::kTree, SectionId::kPatches, SectionId::kOccupancy, SectionId::kHeight};
  if (header.flags & kFlagColors) ids.push_back(SectionId::kColor);
  if (header.flags & kFlagIntensity) ids.push_back(SectionId::kIntensity);
  if (has_bounded_layer(header.version)) {
    ids.push_back(SectionId::kGeometry);
    if (header.flags & kFlagColors) ids.push_back(SectionId::kPointColor);
    if (header.flags & kFlagIntensity) ids.push_back(SectionId::kPointIntensity);
  }
  if (has_las_fields(header.version)) {
    for (int b = 0; b < kLasAttributeCount; ++b) {
      if (header.las_attributes & (1u << b)) ids.push_back(static_cast<SectionId>(kFirstLasSection + b));
    }
  }
  if (header.flags & kFlagClassMap) ids.push_back(SectionId::kClassMap);
  return ids;
}

std::vector<std::uint8_t> write_blob(const ChunkHeader& h, const std::vector<SectionEntry>& sections) {
  ByteWriter w;
  w.bytes(kMagic, 4);
  w.u16(h.version);
  w.u16(header_size_for(h.version));
  w.u8(h.flags);
  w.u8(static_cast<std::uint8_t>(h.decomposition));
  w.u8(static_cast<std::uint8_t>(h.image_codec));
  w.u8(h.map_resolution);
  w.u8(h.tree_depth);
  w.u8(h.height_bits);
  w.u8(static_cast<std::uint8_t>(sections.size()));
  w.u8(0);  // reserved
  w.u32(h.input_points);
  w.u32(h.decoded_points);
  w.u32(h.patch_count);
  w.u16(h.tiles_x);
  w.u16(h.tiles_y);
  w.f64(h.grid_origin.x);
  w.f64(h.grid_origin.y);
  w.f64(h.grid_origin.z);
  w.f64(h.grid_edge);
  w.f64(h.height_min);
  w.f64(h.height_max);
  w.f32(h.intensity_min);
  w.f32(h.intensity_max);
  if (has_bounded_layer(h.version)) {
    w.f64(h.quant_step.x);
    w.f64(h.quant_step.y);
    w.f64(h.quant_step.z);
    w.f64(h.quant_origin.x);
    w.f64(h.quant_origin.y);
    w.f64(h.quant_origin.z);
    for (const std::int64_t b : h.quant_base) w.u64(static_cast<std::uint64_t>(b));
    w.u8(h.geometry_depth);
    w.u8(h.color_tolerance);
    w.u8(static_cast<std::uint8_t>(h.intensity_coding));
    w.u8(0);  // reserved
    w.u16(h.intensity_tolerance);  // reserved (0) before version 12
    w.u16(0);                      // reserved
  }
  if (has_las_fields(h.version)) {
    w.u32(h.las_attributes);
    w.u32(h.extra_bytes_size);
  }
  for (const SectionEntry& s : sections) {
    w.u8(static_cast<std::uint8_t>(s.id));
    w.u8(static_cast<std::uint8_t>(s.codec));
    w.u16(0);  // reserved
    w.u32(s.raw_size);
    w.u32(static_cast<std::uint32_t>(s.payload.size()));
  }
  for (const SectionEntry& s : sections) w.bytes(s.payload);
  w.u32(crc32(w.buffer()));
  return w.take();
}

namespace {

// The header and section table, checked against a blob of `blob_size` bytes
// of which `blob` holds at least those two (their sizes must add up to
// blob_size); `r` reads `blob` and is left at the first payload.
Status parse_head(ByteReader& r, std::span<const std::uint8_t> blob, std::uint64_t blob_size, ParsedBlob& out) {
  ChunkHeader& h = out.header;
  if (blob.size() < 6 || blob_size < 6 || std::memcmp(blob.data(), kMagic, 4) != 0) {
    return corrupt_data("chunk blob: not a Relief chunk (bad magic)");
  }
  RELIEF_RETURN_IF_ERROR(r.skip(4, "magic"));
  RELIEF_RETURN_IF_ERROR(r.u16(h.version, "format_version"));
  if (h.version == 0 || h.version > kChunkFormatVersion) {
    return unsupported("chunk blob: format version " + std::to_string(h.version) +
                       " is not supported by this build (reads 1.." +
                       std::to_string(kChunkFormatVersion) + ")");
  }
  std::uint16_t header_size = 0;
  std::uint8_t decomposition = 0, image_codec = 0, section_count = 0, reserved8 = 0;
  RELIEF_RETURN_IF_ERROR(r.u16(header_size, "header_size"));
  const std::uint16_t want_header = header_size_for(h.version);
  if (header_size != want_header) {
    return corrupt_data("chunk blob: header size " + std::to_string(header_size) + ", expected " +
                        std::to_string(want_header));
  }
  RELIEF_RETURN_IF_ERROR(r.u8(h.flags, "flags"));
  RELIEF_RETURN_IF_ERROR(r.u8(decomposition, "decomposition"));
  RELIEF_RETURN_IF_ERROR(r.u8(image_codec, "image_codec"));
  RELIEF_RETURN_IF_ERROR(r.u8(h.map_resolution, "map_resolution"));
  RELIEF_RETURN_IF_ERROR(r.u8(h.tree_depth, "tree_depth"));
  RELIEF_RETURN_IF_ERROR(r.u8(h.height_bits, "height_bits"));
  RELIEF_RETURN_IF_ERROR(r.u8(section_count, "section_count"));
  RELIEF_RETURN_IF_ERROR(r.u8(reserved8, "reserved"));
  RELIEF_RETURN_IF_ERROR(r.u32(h.input_points, "input_points"));
  RELIEF_RETURN_IF_ERROR(r.u32(h.decoded_points, "decoded_points"));
  RELIEF_RETURN_IF_ERROR(r.u32(h.patch_count, "patch_count"));
  RELIEF_RETURN_IF_ERROR(r.u16(h.tiles_x, "tiles_x"));
  RELIEF_RETURN_IF_ERROR(r.u16(h.tiles_y, "tiles_y"));
  RELIEF_RETURN_IF_ERROR(r.f64(h.grid_origin.x, "grid_origin_x"));
  RELIEF_RETURN_IF_ERROR(r.f64(h.grid_origin.y, "grid_origin_y"));
  RELIEF_RETURN_IF_ERROR(r.f64(h.grid_origin.z, "grid_origin_z"));
  RELIEF_RETURN_IF_ERROR(r.f64(h.grid_edge, "grid_edge"));
  RELIEF_RETURN_IF_ERROR(r.f64(h.height_min, "height_min"));
  RELIEF_RETURN_IF_ERROR(r.f64(h.height_max, "height_max"));
  RELIEF_RETURN_IF_ERROR(r.f32(h.intensity_min, "intensity_min"));
  RELIEF_RETURN_IF_ERROR(r.f32(h.intensity_max, "intensity_max"));
  h.decomposition = static_cast<Decomposition>(decomposition);
  h.image_codec = static_cast<ImageCodec>(image_codec);
  if (reserved8 != 0) return corrupt_data("chunk header: reserved byte is not 0");
  if (has_bounded_layer(h.version)) {
    RELIEF_RETURN_IF_ERROR(r.f64(h.quant_step.x, "quant_step_x"));
    RELIEF_RETURN_IF_ERROR(r.f64(h.quant_step.y, "quant_step_y"));
    RELIEF_RETURN_IF_ERROR(r.f64(h.quant_step.z, "quant_step_z"));
    RELIEF_RETURN_IF_ERROR(r.f64(h.quant_origin.x, "quant_origin_x"));
    RELIEF_RETURN_IF_ERROR(r.f64(h.quant_origin.y, "quant_origin_y"));
    RELIEF_RETURN_IF_ERROR(r.f64(h.quant_origin.z, "quant_origin_z"));
    for (std::int64_t& b : h.quant_base) {
      std::uint64_t v = 0;
      RELIEF_RETURN_IF_ERROR(r.u64(v, "quant_base"));
      b = static_cast<std::int64_t>(v);
    }
    std::uint8_t coding = 0, reserved_b = 0;
    std::uint16_t reserved_w = 0;
    RELIEF_RETURN_IF_ERROR(r.u8(h.geometry_depth, "geometry_depth"));
    RELIEF_RETURN_IF_ERROR(r.u8(h.color_tolerance, "color_tolerance"));
    RELIEF_RETURN_IF_ERROR(r.u8(coding, "intensity_coding"));
    RELIEF_RETURN_IF_ERROR(r.u8(reserved_b, "reserved"));
    RELIEF_RETURN_IF_ERROR(r.u16(h.intensity_tolerance, "intensity_tolerance"));
    RELIEF_RETURN_IF_ERROR(r.u16(reserved_w, "reserved"));
    h.intensity_coding = static_cast<IntensityCoding>(coding);
    if (reserved_b != 0 || reserved_w != 0 || (h.version < 12 && h.intensity_tolerance != 0)) {
      return corrupt_data("chunk header: reserved bytes are not 0");
    }
    if (has_las_fields(h.version)) {
      RELIEF_RETURN_IF_ERROR(r.u32(h.las_attributes, "las_attributes"));
      RELIEF_RETURN_IF_ERROR(r.u32(h.extra_bytes_size, "extra_bytes_size"));
    }
    RELIEF_RETURN_IF_ERROR(check_bounded_header(h));
  }
  RELIEF_RETURN_IF_ERROR(check_header(h));

  const std::vector<SectionId> want = required_sections(h);
  if (section_count != want.size()) {
    return corrupt_data("chunk blob: " + std::to_string(section_count) + " sections, expected " +
                        std::to_string(want.size()));
  }
  std::uint64_t payload_total = 0;
  for (std::size_t i = 0; i < want.size(); ++i) {
    SectionEntry s;
    std::uint8_t id = 0, codec = 0;
    std::uint16_t reserved16 = 0;
    RELIEF_RETURN_IF_ERROR(r.u8(id, "section id"));
    RELIEF_RETURN_IF_ERROR(r.u8(codec, "section codec"));
    RELIEF_RETURN_IF_ERROR(r.u16(reserved16, "section reserved"));
    RELIEF_RETURN_IF_ERROR(r.u32(s.raw_size, "section raw size"));
    RELIEF_RETURN_IF_ERROR(r.u32(s.coded_size, "section coded size"));
    s.id = static_cast<SectionId>(id);
    s.codec = static_cast<SectionCodec>(codec);
    const std::string name = "chunk blob: section " + std::to_string(i);
    if (s.id != want[i]) {
      return corrupt_data(name + " has id " + std::to_string(id) + ", expected " +
                          std::to_string(static_cast<int>(want[i])) + " (" + section_name(want[i]) + ")");
    }
    if (reserved16 != 0) return corrupt_data(name + ": reserved field is not 0");
    if (!codec_allowed(s.id, s.codec, h.image_codec, h.version)) {
      return corrupt_data(std::string("chunk blob: ") + section_name(s.id) + " section has codec id " +
                          std::to_string(codec) + ", not allowed here");
    }
    if (s.id == SectionId::kTree) {
      // Every internal node is one byte and lies on some leaf's path.
      const std::uint64_t bound = static_cast<std::uint64_t>(h.patch_count) * h.tree_depth + 1;
      if (s.raw_size > bound) {
        return corrupt_data("chunk blob: tree section raw size " + std::to_string(s.raw_size) +
                            " exceeds the bound for " + std::to_string(h.patch_count) + " patches");
      }
      // And the other way: a leaf is one bit of its parent's mask, or (octree)
      // a mask byte of its own, so the masks hold at most 8 leaves per byte.
      // Depth 0 is a lone root leaf with no bytes (check_header allows 1 patch).
      if (h.tree_depth > 0 && h.patch_count > std::uint64_t{kMaxLeavesPerTreeByte} * s.raw_size) {
        return corrupt_data("chunk blob: tree section of " + std::to_string(s.raw_size) +
                            " bytes holds at most " +
                            std::to_string(std::uint64_t{kMaxLeavesPerTreeByte} * s.raw_size) +
                            " leaves, header declares " + std::to_string(h.patch_count) + " patches");
      }
    } else if (s.raw_size != expected_raw_size(s.id, h)) {
      return corrupt_data(std::string("chunk blob: ") + section_name(s.id) + " section raw size " +
                          std::to_string(s.raw_size) + ", expected " +
                          std::to_string(expected_raw_size(s.id, h)));
    }
    if (s.codec == SectionCodec::kStored && s.coded_size != s.raw_size) {
      return corrupt_data(std::string("chunk blob: stored ") + section_name(s.id) +
                          " section with coded size != raw size");
    }
    if (s.codec == SectionCodec::kLzma2 && s.raw_size > lzma_max_decoded_size(s.coded_size)) {
      return corrupt_data(std::string("chunk blob: ") + section_name(s.id) + " section of " +
                          std::to_string(s.coded_size) + " LZMA2 bytes cannot hold " +
                          std::to_string(s.raw_size) + " bytes");
    }
    payload_total += s.coded_size;
    out.sections.push_back(s);
  }
  const std::uint64_t expected_size = r.position() + payload_total + kChecksumSize;
  if (expected_size != blob_size) {
    return corrupt_data("chunk blob: " + std::to_string(blob_size) + " bytes, header and sections say " +
                        std::to_string(expected_size));
  }
  return Status::ok();
}

}  // namespace

Result<ParsedBlob> parse_blob(std::span<const std::uint8_t> blob, bool verify_checksum) {
  ByteReader r(blob, "chunk blob");
  ParsedBlob out;
  RELIEF_RETURN_IF_ERROR(parse_head(r, blob, blob.size(), out));
  for (SectionEntry& s : out.sections) {
    RELIEF_RETURN_IF_ERROR(r.span(s.payload, s.coded_size, "section payload"));
  }
  std::uint32_t stored_crc = 0;
  RELIEF_RETURN_IF_ERROR(r.u32(stored_crc, "crc32"));
  if (verify_checksum) {
    const std::uint32_t actual = crc32(blob.first(blob.size() - kChecksumSize));
    if (actual != stored_crc) return corrupt_data("chunk blob: checksum mismatch (the blob is damaged)");
  }
  return out;
}

Result<ParsedBlob> parse_blob_head(std::span<const std::uint8_t> head, std::uint64_t blob_size) {
  if (head.size() > blob_size) return invalid_argument("chunk blob head: longer than the blob");
  ByteReader r(head, "chunk blob");
  ParsedBlob out;
  RELIEF_RETURN_IF_ERROR(parse_head(r, head, blob_size, out));
  return out;
}

}  // namespace codec
}  // namespace relief
