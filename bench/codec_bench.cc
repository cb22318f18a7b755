// Format 1 (float) vs format 2 (quantized delta) state codecs: entities encoded / decoded per
// second, and bytes per entity, on the acceptance-like motion (1.5 m/s, 90 deg/s, 12 Hz).
// Run: build/codec/bench/codec_bench [--benchmark_format=csv]
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>
#include <vector>

#include "bench/bench_frames.h"
#include "protocol/connection.h"
#include "protocol/delta_codec.h"
#include "protocol/state_codec.h"

namespace edgephys {
namespace {


std::vector<std::vector<EntityState>> MakeFrames(int n, int frames) {
  return bench::MakeFrames(n, frames, 12.0, /*first_id=*/0);
}

void BM_Format1Encode(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  auto frames = MakeFrames(n, 64);
  std::vector<uint8_t> buf(kMaxUnreliablePayload);
  FloatStateEncoder enc;
  size_t f = 0, bytes = 0;
  for (auto _ : state) {
    const auto& frame = frames[f++ % frames.size()];
    size_t i = 0;
    while (i < frame.size()) {
      enc.Begin(buf, 0);
      while (i < frame.size() && enc.Add(frame[i])) ++i;
      bytes += enc.Finish();
    }
    benchmark::DoNotOptimize(buf.data());
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations()) * n);
  state.counters["payload_bytes_per_entity"] =
      static_cast<double>(bytes) / (static_cast<double>(state.iterations()) * n);
}

void BM_Format2Encode(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  auto frames = MakeFrames(n, 64);
  std::vector<uint8_t> buf(kMaxUnreliablePayload);
  auto params = MakeQuantizationParams(QuantizationConfig{});
  DeltaEncoder enc(*params);
  uint16_t seq = 0;
  size_t f = 0, bytes = 0;
  for (auto _ : state) {
    const auto& frame = frames[f % frames.size()];
    const uint32_t time_ms = static_cast<uint32_t>(f * 1000 / 12);
    ++f;
    size_t i = 0;
    while (i < frame.size()) {
      enc.Begin(buf, time_ms);
      while (i < frame.size() && enc.Add(frame[i])) ++i;
      bytes += enc.Finish();
      enc.OnSent(seq, f / 12.0);
      enc.OnPacketAcked(seq++);  // perfect network (acked before the next frame)
    }
    benchmark::DoNotOptimize(buf.data());
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations()) * n);
  state.counters["payload_bytes_per_entity"] =
      static_cast<double>(bytes) / (static_cast<double>(state.iterations()) * n);
}

// Pre-encodes a stream, then measures decoding it (a fresh decoder per pass over the stream).
template <bool kDelta>
void BM_Decode(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  auto frames = MakeFrames(n, 64);
  auto params = MakeQuantizationParams(QuantizationConfig{});
  std::vector<std::vector<uint8_t>> payloads;
  std::vector<uint8_t> buf(kMaxUnreliablePayload);
  DeltaEncoder denc(*params);
  FloatStateEncoder fenc;
  StateEncoder& enc = kDelta ? static_cast<StateEncoder&>(denc) : fenc;
  uint16_t seq = 0;
  for (size_t f = 0; f < frames.size(); ++f) {
    size_t i = 0;
    while (i < frames[f].size()) {
      enc.Begin(buf, static_cast<uint32_t>(f * 1000 / 12));
      while (i < frames[f].size() && enc.Add(frames[f][i])) ++i;
      const size_t size = enc.Finish();
      if (kDelta) {
        denc.OnSent(seq, f / 12.0);
        denc.OnPacketAcked(seq++);
      }
      payloads.emplace_back(buf.begin(), buf.begin() + static_cast<long>(size));
    }
  }
  StateBatch batch;
  batch.states.reserve(2048);
  size_t decoded = 0;
  for (auto _ : state) {
    DeltaDecoder dec(*params);
    for (const auto& p : payloads) {
      batch.states.clear();
      if (kDelta) {
        (void)dec.Decode(p, &batch);
      } else {
        (void)DecodeStateBatch(p, &batch);
      }
      decoded += batch.states.size();
    }
  }
  state.SetItemsProcessed(static_cast<int64_t>(decoded));
}

BENCHMARK(BM_Format1Encode)->Arg(32)->Arg(512);
BENCHMARK(BM_Format2Encode)->Arg(32)->Arg(512);
BENCHMARK_TEMPLATE(BM_Decode, false)->Name("BM_Format1Decode")->Arg(32)->Arg(512);
BENCHMARK_TEMPLATE(BM_Decode, true)->Name("BM_Format2Decode")->Arg(32)->Arg(512);

}  // namespace
}  // namespace edgephys

BENCHMARK_MAIN();
