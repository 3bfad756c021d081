// A SQLite VFS for tests of a full disk: it wraps the default VFS and
// refuses (SQLITE_FULL) any write that would take a main database file
// beyond a byte limit, while the -wal and journal files grow freely, as on a
// disk whose last free blocks went to the write-ahead log.
#pragma once

#include <cstdint>

namespace relief::test {

// Registers the limiting VFS as SQLite's default while it lives (one at a
// time); connections opened meanwhile use it.
class LimitedVfs {
 public:
  LimitedVfs();
  ~LimitedVfs();
  LimitedVfs(const LimitedVfs&) = delete;
  LimitedVfs& operator=(const LimitedVfs&) = delete;
  bool ok() const { return ok_; }
  // Bytes a main database file may reach from now on; negative: no limit.
  void limit_main_files(std::int64_t bytes);

 private:
  bool ok_ = false;
};

}  // namespace relief::test
