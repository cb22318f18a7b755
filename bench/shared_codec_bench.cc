// Relay encoding cost per (receiver, entity): format 2 (one DeltaEncoder per receiver, the
// room's PreparedState shared) against format 9 (the room codes each (entity, key) body once
// per tick; receivers append bits), with R receivers all sent every entity each tick and a
// perfect network (acks before the next tick). Counted per iteration: one room tick, i.e. the
// per-entity preparation plus every receiver's payloads. Reported: ns_per_receiver_entity.
// Run: build/default/bench/shared_codec_bench --benchmark_min_time=0.3
#include <benchmark/benchmark.h>

#include <chrono>
#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include "bench/bench_frames.h"
#include "protocol/connection.h"
#include "protocol/delta_codec.h"
#include "protocol/shared_delta_codec.h"

namespace edgephys {
namespace {

constexpr int kTickHz = 12;  // every receiver gets every entity each tick (a 12 Hz class)

std::vector<std::vector<EntityState>> MakeFrames(int n, int frames) {
  return bench::MakeFrames(n, frames, kTickHz, /*first_id=*/1);
}

// Every iteration sent `n` entities to each of `receivers`: items processed (receiver-entity
// updates), ns per update and payload bytes per update (`bytes` over all iterations).
void ReportPerUpdate(benchmark::State& state, int receivers, int n, size_t bytes) {
  const double updates = static_cast<double>(state.iterations()) * receivers * n;
  state.SetItemsProcessed(static_cast<int64_t>(updates));
  state.counters["ns_per_receiver_entity"] =
      benchmark::Counter(updates, benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
  state.counters["payload_bytes_per_update"] = static_cast<double>(bytes) / updates;
}

// What both benchmarks share: `receivers` (range 0) and `n` entities (range 1), the frames,
// format 2's quantisation, each receiver's next sequence number, the tick's prepared states,
// the packet buffer and the payload bytes sent so far.
struct PerReceiverRun {
  explicit PerReceiverRun(const benchmark::State& state)
      : receivers(static_cast<int>(state.range(0))),
        n(static_cast<int>(state.range(1))),
        frames(MakeFrames(n, 256)),
        params(*MakeQuantizationParams(QuantizationConfig{})),
        seq(receivers, 0),
        prepared(n),
        buf(kMaxUnreliablePayload) {}

  // Sends entities 0..n-1 to receiver r through `stream` in as many packets as they take
  // (`add(i)` false: entity i did not fit), each sent and acknowledged at `now` at once.
  template <typename Stream, typename Add>
  void SendAll(Stream& stream, int r, uint32_t time_ms, double now, Add add) {
    int i = 0;
    while (i < n) {
      stream.Begin(buf, time_ms);
      while (i < n && add(i)) ++i;
      bytes += stream.Finish();
      stream.OnSent(seq[r], now);
      stream.OnPacketAcked(seq[r]++);
    }
  }

  const int receivers, n;
  const std::vector<std::vector<EntityState>> frames;
  const QuantizationParams params;
  std::vector<uint16_t> seq;
  std::vector<PreparedState> prepared;
  std::vector<uint8_t> buf;
  size_t bytes = 0;
};

void BM_Format2PerReceiver(benchmark::State& state) {
  PerReceiverRun run(state);
  std::vector<std::unique_ptr<DeltaEncoder>> enc;
  for (int r = 0; r < run.receivers; ++r) enc.push_back(std::make_unique<DeltaEncoder>(run.params));
  size_t f = 0;
  for (auto _ : state) {
    const auto& frame = run.frames[f % run.frames.size()];
    const uint32_t time_ms = static_cast<uint32_t>(f * 1000 / kTickHz);
    const double now = static_cast<double>(f) / kTickHz;
    ++f;
    for (int i = 0; i < run.n; ++i) run.prepared[i] = PrepareState(run.params, frame[i]);
    for (int r = 0; r < run.receivers; ++r) {
      DeltaEncoder& e = *enc[r];
      run.SendAll(e, r, time_ms, now, [&](int i) { return e.Add(frame[i], &run.prepared[i]); });
    }
    benchmark::DoNotOptimize(run.buf.data());
  }
  ReportPerUpdate(state, run.receivers, run.n, run.bytes);
}

void BM_Format9PerReceiver(benchmark::State& state) {
  PerReceiverRun run(state);
  SharedDeltaRoom room(run.params);
  std::vector<std::unique_ptr<SharedEntity>> entities;
  for (int i = 0; i < run.n; ++i) entities.push_back(std::make_unique<SharedEntity>());
  std::vector<std::unique_ptr<SharedDeltaStream>> streams;
  for (int r = 0; r < run.receivers; ++r) {
    streams.push_back(std::make_unique<SharedDeltaStream>(run.params));
  }
  size_t f = 0;
  for (auto _ : state) {
    const auto& frame = run.frames[f % run.frames.size()];
    const double now = static_cast<double>(f) / kTickHz;
    room.BeginTick(static_cast<uint32_t>(f * 1000 / kTickHz));
    ++f;
    for (int i = 0; i < run.n; ++i) {
      run.prepared[i] = PrepareState(run.params, frame[i]);
      room.PrepareEntity(*entities[i], run.prepared[i]);
    }
    for (int r = 0; r < run.receivers; ++r) {
      SharedDeltaStream& s = *streams[r];
      run.SendAll(s, r, 0, now, [&](int i) { return s.Add(frame[i].entity_id, *entities[i]); });
    }
    benchmark::DoNotOptimize(run.buf.data());
  }
  ReportPerUpdate(state, run.receivers, run.n, run.bytes);
  double hits = 0;
  for (const auto& s : streams) hits += static_cast<double>(s->stats().cache_hits);
  state.counters["cache_hit_ratio"] =
      hits / (hits + static_cast<double>(room.stats().encodes.load() + room.stats().uncached.load()));
}

BENCHMARK(BM_Format2PerReceiver)->Args({1, 200})->Args({100, 200})->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Format9PerReceiver)->Args({1, 200})->Args({100, 200})->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace edgephys

BENCHMARK_MAIN();
