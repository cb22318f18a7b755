// Benchmark input shared by the codec benchmarks: `frames` x `n` smooth entity states sampled
// at `tick_hz` (circles of random radius on a 4 m grid, spinning about a tilted axis), entity
// ids first_id .. first_id + n - 1. Deterministic (seed 1). Header-only, bench/ only.
#pragma once

#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>
#include <vector>

#include "protocol/types.h"

namespace edgephys::bench {

inline std::vector<std::vector<EntityState>> MakeFrames(int n, int frames, double tick_hz,
                                                        uint32_t first_id) {
  constexpr double kPi = std::numbers::pi;
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<std::vector<EntityState>> out(frames, std::vector<EntityState>(n));
  for (int i = 0; i < n; ++i) {
    const double r = 1.5 + 3 * u(rng), ph = 2 * kPi * u(rng), tilt = u(rng);
    for (int f = 0; f < frames; ++f) {
      const double t = f / tick_hz;
      const double a = ph + 1.5 / r * t;
      EntityState& s = out[f][i];
      s.entity_id = first_id + static_cast<uint32_t>(i);
      s.position = {static_cast<float>(i % 16 * 4 + r * std::cos(a)), 1.f,
                    static_cast<float>(i / 16 * 4 + r * std::sin(a))};
      const double half = 0.5 * (kPi / 2) * t;
      s.rotation = {static_cast<float>(std::sin(tilt) * std::sin(half)),
                    static_cast<float>(std::cos(tilt) * std::sin(half)), 0.f,
                    static_cast<float>(std::cos(half))};
    }
  }
  return out;
}

}  // namespace edgephys::bench
