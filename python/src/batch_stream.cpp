#include "batch_stream.h"

namespace relief::python {

BatchStream::BatchStream(std::unique_ptr<ArchiveReader> reader, std::optional<Box3d> box,
                         QueryOptions options)
    : reader_(std::move(reader)) {
  worker_ =
      std::thread([this, box, options = std::move(options)]() mutable { run(box, std::move(options)); });
}

BatchStream::~BatchStream() { close(); }

void BatchStream::run(std::optional<Box3d> box, QueryOptions options) {
  options.on_warning = [this](const std::string& w) {
    const std::lock_guard<std::mutex> lock(mutex_);
    warnings_.push_back(w);
  };
  const PointSink sink = [this](const PointCloud& batch) -> Status {
    std::unique_lock<std::mutex> lock(mutex_);
    changed_.wait(lock, [this] { return stopping_ || queue_.size() < kQueueBatches; });
    // Any error stops the query; close() discards it.
    if (stopping_) return invalid_argument("query closed");
    queue_.push_back(batch);
    changed_.notify_all();
    return Status::ok();
  };
  Result<QueryStats> r = box ? reader_->query(*box, options, sink) : reader_->query_all(options, sink);
  const std::lock_guard<std::mutex> lock(mutex_);
  if (!r) status_ = r.status();
  done_ = true;
  changed_.notify_all();
}

bool BatchStream::next(PointCloud& batch, Status& status) {
  std::unique_lock<std::mutex> lock(mutex_);
  changed_.wait(lock, [this] { return !queue_.empty() || done_; });
  if (!queue_.empty()) {
    batch = std::move(queue_.front());
    queue_.pop_front();
    changed_.notify_all();
    return true;
  }
  status = status_;
  return false;
}

std::vector<std::string> BatchStream::take_warnings() {
  const std::lock_guard<std::mutex> lock(mutex_);
  std::vector<std::string> out;
  out.swap(warnings_);
  return out;
}

void BatchStream::close() {
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
    queue_.clear();
    changed_.notify_all();
  }
  const std::lock_guard<std::mutex> lock(join_mutex_);
  if (worker_.joinable()) worker_.join();
}

void BatchStream::close_for_archive() {
  archive_closed_ = true;
  close();
}

}  // namespace relief::python
