// Minimal data-parallel helper. Internal to Relief.
#pragma once

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <mutex>
#include <thread>
#include <vector>

#include "relief/status.h"

namespace relief {

// Number of worker threads to use for `requested` (0 = all cores).
inline unsigned resolve_threads(unsigned requested) {
  if (requested != 0) return requested;
  const unsigned hw = std::thread::hardware_concurrency();
  return hw == 0 ? 1 : hw;
}

// Calls fn(begin, end, worker) on `threads` contiguous slices of [0, n).
// fn must not throw. With fewer than two items a thread (n < 2 * threads) it
// runs fn(0, n, 0) on the calling thread alone: for many small items; to run
// a few large ones side by side, use for_each_parallel.
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

// Calls fn(i) for every i in [0, n) on up to `threads` threads, the calling
// one included, each taking the next index as it finishes one (items of
// uneven cost balance themselves). fn must not throw.
template <typename Fn>
void for_each_parallel(std::size_t n, unsigned threads, Fn&& fn) {
  std::atomic<std::size_t> next{0};
  const auto worker = [&] {
    for (std::size_t i = next.fetch_add(1); i < n; i = next.fetch_add(1)) fn(i);
  };
  std::vector<std::thread> pool;
  const std::size_t helpers = n == 0 ? 0 : std::min<std::size_t>(std::max(1u, threads), n) - 1;
  for (std::size_t t = 0; t < helpers; ++t) pool.emplace_back(worker);
  worker();
  for (std::thread& t : pool) t.join();
}

// An ordered pipeline over items [0, n): the calling thread runs
// read(i, slot) up to `window` items ahead of the next one it delivers,
// `threads` workers run work(i, slot) on items as they are read, and the
// calling thread runs deliver(i, slot, stop) in index order once an item's
// work is done. So reading (e.g. one SQLite connection), working and
// delivering (e.g. a file writer) overlap, no worker waits for a batch's
// slowest item, and at most `window` slots are alive. A slot is reset to
// Slot{} before each read. deliver returning an error, or setting `stop`,
// ends the pipeline: workers finish the item in hand and are joined before
// this returns. read, work and deliver must not throw.
template <typename Slot, typename Read, typename Work, typename Deliver>
Status ordered_pipeline(std::size_t n, unsigned threads, std::size_t window, Read&& read, Work&& work,
                        Deliver&& deliver) {
  if (n == 0) return Status::ok();
  window = std::max<std::size_t>(1, std::min(window, n));
  struct Entry {
    Slot slot;
    bool done = false;  // guarded by `mutex`
  };
  std::vector<Entry> ring(window);
  std::mutex mutex;
  std::condition_variable changed;
  std::size_t read_upto = 0;    // items [0, read_upto) have been read
  std::size_t next_work = 0;    // the next item a worker takes
  bool stop_workers = false;
  const auto worker = [&] {
    for (;;) {
      std::size_t i = 0;
      {
        std::unique_lock<std::mutex> lock(mutex);
        changed.wait(lock, [&] { return stop_workers || next_work < read_upto; });
        if (stop_workers) return;
        i = next_work++;
      }
      Entry& e = ring[i % window];
      work(i, e.slot);
      {
        std::lock_guard<std::mutex> lock(mutex);
        e.done = true;
      }
      changed.notify_all();
    }
  };
  std::vector<std::thread> pool;
  // Stops and joins the workers on every way out.
  struct Joiner {
    std::mutex& mutex;
    std::condition_variable& changed;
    bool& stop_workers;
    std::vector<std::thread>& pool;
    ~Joiner() {
      {
        std::lock_guard<std::mutex> lock(mutex);
        stop_workers = true;
      }
      changed.notify_all();
      for (std::thread& t : pool) t.join();
    }
  } joiner{mutex, changed, stop_workers, pool};
  const auto workers = static_cast<unsigned>(std::min<std::size_t>(std::max(1u, threads), n));
  for (unsigned t = 0; t < workers; ++t) pool.emplace_back(worker);

  for (std::size_t next = 0; next < n; ++next) {
    // Read into the free slots: a slot is free once its item was delivered,
    // and workers touch only items below read_upto.
    while (read_upto < n && read_upto < next + window) {
      Entry& e = ring[read_upto % window];
      e.slot = Slot{};
      e.done = false;  // no worker can see this entry until read_upto moves
      read(read_upto, e.slot);
      {
        std::lock_guard<std::mutex> lock(mutex);
        ++read_upto;
      }
      changed.notify_all();
    }
    Entry& e = ring[next % window];
    {
      std::unique_lock<std::mutex> lock(mutex);
      changed.wait(lock, [&] { return e.done; });
    }
    bool stop = false;
    RELIEF_RETURN_IF_ERROR(deliver(next, e.slot, stop));
    if (stop) break;
  }
  return Status::ok();
}

}  // namespace relief
