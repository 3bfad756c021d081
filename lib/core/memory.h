// Memory hints for large, long-lived buffers. Internal.
#pragma once

#include <cstddef>
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

}  // namespace relief::core
