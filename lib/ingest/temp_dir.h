// The private directory an ingest keeps its temporary files in (bucket files,
// the spool of decoded inputs), and the sweep of ones their owners left
// behind. Internal to ingest.
#pragma once

#include <string>

#include "relief/status.h"

namespace relief::ingest {

// A directory named "relief-ingest-" + host + "-" + owner pid + "-" + six
// characters of mkdtemp, holding a lock file that its owner keeps locked
// (flock) while it lives, so a later run can tell a stale one: its lock can
// be taken (the owner is gone, on whatever machine or in whatever pid
// namespace it ran), or, before the lock exists, the owner ran on this host
// and its pid is gone.
class IngestTempDir {
 public:
  // Creates one under `parent` ("." when empty), after removing the stale
  // ones there (a run killed with SIGKILL cannot remove its own). kIoError
  // naming `parent` when it cannot.
  static Result<IngestTempDir> create(const std::string& parent);
  IngestTempDir() = default;
  IngestTempDir(IngestTempDir&&) noexcept;
  IngestTempDir& operator=(IngestTempDir&&) noexcept;
  IngestTempDir(const IngestTempDir&) = delete;
  IngestTempDir& operator=(const IngestTempDir&) = delete;
  // remove().
  ~IngestTempDir();

  // Empty when none (default-constructed, moved from or removed).
  const std::string& path() const { return path_; }
  // Removes the lock file and the directory, which the owner has emptied of
  // its own files first (a directory still holding some stays, with them).
  void remove();

 private:
  std::string path_;
  int lock_fd_ = -1;  // holds the lock file locked
};

}  // namespace relief::ingest
