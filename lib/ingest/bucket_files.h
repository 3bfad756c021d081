// Temporary run files of the external distribution sort. Points go to one of B
// bucket files by a hash of their chunk key, so every chunk lands whole in one
// bucket and the number of files stays B whatever the number of chunks.
//
// A bucket file is a sequence of blocks; a block holds the points of one input
// batch that fell into the bucket, grouped by chunk (all little-endian):
//
//   u32 point_count, u32 chunk_count
//   chunk_count x { i64 ix, i64 iy, i64 iz, u32 count }
//   point_count records, chunk after chunk:
//     u32 qx, qy, qz   position in the chunk cube, fixed point
//     u8 r, g, b       if colours
//     f32 intensity    if intensity
//
// q = floor((p - chunk_min) / edge * 2^32), clamped to [0, 2^32 - 1], is read
// back as chunk_min + (q + 1/2) * edge / 2^32: within edge * 2^-33 of the input
// per axis (9 nm for a 76 m chunk, far below any map pixel), always inside the
// chunk's cube, and 15 bytes per coloured point instead of 27 as doubles. The
// files are written through the page cache and never outlive the ingest.
// Internal to the ingest module.
#pragma once

#include <cstdint>
#include <string>
#include <unordered_map>
#include <vector>

#include "ingest/ingest_common.h"
#include "relief/archive.h"
#include "relief/status.h"
#include "relief/types.h"

namespace relief::ingest {

// One input batch encoded as blocks, one per bucket it touches.
struct PackedBatch {
  std::vector<std::uint8_t> bytes;
  struct Block {
    std::uint32_t bucket;
    std::size_t offset;  // into bytes
    std::size_t size;
    std::uint32_t points;
  };
  std::vector<Block> blocks;
  // Scratch of pack(), kept to avoid reallocation.
  std::vector<std::uint32_t> chunk_of_point;
  std::vector<ChunkKey> chunk_keys;
  std::vector<Vec3d> chunk_min;
  std::vector<std::uint32_t> chunk_counts;
  std::vector<std::uint64_t> chunk_cursor;
  std::unordered_map<ChunkKey, std::uint32_t, ChunkKeyHash> lookup;
};

class BucketFiles {
 public:
  // Creates a private directory under `parent` with `buckets` files.
  static Result<BucketFiles> create(const std::string& parent, std::uint32_t buckets, const ArchiveGrid& grid,
                                    bool colors, bool intensity);
  BucketFiles(BucketFiles&&) noexcept;
  BucketFiles& operator=(BucketFiles&&) noexcept;
  BucketFiles(const BucketFiles&) = delete;
  BucketFiles& operator=(const BucketFiles&) = delete;
  // Removes every file and the directory.
  ~BucketFiles();

  std::uint32_t bucket_count() const { return static_cast<std::uint32_t>(files_.size()); }
  std::uint32_t bucket_of(const ChunkKey& key) const;
  // Bytes of one point record.
  std::size_t record_bytes() const { return record_; }

  // Encodes points[i] (chunk keys[i]) as blocks. Touches no file and no
  // mutable state, so it may run on another thread than write().
  void pack(const PointCloud& points, const ChunkKey* keys, PackedBatch& out) const;
  // Appends the blocks of a packed batch to their bucket files.
  Status write(const PackedBatch& batch);
  // Closes the write side; call once before reading.
  Status finish_writing();

  std::uint64_t bucket_points(std::uint32_t bucket) const { return counts_[bucket]; }
  // Reads whole blocks of a bucket from `*offset` on (0 = the start), while
  // the slice stays within `max_points` (at least one block), into `out`
  // (replaced) with their chunk ids in `g` (cleared); `buf` is scratch.
  // Advances `*offset`; the bucket is done when it reaches bucket_bytes().
  Status read_slice(std::uint32_t bucket, std::uint64_t* offset, std::uint64_t max_points, PointCloud& out,
                    Grouping& g, std::vector<std::uint8_t>& buf) const;
  std::uint64_t bucket_bytes(std::uint32_t bucket) const { return bytes_[bucket]; }
  // Deletes one bucket's file early (frees disk as the ingest proceeds).
  void discard(std::uint32_t bucket);

  const std::string& directory() const { return dir_; }

 private:
  BucketFiles() = default;
  void remove_all();

  std::string dir_;
  std::vector<std::string> paths_;
  std::vector<int> files_;  // file descriptors, -1 when closed
  std::vector<std::uint64_t> counts_;
  std::vector<std::uint64_t> bytes_;
  ArchiveGrid grid_;
  bool colors_ = false;
  bool intensity_ = false;
  std::size_t record_ = 0;
};

}  // namespace relief::ingest
