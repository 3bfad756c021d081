#include "support/limited_vfs.h"

#include <sqlite3.h>

#include <atomic>

namespace relief::test {
namespace {

// Bytes a main database file may reach; negative: no limit.
std::atomic<sqlite3_int64> g_main_limit{-1};
sqlite3_vfs* g_real = nullptr;

struct LimitedFile {
  sqlite3_file base;   // first: SQLite sees this
  sqlite3_file* real;  // the wrapped file, stored after this struct
  bool main_db;
};

sqlite3_file* real_of(sqlite3_file* f) { return reinterpret_cast<LimitedFile*>(f)->real; }

int x_close(sqlite3_file* f) { return real_of(f)->pMethods->xClose(real_of(f)); }
int x_read(sqlite3_file* f, void* p, int n, sqlite3_int64 at) { return real_of(f)->pMethods->xRead(real_of(f), p, n, at); }
int x_write(sqlite3_file* f, const void* p, int n, sqlite3_int64 at) {
  const sqlite3_int64 limit = g_main_limit.load();
  if (reinterpret_cast<LimitedFile*>(f)->main_db && limit >= 0 && at + n > limit) return SQLITE_FULL;
  return real_of(f)->pMethods->xWrite(real_of(f), p, n, at);
}
int x_truncate(sqlite3_file* f, sqlite3_int64 size) { return real_of(f)->pMethods->xTruncate(real_of(f), size); }
int x_sync(sqlite3_file* f, int flags) { return real_of(f)->pMethods->xSync(real_of(f), flags); }
int x_file_size(sqlite3_file* f, sqlite3_int64* size) { return real_of(f)->pMethods->xFileSize(real_of(f), size); }
int x_lock(sqlite3_file* f, int level) { return real_of(f)->pMethods->xLock(real_of(f), level); }
int x_unlock(sqlite3_file* f, int level) { return real_of(f)->pMethods->xUnlock(real_of(f), level); }
int x_check_reserved(sqlite3_file* f, int* out) { return real_of(f)->pMethods->xCheckReservedLock(real_of(f), out); }
int x_file_control(sqlite3_file* f, int op, void* arg) { return real_of(f)->pMethods->xFileControl(real_of(f), op, arg); }
int x_sector_size(sqlite3_file* f) { return real_of(f)->pMethods->xSectorSize(real_of(f)); }
int x_device(sqlite3_file* f) { return real_of(f)->pMethods->xDeviceCharacteristics(real_of(f)); }
int x_shm_map(sqlite3_file* f, int page, int size, int extend, void volatile** p) {
  return real_of(f)->pMethods->xShmMap(real_of(f), page, size, extend, p);
}
int x_shm_lock(sqlite3_file* f, int offset, int n, int flags) {
  return real_of(f)->pMethods->xShmLock(real_of(f), offset, n, flags);
}
void x_shm_barrier(sqlite3_file* f) { real_of(f)->pMethods->xShmBarrier(real_of(f)); }
int x_shm_unmap(sqlite3_file* f, int del) { return real_of(f)->pMethods->xShmUnmap(real_of(f), del); }
// No memory mapping (version 2 methods only): every write goes through x_write.
const sqlite3_io_methods kMethods = {2,          x_close,   x_read,       x_write,          x_truncate,
                                     x_sync,     x_file_size, x_lock,    x_unlock,         x_check_reserved,
                                     x_file_control, x_sector_size, x_device, x_shm_map,    x_shm_lock,
                                     x_shm_barrier, x_shm_unmap, nullptr,  nullptr};

int x_open(sqlite3_vfs*, sqlite3_filename name, sqlite3_file* f, int flags, int* out_flags) {
  auto* lf = reinterpret_cast<LimitedFile*>(f);
  lf->real = reinterpret_cast<sqlite3_file*>(lf + 1);
  lf->main_db = (flags & SQLITE_OPEN_MAIN_DB) != 0;
  const int rc = g_real->xOpen(g_real, name, lf->real, flags, out_flags);
  lf->base.pMethods = lf->real->pMethods != nullptr ? &kMethods : nullptr;
  return rc;
}

sqlite3_vfs g_vfs{};

}  // namespace

LimitedVfs::LimitedVfs() {
  g_real = sqlite3_vfs_find(nullptr);
  g_vfs = *g_real;
  g_vfs.zName = "relief-limited";
  g_vfs.szOsFile = static_cast<int>(sizeof(LimitedFile)) + g_real->szOsFile;
  g_vfs.xOpen = x_open;
  g_vfs.pNext = nullptr;
  ok_ = sqlite3_vfs_register(&g_vfs, 1) == SQLITE_OK;
}

LimitedVfs::~LimitedVfs() {
  g_main_limit = -1;
  sqlite3_vfs_unregister(&g_vfs);
  sqlite3_vfs_register(g_real, 1);
}

void LimitedVfs::limit_main_files(std::int64_t bytes) { g_main_limit = bytes; }

}  // namespace relief::test
