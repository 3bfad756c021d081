#include "io/output_file.h"

#include "core/file_io.h"
#include "core/host.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>
#include <utility>

namespace relief {

namespace {

std::string errno_text(int err) { return std::strerror(err); }

}  // namespace

Result<std::unique_ptr<OutputFile>> OutputFile::create(const std::string& path) {
  if (path.empty()) return invalid_argument("the output path is empty");
  if (path == "-") {
    // Whatever the program already printed through stdio must come first.
    std::fflush(stdout);
    return std::unique_ptr<OutputFile>(new OutputFile("stdout", "", STDOUT_FILENO, true));
  }
  // Refused now rather than by rename() after the whole output is written.
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode)) {
    return io_error(path + ": is a directory");
  }
  core::remove_stale_temps_beside(path);  // left by a killed writer of this path
  std::string tmp_path = core::temp_path_beside(path);
  // O_NOFOLLOW: a symlink planted under the predictable temporary name must
  // not redirect (and truncate) some other file.
  // Read and write: the LAS writer reads records back to rewrite them (read_at).
  const int fd = ::open(tmp_path.c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC | O_NOFOLLOW, 0666);
  if (fd < 0) {
    const int err = errno;
    // The usual cause, said plainly rather than through the temporary name.
    const std::string dir = std::filesystem::path(path).parent_path().string();
    if (err == ENOENT && !dir.empty() && !std::filesystem::exists(dir)) {
      return io_error(path + ": cannot create: the directory " + dir + " does not exist");
    }
    return io_error(path + ": cannot create temporary file '" + tmp_path + "': " + errno_text(err));
  }
  return std::unique_ptr<OutputFile>(new OutputFile(path, std::move(tmp_path), fd, false));
}

OutputFile::OutputFile(std::string path, std::string tmp_path, int fd, bool is_stdout)
    : path_(std::move(path)), tmp_path_(std::move(tmp_path)), fd_(fd), stdout_(is_stdout) {
  buf_.resize(kBlockSize);
}

OutputFile::~OutputFile() {
  if (!done_) discard();
}

Status OutputFile::write_all(const std::uint8_t* data, std::size_t n) {
  if (done_) return internal_error(path_ + ": the output is already closed");
  std::size_t written = 0;
  while (written < n) {
    const ssize_t w = ::write(fd_, data + written, n - written);
    if (w < 0) {
      if (errno == EINTR) continue;
      return io_error(path_ + ": write failed: " + errno_text(errno));
    }
    written += static_cast<std::size_t>(w);
  }
  flushed_ += n;
  return Status::ok();
}

Status OutputFile::flush() {
  if (used_ == 0) return Status::ok();
  const std::size_t n = used_;
  used_ = 0;  // the bytes are gone either way: on error the output is dead
  return write_all(buf_.data(), n);
}

Status OutputFile::room(std::size_t n, std::span<std::uint8_t>& out) {
  if (buf_.size() - used_ < n) RELIEF_RETURN_IF_ERROR(flush());
  if (buf_.size() < n) buf_.resize(n);  // flush() emptied it
  out = std::span<std::uint8_t>(buf_.data() + used_, buf_.size() - used_);
  return Status::ok();
}

Status OutputFile::append(const void* data, std::size_t n) {
  if (n == 0) return Status::ok();  // `data` may then be null (an empty vector's)
  const auto* bytes = static_cast<const std::uint8_t*>(data);
  if (buf_.size() - used_ < n) {
    RELIEF_RETURN_IF_ERROR(flush());
    // A block or more goes straight out instead of through the buffer.
    if (n >= buf_.size()) return write_all(bytes, n);
  }
  std::memcpy(buf_.data() + used_, bytes, n);
  used_ += n;
  return Status::ok();
}

Status OutputFile::patch(std::uint64_t offset, const void* data, std::size_t n) {
  if (stdout_) return internal_error(path_ + ": standard output cannot be patched");
  if (done_) return internal_error(path_ + ": the output is already closed");
  if (offset + n > position()) return internal_error(path_ + ": patch beyond the written data");
  RELIEF_RETURN_IF_ERROR(flush());
  const auto* bytes = static_cast<const std::uint8_t*>(data);
  std::size_t written = 0;
  while (written < n) {
    const ssize_t w =
        ::pwrite(fd_, bytes + written, n - written, static_cast<off_t>(offset + written));
    if (w < 0) {
      if (errno == EINTR) continue;
      return io_error(path_ + ": write failed: " + errno_text(errno));
    }
    written += static_cast<std::size_t>(w);
  }
  return Status::ok();
}

Status OutputFile::read_at(std::uint64_t offset, void* data, std::size_t n) {
  if (stdout_) return internal_error(path_ + ": standard output cannot be read back");
  if (done_) return internal_error(path_ + ": the output is already closed");
  if (offset + n > position()) return internal_error(path_ + ": read beyond the written data");
  RELIEF_RETURN_IF_ERROR(flush());
  const int e = pread_exact(fd_, data, n, offset);
  if (e == 0) return Status::ok();
  return io_error(path_ + ": read back failed: " + (e > 0 ? errno_text(e) : "the file is shorter than written"));
}

Status OutputFile::commit() {
  Status s = flush();
  if (!s.is_ok()) {
    discard();
    return s;
  }
  if (stdout_) {
    done_ = true;
    return Status::ok();
  }
  // No fsync: rename() already gives readers all-or-nothing visibility, and
  // durability across power loss is the caller's business (it costs a lot).
  // close() can report a delayed write error (NFS, quota), so it is checked.
  const int rc = ::close(fd_);
  fd_ = -1;
  if (rc != 0) {
    s = io_error(path_ + ": write failed on close: " + errno_text(errno));
    discard();
    return s;
  }
  if (std::rename(tmp_path_.c_str(), path_.c_str()) != 0) {
    s = io_error(path_ + ": cannot rename '" + tmp_path_ + "' into place: " + errno_text(errno));
    discard();
    return s;
  }
  done_ = true;
  return Status::ok();
}

void OutputFile::discard() {
  if (done_) return;
  done_ = true;
  used_ = 0;
  if (stdout_) return;  // what went out cannot be taken back; stdout stays open
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  ::unlink(tmp_path_.c_str());
}

Status write_file(const std::string& path, std::span<const std::uint8_t> data) {
  auto out = OutputFile::create(path);
  if (!out) return out.status();
  RELIEF_RETURN_IF_ERROR((*out)->append(data.data(), data.size()));
  return (*out)->commit();
}

}  // namespace relief
