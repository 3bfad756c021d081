// Spatial queries and previews: decode only the chunks a box touches, at any
// level of detail, and stream the points inside the box in batches.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "relief/archive.h"
#include "relief/io.h"
#include "relief/polygon.h"
#include "relief/status.h"
#include "relief/types.h"

namespace relief {

// The largest level of detail the CLI and the Python bindings accept. A level
// of detail keeps ~1/L of each chunk's points (error diffusion over its
// patches), so a chunk with fewer than L/2 points gives none; far larger
// values would return nothing from most archives.
inline constexpr std::uint32_t kMaxQueryLod = 1024;

struct QueryOptions {
  // 1 = every point; L = a spatially uniform ~1/L subset (decodes faster).
  std::uint32_t lod = 1;
  unsigned threads = 0;  // decoder threads; 0 = all cores
  // A chunk whose checksum or decoding fails: false = the query fails with an
  // error naming the chunk and file; true = it is reported through
  // on_warning and skipped.
  bool skip_corrupt = false;
  std::function<void(const std::string&)> on_warning;
  // Filters on LAS attributes, combined (a point must pass every one set):
  // classification in `classes` (when non-empty), return number 1
  // (first_returns), return number == number of returns (last_returns). An
  // archive that does not carry the attribute a filter needs is
  // kInvalidArgument. With a filter, a level of detail above 1 decodes every
  // point (the base layer of coarse levels has no LAS attributes) and keeps
  // ~1/lod of the matching points.
  std::vector<std::uint8_t> classes;
  bool first_returns = false;
  bool last_returns = false;
  // At most this many points (0 = no limit; then `lod` must be 1): the
  // finest level of the pyramid (or the chunks themselves) whose nodes in the
  // box hold at most this many by the share of their bounds inside it (or
  // the level just finer, when that one's estimate is at most 4 times the
  // limit and the fitting level's below half of it), so the answer is a
  // spatially uniform subset; when even the top level holds more, its nodes
  // whole (up to 4 times the limit), or each at the level of detail that
  // leaves it a few times its share of the limit. When the rows read
  // then hold more than the limit in the box (counted exactly: those crossing
  // the box's faces or the polygon's edges, or read at a level of detail, are
  // decoded once beforehand), each keeps its share of the limit, evenly
  // spread over its points: exactly the limit comes back, thinned alike
  // everywhere in the box, the same points whatever the threads
  // (format-spec/archive.md §9).
  std::uint64_t max_points = 0;
  // The attributes each batch carries beyond x, y and z: the archive's
  // that this set names (default: all). Chunks skip decoding the others
  // (DecodeOptions::attributes), so a query for fewer runs faster; filters
  // still see the attributes they need.
  AttributeSet attributes;
  // Read a coarse level of detail from the archive's pyramid (archive.md §9)
  // where one fits: a level with at least as many points as the level of
  // detail asks for, thinned to it. false: always decode the chunks.
  bool use_pyramid = true;
  // Only the points inside this area of x and y (relief/polygon.h), besides
  // the box: chunks wholly outside it are not read, those wholly inside are
  // not tested point by point. Unlike the LAS filters it needs no attribute,
  // so a coarse level of detail still comes from the base layer or pyramid
  // (a max_points query counts the rows the area's bounds touch).
  std::shared_ptr<const Polygon2D> polygon;
};

struct QueryStats {
  std::uint64_t chunks_in_index = 0;  // chunks the spatial index returned
  std::uint64_t chunks_decoded = 0;
  std::uint64_t chunks_skipped = 0;   // corrupt, with skip_corrupt
  std::uint64_t blob_bytes_read = 0;
  std::uint64_t points = 0;           // points delivered
  double seconds = 0;
  int pyramid_level = 0;              // coarsest pyramid level read (0: chunks only)
  // The levels of detail the rows were read at (1: each row's every point;
  // L: a spatially uniform ~1/L of them, from its base layer or, with a LAS
  // filter, of the points that match). A max_points plan may give rows
  // different ones. 0 when no row was read.
  std::uint32_t lod_min = 0, lod_max = 0;
  // A max_points query thinned its rows evenly to the limit (their points
  // in the box were more than max_points).
  bool thinned = false;
};

// Batches carry the archive's attributes (ArchiveInfo: colours, intensity,
// and each LAS attribute, zero-filled for points of scans that lacked one
// and for coarse levels of detail read from a chunk's base layer) that
// QueryOptions::attributes names.
// Receives the query's points batch by batch (one or more chunks at a time, in
// content order: Archive::find_chunks). Returning an error stops the query with that error.
using PointSink = std::function<Status(const PointCloud& batch)>;

// kInvalidArgument naming `path` when `set` (not AttributeSet::all()) names
// an attribute the archive does not carry: a query refuses it, so a typo or
// a wrong archive does not pass for "no such values".
Status check_attributes(const ArchiveInfo& info, const AttributeSet& set, const std::string& path);

class ArchiveReader {
 public:
  // Opens an archive read-only (also while another process appends to it).
  static Result<std::unique_ptr<ArchiveReader>> open(const std::string& path);
  virtual ~ArchiveReader() = default;

