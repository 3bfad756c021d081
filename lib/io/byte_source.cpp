#include "io/byte_source.h"

#include <cctype>

#include "core/file_io.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cassert>
#include <cerrno>
#include <cstring>
#include <utility>

namespace relief {

namespace {

// Big enough that syscalls vanish from the profile, small enough to stay in
// the last-level cache while the decoder walks it.
constexpr std::size_t kBlockSize = std::size_t{1} << 20;

std::string errno_text(int err) { return std::strerror(err); }

}  // namespace

ByteSource ByteSource::from_memory(std::span<const std::uint8_t> data) {
  ByteSource s;
  s.data_ = data;
  s.end_ = data.size();
  s.size_ = data.size();
  s.eof_ = true;
  return s;
}

Result<ByteSource> ByteSource::open_file(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return io_error(path + ": cannot open: " + errno_text(errno));
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    const int err = errno;
    ::close(fd);
    return io_error(path + ": cannot stat: " + errno_text(err));
  }
  if (S_ISDIR(st.st_mode)) {
    ::close(fd);
    return io_error(path + ": cannot read: " + errno_text(EISDIR));
  }
  ByteSource s;
  s.fd_ = fd;
  s.path_ = path;
  if (S_ISREG(st.st_mode)) {
    // Only a regular file has a size worth trusting for bounds checks and seeks.
    s.size_ = static_cast<std::uint64_t>(st.st_size);
    s.seekable_ = true;
    ::posix_fadvise(fd, 0, 0, POSIX_FADV_SEQUENTIAL);
  }
  return s;
}

ByteSource::ByteSource(ByteSource&& other) noexcept { *this = std::move(other); }

ByteSource& ByteSource::operator=(ByteSource&& other) noexcept {
  if (this != &other) {
    close_file();
    data_ = other.data_;
    buf_ = std::move(other.buf_);
    begin_ = other.begin_;
    end_ = other.end_;
    base_ = other.base_;
    size_ = other.size_;
    fd_ = std::exchange(other.fd_, -1);
    seekable_ = other.seekable_;
    eof_ = other.eof_;
    path_ = std::move(other.path_);
  }
  return *this;
}

ByteSource::~ByteSource() { close_file(); }

void ByteSource::close_file() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

Status ByteSource::fill(std::size_t n, std::span<const std::uint8_t>& out) {
  if (fd_ < 0) {
    out = data_.subspan(begin_);
    return Status::ok();
  }
  if (end_ - begin_ < n && !eof_) RELIEF_RETURN_IF_ERROR(read_more(n));
  out = std::span<const std::uint8_t>(buf_.data() + begin_, end_ - begin_);
  return Status::ok();
}

void ByteSource::consume(std::size_t n) {
  assert(n <= end_ - begin_);
  begin_ += n;
}

Status ByteSource::read_more(std::size_t want) {
  // Move the unconsumed tail to the front so the next read lands after it.
  if (begin_ > 0) {
    std::memmove(buf_.data(), buf_.data() + begin_, end_ - begin_);
    base_ += begin_;
    end_ -= begin_;
    begin_ = 0;
  }
  if (buf_.size() < want || buf_.size() < kBlockSize) buf_.resize(std::max(want, kBlockSize));
  while (end_ < want && !eof_) {
    const ssize_t r = ::read(fd_, buf_.data() + end_, buf_.size() - end_);
    if (r < 0) {
      if (errno == EINTR) continue;
      return io_error(path_ + ": read failed at byte " + std::to_string(base_ + end_) + ": " +
                      errno_text(errno));
    }
    if (r == 0) {
      eof_ = true;
    } else {
      end_ += static_cast<std::size_t>(r);
    }
  }
  return Status::ok();
}

Result<ByteSource::Rest> ByteSource::read_rest() {
  constexpr std::size_t kBlock = std::size_t{1} << 16;
  Rest rest;
  bool blank = true;
  for (;;) {
    std::span<const std::uint8_t> view;
    RELIEF_RETURN_IF_ERROR(fill(kBlock, view));
    if (view.empty()) break;
    rest.bytes += view.size();
    for (const std::uint8_t c : view) {
      if (c == '\n') {
        if (!blank) ++rest.lines;
        blank = true;
      } else if (!std::isspace(c)) {
        blank = false;
      }
    }
    consume(view.size());
  }
  if (!blank) ++rest.lines;
  return rest;
}

Status ByteSource::skip(std::uint64_t n, std::uint64_t& skipped) {
  const std::size_t buffered = end_ - begin_;
  if (n <= buffered) {
    begin_ += static_cast<std::size_t>(n);
    skipped = n;
    return Status::ok();
  }
  skipped = buffered;
  if (fd_ < 0) {  // memory: the buffer is the whole input
    begin_ = end_;
    return Status::ok();
  }
  // Drop the buffer; the file offset is now base_ (the buffer is empty).
  base_ += end_;
  begin_ = end_ = 0;
  std::uint64_t left = n - buffered;
  if (seekable_ && size_) {
    const std::uint64_t avail = *size_ > base_ ? *size_ - base_ : 0;
    const std::uint64_t take = std::min(left, avail);
    if (take > 0 && ::lseek(fd_, static_cast<off_t>(take), SEEK_CUR) < 0) {
      return io_error(path_ + ": seek failed at byte " + std::to_string(base_) + ": " +
                      errno_text(errno));
    }
    base_ += take;
    skipped += take;
    if (take < left) eof_ = true;
    return Status::ok();
  }
  // Pipes and devices: read and discard.
  while (left > 0 && !eof_) {
    RELIEF_RETURN_IF_ERROR(read_more(1));
    const std::size_t take = static_cast<std::size_t>(std::min<std::uint64_t>(left, end_ - begin_));
    begin_ += take;
    left -= take;
    skipped += take;
  }
  return Status::ok();
}

Status ByteSource::read_at(std::uint64_t offset, std::span<std::uint8_t> out, std::size_t& got) const {
  got = 0;
  if (fd_ < 0) {  // memory
    if (offset >= data_.size()) return Status::ok();
    got = static_cast<std::size_t>(std::min<std::uint64_t>(out.size(), data_.size() - offset));
    std::memcpy(out.data(), data_.data() + offset, got);
    return Status::ok();
  }
  if (!seekable_) return unsupported(path_ + ": cannot be read out of order (a pipe or device, not a regular file)");
  // An early end leaves got short, which the caller judges.
  const int e = pread_exact(fd_, out.data(), out.size(), offset, &got);
  if (e > 0) return io_error(path_ + ": read failed at byte " + std::to_string(offset + got) + ": " + errno_text(e));
  return Status::ok();
}

}  // namespace relief
