// bench/ingest --dense: `relief compress` of inputs whose chunks are dense (a
// terrestrial scan's chunks beside the scanner, one chunk much larger than
// the memory budget's share, one larger than a slice of the 1 GiB default
// can hold) at several --memory budgets: wall time, peak
// RSS and the blobs, which must not change with the budget; and stage 2 of a
// sharded build holding the same scan in one key range.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace relief::bench {

struct DenseOptions {
  int repeat = 3;
  std::string tmp = "/tmp";
  std::string cli;  // the relief binary (--cli: another build, to compare)
  std::vector<std::string> budgets = {"128M", "256M", "1G"};
  // Case names (empty: all): scanner-12M, one-chunk-4M, one-chunk-16M,
  // shard-range-12M (the scanner scene as one key range of `relief
  // shard-encode`; its last row is a run without --memory).
  std::vector<std::string> cases;
  std::uint64_t seed = 1;
};

// Runs the measurements and prints the table; returns the exit code.
int run_dense(const DenseOptions& options);

}  // namespace relief::bench
