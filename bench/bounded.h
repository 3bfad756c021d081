// bench/codec's error-bounded sweep (see bounded.cpp).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "bench_common.h"

struct BoundedBenchOptions {
  std::vector<int> grids{10, 11, 12, 13, 14};  // G-PCC's g: T = max extent / 2^g / 2
  std::vector<int> color_tolerances{0, 8, 16};
  int repeat = 3;
  unsigned threads = 2;
};

void run_bounded_bench(Output& out, const std::vector<std::filesystem::path>& files, const std::string& anchors_dir,
                       const BoundedBenchOptions& options);
