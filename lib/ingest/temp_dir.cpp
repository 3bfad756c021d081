#include "ingest/temp_dir.h"

#include "core/host.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string_view>
#include <vector>

namespace relief::ingest {

namespace {

constexpr std::string_view kTempPrefix = "relief-ingest-";
constexpr std::size_t kTempSuffixLength = 6;
constexpr const char* kLockName = "lock";

struct TempDirOwner {
  std::string host;
  pid_t pid = 0;
};

bool is_alnum(char c) { return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z'); }

// The owner of a directory name made by IngestTempDir::create (pid 0 when the
// name is not one of ours). Read from the right: the host may hold dashes.
TempDirOwner temp_dir_owner(std::string_view name) {
  if (name.substr(0, kTempPrefix.size()) != kTempPrefix) return {};
  name.remove_prefix(kTempPrefix.size());
  if (name.size() < kTempSuffixLength + 1 || name[name.size() - kTempSuffixLength - 1] != '-') return {};
  for (const char c : name.substr(name.size() - kTempSuffixLength)) {
    if (!is_alnum(c)) return {};
  }
  name.remove_suffix(kTempSuffixLength + 1);
  const std::size_t dash = name.rfind('-');
  if (dash == 0 || dash == std::string_view::npos || dash + 1 == name.size()) return {};
  const core::LeadingPid owner = core::leading_pid(name.substr(dash + 1));
  if (owner.digits != name.size() - dash - 1) return {};
  return {std::string(name.substr(0, dash)), owner.pid};
}

// True when the directory's owner is gone. With a lock file, exactly when its
// lock can be taken (then held in `*lock_fd` until the directory is removed);
// without one (an owner killed between creating the directory and its lock),
// only for an owner of this host whose pid no longer exists. Anything unsure
// (no locks on this file system, a file we may not open) keeps the directory.
bool owner_gone(const std::string& dir, const TempDirOwner& owner, const std::string& host, int* lock_fd) {
  const std::string lock = dir + "/" + kLockName;
  const int fd = ::open(lock.c_str(), O_RDWR | O_CLOEXEC | O_NOFOLLOW);
  if (fd < 0) {
    if (errno != ENOENT || owner.host != host) return false;
    return core::pid_gone(owner.pid);
  }
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    ::close(fd);
    return false;
  }
  *lock_fd = fd;
  return true;
}

void remove_stale_temp_dirs(const std::string& parent, const std::string& host) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::directory_iterator it(parent, ec);
  if (ec) return;  // best effort: mkdtemp reports a bad parent
  for (; it != fs::directory_iterator(); it.increment(ec)) {
    if (ec) return;
    const TempDirOwner owner = temp_dir_owner(it->path().filename().string());
    if (owner.pid <= 0 || (owner.pid == ::getpid() && owner.host == host)) continue;
    // A real directory only (never follow a symlink out of `parent`).
    if (!fs::is_directory(it->symlink_status(ec)) || ec) continue;
    int lock_fd = -1;
    if (!owner_gone(it->path().string(), owner, host, &lock_fd)) continue;
    std::error_code ignored;
    fs::remove_all(it->path(), ignored);
    if (lock_fd >= 0) ::close(lock_fd);
  }
}

// Creates `dir`/kLockName locked: under another name first, renamed once
// locked, so no other process ever finds the lock file unlocked while its
// owner lives. Returns the descriptor that holds the lock, or -1 when the
// file system cannot lock: the directory then has no lock file and is swept
// only by the pid rule (its owner's host, its pid gone).
int create_lock(const std::string& dir) {
  const std::string staging = dir + "/" + kLockName + ".new";
  const int fd = ::open(staging.c_str(), O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  if (fd < 0) return -1;
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0 ||
      std::rename(staging.c_str(), (dir + "/" + kLockName).c_str()) != 0) {
    ::unlink(staging.c_str());
    ::close(fd);
    return -1;
  }
  return fd;
}

}  // namespace

Result<IngestTempDir> IngestTempDir::create(const std::string& parent) {
  const std::string dir = parent.empty() ? std::string(".") : parent;
  const std::string host = core::host_tag();
  remove_stale_temp_dirs(dir, host);
  std::string pattern = dir + "/" + std::string(kTempPrefix) + host + "-" + std::to_string(::getpid()) + "-" +
                        std::string(kTempSuffixLength, 'X');
  std::vector<char> templ(pattern.begin(), pattern.end());
  templ.push_back('\0');
  if (::mkdtemp(templ.data()) == nullptr) {
    return io_error(dir + ": cannot create a temporary directory: " + std::strerror(errno));
  }
  IngestTempDir t;
  t.path_ = templ.data();
  t.lock_fd_ = create_lock(t.path_);
  return t;
}

IngestTempDir::IngestTempDir(IngestTempDir&& o) noexcept { *this = std::move(o); }

IngestTempDir& IngestTempDir::operator=(IngestTempDir&& o) noexcept {
  if (this != &o) {
    remove();
    path_ = std::move(o.path_);
    lock_fd_ = o.lock_fd_;
    o.path_.clear();
    o.lock_fd_ = -1;
  }
  return *this;
}

IngestTempDir::~IngestTempDir() { remove(); }

void IngestTempDir::remove() {
  if (!path_.empty()) {
    // The lock file goes last, while still locked: a sweep that finds the
    // directory without it sees this host's live pid and keeps it.
    ::unlink((path_ + "/" + kLockName).c_str());
    ::rmdir(path_.c_str());
  }
  if (lock_fd_ >= 0) ::close(lock_fd_);
  lock_fd_ = -1;
  path_.clear();
}

}  // namespace relief::ingest
