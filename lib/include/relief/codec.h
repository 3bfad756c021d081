// The chunk codec: one compression chunk of points in, one self-describing blob
// out, and back (Golla & Klein 2015, section III). The blob layout is specified
// byte for byte in format-spec/chunk.md.
#pragma once

#include <cstdint>
#include <optional>
#include <utility>
#include <span>
#include <string>
#include <vector>

#include "relief/status.h"
#include "relief/types.h"

namespace relief {

// On-disk ids: never renumber.
enum class Decomposition : std::uint8_t { kVoxelGrid = 0, kOctree = 1 };
enum class ImageCodec : std::uint8_t { kJpeg = 1, kJpeg2000 = 2 };
// How unoccupied map pixels are filled before image coding (encoder only; a
// decoder never looks at them). kBlockProjection: heights and intensity get
// push-pull, then each partly empty 8x8 block keeps only its lowest DCT
// frequencies where no point constrains it; colour gets the box filter.
// kPushPull: push-pull alone. kBoxFilter: the paper's three passes of a 5x5
// box filter on every map.
enum class FillMethod : std::uint8_t { kBlockProjection = 0, kPushPull = 1, kBoxFilter = 2 };

// Highest chunk format version this build writes and reads. Version 1: the
// paper's maps alone (resampling). Version 2: the maps as a base layer plus an
// error-bounded layer that gives back every point (format-spec/chunk.md).
// Version 3: version 2 plus the LAS attributes (PointCloud::las) of every
// point; the encoder writes it only for clouds that carry some. Version 4:
// version 1 plus a map of the majority classification per pixel, written by
// the resampling codec for clouds that carry a classification (no other LAS
// attribute survives resampling; the base layer of a version-3 blob has the
// same map). Version 5: the error-bounded layer as in versions 2 and 3 (the
// version-3 header, its attribute set possibly empty) with the geometry coded
// by codec 7 (single-child octree coding). Version 6: version 5 with GPS
// times coded in time order (the points' order by time, then the times as
// steps). Version 7: version 6 with the geometry coded by codec 8 (codec 7's
// octree with every bit's probability mixed from two context models).
// Version 8: version 7 where a blob with GPS times may code its geometry in
// time order instead (codec 9: each point's cell predicted from the previous
// points of the scan, the times then without ranks). Version 9: version 8
// where point colours in cell order are predicted from the previous 32
// points, weighted by distance (codec 10). Version 10: version 9 with the
// octree's one-cell subtrees coded as chains (codec 11: a flag, then each
// level's child index without mixing). Version 11: version 10 with the LAS
// attributes' bytes voted (one decision "the byte this tree has coded most"
// before the byte's tree). Version 12: version 11 with an intensity
// tolerance (header bytes 164-165): 16-bit intensities quantised so each
// comes back within it. Version 13: version 12 with the octree coded by codec
// 12 (codec 11 plus a third model per decision, by the minus neighbours'
// children on the shared faces, and an adaptive probability map); the bounded
// encoder writes it for every cloud. Version 14: version 13 whose geometry
// may be in scan order without GPS times, or with times that step back, the
// points then in the order the encoder was given them (ErrorBound::keep_order);
// the encoder writes it for those blobs alone, 13 for every other. Version
// 15: version 14 whose scan angles in time order are coded with the model set
// of what followed the same values before (a scanner's angular sampling
// repeats line after line), and whose NIR values are coded in the context of
// the green level's change at the same points (the bands move together); the
// encoder writes it where those two sections are smaller so. Version 16:
// version 15 whose octree geometry is codec 13, each single child's index
// bits (and each chain's) also told where a plane fitted to the nearby
// cells the decoder knows crosses the node; the encoder writes it for every
// blob whose geometry is the octree, its LAS sections then with version 15's
// codings (13, 14 and 15 stay for geometry in scan order). Version 17:
// version 16 whose octree geometry is codec 14, those index bits also told
// which half of the node lies nearer the known points around it; the
// encoder writes it where it wrote 16 (16 stays readable).
inline constexpr std::uint16_t kChunkFormatVersion = 17;
// What the error-bounded encoder writes for every other blob.
inline constexpr std::uint16_t kOrderFreeFormatVersion = 13;
// Geometry in the given order without GPS times, or with times that step back.
inline constexpr std::uint16_t kKeptOrderFormatVersion = 14;
// Scan angles in time order by their successors, NIR against the colours
// (format-spec/chunk.md §11.7, §11.7.2).
inline constexpr std::uint16_t kLasCodingFormatVersion = 15;
// Octree geometry with plane classes (format-spec/chunk.md §11.3.6).
inline constexpr std::uint16_t kOctreePlanesFormatVersion = 16;
// Octree geometry with plane and near classes (format-spec/chunk.md §11.3.7).
inline constexpr std::uint16_t kOctreeNearestFormatVersion = 17;

// The error-bounded mode: every input point comes back as exactly one point,
// each coordinate within step / 2 of the input. Coordinates are snapped to the
// grid origin + k * step (k integer, per axis), so with origin = a LAS file's
// offset and step = its scale the LAS integers come back exactly.
struct ErrorBound {
  Vec3d step{0.001, 0.001, 0.001};  // per axis, finite and > 0 (= 2 x tolerance)
  Vec3d origin{0, 0, 0};            // finite
  // Every colour channel within this many levels (0 = exact), 0..127.
  int color_tolerance = 0;
  // Every 16-bit integer intensity within this many levels (0 = exact),
  // 0..32767. Intensities that are not all whole numbers 0..65535 in a
  // chunk (a PLY's float values) stay exact whatever it says.
  int intensity_tolerance = 0;
  // Keep the order the points were given in: the decoder returns them in
  // that order, and the geometry is coded in it, as scan order (chunk format
  // 14 when the points carry no GPS time or their times step back in that
  // order; format-spec/chunk.md §11.3.3).
  // Smaller than the order-free octree on points in acquisition order
  // without GPS times (an airborne survey's PLY, an organized depth image),
  // larger on others; the blobs then depend on the input order.
  bool keep_order = false;
  // Code octree geometry with codec 12 (chunk format 13, or 15) instead of
  // codec 13's plane classes (format 16, format-spec/chunk.md §11.3.6):
  // about twice as fast to encode and decode, ~2 % more geometry bytes.
  // Blobs whose geometry is in scan order are the same either way.
  bool fast_geometry = false;
};
inline constexpr int kMaxIntensityTolerance = 32767;

struct EncodeParams {
  Decomposition decomposition = Decomposition::kVoxelGrid;
  // Voxel-grid cell edge, or the smallest octree leaf edge, in coordinate units.
  // 0 = derive from the point density (see suggest_cell_size).
  double cell_size = 0;
  // Octree: split a node while it holds more than this many points (n_l).
  std::uint32_t octree_max_points = 1024;
  // Octree: also split while the supplied normals of a node do not fit in a
  // cone of this half-angle (degrees). 0 disables; ignored without normals.
  double normal_cone_degrees = 0;
  // Map resolution r (r x r pixels per patch): a multiple of 8, 8..64.
  int map_resolution = 16;
  ImageCodec image_codec = ImageCodec::kJpeg;
  int height_quality = 75;     // 1..100
  int color_quality = 70;      // 1..100
  int intensity_quality = 70;  // 1..100
  // 8, or 16 (JPEG 2000 only): bits per height sample.
  int height_bits = 8;
  FillMethod fill = FillMethod::kBlockProjection;
  // Intensity is quantised to 8 bits over this range (an archive passes its
  // global range so every chunk uses the same step). Unset: the chunk's own range.
  std::optional<std::pair<float, float>> intensity_range;
  // The chunk cube the patch grid is aligned to (e.g. the archive voxel).
  // Unset: the bounding box of the points, grown to a cube.
  std::optional<Vec3d> grid_origin;
  double grid_edge = 0;  // with grid_origin: edge of the cube; must contain every point
  // Set: error-bounded mode (chunk format 2): every point back within the
  // bound, the maps above (with cell_size) become the coarse base layer that
  // levels of detail decode. Unset: the paper's resampling codec (format 1,
  // or 4 when the cloud carries a LAS classification).
  std::optional<ErrorBound> bound;
};

// Largest map atlas the encoder writes (tiles x r squared), so that a blob's
// images stay within a few hundred MB to decode.
inline constexpr std::uint64_t kMaxAtlasPixels = std::uint64_t{1} << 26;

// The coarsest level of detail every error-bounded blob's base layer serves
// alone (format-spec/chunk.md §11.6: 2 x decoded_points >= ceil(input_points /
// L)), what previews and coarse queries ask for. The encoder makes a chunk's
// maps finer (half the cell, up to kMaxBaseRefinements times) until they do.
inline constexpr std::uint32_t kBaseLayerLod = 16;
inline constexpr int kMaxBaseRefinements = 3;

struct DecodeOptions {
  // Level of detail: 1 = every point; L = a spatially uniform ~1/L subset
  // (the quota is spread over the patches by error diffusion, so small patches
  // take turns and a chunk with fewer than L/2 decoded points gives none).
  // For an error-bounded blob, a level the base layer can supply (at least
  // half the wanted points) decodes the base layer alone (fast); a finer one
  // decodes every point and keeps every L-th in Morton order. Points decoded
  // from maps carry no LAS attribute but a classification (the majority of
  // their pixel) when the blob has a classification map.
  std::uint32_t lod = 1;
  // Every point of the map layer and nothing else, whatever `lod`: an
  // error-bounded blob's base layer (one point per occupied pixel), a
  // resampling blob's whole content. A level-of-detail pyramid is built from it.
  bool base_layer = false;
  // The attributes to return beyond x, y and z (those the blob holds). An
  // error-bounded blob's full decode skips the sections of the others, and
  // of what only they depend on (GPS times, return numbers and colours are
  // decoded when a wanted section is coded against them), so asking for
  // fewer is faster; other paths decode everything and drop the rest.
  AttributeSet attributes;
  // Verify the blob's CRC-32 first (turn off only to exercise the inner decoders).
  bool verify_checksum = true;
  // Refuse blobs that claim more decoded points than this (bounds memory).
  std::uint64_t max_points = std::uint64_t{1} << 26;
  // Refuse blobs whose map atlas has more pixels than this before decoding
  // any image (a header can claim up to 65500 x 65500; the encoder never
  // writes more than kMaxAtlasPixels).
  std::uint64_t max_atlas_pixels = kMaxAtlasPixels;
};

struct ChunkSectionInfo {
  std::uint8_t id = 0;
  std::uint8_t codec = 0;
  std::uint32_t raw_size = 0;
  std::uint32_t coded_size = 0;
};

struct ChunkInfo {
  std::uint16_t format_version = 0;
  Decomposition decomposition = Decomposition::kVoxelGrid;
  ImageCodec image_codec = ImageCodec::kJpeg;
  bool has_colors = false;
  bool has_intensity = false;
  int map_resolution = 0;
  int height_bits = 0;
  int tree_depth = 0;
  std::uint32_t input_points = 0;    // points given to the encoder
  std::uint32_t decoded_points = 0;  // points a full decode returns (occupied pixels; every point when bounded)
  // Error-bounded blobs (format 2).
  bool error_bounded = false;
  std::uint32_t base_points = 0;     // points of the base layer (occupied pixels)
  Vec3d quant_step;                  // coordinate step; the error bound is half of it
  int color_tolerance = 0;
  // The LasAttributeBits a full decode returns (formats 3, 5 and 6: those of the
  // points; format 4: classification, from the map), and extra bytes per point.
  std::uint32_t las_attributes = 0;
  std::uint32_t extra_bytes_size = 0;
  std::uint32_t patch_count = 0;
  std::uint32_t atlas_width = 0;   // pixels
  std::uint32_t atlas_height = 0;  // pixels
  Vec3d grid_origin;
  double grid_edge = 0;
  std::size_t blob_size = 0;
  std::vector<ChunkSectionInfo> sections;
};

// What a full decode of a blob will return, known to the encoder.
struct EncodeStats {
  std::uint32_t decoded_points = 0;
  // Exact bounds of every point any level of detail decodes (for an
  // error-bounded blob, its points and its base layer's), and of decode_chunk's
  // points (lod 1) alone.
  Box3d decoded_bounds;
  Box3d point_bounds;
  // An intensity tolerance was asked for, but the intensities are not all
  // whole numbers 0..65535: they were kept exact.
  bool intensities_kept_exact = false;
};

// Checks the parameters alone (ranges, combinations such as 16-bit heights
// without JPEG 2000) -> kInvalidArgument naming the problem. encode_chunk and
// the ingest entry points call it before any work.
Status validate_encode_params(const EncodeParams& params);

// Encodes one chunk. `normals`, when not empty, holds one unit normal per point
// and enables the octree normal-cone criterion. With `stats`, also reports the
// decoded count and exact bounds (it decodes only the height map to do so).
Result<std::vector<std::uint8_t>> encode_chunk(const PointCloud& cloud, const EncodeParams& params,
                                               std::span<const Vec3d> normals = {}, EncodeStats* stats = nullptr);

// Encodes the points cloud[subset[i]] as one chunk, without copying them out
// first (an ingest groups a large cloud by chunk and encodes index lists).
// params.cell_size must be set.
Result<std::vector<std::uint8_t>> encode_chunk_subset(const PointCloud& cloud, std::span<const std::uint32_t> subset,
                                                      const EncodeParams& params, EncodeStats* stats = nullptr);

// Decodes a blob made by encode_chunk. Never reads out of bounds, never trusts
// a size field for allocation beyond DecodeOptions::max_points.
Result<PointCloud> decode_chunk(std::span<const std::uint8_t> blob, const DecodeOptions& options = {});

// Reads and validates the header and section table only.
Result<ChunkInfo> inspect_chunk(std::span<const std::uint8_t> blob);
// Empty when a blob holds the counts its archive row gives (input and decoded
// points), else what differs (or why the blob does not parse): for
// check_archive's ChunkRowCheck (relief/query.h chunk_row_check).
std::string chunk_counts_problem(std::uint64_t input_points, std::uint64_t decoded_points,
                                 std::span<const std::uint8_t> blob);
// The same from the first bytes of a blob of `blob_size` bytes: its first
// kChunkHeadBytes (or all of it, when shorter) hold the header and section
// table. Nothing after them is read, so the checksum is not verified.
inline constexpr std::size_t kChunkHeadBytes = 512;
Result<ChunkInfo> inspect_chunk_head(std::span<const std::uint8_t> head, std::uint64_t blob_size);
// What a section id (format-spec/chunk.md §3, ChunkSectionInfo::id) holds,
// for people: "geometry", "rgb", "intensity", a LAS attribute's name
// ("gps_time" ...), or one of the paper's maps ("occupancy map", "height
// map" ...; chunk_section_is_map). "section N" for an id the format lacks.
std::string chunk_section_label(int id);
bool chunk_section_is_map(int id);

// A cell edge from the point density: the median nearest-neighbour spacing of a
// sample of the points times map_resolution, so one map pixel ~ one point.
double suggest_cell_size(const PointCloud& cloud, int map_resolution);
// The cell edge at which occupied cells hold about `points_per_cell` points of
// `cloud` (suggest_cell_size is this with r^2). A sample holding a fraction f
// of a cloud's points estimates the cloud's cell for n points per cell with
// n * f here.
double cell_size_for_density(const PointCloud& cloud, double points_per_cell);

const char* decomposition_name(Decomposition d);
const char* image_codec_name(ImageCodec c);

// Text form of the parameters an archive records (format-spec/archive.md
// §2.1.1), one line, no spaces. kFull names every key, e.g.
// "decomposition=voxel;cell=0.25;max_points=1024;cone=0;r=16;image=jpeg;q=75;
//  color_q=70;intensity_q=70;height_bits=8;fill=project" (how it is shown);
// kCompact, what archives store, leaves out the keys at their text defaults
// ("cell=0.25"; "cell" and, in the error-bounded mode, "step" are always
// there). The grid cube is not included (it is per chunk). Doubles
// round-trip exactly.
enum class ParamsText { kFull, kCompact };
std::string encode_params_to_string(const EncodeParams& params, ParamsText form = ParamsText::kFull);
// Parses either form (a missing key takes its text default); unknown keys or
// malformed values -> kFormatError naming the key.
Result<EncodeParams> encode_params_from_string(const std::string& text);
// The kFull form of a stored text, for showing it (the text itself when it
// does not parse).
std::string full_params_text(const std::string& text);

}  // namespace relief
