// A sharded build: one archive made by many tasks on many machines, with the
// same chunk blobs as a one-box compress_files of the same inputs.
//
//   stage 0  plan_shards        every global decision, from one pass over all
//                               inputs, into a small plan file
//   stage 1  partition_input    one task per input file: read, snap, and write
//                               the points partitioned by chunk-key range
//   stage 2  encode_shard       one task per key range: every input's
//                               partition of the range -> a shard archive
//   merge    merge_archives     the shards -> one archive
//
// Stage 1 and 2 tasks write only files with deterministic names, each to a
// temporary name then renamed, so a killed or retried task leaves no partial
// output and a re-run writes the same bytes (shard archives: the same rows).
// The files are described in format-spec/shard.md.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "relief/archive.h"
#include "relief/ingest.h"
#include "relief/status.h"

namespace relief {

// First line of a plan file: "relief-shard-plan <version>". Version 2 adds
// the LAS attributes; a plan without them is written as version 1 (the same
// bytes as before, so earlier plans and their partition files stay valid).
inline constexpr int kShardPlanVersion = 3;
// Partition files (".rpart") and their per-input manifests (".done") this
// build writes; it reads versions 1 (no LAS attributes) and 2.
inline constexpr int kPartitionFormatVersion = 2;
// Key ranges of a plan: a stage-1 task keeps one file open per range.
inline constexpr std::uint32_t kMaxShardRanges = 512;
// Automatic number of ranges: about this many points each (stage 2 holds a
// range in memory: ~40 bytes per point plus the encoders' scratch).
inline constexpr std::uint64_t kDefaultRangePoints = std::uint64_t{8} << 20;

struct ShardPlan {
  std::string creator;
  // The archive's codec parameters (Archive::create) and the scan's intensity
  // range, which the chunks are encoded with.
  std::string archive_params;
  bool has_intensity_range = false;
  float intensity_lo = 0, intensity_hi = 0;
  ArchiveGrid grid;
  // What the shard's scan records (Archive::begin_scan), as a one-box
  // compress records it: colours, intensity, the CRS (WKT2, empty when none)
  // and the LAS metadata: the union of the inputs' attribute sets (a point of
  // an input without one carries 0), the widest point format, the highest
  // minor version, the one Extra Bytes layout (raw VLR payload and bytes per
  // point) and whether the LAS sources stored 8-bit colour levels.
  ScanAttributes attributes;
  std::uint64_t split_points = kMaxBoundedChunkPoints;
  bool has_xyz_columns = false;
  std::string xyz_columns;
  // Every stage reads without extra bytes (compress --no-extra-bytes).
  bool no_extra_bytes = false;
  // Every stage reads only these attributes (compress --attributes; all by default).
  AttributeSet keep;
  std::uint64_t points = 0;  // points the plan pass read (all inputs)
  // One per input, in order: path, format and CRS as compress records them
  // (point_count is filled by stage 1).
  std::vector<ArchiveSource> sources;
  // Range r holds the chunk keys k with range_starts[r] <= k < range_starts[r + 1]
  // (lexicographic ix, iy, iz); range 0 starts at the smallest key.
  std::vector<ChunkKey> range_starts;
  // Not stored: what the plan pass noticed (CRS decisions, reader warnings).
  std::vector<std::string> warnings;

