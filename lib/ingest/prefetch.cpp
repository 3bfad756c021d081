#include "ingest/prefetch.h"

#include <utility>

namespace relief::ingest {

Prefetcher::Prefetcher(const std::vector<std::unique_ptr<PointReader>>& readers, std::size_t batch_points,
                       std::size_t depth, std::uint64_t first_point, Stage stage)
    : readers_(readers),
      batch_points_(batch_points),
      depth_(depth == 0 ? 1 : depth),
      next_first_(first_point),
      stage_(std::move(stage)) {
  thread_ = std::thread([this] { run(); });
}

Prefetcher::~Prefetcher() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    stop_ = true;
  }
  cv_.notify_all();
  thread_.join();
}

void Prefetcher::run() {
  std::size_t reader = 0;
  for (;;) {
    ReadBatch batch;
    {
      std::unique_lock<std::mutex> lock(mu_);
      cv_.wait(lock, [&] { return stop_ || filled_.size() < depth_; });
      if (stop_) return;
      if (!spare_.empty()) {
        batch = std::move(spare_.back());
        spare_.pop_back();
      }
    }
    Status status;
    std::size_t got = 0;
    while (reader < readers_.size()) {
      auto r = readers_[reader]->read(batch.points, batch_points_);
      if (!r) {
        status = r.status();
        break;
      }
      got = *r;
      if (got > 0) break;
      ++reader;
    }
    if (status && got > 0) {
      batch.reader = reader;
      batch.first = next_first_;
      next_first_ += got;
      if (stage_) status = stage_(batch);
    }
    std::lock_guard<std::mutex> lock(mu_);
    if (!status || got == 0) {
      error_ = std::move(status);
      done_ = true;
      cv_.notify_all();
      return;
    }
    filled_.push_back(std::move(batch));
    cv_.notify_all();
  }
}

Result<bool> Prefetcher::next(ReadBatch& batch) {
  std::unique_lock<std::mutex> lock(mu_);
  cv_.wait(lock, [&] { return !filled_.empty() || done_; });
  if (filled_.empty()) {
    if (!error_) return error_;
    return false;
  }
  std::swap(batch, filled_.front());
  if (spare_.size() <= depth_) spare_.push_back(std::move(filled_.front()));
  filled_.pop_front();
  cv_.notify_all();
  return true;
}

}  // namespace relief::ingest
