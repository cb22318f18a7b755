// Small statistics helpers for the load generator: max, percentiles and medians of samples.
#pragma once

#include <algorithm>
#include <cstddef>
#include <vector>

namespace edgephys::loadgen {

// Percentile p in [0, 100] by nearest rank; 0 for no samples. Sorts a copy.
inline double Percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  size_t rank = static_cast<size_t>(p / 100.0 * static_cast<double>(v.size() - 1) + 0.5);
  return v[std::min(rank, v.size() - 1)];
}

inline double Median(std::vector<double> v) { return Percentile(std::move(v), 50); }

inline double Max(const std::vector<double>& v) {
  return v.empty() ? 0 : *std::max_element(v.begin(), v.end());
}

}  // namespace edgephys::loadgen
