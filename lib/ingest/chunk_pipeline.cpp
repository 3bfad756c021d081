#include "ingest/chunk_pipeline.h"

#include "core/memory.h"

#include <cmath>
#include <csignal>
#include <cstdlib>
#include <utility>

namespace relief::ingest {

namespace {

// A transaction per this many rows or blob bytes, whichever comes first:
// large enough to amortise the commit, small enough that a kill loses little.
constexpr std::size_t kBatchRows = 64;
constexpr std::size_t kBatchBytes = 32u << 20;

// See ChunkPipeline::kill_after_commits_.
constexpr const char* kKillAfterCommitsEnv = "RELIEF_TEST_KILL_AFTER_COMMITS";

std::uint64_t kill_after_commits_from_env() {
  const char* text = std::getenv(kKillAfterCommitsEnv);
  if (text == nullptr || *text == '\0') return 0;
  char* end = nullptr;
  const unsigned long long n = std::strtoull(text, &end, 10);
  return *end == '\0' ? static_cast<std::uint64_t>(n) : 0;
}

}  // namespace

ChunkPipeline::ChunkPipeline(Archive& archive, const EncodeParams& params, const ArchiveGrid& grid,
                             std::int64_t scan_id, unsigned threads, const std::atomic<bool>* cancel, bool verify,
                             EncodeMemory memory)
    : archive_(archive),
      params_(params),
      params_text_(encode_params_to_string(params, ParamsText::kCompact)),
      grid_(grid),
      scan_id_(scan_id),
      threads_(threads == 0 ? 1 : threads),
      cancel_(cancel),
      verify_(verify),
      memory_(memory),
      kill_after_commits_(kill_after_commits_from_env()) {}

Status ChunkPipeline::encode_one(ChunkTask& task, ChunkRow& row) const {
  EncodeParams p = params_;
  const Box3d cube = grid_.chunk_box(task.key);
  const double edge = std::ldexp(grid_.chunk_edge, -task.split_depth);
  p.grid_origin = Vec3d{cube.min.x + task.sub[0] * edge, cube.min.y + task.sub[1] * edge, cube.min.z + task.sub[2] * edge};
  p.grid_edge = edge;
  // The encoder reports the exact bounds of what a reader will decode: the
  // spatial index must contain every decoded point.
  EncodeStats stats;
  // Tasks that index into a shared cloud are not copied out first:
  // encode_chunk_subset gathers the task's points (one pass), or encodes the
  // cloud where it lies when the task is all of it in order.
  auto blob = task.source != nullptr
                  ? encode_chunk_subset(*task.source, std::span<const std::uint32_t>(task.index, task.count), p, &stats)
                  : encode_chunk(task.points, p, {}, &stats);
  if (!blob) return blob.status();
  if (stats.intensities_kept_exact) exact_intensity_chunks_.fetch_add(1, std::memory_order_relaxed);
  if (verify_) {
    auto decoded = decode_chunk(*blob);
    if (!decoded) return internal_error("a freshly encoded chunk does not decode: " + decoded.status().message());
    const Box3d b = decoded->bounds();
    const Box3d& s = stats.decoded_bounds;
    const Box3d& e = stats.point_bounds;
    // Error-bounded blobs index the union of every point and the base layer;
    // their points' own bounds are exact.
    const bool bounds_ok = decoded->empty() ? e.empty() : b.min == e.min && b.max == e.max && s.contains(b);
    if (decoded->size() != stats.decoded_points || !bounds_ok) {
      return internal_error("a freshly encoded chunk decodes to other points than the encoder expects");
    }
  }
  row.ref.key = task.key;
  row.ref.scan_id = scan_id_;
  row.ref.bounds = stats.decoded_bounds;
  if (stats.point_bounds.min != stats.decoded_bounds.min ||
      stats.point_bounds.max != stats.decoded_bounds.max) {
    row.ref.point_bounds = stats.point_bounds;
  }
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

ChunkPipeline::~ChunkPipeline() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    stop_ = true;
    queue_.clear();
  }
  work_cv_.notify_all();
  for (std::thread& t : pool_) t.join();
}

void ChunkPipeline::submit(std::vector<ChunkTask> tasks, std::shared_ptr<const void> owner) {
  if (tasks.empty()) return;
  {
    std::lock_guard<std::mutex> lock(mu_);
    const std::uint64_t id = next_submission_++;
    pending_[id] = {tasks.size(), std::move(owner)};
    for (ChunkTask& t : tasks) queue_.push_back(Item{std::move(t), id});
    while (pool_.size() < threads_) pool_.emplace_back([this] { work(); });
  }
  work_cv_.notify_all();
}

