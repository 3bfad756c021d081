// A query whose batches are pulled one at a time (Archive.query(batches=True)):
// the query runs on a worker thread and hands its batches through a queue of
// kQueueBatches, so at most that many decoded batches wait, whatever the box.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "relief/query.h"

namespace relief::python {

// Batches decoded ahead of the consumer: enough to overlap Python's work
// on one batch with the decoding of the next, small enough to bound memory.
inline constexpr std::size_t kQueueBatches = 2;

class BatchStream {
 public:
  // Starts the query on its own reader (`reader` is used by no one else), so
  // other queries on the archive run beside it. `box` null = every point.
  BatchStream(std::unique_ptr<ArchiveReader> reader, std::optional<Box3d> box, QueryOptions options);
  ~BatchStream();
  BatchStream(const BatchStream&) = delete;
  BatchStream& operator=(const BatchStream&) = delete;

  // Blocks until the next batch is decoded. False at the end; `status` is
  // then the query's result (ok, or the error that stopped it).
  bool next(PointCloud& batch, Status& status);
  // Warnings (skipped corrupt chunks) since the last call.
  std::vector<std::string> take_warnings();
  // Stops the query and waits for the worker; idempotent, and safe from
  // several threads at once (the iterator's close and the archive's).
  void close();
  // close() on behalf of the archive that was closed under the iteration:
  // the iterator then refuses next() instead of ending quietly.
  void close_for_archive();
  bool archive_closed() const { return archive_closed_; }

 private:
  void run(std::optional<Box3d> box, QueryOptions options);

  std::unique_ptr<ArchiveReader> reader_;
  std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<PointCloud> queue_;
  std::vector<std::string> warnings_;
  bool done_ = false;      // the worker has finished
  bool stopping_ = false;  // the consumer gave up
  std::atomic<bool> archive_closed_{false};
  Status status_;
  std::mutex join_mutex_;  // one close() joins the worker, the others wait for it
  std::thread worker_;
};

}  // namespace relief::python
