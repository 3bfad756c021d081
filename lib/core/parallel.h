// Minimal data-parallel helper. Internal to Relief.
#pragma once

#include <algorithm>
#include <cstddef>
#include <thread>
#include <vector>

namespace relief {

// Number of worker threads to use for `requested` (0 = all cores).
inline unsigned resolve_threads(unsigned requested) {
  if (requested != 0) return requested;
  const unsigned hw = std::thread::hardware_concurrency();
  return hw == 0 ? 1 : hw;
}

// Calls fn(begin, end, worker) on `threads` contiguous slices of [0, n).
// fn must not throw.
template <typename Fn>
void parallel_for_ranges(std::size_t n, unsigned threads, Fn&& fn) {
  threads = std::max(1u, threads);
  if (threads == 1 || n < 2 * threads) {
    fn(std::size_t{0}, n, 0u);
    return;
  }
  std::vector<std::thread> pool;
  const std::size_t step = (n + threads - 1) / threads;
  for (unsigned t = 0; t < threads; ++t) {
    const std::size_t b = std::min(n, t * step);
    const std::size_t e = std::min(n, b + step);
    if (b >= e) break;
    pool.emplace_back([&fn, b, e, t] { fn(b, e, t); });
  }
  for (auto& th : pool) th.join();
}

}  // namespace relief
