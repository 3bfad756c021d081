// Read-ahead over a sequence of point readers: a background thread reads the
// next batch and runs a caller-given stage on it (keying, copying into the
// final buffer, ...) while the caller consumes the previous one, so reading
// overlaps the caller's work on a second core. Batches are recycled, so a
// steady state allocates nothing. Internal to ingest.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include "relief/archive.h"
#include "relief/io.h"
#include "relief/status.h"

namespace relief::ingest {

struct ReadBatch {
  PointCloud points;
  std::vector<ChunkKey> keys;  // for the stage's use
  std::size_t reader = 0;      // index of the input the points came from
  std::uint64_t first = 0;     // index of points[0] among all points read
};

class Prefetcher {
 public:
  using Stage = std::function<Status(ReadBatch&)>;
  // Reads readers[0], readers[1], ... in turn, `batch_points` at a time,
  // keeping at most `depth` staged batches ahead of the caller. `stage` runs on
  // the background thread, once per batch in input order. `first_point` is the
  // stream index of the first point to be read. The readers must outlive the
  // prefetcher.
  Prefetcher(const std::vector<std::unique_ptr<PointReader>>& readers, std::size_t batch_points, std::size_t depth,
             std::uint64_t first_point, Stage stage);
  // Stops the thread (after the batch in progress) and discards unread batches.
  ~Prefetcher();
  Prefetcher(const Prefetcher&) = delete;
  Prefetcher& operator=(const Prefetcher&) = delete;

  // Swaps the next staged batch into `batch` (its old contents are recycled).
  // Returns false when every reader is exhausted; a read or stage error is
  // returned once the batches before it have been delivered.
  Result<bool> next(ReadBatch& batch);

 private:
  void run();

  const std::vector<std::unique_ptr<PointReader>>& readers_;
  const std::size_t batch_points_;
  const std::size_t depth_;
  std::uint64_t next_first_;
  Stage stage_;
  std::mutex mu_;
  std::condition_variable cv_;
  std::deque<ReadBatch> filled_;
  std::vector<ReadBatch> spare_;
  bool done_ = false;  // the thread has read everything or failed
  bool stop_ = false;  // the caller is gone
  Status error_;
  std::thread thread_;
};

}  // namespace relief::ingest
