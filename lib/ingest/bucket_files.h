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
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "ingest/ingest_common.h"
#include "ingest/temp_dir.h"
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

  // The raw records, for passes that only route points (bucket_split.h):
  // visit(key, cube_min, records, count) for every chunk run of every block
  // of the bucket, in file order. record_bytes() apart; position() decodes a
  // record's x y z exactly as read_slice does.
  using RunVisitor =
      std::function<Status(const ChunkKey& key, const Vec3d& cube_min, const std::uint8_t* records, std::uint32_t n)>;
  Status scan(std::uint32_t bucket, AlignedBuffer& buf, const RunVisitor& visit) const;
  std::size_t record_bytes() const { return record_; }
  // What every record carries, as created.
  bool colors() const { return colors_; }
  bool intensity() const { return intensity_; }
  std::uint32_t las_attributes() const { return las_; }
  std::uint32_t extra_bytes_size() const { return extra_size_; }
  Vec3d position(const Vec3d& cube_min, const std::uint8_t* record) const;
  // Appends one block of raw records (runs: chunk key and record count, the
  // records in that order) to a bucket. The records keep their fixed-point
  // positions, so a point read back is the same double as where it came from.
  Status append_block(std::uint32_t bucket, const std::vector<std::pair<ChunkKey, std::uint32_t>>& runs,
                      const std::uint8_t* records, std::uint32_t points);
  // Buckets chosen by the caller (append_block), not by the keys' hash:
  // read_slice then accepts any key in any bucket.
  void set_explicit_buckets() { explicit_buckets_ = true; }
  std::uint64_t bucket_bytes(std::uint32_t bucket) const { return bytes_[bucket]; }
  // Deletes one bucket's file early (frees disk as the ingest proceeds).
  void discard(std::uint32_t bucket);

  const std::string& directory() const { return dir_.path(); }
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
  // Room for a block of `size` bytes at the end of a bucket's staging buffer
  // (flushing whole pages first when it would overflow its share).
  Result<std::uint8_t*> stage_block(std::uint32_t bucket, std::size_t size);
  // A window of a bucket file's bytes, and the next block in it.
  struct Window {
    std::uint64_t from = 0, to = 0;
    std::size_t skip = 0;
  };
  struct Block {
    std::uint32_t points = 0, chunks = 0;
    std::uint64_t size = 0;
    const std::uint8_t* entries = nullptr;  // chunks x kChunkEntry bytes, then the records
  };
  // Reads the block at *offset into the window (`max_points`: stop, with
  // block.points set and nothing loaded, when the block holds more than
  // that), checking its header against the file. Advances nothing.
  Status peek_block(std::uint32_t bucket, std::uint64_t offset, AlignedBuffer& buf, Window& w, Block& block,
                    std::uint64_t max_points) const;
  // The error for a damaged temporary file: its path and the block's offset.
  Status damaged_at(std::uint32_t bucket, std::uint64_t offset, const std::string& what) const;
  // Checks a loaded block's chunk entries and calls fn(key, count, records)
  // for each run, up to the first error it returns.
  Status each_run(std::uint32_t bucket, std::uint64_t offset, const Block& block,
                  const std::function<Status(const ChunkKey&, std::uint32_t, const std::uint8_t*)>& fn) const;
  // Writes out a staging buffer that a large block grew past its share and
  // gives the memory back.
  Status shrink_staging(std::uint32_t bucket);

  IngestTempDir dir_;
  std::vector<std::string> paths_;
  std::vector<int> files_;  // file descriptors, -1 when closed
  std::vector<std::uint64_t> counts_;
  std::vector<std::uint64_t> bytes_;       // logical bytes written per bucket
  std::vector<AlignedBuffer> staging_;
  std::vector<std::size_t> staged_;        // bytes staged per bucket
  std::vector<std::uint64_t> file_pos_;    // bytes on disk per bucket (page multiple)
  std::size_t staging_target_ = 0;         // flush a bucket's pages at this fill
  bool direct_ = false;
  bool explicit_buckets_ = false;
  // append() scratch.
  Grouping batch_;  // chunk ids of the batch being appended
  std::vector<Vec3d> chunk_min_;
  std::vector<std::uint32_t> chunk_counts_;
  std::vector<std::uint8_t*> chunk_cursor_;
  ArchiveGrid grid_;
  double step_ = 0;  // a record's fixed-point unit: chunk edge / 2^32
  bool colors_ = false;
  bool intensity_ = false;
  std::uint32_t las_ = 0;  // LasAttributeBits in every record
  std::uint32_t extra_size_ = 0;
  std::size_t record_ = 0;
};

}  // namespace relief::ingest
