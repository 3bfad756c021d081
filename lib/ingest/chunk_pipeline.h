// Parallel chunk encoding with a single writer: worker threads encode chunks
// (the encoder reports each blob's exact decoded bounds; with verify, every
// blob is also decoded back as a check); the calling thread commits finished
// rows in batched transactions. Internal to ingest.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <vector>

#include "relief/archive.h"
#include "relief/codec.h"
#include "relief/ingest.h"

namespace relief::ingest {

// One chunk (or part of one) to encode: either its own points, or `count`
// indices into a shared `source` cloud, gathered by the worker that encodes
// it (so a large grouped slice is never copied chunk by chunk up front).
struct ChunkTask {
  ChunkKey key;
  PointCloud points;
  const PointCloud* source = nullptr;
  const std::uint32_t* index = nullptr;
  std::size_t count = 0;
};

struct PipelineTotals {
  std::uint64_t chunks = 0;
  std::uint64_t points_in = 0;
  std::uint64_t points_decoded = 0;
  std::uint64_t blob_bytes = 0;
};

class ChunkPipeline {
 public:
  ChunkPipeline(Archive& archive, const EncodeParams& params, const ArchiveGrid& grid, std::int64_t scan_id,
                unsigned threads, const std::atomic<bool>* cancel, bool verify);

  // Encodes and stores every task; returns when all are committed or on the
  // first error (nothing of a failed batch is committed). `tick` is called
  // from this thread between commits.
  Status run(std::vector<ChunkTask>& tasks, const std::function<void()>& tick);

  const PipelineTotals& totals() const { return totals_; }

 private:
  Status encode_one(ChunkTask& task, ChunkRow& row) const;

  Archive& archive_;
  EncodeParams params_;
  std::string params_text_;
  ArchiveGrid grid_;
  std::int64_t scan_id_;
  unsigned threads_;
  const std::atomic<bool>* cancel_;
  bool verify_;
  PipelineTotals totals_;
};

}  // namespace relief::ingest
