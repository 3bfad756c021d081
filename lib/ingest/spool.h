// The decoded points of inputs that are costly to read (LAZ, text), kept in
// temporary files by the pass that fixes an archive's grid (every point is
// read once before the ingest, ingest_common.h order_free_cells), so that the
// ingest reads them back from there instead of decompressing or parsing each
// file a second time. Internal to ingest.
//
// A spool file holds one input's batches as read, each a header and then its
// columns (x y z, colours, intensities, each LAS vector, the extra bytes) as
// the PointCloud holds them; x y z as the LAS integers when the input's scale
// and offset give every coordinate back exactly (checked batch by batch), else
// as doubles. The files live in an IngestTempDir; what the ingest has read of
// one is given back to the file system as it goes (a hole punched over it),
// and the file is deleted once read.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "ingest/temp_dir.h"
#include "relief/io.h"
#include "relief/status.h"

namespace relief::ingest {

class Spool : public std::enable_shared_from_this<Spool> {
 public:
  // A spool under `parent` for the inputs whose `wanted` entry is true (the
  // others are not spooled), whose pass reads `batch_points` at a time (its
  // batches carry every attribute: the ingest's batch size keeps them within
  // its memory budget). Its readers punch a hole in their file over what
  // they have read, `release_bytes` or more at a time (where the file system
  // can), so the spool's disk goes back as the ingest's bucket files take
  // theirs. kIoError when its directory cannot be made.
  static constexpr std::uint64_t kReleaseBytes = std::uint64_t{64} << 20;
  static Result<std::shared_ptr<Spool>> create(const std::string& parent, std::vector<bool> wanted,
                                               std::size_t batch_points,
                                               std::uint64_t release_bytes = kReleaseBytes);
  ~Spool();
  Spool(const Spool&) = delete;
  Spool& operator=(const Spool&) = delete;

  bool wants(std::size_t input) const { return input < wanted_.size() && wanted_[input]; }
  std::size_t batch_points() const { return batch_points_; }
  // Appends a batch of input `input` (inputs in order), whose LAS offset and
  // scale (PointStreamInfo; scale 0 when none) may give x y z as integers.
  // A write error (a full disk) abandons the spool: its files are removed,
  // failure() says why, and later calls do nothing.
  void append(std::size_t input, const PointCloud& batch, const Vec3d& offset, const Vec3d& scale);
  // Input `input` has been read to its end; `info` is its reader's info()
  // then (counts, warnings, the colour rule: what only reading settles).
  void finish(std::size_t input, const PointStreamInfo& info);
  // Why the spool was abandoned; empty while it holds.
  const std::string& failure() const { return failure_; }
  std::uint64_t bytes_written() const { return bytes_written_; }

  // A reader of input `input`'s spooled points, whose info() is the one
  // finish() was given. The spool must be whole (failure() empty) and the
  // input finished.
  std::unique_ptr<PointReader> reader(std::size_t input);

  // Bytes a point takes in a spool file at most (x y z as doubles) with
  // these attributes, for the free-space check before spooling.
  static std::uint64_t point_bytes(const PointStreamInfo& info);

  // The file of input `input` (for tests and error messages).
  std::string file(std::size_t input) const;

 private:
  Spool() = default;
  void abandon(const std::string& why);
  void close_open();

  IngestTempDir dir_;
  std::vector<bool> wanted_;
  std::size_t batch_points_ = 0;
  std::uint64_t release_bytes_ = kReleaseBytes;
  std::vector<bool> finished_;
  std::vector<PointStreamInfo> infos_;
  int fd_ = -1;               // the file being written
  std::size_t fd_input_ = 0;  // its input
  std::uint64_t bytes_written_ = 0;
  std::string failure_;
  std::vector<std::int32_t> ints_;  // append() scratch
  std::vector<Vec3d> check_;
};

}  // namespace relief::ingest
