// A bucket of the error-bounded ingest too large to load whole (a dense
// chunk: a terrestrial scan's ground beside the scanner can hold tens of
// millions of points in one chunk), cut into loads that fit the memory budget
// without ever holding it whole.
//
// The encoder splits a chunk of more than `split_points` points into the
// octants of its cube, recursively (make_tasks, compress.cpp), and each part
// becomes its own blob. Those parts depend on the points alone, so they can
// be found by streaming: passes over the bucket file count the points per
// chunk, then per octant of each part still too large, two levels per pass
// (kMaxSplitDepth / 2 passes at most; a 16 M-point chunk of a 10 m surface in
// a 100 m chunk takes three, its octants dividing the points only from depth
// 3 on). A last pass copies every record, byte for byte, into the temporary
// file of its load: parts packed whole into loads of at most
// `load_points` points (a part larger than that is a load alone). Each load is
// then read and encoded as a bucket slice would be, and gives the same tasks,
// hence the same blobs, as the whole bucket would have given. Internal to
// ingest.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <string>
#include <unordered_map>
#include <vector>

#include "ingest/bucket_files.h"
#include "ingest/chunk_pipeline.h"
#include "ingest/ingest_common.h"
#include "relief/status.h"
#include "relief/types.h"

namespace relief::ingest {

struct BucketSplitOptions {
  std::uint64_t split_points = 0;  // the encoder's split size (bounded_split_points)
  std::uint64_t load_points = 0;   // points a load may hold
  std::string tmp_parent;          // where the loads' temporary files go
  std::size_t staging_bytes = 0;   // write buffers, in all
  // The loads' records are the bucket's, copied byte for byte: their
  // attributes are the bucket files' own (BucketFiles::colors() ...).
};

class BucketSplit {
 public:
  // Routes every point of `bucket` to its load; `buf` is scratch. Every
  // 65,536 points of each pass, `tick` (may be empty) is called, for
  // progress, and a set `*cancel` stops the work ("interrupted", as ingest).
  static Result<BucketSplit> create(const BucketFiles& files, std::uint32_t bucket, const ArchiveGrid& grid,
                                    const BucketSplitOptions& options, AlignedBuffer& buf,
                                    const std::function<void()>& tick = {},
                                    const std::atomic<bool>* cancel = nullptr);

  std::uint32_t load_count() const { return static_cast<std::uint32_t>(load_first_part_.size()) - 1; }
  std::uint64_t load_points(std::uint32_t load) const { return loads_.bucket_points(load); }
  // Passes over the bucket file (counting and routing).
  int passes() const { return passes_; }
  // Reads a load into `points` (its chunk ids in `g`) and returns its parts'
  // encode tasks, indexing into `points` through g.order. Largest first.
  Result<std::vector<ChunkTask>> read_load(std::uint32_t load, PointCloud& points, Grouping& g, AlignedBuffer& buf);
  // Deletes a load's temporary file once it has been read.
  void discard(std::uint32_t load) { loads_.discard(load); }

 private:
  // A sub-cube of a chunk: a part when it has no children.
  struct Node {
    Vec3d origin;
    double edge = 0;
    std::uint64_t count = 0;
    std::uint32_t sub[3] = {0, 0, 0};
    std::int32_t first_child = -1;  // eight consecutive nodes, or -1
    std::int32_t parent = -1;
    std::uint32_t part = 0;         // leaves: the part's number
    std::uint8_t depth = 0;
  };
  struct Part {
    ChunkKey key;
    std::uint32_t node = 0;
  };

  explicit BucketSplit(BucketFiles loads) : loads_(std::move(loads)) {}
  // The leaf of `root`'s tree that holds p (by Octants, as make_tasks splits).
  static std::uint32_t leaf(const std::vector<Node>& nodes, std::uint32_t root, const Vec3d& p);

  BucketFiles loads_;
  std::vector<Node> nodes_;
  std::unordered_map<ChunkKey, std::uint32_t, ChunkKeyHash> roots_;
  std::vector<Part> parts_;                     // in key order, then depth first
  std::vector<std::uint32_t> load_first_part_;  // load i holds parts [first[i], first[i + 1])
  int passes_ = 0;
};

}  // namespace relief::ingest
