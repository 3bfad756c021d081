// Chunk decoder (Golla & Klein 2015, section III-E). Mirror: chunk_encoder.cpp.
#include <algorithm>
#include <cmath>
#include <string>

#include "codec/atlas.h"
#include "codec/bounded.h"
#include "codec/chunk_format.h"
#include "codec/coders.h"
#include "codec/jpeg_tables.h"
#include "codec/las_attribute_coder.h"
#include "codec/octree.h"
#include "codec/patch.h"
#include "codec/reconstruct.h"

namespace relief {

namespace {

using codec::SectionCodec;
using codec::SectionEntry;
using codec::SectionId;

Result<std::vector<std::uint8_t>> unpack_bytes(const SectionEntry& s, const char* name) {
  if (s.codec == SectionCodec::kStored) {
    return std::vector<std::uint8_t>(s.payload.begin(), s.payload.end());
  }
  auto out = codec::lzma_decompress(s.payload, s.raw_size);
  if (!out) return out.status().with_context(std::string("chunk blob: ") + name + " section");
  return out;
}

Result<codec::Image8> decode_image8(const SectionEntry& s, std::uint32_t w, std::uint32_t h,
                                    std::uint32_t channels, const char* name) {
  Result<codec::Image8> img = corrupt_data("empty");
  if (s.codec == SectionCodec::kJpegAbbreviated) {
    if (s.payload.empty()) return corrupt_data(std::string("chunk blob: ") + name + " section is empty");
    auto full = codec::jpeg_restore(s.payload.subspan(1), s.payload[0], channels);
    if (!full) return full.status().with_context(std::string("chunk blob: ") + name + " section");
    img = codec::jpeg_decode(*full, w, h, channels);
  } else if (s.codec == SectionCodec::kJpeg) {
    img = codec::jpeg_decode(s.payload, w, h, channels);
  } else {
    img = codec::j2k_decode8(s.payload, w, h, channels);
  }
  if (!img) return img.status().with_context(std::string("chunk blob: ") + name + " section");
  return img;
}

// Number of points each patch contributes when a fraction keep_num / keep_den
// (<= 1) of the occupied pixels is kept: error diffusion along the
// Morton-ordered patch list, so small neighbouring patches take turns. Level
// of detail L of a format-1 blob keeps 1 / L.
std::vector<std::uint32_t> lod_quota(const std::vector<std::uint32_t>& occupied, std::uint64_t keep_num,
                                     std::uint64_t keep_den) {
  std::vector<std::uint32_t> quota(occupied.size());
  if (keep_num >= keep_den) return occupied;
  std::uint64_t seen = 0, emitted = 0;
  for (std::size_t i = 0; i < occupied.size(); ++i) {
    seen += occupied[i];
    // Round half up so one point in lod is kept even for the first patch.
    const std::uint64_t target = (seen * keep_num + keep_den / 2) / keep_den;
    const std::uint64_t take = std::min<std::uint64_t>(occupied[i], target - std::min(target, emitted));
    quota[i] = static_cast<std::uint32_t>(take);
    emitted += take;
  }
  return quota;
}

}  // namespace

namespace {

ChunkInfo info_of(const codec::ParsedBlob& parsed, std::size_t blob_size) {
  const codec::ChunkHeader& h = parsed.header;
  ChunkInfo info;
  info.format_version = h.version;
  info.decomposition = h.decomposition;
  info.image_codec = h.image_codec;
  info.has_colors = (h.flags & codec::kFlagColors) != 0;
  info.has_intensity = (h.flags & codec::kFlagIntensity) != 0;
  info.map_resolution = h.map_resolution;
  info.height_bits = h.height_bits;
  info.tree_depth = h.tree_depth;
  info.input_points = h.input_points;
  info.decoded_points = h.decoded_points;
  info.patch_count = h.patch_count;
  info.atlas_width = static_cast<std::uint32_t>(h.tiles_x) * h.map_resolution;
  info.atlas_height = static_cast<std::uint32_t>(h.tiles_y) * h.map_resolution;
  info.grid_origin = h.grid_origin;
  info.grid_edge = h.grid_edge;
  info.blob_size = blob_size;
  if (codec::has_bounded_layer(h.version)) {
    info.error_bounded = true;
    info.base_points = h.decoded_points;
    info.decoded_points = h.input_points;
    info.quant_step = h.quant_step;
    info.color_tolerance = h.color_tolerance;
    info.las_attributes = h.las_attributes;
    info.extra_bytes_size = h.extra_bytes_size;
  } else if ((h.flags & codec::kFlagClassMap) != 0) {
    info.las_attributes = kLasClassification;  // every resampled point gets its pixel's class
  }
  for (const SectionEntry& s : parsed.sections) {
    info.sections.push_back({static_cast<std::uint8_t>(s.id), static_cast<std::uint8_t>(s.codec),
                             s.raw_size, s.coded_size});
  }
  return info;
}

}  // namespace

Result<ChunkInfo> inspect_chunk(std::span<const std::uint8_t> blob) {
  RELIEF_ASSIGN_OR_RETURN(const codec::ParsedBlob parsed, codec::parse_blob(blob, true));
  return info_of(parsed, blob.size());
}

std::string chunk_counts_problem(std::uint64_t input_points, std::uint64_t decoded_points,
                                 std::span<const std::uint8_t> blob) {
  const Result<ChunkInfo> info = inspect_chunk(blob);
  if (!info) return "its blob does not parse: " + info.status().message();
  std::string problem;
  const auto differ = [&](const char* what, std::uint64_t row, std::uint64_t held) {
    if (row == held) return;
    problem += (problem.empty() ? "" : "; ") + std::string("its row says ") + std::to_string(row) + " " +
               what + " points, its blob " + std::to_string(held);
  };
  differ("decoded", decoded_points, info->decoded_points);
  differ("input", input_points, info->input_points);
  return problem;
}

std::string chunk_section_label(int id) {
  switch (id) {
    case 1: return "tree";
    case 2: return "patches";
    case 3: return "occupancy map";
    case 4: return "height map";
    case 5: return "colour map";
    case 6: return "intensity map";
    case 7: return "geometry";
    case 8: return "rgb";
    case 9: return "intensity";
    case 22: return "classification map";
    default: break;
  }
  constexpr int kFirstLasSection = 10;
  if (id >= kFirstLasSection && id < kFirstLasSection + static_cast<int>(kLasAttributeCount)) {
    return kLasAttributeNames[id - kFirstLasSection];
  }
  return "section " + std::to_string(id);
}

bool chunk_section_is_map(int id) { return (id >= 1 && id <= 6) || id == 22; }

Result<ChunkInfo> inspect_chunk_head(std::span<const std::uint8_t> head, std::uint64_t blob_size) {
  RELIEF_ASSIGN_OR_RETURN(const codec::ParsedBlob parsed, codec::parse_blob_head(head, blob_size));
  return info_of(parsed, static_cast<std::size_t>(blob_size));
}

namespace {

// The paper's maps (a format-1 blob, or a format-2 blob's base layer),
// keeping keep_num / keep_den of the occupied pixels.
Result<PointCloud> decode_maps(const codec::ParsedBlob& parsed, std::uint64_t keep_num, std::uint64_t keep_den,
                               const DecodeOptions& options) {
  const codec::ChunkHeader& h = parsed.header;
  PointCloud out;
  if (h.patch_count == 0) return out;
  if (h.decoded_points > options.max_points) {
    return limit_exceeded("chunk blob: " + std::to_string(h.decoded_points) +
                          " points exceed the decoder limit of " + std::to_string(options.max_points));
  }
  const auto section = [&](SectionId id) -> const SectionEntry& {
    for (const SectionEntry& s : parsed.sections) {
      if (s.id == id) return s;
    }
    return parsed.sections.front();  // unreachable: parse_blob checked the set
  };
  const bool has_rgb = (h.flags & codec::kFlagColors) != 0;
  const bool has_i = (h.flags & codec::kFlagIntensity) != 0;
  const int r = h.map_resolution;
  const std::uint32_t n = h.patch_count;
  const std::uint32_t aw = static_cast<std::uint32_t>(h.tiles_x) * static_cast<std::uint32_t>(r);
  const std::uint32_t ah = static_cast<std::uint32_t>(h.tiles_y) * static_cast<std::uint32_t>(r);
  if (static_cast<std::uint64_t>(aw) * ah > options.max_atlas_pixels) {
    return limit_exceeded("chunk blob: a map atlas of " + std::to_string(aw) + " x " + std::to_string(ah) +
                          " pixels exceeds the decoder limit of " + std::to_string(options.max_atlas_pixels));
  }

  RELIEF_ASSIGN_OR_RETURN(std::vector<std::uint8_t> masks, unpack_bytes(section(SectionId::kTree), "tree"));
  RELIEF_ASSIGN_OR_RETURN(std::vector<codec::Leaf> leaves,
                          codec::parse_tree(masks, h.tree_depth,
                                            h.decomposition == Decomposition::kOctree, n));
  RELIEF_ASSIGN_OR_RETURN(std::vector<std::uint8_t> records,
                          unpack_bytes(section(SectionId::kPatches), "patches"));
  auto occ_result = codec::bilevel_decode(section(SectionId::kOccupancy).payload, aw, ah);
  if (!occ_result) return occ_result.status().with_context("chunk blob: occupancy section");
  const std::vector<std::uint8_t> occupancy = std::move(occ_result).value();

  // Count occupied pixels per patch; unused tiles must be empty.
  std::vector<std::uint32_t> occupied(n, 0);
  std::uint64_t total = 0;
  for (std::uint32_t ty = 0; ty < h.tiles_y; ++ty) {
    for (std::uint32_t tx = 0; tx < h.tiles_x; ++tx) {
      std::uint32_t count = 0;
      for (int y = 0; y < r; ++y) {
        const std::uint8_t* row = occupancy.data() + (static_cast<std::size_t>(ty) * r + y) * aw +
                                  static_cast<std::size_t>(tx) * r;
        for (int x = 0; x < r; ++x) count += row[x];
      }
      if (count == 0) continue;
      // Inverse Z-order: interleave tx (even bits) and ty (odd bits).
      std::uint32_t index = 0;
      for (int b = 0; b < 16; ++b) {
        index |= ((tx >> b) & 1u) << (2 * b);
        index |= ((ty >> b) & 1u) << (2 * b + 1);
      }
      if (index >= n) return corrupt_data("chunk blob: occupancy set in an unused atlas tile");
      occupied[index] = count;
      total += count;
    }
  }
  if (total != h.decoded_points) {
    return corrupt_data("chunk blob: occupancy holds " + std::to_string(total) +
                        " pixels, header declares " + std::to_string(h.decoded_points));
  }
  for (std::uint32_t i = 0; i < n; ++i) {
    if (occupied[i] == 0) return corrupt_data("chunk blob: patch " + std::to_string(i) + " has no occupied pixel");
  }

  const SectionEntry& hs = section(SectionId::kHeight);
  codec::Image8 height8;
  codec::Image16 height16;
  if (h.height_bits == 16) {
    auto img = codec::j2k_decode16(hs.payload, aw, ah);
    if (!img) return img.status().with_context("chunk blob: height section");
    height16 = std::move(img).value();
  } else {
    RELIEF_ASSIGN_OR_RETURN(height8, decode_image8(hs, aw, ah, 1, "height"));
  }
  codec::Image8 colors, intensity;
  if (has_rgb) {
    RELIEF_ASSIGN_OR_RETURN(colors, decode_image8(section(SectionId::kColor), aw, ah, 3, "colour"));
  }
  if (has_i) {
    RELIEF_ASSIGN_OR_RETURN(intensity, decode_image8(section(SectionId::kIntensity), aw, ah, 1, "intensity"));
  }

  // Classification map: the classes of the occupied pixels in raster order,
  // spread onto an atlas plane so the reconstruction can look them up.
  std::vector<std::uint8_t> class_plane;
  const bool has_class = (h.flags & codec::kFlagClassMap) != 0;
  if (has_class) {
    LasAttributes map;
    RELIEF_RETURN_IF_ERROR(codec::decode_las_attribute(kLasClassification, section(SectionId::kClassMap).payload,
                                                       h.decoded_points, map)
                               .with_context("chunk blob: classification map"));
    class_plane.assign(occupancy.size(), 0);
    std::size_t next = 0;
    for (std::size_t a = 0; a < occupancy.size(); ++a) {
      if (occupancy[a]) class_plane[a] = map.classification[next++];  // total == decoded_points, checked above
    }
  }

  const std::vector<std::uint32_t> quota = lod_quota(occupied, keep_num, keep_den);
  std::uint64_t out_count = 0;
  for (std::uint32_t q : quota) out_count += q;
  out.positions.resize(out_count);
  if (has_rgb) out.colors.resize(out_count);
  if (has_i) out.intensities.resize(out_count);
  if (has_class) out.las.classification.resize(out_count);
  std::size_t k = 0;  // next output point

  const double i_step = static_cast<double>(h.intensity_max - h.intensity_min) / 255.0;
  codec::MapsView maps;
  maps.header = &h;
  maps.leaves = &leaves;
  maps.records = records.data();
  maps.occupancy = occupancy.data();
  if (h.height_bits == 16) {
    maps.height16 = height16.pixels.data();
  } else {
    maps.height8 = height8.pixels.data();
  }
  maps.atlas_width = aw;
  for (std::uint32_t p = 0; p < n; ++p) {
    if (quota[p] == 0) continue;
    codec::reconstruct_patch(maps, p, quota[p], occupied[p], [&](std::size_t a, const Vec3d& pos) {
      out.positions[k] = pos;
      if (has_rgb) out.colors[k] = {colors.pixels[a * 3], colors.pixels[a * 3 + 1], colors.pixels[a * 3 + 2]};
      if (has_i) out.intensities[k] = static_cast<float>(h.intensity_min + intensity.pixels[a] * i_step);
      if (has_class) out.las.classification[k] = class_plane[a];
      ++k;
    });
  }
  return out;
}

}  // namespace

namespace {

Result<PointCloud> decode_any(std::span<const std::uint8_t> blob, const DecodeOptions& options) {
  RELIEF_ASSIGN_OR_RETURN(codec::ParsedBlob parsed, codec::parse_blob(blob, options.verify_checksum));
  const codec::ChunkHeader& h = parsed.header;
  if (!codec::has_bounded_layer(h.version)) return decode_maps(parsed, 1, options.base_layer ? 1 : options.lod, options);
  if (options.base_layer) return decode_maps(parsed, 1, 1, options);
  const std::uint64_t n = h.input_points;
  if (n > options.max_points) {
    return limit_exceeded("chunk blob: " + std::to_string(n) + " points exceed the decoder limit of " +
                          std::to_string(options.max_points));
  }
  // A coarse level the base layer can supply (at least half the points it
  // wants) is read from the base layer alone.
  const std::uint64_t want = (n + options.lod - 1) / options.lod;
  if (options.lod > 1 && want > 0 && 2 * static_cast<std::uint64_t>(h.decoded_points) >= want) {
    return decode_maps(parsed, std::min<std::uint64_t>(want, h.decoded_points), h.decoded_points, options);
  }
  RELIEF_ASSIGN_OR_RETURN(PointCloud all, codec::decode_bounded_points(parsed, options.attributes));
  if (options.lod == 1) return all;
  // Every lod-th point in the layer's Morton order: spread over the chunk.
  std::vector<std::uint32_t> keep;
  keep.reserve((all.size() + options.lod - 1) / options.lod);
  for (std::size_t i = 0; i < all.size(); i += options.lod) keep.push_back(static_cast<std::uint32_t>(i));
  return all.gathered(keep);
}

}  // namespace

Result<PointCloud> decode_chunk(std::span<const std::uint8_t> blob, const DecodeOptions& options) {
  if (options.lod < 1) return invalid_argument("level of detail must be at least 1");
  RELIEF_ASSIGN_OR_RETURN(PointCloud out, decode_any(blob, options));
  keep_attributes(out, options.attributes);
  return out;
}

}  // namespace relief
