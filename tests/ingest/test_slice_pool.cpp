// The ingest's pool of bucket slices (internal to lib/ingest): slices within
// the share it keeps are recycled with their buffers, larger ones are freed
// when let go, so one oversized bucket does not hold its size for the rest of
// the ingest.
#include <catch2/catch.hpp>

#include <memory>
#include <thread>

#include "ingest/slice_pool.h"

using relief::ingest::Slice;
using relief::ingest::slice_capacity;
using relief::ingest::SlicePool;

namespace {

constexpr std::uint64_t kKeep = 1000;

// Takes a slice from the pool and gives it room for `points` points, as
// reading a bucket does.
std::shared_ptr<Slice> slice_of(SlicePool& pool, std::size_t points) {
  std::shared_ptr<Slice> s = pool.acquire();
  s->points.reserve(points, true, true);
  s->grouping.ids.reserve(points);
  return s;
}

}  // namespace

TEST_CASE("slice pool: a slice within the share is recycled with its buffers") {
  SlicePool pool(kKeep);
  std::shared_ptr<Slice> s = slice_of(pool, kKeep);
  const Slice* first = s.get();
  s.reset();
  CHECK(pool.kept() == 1);
  std::shared_ptr<Slice> again = pool.acquire();
  CHECK(again.get() == first);
  CHECK(slice_capacity(*again) >= kKeep);
  CHECK(pool.kept() == 0);
}

TEST_CASE("slice pool: a slice grown beyond the share is freed, not kept") {
  SlicePool pool(kKeep);
  // Recycled once within the share, then grown past it by a larger bucket.
  slice_of(pool, kKeep / 2).reset();
  REQUIRE(pool.kept() == 1);
  std::shared_ptr<Slice> big = slice_of(pool, kKeep + 1);
  CHECK(slice_capacity(*big) > kKeep);
  CHECK(pool.kept() == 0);
  big.reset();
  CHECK(pool.kept() == 0);
  CHECK(slice_capacity(*pool.acquire()) == 0);  // a fresh slice
}

TEST_CASE("slice pool: the rule holds for slices let go by another thread") {
  SlicePool pool(kKeep);
  std::shared_ptr<Slice> small = slice_of(pool, kKeep);
  std::shared_ptr<Slice> big = slice_of(pool, 4 * kKeep);
  std::thread worker([s = std::move(small), b = std::move(big)]() mutable {
    s.reset();
    b.reset();
  });
  worker.join();
  CHECK(pool.kept() == 1);
  pool.clear();
  CHECK(pool.kept() == 0);
}
