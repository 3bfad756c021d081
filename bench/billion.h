// bench/ingest --billion: `relief compress` fed a generated aerial survey
// (bench/scene.h) through a named pipe at 10 M, 100 M and (opt-in) 1 B points.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace relief::bench {

struct BillionOptions {
  std::vector<std::uint64_t> sizes = {10'000'000, 100'000'000};
  int repeat = 3;            // runs of sizes up to 10 M; larger sizes run once
  std::string tmp = "/tmp";  // the pipe, the archive and relief's bucket files
  std::string cli;           // the relief binary
  std::uint64_t seed = 1;
  // When set, each size's last archive is moved here (as scene-10M.relief,
  // ...) instead of being removed, e.g. for bench/pyramid.
  std::string keep;
};

// "10M,100M,1G" (K, M, G = 10^3, 10^6, 10^9; plain numbers are points);
// empty on a malformed list.
std::vector<std::uint64_t> parse_point_counts(const std::string& text);

// Runs the measurements and prints the table; returns the exit code.
int run_billion(const BillionOptions& options);

}  // namespace relief::bench
