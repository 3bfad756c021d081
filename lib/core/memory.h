// Memory hints for large, long-lived buffers. Internal.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace relief::core {

// Asks the kernel to back [p, p + bytes) with transparent huge pages where it
// supports them (Linux, THP in "madvise" mode, Debian's default). Call it on a
// buffer that is reserved but not yet written: first-touch page faults then
// cost one per 2 MiB instead of one per 4 KiB, which on a VM is most of the
// cost of filling a few hundred MB. Only whole huge pages inside the range
// are advised; a no-op elsewhere or on failure (it is a hint).
void advise_huge_pages(void* p, std::size_t bytes);

template <typename T>
void advise_huge_pages(std::vector<T>& v) {
  advise_huge_pages(v.data(), v.capacity() * sizeof(T));
}

// The process's resident set in bytes (Linux: /proc/self/statm), or 0 where
// it cannot be read.
std::uint64_t resident_bytes();

// Gives memory the allocator holds free back to the system (glibc:
// malloc_trim, which also covers the arenas of other threads, where freed
// blocks otherwise stay resident); a no-op elsewhere.
void release_free_memory();

}  // namespace relief::core
