// Temporary run files of the external distribution sort: points are appended to
// one of B bucket files by a hash of their chunk key, so every chunk lands whole
// in one bucket and the number of files stays B whatever the number of chunks.
// Internal to the ingest module.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "relief/archive.h"
#include "relief/status.h"
#include "relief/types.h"

namespace relief::ingest {

// Bytes of one point record: x y z as f64, then r g b (u8) if colours, then
// intensity (f32) if intensity. Written field by field, little-endian.
std::size_t record_size(bool colors, bool intensity);

class BucketFiles {
 public:
  // Creates a private directory under `parent` with `buckets` files and a
  // write buffer of `buffer_bytes` shared among them.
  static Result<BucketFiles> create(const std::string& parent, std::uint32_t buckets, std::size_t buffer_bytes,
                                    bool colors, bool intensity);
  BucketFiles(BucketFiles&&) noexcept;
  BucketFiles& operator=(BucketFiles&&) noexcept;
  BucketFiles(const BucketFiles&) = delete;
  BucketFiles& operator=(const BucketFiles&) = delete;
  // Removes every file and the directory.
  ~BucketFiles();

  std::uint32_t bucket_count() const { return static_cast<std::uint32_t>(files_.size()); }
  std::uint32_t bucket_of(const ChunkKey& key) const;

  // Appends points[i] to the bucket of keys[i].
  Status append(const PointCloud& points, const std::vector<ChunkKey>& keys);
  // Flushes buffers and closes the write side; call once before reading.
  Status finish_writing();

  std::uint64_t bucket_points(std::uint32_t bucket) const { return counts_[bucket]; }
  // Reads points [first, first + count) of a bucket, in the order written.
  Status read(std::uint32_t bucket, std::uint64_t first, std::uint64_t count, PointCloud& out) const;
  // Deletes one bucket's file early (frees disk as the ingest proceeds).
  void discard(std::uint32_t bucket);

  const std::string& directory() const { return dir_; }

 private:
  BucketFiles() = default;
  Status flush(std::uint32_t bucket);
  void remove_all();

  std::string dir_;
  std::vector<std::string> paths_;
  std::vector<int> files_;  // file descriptors, -1 when closed
  std::vector<std::vector<std::uint8_t>> buffers_;
  std::vector<std::uint64_t> counts_;
  std::size_t per_bucket_buffer_ = 0;
  bool colors_ = false;
  bool intensity_ = false;
  std::size_t record_ = 0;
};

}  // namespace relief::ingest
