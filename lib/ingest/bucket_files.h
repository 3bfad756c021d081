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
//     LAS attributes   the carried ones (ingest/las_columns.h), then extra bytes
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
#include <vector>

#include "ingest/ingest_common.h"
#include "relief/archive.h"
#include "relief/status.h"
#include "relief/types.h"

namespace relief::ingest {

// A buffer aligned for direct I/O.
class AlignedBuffer {
 public:
  static constexpr std::size_t kAlign = 4096;
  AlignedBuffer() = default;
  ~AlignedBuffer();
  AlignedBuffer(AlignedBuffer&& o) noexcept;
  AlignedBuffer& operator=(AlignedBuffer&& o) noexcept;
  AlignedBuffer(const AlignedBuffer&) = delete;
  AlignedBuffer& operator=(const AlignedBuffer&) = delete;

  // Capacity at least `bytes` (a multiple of kAlign), keeping the first `keep` bytes.
  void reserve(std::size_t bytes, std::size_t keep);
  std::uint8_t* data() const { return data_; }
  std::size_t capacity() const { return capacity_; }

 private:
  std::uint8_t* data_ = nullptr;
  std::size_t capacity_ = 0;
};

class BucketFiles {
 public:
  // Creates a private directory under `parent` with `buckets` files, staging
  // about `staging_bytes` in all. The files use direct I/O (O_DIRECT) where
  // the file system supports it: gigabytes of temporary records then neither
  // fill the page cache nor pay for its page allocation, twice.
  static Result<BucketFiles> create(const std::string& parent, std::uint32_t buckets, const ArchiveGrid& grid,
                                    bool colors, bool intensity, std::size_t staging_bytes,
                                    std::uint32_t las_attributes = 0, std::uint32_t extra_bytes_size = 0);
  BucketFiles(BucketFiles&&) noexcept;
  BucketFiles& operator=(BucketFiles&&) noexcept;
  BucketFiles(const BucketFiles&) = delete;
  BucketFiles& operator=(const BucketFiles&) = delete;
  // Removes every file and the directory.
  ~BucketFiles();

  std::uint32_t bucket_count() const { return static_cast<std::uint32_t>(files_.size()); }
  std::uint32_t bucket_of(const ChunkKey& key) const;

  // Appends points[i] (chunk keys[i]) to their buckets, one block per bucket
  // touched. Each bucket stages its bytes in an aligned buffer and writes
  // whole 4 KiB pages as it fills.
  Status append(const PointCloud& points, const ChunkKey* keys);
  // Writes what is staged (the last page zero-padded); call once before reading.
  Status finish_writing();

  std::uint64_t bucket_points(std::uint32_t bucket) const { return counts_[bucket]; }
  // Reads whole blocks of a bucket from `*offset` on (0 = the start), while
  // the slice stays within `max_points` (at least one block), into `out`
  // (replaced) with their chunk ids in `g` (cleared); `buf` is scratch.
  // Advances `*offset`; the bucket is done when it reaches bucket_bytes().
  Status read_slice(std::uint32_t bucket, std::uint64_t* offset, std::uint64_t max_points, PointCloud& out,
                    Grouping& g, AlignedBuffer& buf) const;
  std::uint64_t bucket_bytes(std::uint32_t bucket) const { return bytes_[bucket]; }
  // Deletes one bucket's file early (frees disk as the ingest proceeds).
  void discard(std::uint32_t bucket);

  const std::string& directory() const { return dir_; }
  // Bytes held by the staging buffers: about staging_bytes between appends,
  // however large the blocks of a batch were.
  std::size_t staging_capacity() const;

 private:
  BucketFiles() = default;
  void remove_all();
  // Writes the whole pages staged for a bucket (all of it, padded, if `all`).
  Status flush(std::uint32_t bucket, bool all);
  // Reads file bytes [from, from + n) into buf, which then holds them at
  // offset `from % kAlign`.
  Status read_range(std::uint32_t bucket, std::uint64_t from, std::size_t n, AlignedBuffer& buf) const;

  std::string dir_;
  std::vector<std::string> paths_;
  std::vector<int> files_;  // file descriptors, -1 when closed
  std::vector<std::uint64_t> counts_;
  std::vector<std::uint64_t> bytes_;       // logical bytes written per bucket
  std::vector<AlignedBuffer> staging_;
  std::vector<std::size_t> staged_;        // bytes staged per bucket
  std::vector<std::uint64_t> file_pos_;    // bytes on disk per bucket (page multiple)
  std::size_t staging_target_ = 0;         // flush a bucket's pages at this fill
  bool direct_ = false;
  // append() scratch.
  Grouping batch_;  // chunk ids of the batch being appended
  std::vector<Vec3d> chunk_min_;
  std::vector<std::uint32_t> chunk_counts_;
  std::vector<std::uint8_t*> chunk_cursor_;
  ArchiveGrid grid_;
  bool colors_ = false;
  bool intensity_ = false;
  std::uint32_t las_ = 0;  // LasAttributeBits in every record
  std::uint32_t extra_size_ = 0;
  std::size_t record_ = 0;
};

}  // namespace relief::ingest
