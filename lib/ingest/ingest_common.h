// Pieces shared by compress/append and streaming. Internal to ingest.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

#include "ingest/chunk_pipeline.h"
#include "ingest/prefetch.h"
#include "relief/archive.h"
#include "relief/ingest.h"
#include "relief/io.h"

namespace relief::ingest {

class Spool;

struct InputSet {
  std::vector<std::unique_ptr<PointReader>> readers;
  std::vector<ArchiveSource> sources;
  bool colors = false;     // every input has colours
  bool intensity = false;  // every input has intensity
  // The first input without colours (intensity), when some input has none.
  std::string colors_missing_from;
  std::string intensity_missing_from;
  std::uint64_t estimated_points = 0;
  std::uint64_t known_total = 0;
  bool all_counts_known = true;
  // LAS attributes: the union over the inputs (an input without one gets
  // zeros, ingest/las_columns.h), the widest source point format and highest
  // minor version, the extra bytes (every input with extra bytes must have
  // the same Extra Bytes VLR and size; extra_bytes_from names the first).
  std::uint32_t las_attributes = 0;
  int las_point_format = -1;
  int las_version_minor = -1;
  std::string extra_bytes_vlr;
  std::uint32_t extra_bytes_size = 0;
  std::string extra_bytes_from;
  // What the GPS times count (every LAS input with GPS time must agree);
  // gps_time_from names the first input that said.
  GpsTimeType las_gps_time_type = GpsTimeType::kUnknown;
  std::string gps_time_from;
  // Per reader: it has GPS times but says not what they count (a text
  // column): they take the set's kind, so under GPS week time they must lie
  // within a week (check_week_times).
  std::vector<bool> time_kind_unknown;
  std::string crs;  // WKT2 of the first input that has one
  std::string crs_from;  // that input's path
  // CRS decisions the user should hear of (inputs without a CRS among ones
  // with, a different CRS overridden by --assume-crs).
  std::vector<std::string> warnings;
  // An append to an archive of 8-bit colour levels with exact colour: the
  // 16-bit levels of the new inputs are stored split as 8-bit ones
  // (split_8bit_level), so the archive keeps its rule and every level of
  // either kind comes back (format-spec/archive.md §2.1 las_colors_8bit).
  bool split_wide_levels = false;
  // A compress whose whole input fits its memory reads every point once: the
  // order-free pass that fixes the grid reads through `readers` (after the
  // first batch, which derive_build_parameters read) and keeps the batches
  // here, as read, in order; run_ingest then stages them instead of reading
  // the inputs a second time (the readers are at their ends).
  std::vector<ReadBatch> read_ahead;
  // Otherwise the same pass may have kept the decoded points of LAZ and text
  // inputs in a spool (spool.h, IngestOptions::spool): their readers are then
  // the spool's, which this keeps alive.
  std::shared_ptr<Spool> spool;
};

// With InputSet::split_wide_levels: the batch's 16-bit levels, as `reader`
// (which read them) narrowed them, become split 8-bit levels. Nothing for a
// reader of 8-bit levels or one without colour low bytes.
void split_wide_levels(PointCloud& batch, const PointReader& reader);

// Opens every input up front, so a missing or unsupported file fails before
// anything is created. Inputs whose CRSs differ are refused (kInvalidArgument
// naming both) unless `assume_crs`, when the first one's is taken for all
// (with a warning). `crs` (IngestOptions::crs), when set, is every input's
// CRS: those naming another are told of in the warnings.
Result<InputSet> open_inputs(const std::vector<std::string>& inputs, const ReaderOptions& reader_options,
                             bool assume_crs = false, const std::string& crs = {});
// The reader options of an ingest's reads: options.reader, allowed to hold
// the colour rule's sample (ReaderOptions::color_sample_memory) in an eighth
// of the memory budget, so a LAZ input's first 2^20 points are not
// decompressed twice, and decompressing LAZ on the ingest's threads.
ReaderOptions ingest_reader_options(const IngestOptions& options);
// Whether two CRSs are the same (PROJ equivalence; text equality for a CRS
// PROJ cannot read).
bool same_crs(const std::string& a, const std::string& b);
// Drops attributes the archive does not carry; gives the batch exactly the
// set's LAS attributes (zero-filled where it has none).
void conform_attributes(PointCloud& batch, bool colors, bool intensity);
void conform_attributes(PointCloud& batch, const InputSet& in);
// The ScanAttributes of the inputs (after reading: the colour-level rule of
// LAS inputs is known once they have been read).
ScanAttributes scan_attributes(const InputSet& in);

// A LAS-style colour source of a scan: its path, whether it stores 8-bit
// levels in its 16-bit fields (PointStreamInfo::las_colors_8bit) and whether
// every level is 0 (las_colors_all_zero: unchanged by either rule, so never
// named in a warning).
struct ColourSource {
  std::string path;
  bool levels_8bit = false;
  bool all_zero = false;
};
// Warnings for the levels the archive's colour rule (format-spec/archive.md
// §2.1 las_colors_8bit: 8-bit only while every source is) gives back scaled
// to 16 bits (v * 257): a scan's 8-bit sources beside 16-bit ones or in an
// archive of 16-bit levels, and an archive's earlier 8-bit levels when 16-bit
// ones join them. `archive_rgb`: the archive already holds such colours,
// `archive_8bit` as 8-bit levels.
std::vector<std::string> colour_rule_warnings(bool archive_rgb, bool archive_8bit,
                                              const std::vector<ColourSource>& sources);
// The scan's sources with LAS-style colours (colour low bytes), from its readers.
std::vector<ColourSource> colour_sources(const InputSet& in);
// The scan's rule (ScanAttributes::las_colors_8bit): some source has such
// colours, and every one stores 8-bit levels.
bool all_8bit_levels(const std::vector<ColourSource>& sources);
// kInvalidArgument naming `source`, the point's index (first_index + i) and the
// value when a coordinate of `batch` exceeds `limit` in magnitude
// (max_coordinate_magnitude): such points would overflow chunk keys or lose
// the cell's precision.
Status check_coordinates(const PointCloud& batch, double limit, const std::string& source,
                         std::uint64_t first_index);
// kIoError naming the archive and its directory when that directory does not
// exist (or is not a directory), before anything is created.
Status check_output_directory(const std::string& archive_path);
// check_sample_density looks at no more than this many of the first points:
// the mean density of a run of points is what matters, and it keeps the check
// to milliseconds before the archive is created.
inline constexpr std::size_t kDensitySamplePoints = std::size_t{1} << 17;
// kLimitExceeded when `sample` (the first points of `source`) puts on average
// fewer than 2 points in a cell or 16 in a chunk: a cell or chunk edge far too
// small for the data, which would make an archive far larger than its input.
// Samples under 10,000 points pass; only the first kDensitySamplePoints count.
// edge_capped_by_step > 0: the automatic chunk edge was halved to 2^21 grid
// steps of that size, so the hint names the tolerance, not --chunk-edge.
Status check_sample_density(const PointCloud& sample, const ArchiveGrid& grid, double cell_size,
                            const std::string& source, double edge_capped_by_step = 0);
// "colours and intensity", "colours, no intensity", ... for mismatch messages.
std::string attribute_list(bool colors, bool intensity);

struct ChunkKeyHash {
  std::size_t operator()(const ChunkKey& k) const {
    std::uint64_t h = static_cast<std::uint64_t>(k.ix) * 0x9e3779b97f4a7c15ULL;
    h ^= static_cast<std::uint64_t>(k.iy) * 0xc2b2ae3d27d4eb4fULL + (h << 6) + (h >> 2);
    h ^= static_cast<std::uint64_t>(k.iz) * 0x165667b19e3779f9ULL + (h << 6) + (h >> 2);
    return static_cast<std::size_t>(h);
  }
};

// Chunk ids of a cloud's points, assigned batch by batch as the points
// arrive (so keying overlaps reading), then turned into encode tasks by a
// counting sort. Reused across slices; tasks point into `order`, so it must
// outlive them.
struct Grouping {
  std::vector<ChunkKey> keys;        // distinct keys, indexed by chunk id
  std::vector<std::uint32_t> ids;    // chunk id of every point added so far
  std::vector<std::uint32_t> order;  // point indices grouped by chunk id
  std::unordered_map<ChunkKey, std::uint32_t, ChunkKeyHash> lookup;
  std::vector<ChunkKey> batch_keys;

