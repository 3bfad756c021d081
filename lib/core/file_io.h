// Whole reads of file descriptors. Internal to Relief (not installed).
#pragma once

#include <unistd.h>

#include <cerrno>
#include <cstddef>
#include <cstdint>

namespace relief {

// Reads exactly `n` bytes of `fd` at `offset` into `to`, going on after short
// reads and EINTR. Returns 0 when all were read, the errno of a failed read,
// or -1 when the file ends first; the caller says which file and why.
inline int pread_exact(int fd, void* to, std::size_t n, std::uint64_t offset) {
  auto* p = static_cast<std::uint8_t*>(to);
  while (n > 0) {
    const ssize_t r = ::pread(fd, p, n, static_cast<off_t>(offset));
    if (r < 0 && errno == EINTR) continue;
    if (r < 0) return errno;
    if (r == 0) return -1;
    p += r;
    offset += static_cast<std::uint64_t>(r);
    n -= static_cast<std::size_t>(r);
  }
  return 0;
}

}  // namespace relief
