#include "ingest/chunk_pipeline.h"

#include <condition_variable>
#include <deque>
#include <mutex>
#include <thread>

namespace relief::ingest {

namespace {

// A transaction per this many rows or blob bytes, whichever comes first:
// large enough to amortise the commit, small enough that a kill loses little.
constexpr std::size_t kBatchRows = 64;
constexpr std::size_t kBatchBytes = 32u << 20;

}  // namespace

ChunkPipeline::ChunkPipeline(Archive& archive, const EncodeParams& params, const ArchiveGrid& grid,
                             std::int64_t scan_id, unsigned threads, const std::atomic<bool>* cancel, bool verify)
    : archive_(archive),
      params_(params),
      params_text_(encode_params_to_string(params)),
      grid_(grid),
      scan_id_(scan_id),
      threads_(threads == 0 ? 1 : threads),
      cancel_(cancel),
      verify_(verify) {}

Status ChunkPipeline::encode_one(ChunkTask& task, ChunkRow& row) const {
  EncodeParams p = params_;
  const Box3d cube = grid_.chunk_box(task.key);
  p.grid_origin = cube.min;
  p.grid_edge = grid_.chunk_edge;
  // The encoder reports the exact bounds of what a reader will decode: the
  // spatial index must contain every decoded point.
  EncodeStats stats;
  // Tasks that index into a shared cloud are encoded in place (no copy).
  auto blob = task.source != nullptr
                  ? encode_chunk_subset(*task.source, std::span<const std::uint32_t>(task.index, task.count), p, &stats)
                  : encode_chunk(task.points, p, {}, &stats);
  if (!blob) return blob.status();
  if (verify_) {
    auto decoded = decode_chunk(*blob);
    if (!decoded) return internal_error("a freshly encoded chunk does not decode: " + decoded.status().message());
    const Box3d b = decoded->bounds();
    if (decoded->size() != stats.decoded_points || !(b.min == stats.decoded_bounds.min) ||
        !(b.max == stats.decoded_bounds.max)) {
      return internal_error("a freshly encoded chunk decodes to other points than the encoder expects");
    }
  }
  row.ref.key = task.key;
  row.ref.scan_id = scan_id_;
  row.ref.bounds = stats.decoded_bounds;
  row.ref.input_points = task.source != nullptr ? task.count : task.points.size();
  row.ref.decoded_points = stats.decoded_points;
  row.ref.blob_size = blob->size();
  row.codec = 1;
  row.codec_params = params_text_;
  row.blob = std::move(blob).value();
  PointCloud().positions.swap(task.points.positions);  // free the input early
  task.points = PointCloud();
  return Status::ok();
}

Status ChunkPipeline::run(std::vector<ChunkTask>& tasks, const std::function<void()>& tick) {
  std::mutex mu;
  std::condition_variable cv;
  std::deque<ChunkRow> ready;
  std::atomic<std::size_t> next{0};
  std::atomic<bool> failed{false};
  Status first_error;
  std::size_t finished_workers = 0;
  const unsigned workers = static_cast<unsigned>(std::min<std::size_t>(threads_, std::max<std::size_t>(1, tasks.size())));

  auto worker = [&] {
    for (;;) {
      if (failed.load() || (cancel_ && cancel_->load())) break;
      const std::size_t i = next.fetch_add(1);
      if (i >= tasks.size()) break;
      ChunkRow row;
      Status s = encode_one(tasks[i], row);
      std::lock_guard<std::mutex> lock(mu);
      if (!s) {
        if (!failed.exchange(true)) {
          const ChunkKey k = tasks[i].key;
          first_error = s.with_context("chunk (" + std::to_string(k.ix) + "," + std::to_string(k.iy) + "," +
                                       std::to_string(k.iz) + ")");
        }
        break;
      }
      ready.push_back(std::move(row));
      cv.notify_one();
    }
    std::lock_guard<std::mutex> lock(mu);
    ++finished_workers;
    cv.notify_one();
  };
  std::vector<std::thread> pool;
  pool.reserve(workers);
  for (unsigned t = 0; t < workers; ++t) pool.emplace_back(worker);

  Status status;
  std::vector<ChunkRow> batch;
  std::size_t batch_bytes = 0;
  const auto commit = [&]() -> Status {
    if (batch.empty()) return Status::ok();
    RELIEF_RETURN_IF_ERROR(archive_.put_chunks(batch));
    for (const ChunkRow& r : batch) {
      ++totals_.chunks;
      totals_.points_in += r.ref.input_points;
      totals_.points_decoded += r.ref.decoded_points;
      totals_.blob_bytes += r.blob.size();
    }
    batch.clear();
    batch_bytes = 0;
    if (tick) tick();
    return Status::ok();
  };
  for (;;) {
    std::unique_lock<std::mutex> lock(mu);
    cv.wait_for(lock, std::chrono::milliseconds(200),
                [&] { return !ready.empty() || finished_workers == workers; });
    const bool all_done = finished_workers == workers;
    while (!ready.empty()) {
      batch_bytes += ready.front().blob.size();
      batch.push_back(std::move(ready.front()));
      ready.pop_front();
    }
    lock.unlock();
    if (status && (batch.size() >= kBatchRows || batch_bytes >= kBatchBytes || (all_done && !failed.load()))) {
      status = commit();
      if (!status) failed.store(true);
    } else if (tick) {
      tick();
    }
    if (all_done) break;
  }
  for (std::thread& t : pool) t.join();
  if (!status) return status;
  if (failed.load()) return first_error;
  if (cancel_ && cancel_->load()) return io_error("interrupted");
  return Status::ok();
}

}  // namespace relief::ingest