void ChunkPipeline::work() {
  for (;;) {
    Item item;
    std::uint64_t item_bytes = 0;  // its memory estimate
    {
      std::unique_lock<std::mutex> lock(mu_);
      work_cv_.wait(lock, [&] { return stop_ || may_start(); });
      if (stop_) return;
      item = std::move(queue_.front());
      queue_.pop_front();
      ++running_;
      item_bytes = estimate(item.task);
      running_bytes_ += item_bytes;
    }
    ChunkRow row;
    // After Ctrl-C the remaining tasks are skipped; wait() reports it.
    const bool skip = cancel_ != nullptr && cancel_->load();
    Status s = skip ? Status::ok() : encode_one(item.task, row);
    const ChunkKey k = item.task.key;
    item.task = ChunkTask();
    // Only after a large task: trimming costs a walk of every arena and the
    // page faults of memory taken again, too much after every small chunk.
    if (memory_.trim_above != 0 && item_bytes >= memory_.bytes / 4 && core::resident_bytes() > memory_.trim_above) {
      core::release_free_memory();
    }
    std::shared_ptr<const void> release;
    {
      std::lock_guard<std::mutex> lock(mu_);
      --running_;
      running_bytes_ -= item_bytes;
      if (!s) {
        if (!failed_) {
          failed_ = true;
          first_error_ = s.with_context("chunk (" + std::to_string(k.ix) + "," + std::to_string(k.iy) + "," +
                                        std::to_string(k.iz) + ")");
        }
      } else if (!skip) {
        ready_.push_back(std::move(row));
      }
      auto it = pending_.find(item.submission);
      if (it != pending_.end() && --it->second.first == 0) {
        release = std::move(it->second.second);
        pending_.erase(it);
      }
    }
    done_cv_.notify_all();
    // A task waiting for memory may fit now.
    if (memory_.bytes != 0) work_cv_.notify_all();
    release.reset();  // frees the submission's memory outside the lock
  }
}

Status ChunkPipeline::commit() {
  if (batch_.empty()) return Status::ok();
  RELIEF_RETURN_IF_ERROR(archive_.put_chunks(batch_));
  for (const ChunkRow& r : batch_) count_row(totals_, r);
  batch_.clear();
  batch_bytes_ = 0;
  if (kill_after_commits_ != 0 && ++commits_ == kill_after_commits_) std::raise(SIGKILL);
  return Status::ok();
}

Status ChunkPipeline::wait(std::size_t max_pending, const std::function<void()>& tick) {
  for (;;) {
    std::unique_lock<std::mutex> lock(mu_);
    done_cv_.wait_for(lock, std::chrono::milliseconds(200),
                      [&] { return !ready_.empty() || failed_ || pending_.size() <= max_pending; });
    if (!failed_ && cancel_ && cancel_->load()) {
      failed_ = true;
      first_error_ = io_error("interrupted");
    }
    if (failed_) {
      // Drop what has not started, let running tasks finish, keep nothing
      // of the uncommitted batch.
      queue_.clear();
      done_cv_.wait(lock, [&] { return running_ == 0; });
      pending_.clear();
      ready_.clear();
      batch_.clear();
      batch_bytes_ = 0;
      return first_error_;
    }
    while (!ready_.empty()) {
      batch_bytes_ += ready_.front().blob.size();
      batch_.push_back(std::move(ready_.front()));
      ready_.pop_front();
    }
    const bool all_done = pending_.empty() && running_ == 0 && queue_.empty();
    const bool enough = pending_.size() <= max_pending;
    lock.unlock();
    if (batch_.size() >= kBatchRows || batch_bytes_ >= kBatchBytes || (max_pending == 0 && all_done)) {
      Status s = commit();
      if (!s) {
        std::lock_guard<std::mutex> relock(mu_);
        if (!failed_) {
          failed_ = true;
          first_error_ = std::move(s);
        }
        continue;
      }
    }
    if (tick) tick();
    if (max_pending == 0 ? all_done : enough) return Status::ok();
  }
}

Status ChunkPipeline::run(std::vector<ChunkTask> tasks, const std::function<void()>& tick) {
  submit(std::move(tasks), nullptr);
  return wait(0, tick);
}

}  // namespace relief::ingest
