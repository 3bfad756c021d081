// The median of the bench programs that time runs of the CLI or the
// library: the upper of the two middle values for an even count (a time
// actually measured), 0 for none. (bench/codec's bench_common.h averages
// the two middle values instead.)
#pragma once

#include <algorithm>
#include <vector>

namespace relief::bench {

inline double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : v[v.size() / 2];
}

}  // namespace relief::bench