  void clear();
  // Appends the chunk ids of points[0..n) to `ids`.
  void add(const Vec3d* points, std::size_t n, const ArchiveGrid& grid);
  // The same for points whose chunk keys are already known.
  void add_keys(const ChunkKey* point_keys, std::size_t n);
  // Appends `count` points of chunk `key`.
  void add_run(const ChunkKey& key, std::size_t count);
  // Fills `order` with the point indices grouped by chunk id (a counting
  // sort): chunk k's points are order[start[k] .. start[k + 1]). Returns the
  // chunk ids in key order (deterministic archives).
  std::vector<std::uint32_t> sort_by_key(std::vector<std::uint64_t>& start);
};

// Groups the points of `cloud` (whose ids `g` holds, one per point) by chunk
// key into encode tasks that index into `cloud`, in key order. A chunk of
// more than `part_points` points becomes several blobs of one voxel: cut by
// point count, or with `split_grid` (the error-bounded mode) split into
// octants of its cube, recursively, so the blobs depend only on the points.
// `cloud` and `g` must outlive the tasks.
std::vector<ChunkTask> make_tasks(const PointCloud& cloud, std::uint64_t part_points, Grouping& g,
                                  const ArchiveGrid* split_grid = nullptr);
// The deepest octant split (a sub-cube 2^10 times smaller than its chunk
// holds only points too close to tell apart at any useful tolerance).
inline constexpr int kMaxSplitDepth = 10;

// The octants of a sub-cube (corner `origin`, edge 2 * half), as make_tasks
// splits chunks and bucket_split.cpp routes points to the same parts without
// loading them: one definition, so the two agree bit for bit. A point on a
// mid-plane belongs to the upper octant.
struct Octants {
  Vec3d origin;
  double half = 0;
  Vec3d mid() const { return {origin.x + half, origin.y + half, origin.z + half}; }
  int of(const Vec3d& p, const Vec3d& m) const {
    return (p.x >= m.x ? 1 : 0) | (p.y >= m.y ? 2 : 0) | (p.z >= m.z ? 4 : 0);
  }
  Vec3d origin_of(int o, const Vec3d& m) const {
    return {(o & 1) ? m.x : origin.x, (o & 2) ? m.y : origin.y, (o & 4) ? m.z : origin.z};
  }
  // Octant o's integer position one level down from `sub`.
  static void sub_of(const std::uint32_t sub[3], int o, std::uint32_t out[3]) {
    for (int a = 0; a < 3; ++a) out[a] = 2 * sub[a] + static_cast<std::uint32_t>((o >> a) & 1);
  }
};

// The error-bounded mode's split size: `split_points`, or fewer for wide
// points, so that one chunk's LAS attributes (las_record_bytes of the
// archive's set) stay within kMaxChunkAttributeBytes, keeping a chunk's
// encoder near its share of the memory budget. Every LAS point format with up
// to 7 extra bytes keeps the 2^20-point split; a PLY with 200 bytes of
// properties splits at 167,772. The rule depends on the archive's attributes
// alone, never on --memory, so blobs stay deterministic; at least
// kMinSplitPoints.
inline constexpr std::uint64_t kMaxChunkAttributeBytes = std::uint64_t{1} << 25;
inline constexpr std::uint64_t kMinSplitPoints = 4096;
std::uint64_t bounded_split_points(std::uint64_t split_points, std::uint32_t las_attributes,
                                   std::uint32_t extra_bytes_size);

// clear + add + make_tasks for a whole cloud.
std::vector<ChunkTask> group_into_tasks(const PointCloud& cloud, const ArchiveGrid& grid, std::uint64_t part_points,
                                        Grouping& g, bool split_spatially = false);

// The error-bounded grid for this ingest: the options' tolerance, or the
// automatic one (ingest.h, IngestOptions::tolerance) from the inputs.
ErrorBound resolve_error_bound(const IngestOptions& options, const InputSet& in);
// Moves every point onto the grid (origin + k * step). Done as points are
// read, so chunk keys, bucket files and encoders all see the final positions.
Status snap_to_grid(PointCloud& batch, const ErrorBound& bound, const std::string& source = "points",
                    std::uint64_t first_index = 0);
// The density-derived cell size (suggest_cell_size) of all the inputs' points
// and the bounded mode's base-layer cell, estimated from a sample chosen by a
// hash of each position: one extra read of the inputs, and a result that does
// not depend on the points' order; density_cell is 0 when the inputs hold
// no point.
// With `bounds`, also adds every input point to it.
struct OrderFreeCells {
  double density_cell = 0;  // suggest_cell_size of all the points
  double base_cell = 0;     // the bounded mode's base-layer cell
  std::uint64_t points = 0; // points read
};
// With `extra`, also what a shard plan needs from the same pass (below).
struct OrderFreeSample {
  std::vector<Vec3d> positions;  // the hash-chosen sample, in hash order
  std::uint64_t points = 0;      // points read
  // Of every point's intensity (widen_intensity_range): the scan's range.
  float intensity_lo = std::numeric_limits<float>::infinity();
  float intensity_hi = -std::numeric_limits<float>::infinity();
  // Inputs read, and those with LAS-style colours in input order, with the
  // colour rule their readers decided once they were read (a LAS reader
  // decides it on its first points).
  std::size_t inputs = 0;
  std::vector<ColourSource> colour_sources;
};
// With `keep_from`, the pass reads `keep_from->readers` themselves from the
// point after `first` (whose points it counts first) and keeps every batch in
// keep_from->read_ahead (InputSet::read_ahead); else it opens the inputs anew
// (positions only). With `spool` too, only the inputs the spool wants are
// read through `keep_from->readers` (input 0 after `first`), their batches
// appended to the spool (Spool::append, then Spool::finish) and not kept;
// the others are opened anew. With `run`, the pass reports its progress
// (phase "scanning") and stops ("interrupted") when run->cancel is set.
// `read_batch`: points per read without a spool (the budget's, so that the
// batch read ahead and the one hashed stay within it; the sample does not
// depend on it).
Result<OrderFreeCells> order_free_cells(const std::vector<std::string>& inputs,
                                        const ReaderOptions& reader_options, int map_resolution,
                                        Box3d* bounds = nullptr, OrderFreeSample* extra = nullptr,
                                        InputSet* keep_from = nullptr, const PointCloud* first = nullptr,
                                        Spool* spool = nullptr, const IngestOptions* run = nullptr,
                                        std::size_t read_batch = std::size_t{1} << 20);

// ---- The steps of a new archive's build, shared by compress_files and the
// sharded build (lib/shard), so both make the same decisions.

// The option checks made before anything is read.
Status validate_build_options(const IngestOptions& options);
// Every global parameter of a new archive, derived from all the inputs: the
// codec parameters (error bound, base cell; no intensity range yet) and the
// chunk grid (edge, origin). Reads the first points of input 0 into `first`
// (they are then ingested like every batch) and checks them. With `sample`,
// the order-free pass always runs and fills it (in the bounded mode with a
// given cell size the pass is otherwise skipped; the result is the same).
struct BuildParameters {
  EncodeParams params;
  ArchiveGrid grid;
};
// `tmp_parent`: where a spool of the pass may go (IngestOptions::spool;
// empty: no spool).
Result<BuildParameters> derive_build_parameters(const std::vector<std::string>& inputs, const IngestOptions& options,
                                                InputSet& in, PointCloud& first, OrderFreeSample* sample = nullptr,
                                                const std::string& tmp_parent = {});
// What every point goes through between its reader and its chunk key: the
// coordinate limit (naming `source` and the point's index first_index + i),
// the archive's attribute set, the error-bounded grid.
Status stage_points(PointCloud& batch, double coordinate_limit, const std::string& source, std::uint64_t first_index,
                    bool colors, bool intensity, const EncodeParams& params);
// Widens [lo, hi] to the batch's intensities (NaN ignored).
void widen_intensity_range(const PointCloud& batch, float& lo, float& hi);
// The parameters every chunk of a scan is encoded with: intensity quantised
// over the scan's range, so the step does not depend on how points fall into
// chunks.
EncodeParams with_intensity_range(const EncodeParams& params, bool intensity, float lo, float hi);
// A scan's metadata rows (begin with the sources, finish with the attributes).
Result<std::int64_t> begin_scan(Archive& archive, const std::vector<ArchiveSource>& sources, bool colors,
                                bool intensity, const std::string& crs);
Status finish_scan(Archive& archive, std::int64_t scan_id, bool colors, bool intensity, const std::string& crs);

// Reads every input into the archive as one scan (see compress.cpp).
Result<IngestResult> run_ingest(Archive& archive, const ArchiveGrid& grid, const EncodeParams& params, InputSet& in,
                                PointCloud pending, const IngestOptions& options, const std::string& tmp_parent);

void remove_archive_files(const std::string& path);
std::string default_tmp_parent(const std::string& archive_path, const IngestOptions& options);
// The same for a directory given as such (empty: beside the archive).
std::string default_tmp_parent(const std::string& archive_path, const std::string& tmp_dir);

// Throttles progress callbacks to a few per second.
class Progress {
 public:
  Progress(std::function<void(const IngestProgress&)> fn, std::uint64_t total)
      : fn_(std::move(fn)), total_(total), start_(std::chrono::steady_clock::now()) {}

