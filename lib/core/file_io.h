// Whole reads of file descriptors. Internal to Relief (not installed).
#pragma once

#include <unistd.h>

#include <cerrno>
#include <cstddef>
#include <cstdint>

namespace relief {

// Reads exactly `n` bytes of `fd` at `offset` into `to`, going on after short
// reads and EINTR. Returns 0 when all were read, the errno of a failed read,
// or -1 when the file ends first; the caller says which file and why. `got`,
// when given, is set to the bytes read either way.
inline int pread_exact(int fd, void* to, std::size_t n, std::uint64_t offset, std::size_t* got = nullptr) {
  auto* p = static_cast<std::uint8_t*>(to);
  std::size_t done = 0;
  int result = 0;
  while (done < n) {
    const ssize_t r = ::pread(fd, p + done, n - done, static_cast<off_t>(offset + done));
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) {
      result = r < 0 ? errno : -1;
      break;
    }
    done += static_cast<std::size_t>(r);
  }
  if (got != nullptr) *got = done;
  return result;
}

}  // namespace relief
