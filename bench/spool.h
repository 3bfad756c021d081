// bench/ingest --spool: `relief compress` of LAZ and text inputs larger than
// its in-memory path, with the spool of decoded points (the default,
// lib/ingest/spool.h) and with --no-spool (each input decompressed or parsed
// twice), alternating: wall and CPU seconds, peak RSS, and the blobs, which
// must be the same.
#pragma once

#include <cstdint>
#include <string>

namespace relief::bench {

struct SpoolOptions {
  int repeat = 3;
  std::string tmp = "/tmp";
  std::string cli;                      // the relief binary
  std::string data_dir;                 // the shared data (the aerial tile's LAZ at --memory 64M)
  std::uint64_t points = 10000000;      // the generated scene, as LAZ (LAS 1.2 format 3)
  std::uint64_t text_points = 3000000;  // its first points as CSV (x y z r g b i)
  std::uint64_t seed = 1;
};

// Writes the inputs to `tmp`, runs the measurements, prints the table and
// removes the inputs; returns the exit code (1 when a run failed or the
// blobs differ).
int run_spool(const SpoolOptions& options);

}  // namespace relief::bench
