// Parallel chunk encoding with a single writer: worker threads encode chunks
// (the encoder reports each blob's exact decoded bounds; with verify, every
// blob is also decoded back as a check); the calling thread commits finished
// rows in batched transactions. Internal to ingest.
#pragma once

#include <atomic>
#include <cstdint>
#include <condition_variable>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <thread>
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
  // A part of a chunk split into octants: the sub-cube at depth split_depth
  // with integer position sub[] inside the chunk cube (0 = the whole chunk).
  std::uint8_t split_depth = 0;
  std::uint32_t sub[3] = {0, 0, 0};
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
  // Chunks whose intensities an asked-for tolerance could not apply to
  // (EncodeStats::intensities_kept_exact).
  std::uint64_t exact_intensity_chunks = 0;
};

// How much encoding may run at once: a task of n points is estimated to take
// n * bytes_per_point while it encodes, and a worker starts a task only when
// the running tasks' estimates and its own stay within `bytes` (or nothing
// else runs: a task larger than the limit runs alone). bytes = 0: no limit.
// Blobs never depend on it. A worker that finishes a task while the process
// holds more than `trim_above` bytes gives the allocator's free memory back
// (each thread's malloc arena keeps what its last task freed, which another
// thread cannot reuse); 0: never.
struct EncodeMemory {
  std::uint64_t bytes = 0;
  std::uint64_t bytes_per_point = 0;
  std::uint64_t trim_above = 0;
};

class ChunkPipeline {
 public:
  ChunkPipeline(Archive& archive, const EncodeParams& params, const ArchiveGrid& grid, std::int64_t scan_id,
                unsigned threads, const std::atomic<bool>* cancel, bool verify, EncodeMemory memory = {});
  // Stops the workers; tasks not yet started are dropped.
  ~ChunkPipeline();
  ChunkPipeline(const ChunkPipeline&) = delete;
  ChunkPipeline& operator=(const ChunkPipeline&) = delete;

  // Queues tasks for the workers, which start on them at once. `owner` keeps
  // the memory the tasks index into alive; it is released as soon as the last
  // of these tasks is encoded (or dropped after an error).
  void submit(std::vector<ChunkTask> tasks, std::shared_ptr<const void> owner);
  // Commits finished rows (in batched transactions) until at most
  // `max_pending` submissions still have tasks not yet encoded; with 0, until
  // everything submitted is committed. On the first error (or cancellation)
  // queued tasks are dropped, running ones finish, and the error is returned;
  // nothing of a failed batch is committed. `tick` is called from this thread
  // between commits.
  Status wait(std::size_t max_pending, const std::function<void()>& tick);
  // submit + wait(0).
  Status run(std::vector<ChunkTask> tasks, const std::function<void()>& tick);

  // What is committed.
  PipelineTotals totals() const {
    PipelineTotals t = totals_;
    t.exact_intensity_chunks = exact_intensity_chunks_.load(std::memory_order_relaxed);
    return t;
  }
  // What is committed plus the rows encoded and waiting for their batch's
  // transaction (up to kBatchRows rows or 32 MB): what progress reports.
  // From the thread that calls wait(), as tick does.
  PipelineTotals encoded() const {
    PipelineTotals t = totals();
    for (const ChunkRow& r : batch_) count_row(t, r);
    return t;
  }

 private:
  struct Item {
    ChunkTask task;
    std::uint64_t submission;
  };
  // The memory estimate of a task (EncodeMemory).
  std::uint64_t estimate(const ChunkTask& t) const {
    const std::uint64_t n = t.source != nullptr ? t.count : t.points.size();
    return n * memory_.bytes_per_point;
  }
  // Whether the task at the queue's front may start now (under mu_).
  bool may_start() const {
    return !queue_.empty() && (memory_.bytes == 0 || running_ == 0 ||
                               running_bytes_ + estimate(queue_.front().task) <= memory_.bytes);
  }
  static void count_row(PipelineTotals& t, const ChunkRow& r) {
    ++t.chunks;
    t.points_in += r.ref.input_points;
    t.points_decoded += r.ref.decoded_points;
    t.blob_bytes += r.blob.size();
  }
  Status encode_one(ChunkTask& task, ChunkRow& row) const;
  void work();
  Status commit();

  Archive& archive_;
  EncodeParams params_;
  std::string params_text_;
  ArchiveGrid grid_;
  std::int64_t scan_id_;
  unsigned threads_;
  const std::atomic<bool>* cancel_;
  bool verify_;
  EncodeMemory memory_;
  PipelineTotals totals_;

  std::mutex mu_;
  std::condition_variable work_cv_;  // workers wait for tasks
  std::condition_variable done_cv_;  // the committing thread waits for rows
  std::deque<Item> queue_;
  std::deque<ChunkRow> ready_;
  // Per submission: tasks not yet finished, and the memory they use.
  std::map<std::uint64_t, std::pair<std::size_t, std::shared_ptr<const void>>> pending_;
  std::uint64_t next_submission_ = 0;
  std::size_t running_ = 0;  // tasks being encoded
  std::uint64_t running_bytes_ = 0;  // their memory estimates
  bool failed_ = false;
  bool stop_ = false;
  Status first_error_;
  std::vector<std::thread> pool_;
  // Rows received but not yet committed (touched by the committing thread only).
  std::vector<ChunkRow> batch_;
  std::size_t batch_bytes_ = 0;
  // Test hook: RELIEF_TEST_KILL_AFTER_COMMITS=N makes the process SIGKILL
  // itself right after its N-th committed batch (0 = off), so crash tests
  // kill at a known point instead of racing a sleep.
  std::uint64_t kill_after_commits_ = 0;
  std::uint64_t commits_ = 0;
  // Chunks encode_one (on the workers) saw keep their intensities exact.
  mutable std::atomic<std::uint64_t> exact_intensity_chunks_{0};
};

}  // namespace relief::ingest
