// Samples per second of each client-side interpolator (client/interpolation.h) on a full
// jitter buffer (32 snapshots of a screw motion at 30 Hz), at render times spread over the
// buffered span plus a little extrapolation.
#include <benchmark/benchmark.h>

#include <array>
#include <cmath>
#include <random>
#include <utility>
#include <vector>

#include "client/interpolation.h"
#include "client/snapshot_buffer.h"

namespace edgephys {
namespace {

SnapshotBuffer MakeScrewBuffer() {
  SnapshotBuffer buffer;
  const Eigen::Vector3f axis = Eigen::Vector3f(0.2f, 1, 0.3f).normalized();
  const Eigen::Vector3f offset = axis.unitOrthogonal();
  for (int i = 0; i < 32; ++i) {
    const float t = static_cast<float>(i) / 30;
    const Eigen::Quaternionf r(Eigen::AngleAxisf(2.0f * t, axis));
    buffer.Insert({.sender_time_s = t,
                   .position = FromEigen(r * offset + axis * (0.3f * t)),
                   .rotation = FromEigen(r)},
                  t + 0.05);
  }
  return buffer;
}

void BM_Sample(benchmark::State& state) {
  const auto method = static_cast<Interpolator>(state.range(0));
  const SnapshotBuffer buffer = MakeScrewBuffer();
  // 97 render times (a prime count, so the pattern does not align with snapshot spacing).
  std::array<double, 97> times;
  const double span = buffer.newest().sender_time_s + 0.05;
  for (size_t i = 0; i < times.size(); ++i) times[i] = span * static_cast<double>(i) / 97;
  size_t i = 0;
  for (auto _ : state) {
    Pose pose = Sample(buffer, times[i], method);
    benchmark::DoNotOptimize(pose);
    if (++i == times.size()) i = 0;
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations()));
  state.SetLabel(InterpolatorName(method));
}
BENCHMARK(BM_Sample)
    ->Arg(static_cast<int>(Interpolator::kLerpSlerp))
    ->Arg(static_cast<int>(Interpolator::kDualQuatDlb))
    ->Arg(static_cast<int>(Interpolator::kDualQuatSclerp))
    ->Arg(static_cast<int>(Interpolator::kHermite))
    ->Arg(static_cast<int>(Interpolator::kNone));

void BM_InsertInOrder(benchmark::State& state) {
  SnapshotBuffer buffer;
  double t = 0;
  for (auto _ : state) {
    t += 1.0 / 30;
    benchmark::DoNotOptimize(buffer.Insert({.sender_time_s = t}, t + 0.05));
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations()));
}
BENCHMARK(BM_InsertInOrder);

// Insert with what a real link does: +-20 ms arrival jitter, 5 % loss and the occasional late
// (reordered) snapshot, so the estimates' windows and the in-place insertion both get exercised.
// The arrival pattern is precomputed (a prime count of them, replayed with a growing time base).
void BM_InsertJittered(benchmark::State& state) {
  struct Arrival {
    double sent, received;
  };
  std::vector<Arrival> pattern;
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int i = 0; i < 4093; ++i) {
    if (unit(rng) < 0.05) continue;
    const double sent = i / 30.0;
    pattern.push_back({sent, sent + 0.05 + 0.04 * unit(rng)});
  }
  for (size_t i = 0; i + 1 < pattern.size(); i += 7) std::swap(pattern[i], pattern[i + 1]);
  const double period = 4093 / 30.0;
  SnapshotBuffer buffer;
  size_t i = 0;
  double base = 0;
  for (auto _ : state) {
    const Arrival& a = pattern[i];
    benchmark::DoNotOptimize(buffer.Insert({.sender_time_s = base + a.sent}, base + a.received));
    if (++i == pattern.size()) i = 0, base += period;
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations()));
}
BENCHMARK(BM_InsertJittered);

}  // namespace
}  // namespace edgephys

BENCHMARK_MAIN();
