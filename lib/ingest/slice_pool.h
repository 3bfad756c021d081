// Bucket slices being encoded, and the pool that recycles them. Internal to
// ingest.
#pragma once

#include <algorithm>
#include <cstdint>
#include <memory>
#include <mutex>
#include <vector>

#include "ingest/ingest_common.h"
#include "relief/types.h"

namespace relief::ingest {

// A bucket slice: its points and their chunk ids.
struct Slice {
  PointCloud points;
  Grouping grouping;
};

// Points a slice has room for (its largest per-point arrays).
inline std::uint64_t slice_capacity(const Slice& s) {
  return std::max<std::uint64_t>(s.points.positions.capacity(),
                                 std::max(s.grouping.ids.capacity(), s.grouping.order.capacity()));
}

// A slice's buffers are reused by the next one instead of being freshly
// faulted in, but only up to `keep_points`: the error-bounded mode reads a
// bucket whole, so one larger than a slice's share of the budget makes its
// slice larger too, and a pool that kept it would hold that size for the rest
// of the ingest (twice: one slice encoding, one loading). Such a slice is
// freed when its last user lets go.
class SlicePool {
 public:
  explicit SlicePool(std::uint64_t keep_points) : keep_points_(keep_points) {}
  // A slice that returns to the pool when the last reference goes (from any
  // thread). The pool must outlive every slice it hands out.
  std::shared_ptr<Slice> acquire() {
    std::unique_ptr<Slice> s;
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (!free_.empty()) {
        s = std::move(free_.back());
        free_.pop_back();
      }
    }
    if (!s) s = std::make_unique<Slice>();
    return std::shared_ptr<Slice>(s.release(), [this](Slice* p) { give_back(p); });
  }
  // Frees the slices not in use.
  void clear() {
    std::lock_guard<std::mutex> lock(mu_);
    free_.clear();
  }
  // Slices kept for reuse.
  std::size_t kept() {
    std::lock_guard<std::mutex> lock(mu_);
    return free_.size();
  }

 private:
  void give_back(Slice* p) {
    std::unique_ptr<Slice> s(p);
    if (slice_capacity(*s) > keep_points_) return;  // freed here, outside the lock
    std::lock_guard<std::mutex> lock(mu_);
    free_.push_back(std::move(s));
  }

  std::uint64_t keep_points_;
  std::mutex mu_;
  std::vector<std::unique_ptr<Slice>> free_;
};

}  // namespace relief::ingest
