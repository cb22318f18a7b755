// Small statistics helpers for the load generator: max, percentiles and medians of samples, and
// a seeded random generator that gives the same numbers on every platform.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
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

// The median and the 99th percentile of `v` into *p50 and *p99 (Percentile's nearest rank).
inline void SetP50P99(const std::vector<double>& v, double* p50, double* p99) {
  *p50 = Percentile(v, 50);
  *p99 = Percentile(v, 99);
}

inline double Max(const std::vector<double>& v) {
  return v.empty() ? 0 : *std::max_element(v.begin(), v.end());
}

// SplitMix64: a tiny, fully specified generator, so runs are identical on every platform
// (std::uniform_real_distribution is implementation-defined).
class SplitMix64 {
 public:
  explicit SplitMix64(uint64_t seed) : state_(seed) {}
  uint64_t Next() {
    uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  // Uniform in [0, 1).
  double Uniform() { return static_cast<double>(Next() >> 11) * (1.0 / 9007199254740992.0); }

 private:
  uint64_t state_;
};

}  // namespace edgephys::loadgen
