// Shared by the fuzz targets: draining a point reader with a bound that turns
// "unbounded work from a few bytes" into a crash the fuzzer reports.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <memory>

#include "relief/io.h"

namespace relief::fuzz {

// Batch size for draining readers: small, so a lying point count that a
// reader trusted for allocation would show up as a large batch anyway.
inline constexpr std::size_t kBatchPoints = 1024;

// Every point of every supported format takes at least one byte of input (a
// binary record of three 1-byte coordinates is 3 bytes, a text line at least
// "0 0 0" plus a separator), so a reader returning more points than the input
// has bytes is producing points from nothing: abort so the fuzzer keeps it.
inline void check_points_bounded(std::uint64_t points, std::size_t input_size, const char* what) {
  if (points > input_size) {
    std::fprintf(stderr, "%s: %llu points from %zu bytes\n", what, static_cast<unsigned long long>(points),
                 input_size);
    std::abort();
  }
}

// Reads every batch; errors are fine (that is what bad input must produce).
inline void drain(PointReader& reader, std::size_t input_size, const char* what) {
  PointCloud batch;
  std::uint64_t total = 0;
  for (;;) {
    auto n = reader.read(batch, kBatchPoints);
    if (!n.is_ok() || *n == 0) break;
    if (*n > kBatchPoints || batch.size() != *n) {
      std::fprintf(stderr, "%s: batch of %zu points (%zu in the cloud), asked for at most %zu\n", what, *n,
                   batch.size(), kBatchPoints);
      std::abort();
    }
    // Every carried attribute has one entry per point (extra bytes: its width each).
    const auto& info = reader.info();
    if (batch.las.extra_bytes.size() != static_cast<std::size_t>(info.extra_bytes_size) * *n &&
        (info.las_attributes & kLasExtraBytes) != 0) {
      std::fprintf(stderr, "%s: %zu extra bytes for %zu points of %u bytes\n", what, batch.las.extra_bytes.size(), *n,
                   static_cast<unsigned>(info.extra_bytes_size));
      std::abort();
    }
    total += *n;
    check_points_bounded(total, input_size, what);
  }
}

}  // namespace relief::fuzz