  void update(const char* phase, std::uint64_t points, std::uint64_t chunks, std::uint64_t bytes,
              std::uint64_t encoded = 0) {
    if (!fn_) return;
    const auto now = std::chrono::steady_clock::now();
    if (now - last_ < std::chrono::milliseconds(kIntervalMs)) return;
    last_ = now;
    emit(phase, points, chunks, bytes, encoded, now);
  }
  void finish(const char* phase, std::uint64_t points, std::uint64_t chunks, std::uint64_t bytes,
              std::uint64_t encoded = 0) {
    if (fn_) emit(phase, points, chunks, bytes, encoded, std::chrono::steady_clock::now());
  }

 private:
  static constexpr int kIntervalMs = 500;
  void emit(const char* phase, std::uint64_t points, std::uint64_t chunks, std::uint64_t bytes, std::uint64_t encoded,
            std::chrono::steady_clock::time_point now) {
    IngestProgress p;
    p.phase = phase;
    p.points_read = points;
    p.points_total = total_;
    p.points_encoded = encoded;
    p.chunks_written = chunks;
    p.bytes_written = bytes;
    p.seconds = std::chrono::duration<double>(now - start_).count();
    fn_(p);
  }
  std::function<void(const IngestProgress&)> fn_;
  std::uint64_t total_;
  std::chrono::steady_clock::time_point start_;
  std::chrono::steady_clock::time_point last_{};
};

// The result of a finished scan, reported to `progress` as done.
// Builds the scan's pyramid when options.pyramid asks for it (kAuto: a scan
// of at least kPyramidAutoMinPoints points); levels 0 when none was built.
Result<PyramidResult> build_scan_pyramid(Archive& archive, std::int64_t scan_id, std::uint64_t points,
                                         const IngestOptions& options, const std::string& tmp_parent,
                                         Progress& progress);
IngestResult scan_result(const PipelineTotals& totals, std::uint64_t points_read,
                         std::chrono::steady_clock::time_point start, double cell_size, double chunk_edge,
                         std::int64_t scan_id, Progress& progress);

}  // namespace relief::ingest
