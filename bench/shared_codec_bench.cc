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

void BM_Format2PerReceiver(benchmark::State& state) {
  const int receivers = static_cast<int>(state.range(0));
  const int n = static_cast<int>(state.range(1));
  auto frames = MakeFrames(n, 256);
  auto params = MakeQuantizationParams(QuantizationConfig{});
  std::vector<std::unique_ptr<DeltaEncoder>> enc;
  for (int r = 0; r < receivers; ++r) enc.push_back(std::make_unique<DeltaEncoder>(*params));
  std::vector<uint16_t> seq(receivers, 0);
  std::vector<PreparedState> prepared(n);
  std::vector<uint8_t> buf(kMaxUnreliablePayload);
  size_t f = 0, bytes = 0;
  for (auto _ : state) {
    const auto& frame = frames[f % frames.size()];
    const uint32_t time_ms = static_cast<uint32_t>(f * 1000 / kTickHz);
    const double now = static_cast<double>(f) / kTickHz;
    ++f;
    for (int i = 0; i < n; ++i) prepared[i] = PrepareState(*params, frame[i]);
    for (int r = 0; r < receivers; ++r) {
      DeltaEncoder& e = *enc[r];
      int i = 0;
      while (i < n) {
        e.Begin(buf, time_ms);
        while (i < n && e.Add(frame[i], &prepared[i])) ++i;
        bytes += e.Finish();
        e.OnSent(seq[r], now);
        e.OnPacketAcked(seq[r]++);
      }
    }
    benchmark::DoNotOptimize(buf.data());
  }
  ReportPerUpdate(state, receivers, n, bytes);
}

void BM_Format9PerReceiver(benchmark::State& state) {
  const int receivers = static_cast<int>(state.range(0));
  const int n = static_cast<int>(state.range(1));
  auto frames = MakeFrames(n, 256);
  auto params = MakeQuantizationParams(QuantizationConfig{});
  SharedDeltaRoom room(*params);
  std::vector<std::unique_ptr<SharedEntity>> entities;
  for (int i = 0; i < n; ++i) entities.push_back(std::make_unique<SharedEntity>());
  std::vector<std::unique_ptr<SharedDeltaStream>> streams;
  for (int r = 0; r < receivers; ++r) {
    streams.push_back(std::make_unique<SharedDeltaStream>(*params));
  }
  std::vector<uint16_t> seq(receivers, 0);
  std::vector<PreparedState> prepared(n);
  std::vector<uint8_t> buf(kMaxUnreliablePayload);
  size_t f = 0, bytes = 0;
  for (auto _ : state) {
    const auto& frame = frames[f % frames.size()];
    const double now = static_cast<double>(f) / kTickHz;
    room.BeginTick(static_cast<uint32_t>(f * 1000 / kTickHz));
    ++f;
    for (int i = 0; i < n; ++i) {
      prepared[i] = PrepareState(*params, frame[i]);
      room.PrepareEntity(*entities[i], prepared[i]);
    }
    for (int r = 0; r < receivers; ++r) {
      SharedDeltaStream& s = *streams[r];
      int i = 0;
      while (i < n) {
        s.Begin(buf, 0);
        while (i < n && s.Add(frame[i].entity_id, *entities[i])) ++i;
        bytes += s.Finish();
        s.OnSent(seq[r], now);
        s.OnPacketAcked(seq[r]++);
      }
    }
    benchmark::DoNotOptimize(buf.data());
  }
  ReportPerUpdate(state, receivers, n, bytes);
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
