// relief::retain_freed_memory() (relief/types.h).
#include <catch2/catch.hpp>

#include <condition_variable>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <thread>

#include "relief/types.h"
#include "support/skip.h"

#ifdef __GLIBC__
#include <malloc.h>
#endif

// A block of a few MB, below the mmap threshold retain_freed_memory sets.
constexpr std::size_t kBytes = 8u << 20;

// relief::retain_freed_memory(): a freed block of a few MB stays in the
// allocator (free bytes of the arena) instead of going back to the kernel,
// so the next chunk's buffers reuse its pages.
TEST_CASE("retain_freed_memory keeps a freed 8 MB block in the allocator", "[memory]") {
#if !defined(__GLIBC__) || defined(__SANITIZE_ADDRESS__)
  // AddressSanitizer replaces malloc: mallinfo2 does not describe its heap.
  WARN("skipped: needs glibc's malloc");
  relief::test::note_skipped();
#else
  relief::retain_freed_memory();
  void* p = std::malloc(kBytes);
  REQUIRE(p != nullptr);
  std::memset(p, 1, kBytes);
  // Not mapped by itself: with glibc's default threshold (128 KiB, raised
  // only by freeing a mapped block) an 8 MB block would be.
  CHECK(mallinfo2().hblkhd < kBytes);
  std::free(p);
  // The arena's free bytes (its top included) now hold the whole block.
  CHECK(mallinfo2().fordblks >= kBytes);
#endif
}

// ... and every thread allocates from one arena: a block one thread freed
// (while it still runs, so its arena stays attached to it) is the block the
// next thread's allocation of that size gets. With glibc's per-thread
// arenas the second thread would take an arena of its own.
TEST_CASE("retain_freed_memory has threads share one malloc arena", "[memory]") {
#if !defined(__GLIBC__) || defined(__SANITIZE_ADDRESS__)
  WARN("skipped: needs glibc's malloc");
  relief::test::note_skipped();
#else
  relief::retain_freed_memory();
  std::mutex mu;
  std::condition_variable cv;
  bool freed = false, done = false;
  void* first = nullptr;
  void* second = nullptr;
  std::thread a([&] {
    void* p = std::malloc(kBytes);
    std::memset(p, 1, kBytes);
    std::free(p);
    std::unique_lock<std::mutex> lock(mu);
    first = p;
    freed = true;
    cv.notify_all();
    cv.wait(lock, [&] { return done; });  // alive until the other thread allocated
  });
  {
    std::unique_lock<std::mutex> lock(mu);
    cv.wait(lock, [&] { return freed; });
  }
  std::thread b([&] {
    void* p = std::malloc(kBytes);
    std::memset(p, 2, kBytes);
    second = p;
    std::free(p);
  });
  b.join();
  {
    std::lock_guard<std::mutex> lock(mu);
    done = true;
  }
  cv.notify_all();
  a.join();
  CHECK(first != nullptr);
  CHECK(second == first);
#endif
}
