// How an ingest shares its memory budget, and the encoding half of the
// external distribution sort: the bucket files, slice by slice, through a
// chunk pipeline. Shared by compress_files / append_files (compress.cpp) and
// a sharded build's stage 2 (lib/shard/encode.cpp), so both encode the same
// chunks the same way within the same budget. Internal to the ingest module.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <string>

#include "ingest/bucket_files.h"
#include "ingest/chunk_pipeline.h"
#include "ingest/slice_pool.h"
#include "relief/archive.h"
#include "relief/status.h"

namespace relief::ingest {

// Points per read from an input (at most; a small budget reads fewer).
inline constexpr std::size_t kReadBatchPoints = std::size_t{1} << 20;

// The shares of one budget (bytes; at least kMinMemoryBudget).
//
// While reading: 1/8 for bucket staging buffers, 3/16 for batches in flight
// (plus, without bucket files, the whole input in half the budget). While
// encoding: 1/3 for two bucket slices (one encoding, the next loading; a
// bucket read whole that is larger loads alone and its slice is freed, not
// recycled), 1/3 for the encoders; the rest is headroom (SQLite cache,
// allocator slack, which is given back above 2/3).
struct IngestBudget {
  std::uint64_t budget = 0;
  unsigned encode_threads = 1;  // as many as the encoders' third holds
  std::uint64_t group_bytes = 0;  // per point of a slice being grouped
  std::uint64_t slice_points = 0;
  std::uint64_t part_points = 0;       // resampling mode's task size
  std::uint64_t in_memory_points = 0;  // inputs up to this many skip the bucket files
  std::uint64_t read_batch = 0;        // points per read from an input
  std::uint32_t buckets = 0;
  std::size_t staging_bytes = 0;
  EncodeMemory encode_memory;
  // Resident bytes above which free allocator memory goes back between slices.
  std::uint64_t trim_above = 0;
};

// `las_bytes`: a point's carried LAS record (las_record_bytes); `estimated_points`:
// the inputs' points (header counts or an estimate); `whole_chunks`: buckets
// are read whole (error-bounded archives, which must not depend on the budget).
IngestBudget plan_ingest_budget(std::uint64_t memory_budget, unsigned threads, std::uint64_t las_bytes,
                                std::uint64_t estimated_points, bool whole_chunks);

struct BucketEncodeOptions {
  // Error-bounded (and sharded) ingests: every chunk is encoded whole, cut into
  // parts of at most `task_points` by the octant rule on `split_grid`
  // (make_tasks); a bucket larger than two slices is split into loads
  // (bucket_split.h) rather than read whole. Otherwise (resampling) a slice is
  // at most `slice_points` and its tasks `task_points` by count.
  bool whole_chunks = true;
  std::uint64_t task_points = 0;
  const ArchiveGrid* split_grid = nullptr;
  std::string tmp_parent;  // where a split bucket's loads are written
  const std::atomic<bool>* cancel = nullptr;
};

// Encodes every bucket of `files` (written and finished) into `pipeline`,
// slices recycled through `slices` (which must outlive the pipeline: its
// workers hand slices back until they stop), and waits for the last chunk. `tick` is
// called while waiting (progress). Buckets are deleted as they are done.
Status encode_bucket_files(BucketFiles& files, const ArchiveGrid& grid, ChunkPipeline& pipeline, SlicePool& slices,
                           const IngestBudget& budget, const BucketEncodeOptions& options,
                           const std::function<void()>& tick);

}  // namespace relief::ingest
