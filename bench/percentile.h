// Latency percentiles of the end-to-end benchmarks: the value at rank p * n of the sorted
// samples (p = 1: the maximum), 0 for no samples.
#pragma once

#include <algorithm>
#include <vector>

namespace bgkmap::bench {

inline double Percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(p * static_cast<double>(v.size())))];
}

}  // namespace bgkmap::bench