  virtual const std::string& path() const = 0;
  virtual const ArchiveInfo& info() const = 0;

  // Streams every decoded point inside `box` (closed: min <= p <= max, each
  // face moved out by the rounding of decoded coordinates: 2^-46 of the
  // largest magnitude on its axis, at most 1/8 of the grid step) to
  // `sink`. Chunks come from the spatial index; only they are read and
  // decoded, in parallel, at most a few at a time (memory stays bounded by a
  // few chunks whatever the box). An empty or inverted box is kInvalidArgument.
  virtual Result<QueryStats> query(const Box3d& box, const QueryOptions& options, const PointSink& sink) = 0;
  // Every point of the archive.
  virtual Result<QueryStats> query_all(const QueryOptions& options, const PointSink& sink) = 0;
};

// The archive's description as one JSON object ("path" is `path` as given):
// what `relief info --json` prints and the Python bindings' Archive.info holds
// (README "relief info"). Always valid UTF-8: text from files that is not
// becomes U+FFFD.
std::string archive_info_json(const ArchiveInfo& info, const std::string& path);
// The archive's attribute names: "rgb", "intensity", then the LAS ones
// (kLasAttributeNames order), as info lists them.
std::vector<std::string> archive_attribute_names(const ArchiveInfo& info);
// The typed fields of the archive's Extra Bytes VLR (empty when it has none,
// or when it does not parse, which the reader that stored it had checked).
std::vector<ExtraBytesField> archive_extra_bytes_fields(const ArchiveInfo& info);

// ---- Statistics of the points (what lasinfo prints of a LAS file)

// The smallest and largest of some values, their count and sum. Non-finite
// values (a float extra field's NaN, its missing value) are counted apart.
struct ValueSummary {
  std::uint64_t count = 0;
  double min = 0, max = 0;
  // The sum, compensated (Neumaier): sum + sum_error is within about an ulp
  // of the exact sum whatever the order of the values, so the mean of an
  // archive and of its source agree (GPS times near 4e8 summed naively over
  // 700 k points drift by 1e-5). In long double, whose exponent reaches
  // 2^16383 on x86-64 and AArch64, so finite doubles (up to 1.8e308, as a
  // float64 extra bytes field may hold) never overflow the sum to inf or NaN.
  long double sum = 0, sum_error = 0;
  std::uint64_t non_finite = 0;
  void add(double v);
  double mean() const {
    return count > 0 ? static_cast<double>((sum + sum_error) / static_cast<long double>(count)) : 0.0;
  }
};

// Per attribute, for the points of an archive (or a box): each `has_*` says
// whether the archive carries it and the statistics were asked for.
struct ArchiveStats {
  std::uint64_t points = 0;
  ValueSummary x, y, z;
  bool has_colors = false;
  ValueSummary red, green, blue;  // 8-bit levels
  bool has_intensity = false;
  ValueSummary intensity;
  std::uint32_t las = 0;  // the LasAttributeBits summarised below
  std::array<std::uint64_t, 256> classification{};
  // Points with each flag set: synthetic, key-point, withheld, overlap
  // (class_flags), scan direction, edge of flight line (scan_flags).
  std::uint64_t synthetic = 0, key_point = 0, withheld = 0, overlap = 0, scan_direction = 0, edge_of_flight_line = 0;
  std::array<std::uint64_t, 4> scanner_channel{};
  std::array<std::uint64_t, 16> return_number{};
  std::array<std::uint64_t, 16> number_of_returns{};
  ValueSummary scan_angle;  // degrees
  ValueSummary user_data;
  ValueSummary point_source_id;
  std::uint64_t point_sources = 0;  // distinct point source IDs
  ValueSummary gps_time;
  ValueSummary nir;
  // The archive's scalar extra bytes fields, by name, after their scale and
  // offset (arrays and undocumented bytes are not summarised).
  std::vector<std::pair<std::string, ValueSummary>> extra;
};

// The codec's check of each chunk row against its blob (the counts it
// gives), for check_archive: relief check passes it.
ChunkRowCheck chunk_row_check();

// Decodes the points in `box` (every point when null) with the attributes
// `options.attributes` names (and the query's filters) and summarises them.
// Only what is asked for is decoded, so `--attributes classification` is a
// fraction of a full decode. kInvalidArgument for a level of detail above 1
// (coarse levels read from the base layer carry no LAS attributes but a
// classification, which would summarise as zeros) or max_points.
// `progress`, when set, hears the points of each batch as it is summarised.
Result<ArchiveStats> archive_stats(ArchiveReader& reader, const Box3d* box, const QueryOptions& options,
                                   const std::function<void(std::uint64_t points)>& progress = {});
// The same of a point file (any format open_point_reader reads), read whole
// with `options` (its `attributes` choose what is summarised): `relief stats
// in.laz` beside `relief stats out.relief` checks an archive against its
// source. The colour rule's sample is decoded once: at least 128 MiB of
// ReaderOptions::color_sample_memory.
Result<ArchiveStats> point_file_stats(const std::string& path, const ReaderOptions& options = {},
                                      const std::function<void(std::uint64_t points)>& progress = {});
// The statistics as one JSON object: what `relief stats --json` prints and
// Python's Archive.stats returns.
std::string archive_stats_json(const ArchiveStats& stats);

// ---- Where an archive's bytes go (what `relief info --sections` prints)

// One kind of chunk section (format-spec/chunk.md §3), summed over chunks.
struct SectionTotal {
  int id = 0;                 // the section id
  std::string name;           // "geometry", "rgb", "gps_time", "height map" ...
  bool maps = false;          // one of the paper's maps: the base layer of error-bounded chunks
  std::uint64_t bytes = 0;    // coded bytes
  std::uint64_t chunks = 0;   // chunks that hold it
};

struct ArchiveSections {
  std::uint64_t chunks = 0;        // full-resolution chunks (pyramid nodes apart)
  std::uint64_t input_points = 0;  // their input points
  std::uint64_t file_bytes = 0;    // the archive file (+ WAL) on disk
  std::uint64_t blob_bytes = 0;    // the chunks' blobs
  std::uint64_t framing_bytes = 0; // of which blob headers, section tables and checksums
  std::uint64_t pyramid_chunks = 0, pyramid_bytes = 0;  // the level-of-detail pyramid's nodes
  std::vector<SectionTotal> sections;  // by id, those some chunk holds
  // The rest of the file: SQLite's pages, indexes and free space, the
  // metadata, scan and source rows.
  std::uint64_t container_bytes() const {
    const std::uint64_t stored = blob_bytes + pyramid_bytes;
    return file_bytes > stored ? file_bytes - stored : 0;
  }
};

// Reads every chunk's header and section table (its first bytes,
// Archive::read_chunk_head: a few pages per chunk whatever the archive's
// size; the blobs' checksums are not verified, `relief check` does that)
// and sums the sections' sizes; the pyramid's nodes are counted from the
// archive's totals, not read. `progress`, when set, hears the input points
// of each chunk as it is read. A header or section table that is damaged
// or disagrees with the blob's size is kCorruptData naming the chunk.
Result<ArchiveSections> archive_sections(const Archive& archive,
                                         const std::function<void(std::uint64_t points)>& progress = {});
// As one JSON object (`relief info --sections --json` adds it as "sections").
std::string archive_sections_json(const ArchiveSections& sections);

// A box for "all heights" from a 2D box: z from -inf to +inf.
Box3d box_2d(double xmin, double ymin, double xmax, double ymax);

}  // namespace relief
