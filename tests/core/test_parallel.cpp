// core/parallel.h's ordered pipeline: every item read once, worked once and
// delivered once in index order, whatever the threads and window; an error
// or a stop from deliver ends it with the workers joined.
#include <catch2/catch.hpp>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <string>
#include <vector>

#include "core/parallel.h"

namespace relief {

namespace {

struct Slot {
  std::size_t item = 0;
  std::uint64_t value = 0;
};

// Uneven work, so items finish out of order with several workers.
std::uint64_t slow_square(std::size_t i) {
  std::uint64_t acc = 0;
  const std::size_t rounds = (i * 7919) % 5000;
  for (std::size_t r = 0; r < rounds; ++r) acc = acc * 6364136223846793005ull + r;
  volatile std::uint64_t keep = acc;  // the loop is the point: uneven work
  (void)keep;
  return static_cast<std::uint64_t>(i) * i;
}

}  // namespace

TEST_CASE("ordered_pipeline delivers every item once, in order, whatever threads and window", "[core][parallel]") {
  for (const unsigned threads : {1u, 2u, 5u}) {
    for (const std::size_t window : {std::size_t{1}, std::size_t{3}, std::size_t{64}}) {
      for (const std::size_t n : {std::size_t{0}, std::size_t{1}, std::size_t{200}}) {
        CAPTURE(threads, window, n);
        std::vector<int> reads(n, 0);
        std::atomic<std::size_t> worked{0};
        std::vector<std::size_t> delivered;
        std::size_t alive = 0, most_alive = 0;  // read but not yet delivered
        const Status s = ordered_pipeline<Slot>(
            n, threads, window,
            [&](std::size_t i, Slot& slot) {
              CHECK(slot.value == 0);  // a fresh slot
              slot.item = i;
              ++reads[i];
              most_alive = std::max(most_alive, ++alive);
            },
            [&](std::size_t i, Slot& slot) {
              slot.value = slow_square(i);
              ++worked;
            },
            [&](std::size_t i, Slot& slot, bool&) -> Status {
              --alive;
              if (slot.item != i || slot.value != static_cast<std::uint64_t>(i) * i) {
                return internal_error("item " + std::to_string(i) + " got slot of " + std::to_string(slot.item));
              }
              delivered.push_back(i);
              return Status::ok();
            });
        REQUIRE(s.is_ok());
        CHECK(worked == n);
        CHECK(std::all_of(reads.begin(), reads.end(), [](int r) { return r == 1; }));
        std::vector<std::size_t> want(n);
        for (std::size_t i = 0; i < n; ++i) want[i] = i;
        CHECK(delivered == want);
        CHECK(most_alive <= std::max<std::size_t>(window, 1));
      }
    }
  }
}

TEST_CASE("ordered_pipeline stops at deliver's error or stop, and nothing is delivered after", "[core][parallel]") {
  for (const unsigned threads : {1u, 3u}) {
    std::vector<std::size_t> delivered;
    const Status failed = ordered_pipeline<Slot>(
        100, threads, 6, [](std::size_t, Slot&) {}, [](std::size_t, Slot&) {},
        [&](std::size_t i, Slot&, bool&) -> Status {
          delivered.push_back(i);
          return i == 9 ? io_error("full disk") : Status::ok();
        });
    CHECK(failed.code() == StatusCode::kIoError);
    CHECK(delivered.size() == 10);

    delivered.clear();
    std::atomic<std::size_t> worked{0};
    const Status stopped = ordered_pipeline<Slot>(
        1000, threads, 4, [](std::size_t, Slot&) {}, [&](std::size_t, Slot&) { ++worked; },
        [&](std::size_t i, Slot&, bool& stop) -> Status {
          delivered.push_back(i);
          stop = i == 20;
          return Status::ok();
        });
    CHECK(stopped.is_ok());
    CHECK(delivered.size() == 21);
    CHECK(worked <= 21 + 4);  // no more than the window beyond the stop
  }
}

}  // namespace relief

namespace relief {

TEST_CASE("for_each_parallel calls fn once for every index, whatever the threads", "[core][parallel]") {
  for (const std::size_t n : {std::size_t{0}, std::size_t{1}, std::size_t{7}, std::size_t{1000}}) {
    for (const unsigned threads : {0u, 1u, 2u, 5u, 64u}) {
      INFO(n << " items, " << threads << " threads");
      std::vector<std::atomic<int>> calls(n);
      std::vector<std::uint64_t> out(n, 0);
      for_each_parallel(n, threads, [&](std::size_t i) {
        calls[i].fetch_add(1);
        out[i] = slow_square(i);
      });
      for (std::size_t i = 0; i < n; ++i) {
        REQUIRE(calls[i].load() == 1);
        REQUIRE(out[i] == std::uint64_t{i} * i);
      }
    }
  }
}

}  // namespace relief