  std::uint32_t range_count() const { return static_cast<std::uint32_t>(range_starts.size()); }
  std::uint32_t input_count() const { return static_cast<std::uint32_t>(sources.size()); }
  std::uint32_t range_of(const ChunkKey& key) const;
  // The reader options every stage opens the inputs with.
  ReaderOptions reader_options() const;
  // Whether the plan records LAS metadata (then it is a version 2 plan).
  bool has_las() const {
    return attributes.las_attributes != 0 || attributes.las_point_format >= 0 ||
           attributes.las_version_minor >= 0;
  }
};

struct ShardPlanOptions {
  // As for compress_files (the error-bounded mode only; threads, memory,
  // tmp_dir and spool do not change the archive, and the plan keeps no
  // spool). Its pass over every point reports progress (phase "scanning")
  // and stops ("interrupted") when cancel is set.
  IngestOptions ingest;
  // 0 = automatic (about kDefaultRangePoints points each), else at most this
  // many (fewer when the data has fewer distinct chunks).
  std::uint32_t ranges = 0;
};

// Stage 0: reads every input once (the same order-free pass compress_files
// makes) and fixes every parameter.
Result<ShardPlan> plan_shards(const std::vector<std::string>& inputs, const ShardPlanOptions& options);
// The plan file (format-spec/shard.md): written to a temporary name and renamed.
Status write_shard_plan(const ShardPlan& plan, const std::string& path);
Result<ShardPlan> read_shard_plan(const std::string& path);
// The plan's text as written (its identity: partition files carry a hash of it).
std::string shard_plan_text(const ShardPlan& plan);
std::uint64_t shard_plan_id(const ShardPlan& plan);

// Names inside a partition directory.
std::string partition_file_name(std::uint32_t input, std::uint32_t range);
std::string partition_manifest_name(std::uint32_t input);

struct PartitionResult {
  std::uint64_t points = 0;
  std::vector<std::uint64_t> range_points;  // per range
  std::vector<std::string> warnings;
};

// Stage 1: reads input `input` of the plan, snaps its points to the plan's
// grid and writes one partition file per range into `dir` (which must
// exist), then the input's manifest. Safe to re-run; writes the same bytes.
// A set `*cancel` (from any thread) stops it between batches: kIoError
// "interrupted", its temporary files removed and no manifest written.
Result<PartitionResult> partition_input(const ShardPlan& plan, std::uint32_t input, const std::string& dir,
                                        const std::atomic<bool>* cancel = nullptr);

struct EncodeShardOptions {
  unsigned threads = 0;  // 0 = all cores
  bool verify_blobs = false;
  // Working memory, shared as compress shares it (IngestOptions): a range of
  // more points than half of it fits goes through temporary bucket files in
  // `tmp_dir` (empty: beside the shard) and is encoded slice by slice.
  std::uint64_t memory_budget = std::uint64_t{1} << 30;
  std::string tmp_dir;
  // Set (from any thread) to stop: encode_shard returns kIoError
  // "interrupted", having removed its temporary shard and bucket files.
  const std::atomic<bool>* cancel = nullptr;
  // Called at most every half second from the calling thread ("reading",
  // "encoding", then "done"), as compress_files' IngestOptions::progress.
  std::function<void(const IngestProgress&)> progress;
};

// Stage 2: reads range `range`'s partition file of every input from `dir`
// (every manifest must be there) and encodes its chunks into a new archive at
// `out` (an archive there is replaced: a retried task; any other file there
// is refused, kIoError). The shard holds the plan's metadata and the sources
// with their point counts.
Result<IngestResult> encode_shard(const ShardPlan& plan, std::uint32_t range, const std::string& dir,
                                  const std::string& out, const EncodeShardOptions& options = {});

struct MergeResult {
  std::uint64_t shards = 0;
  std::uint64_t chunks = 0;
  std::uint64_t input_points = 0;
  std::uint64_t blob_bytes = 0;
  PyramidResult pyramid;  // levels 0: none built
};

struct MergeOptions {
  // The merged scan's level-of-detail pyramid, built from the merged chunks
  // (so it is the one a one-box compress of the same inputs builds).
  PyramidMode pyramid = PyramidMode::kAuto;
  unsigned threads = 0;  // 0 = all cores
  std::uint64_t memory_budget = std::uint64_t{1} << 30;
};

// Joins shard archives into a new archive at `out` (never overwritten; written
// to a temporary name beside it and moved into place only when complete).
// The shards must agree on grid, codec parameters, creator, CRS, attributes
// (LAS metadata included) and sources, each hold one complete scan, and hold disjoint chunk keys;
// otherwise kInvalidArgument naming the shard. The rows are copied as they
// are (blobs, bounds, counts) in key order, the blobs of one voxel by content.
Result<MergeResult> merge_archives(const std::vector<std::string>& shards, const std::string& out,
                                   const MergeOptions& options = {});

}  // namespace relief
