// State format 14 (format 13 whose records may hold at times of their own; protocol/delta_codec.h):
// random round trips with past states at their times, 20 % loss with reordering, the cost of a
// record's time, and forged times refused and counted.
#include <gtest/gtest.h>

#include <cstdio>
#include <random>
#include <vector>

#include "protocol/bit_stream.h"
#include "protocol/byte_io.h"
#include "protocol/delta_codec.h"
#include "protocol/testing/codec_test_util.h"
#include "protocol/testing/delta_stream_sim.h"

namespace edgephys {
namespace {

using namespace testing_util;  // NOLINT(google-build-using-namespace): test helpers

DeltaEncoderOptions Timed() {
  DeltaEncoderOptions o;
  o.record_times = true;
  return o;
}

// Irregular sends, half of them a past state (up to 8 ticks back) at its own time, many seeds:
// every decoded state is the one sent, within the lattice, at the time it was sent for.
TEST(DeltaTimedCodec, PastStatesRoundTripAtTheirOwnTimes) {
  for (uint64_t seed = 1; seed <= 8; ++seed) {
    SimConfig c = IrregularSendsSim(seed, 0.1 + 0.05 * static_cast<double>(seed % 4));
    c.options = Timed();
    c.record_back_ticks = 8;
    SimResult r = RunStream(c);
    std::printf("seed %llu: %.2f bytes/update, %llu timed records of %llu outputs\n",
                static_cast<unsigned long long>(seed), r.BytesPerUpdate(),
                static_cast<unsigned long long>(r.timed_records),
                static_cast<unsigned long long>(r.outputs));
    ExpectWithinBounds(r, c.quant);
    EXPECT_EQ(r.time_mismatches, 0u);
    EXPECT_GT(r.timed_records, r.outputs / 10);  // 15-27 % of the outputs held at a past time
    EXPECT_EQ(r.bad_references, 0u);
    EXPECT_EQ(r.dec.unresolved_references, 0u);
    EXPECT_EQ(r.dec.malformed, 0u);
    EXPECT_TRUE(r.converged);
  }
}

TEST(DeltaTimedCodec, LossyReorderedStreamConvergesWithTheTimesSent) {
  for (uint64_t seed : {1, 2, 3, 4}) {
    SimConfig c = LossyReorderedSim(seed);
    c.send_probability = seed <= 2 ? 0.3 : 1.0;
    c.options = Timed();
    c.record_back_ticks = seed <= 2 ? 6 : 0;  // every tick: no room for past states
    SimResult r = RunStream(c);
    ExpectConvergedUnderLoss(r, c.quant, seed);
    EXPECT_EQ(r.time_mismatches, 0u);
    if (seed <= 2) {
      EXPECT_GT(r.timed_records, 0u);
    }
  }
}

// At the payload's time a record's time costs one bit: the same stream as format 13 costs at
// most a bit a record more.
TEST(DeltaTimedCodec, RecordsAtThePayloadTimeCostOneBitMoreThanFormat13) {
  SimConfig c;
  c.seed = 5;
  c.entities = 100;
  c.ticks = 200;
  c.tick_hz = 30;
  c.send_probability = 0.3;
  c.freeze_after_tick = 150;
  c.lossless_after_tick = 160;
  c.options.previous_reference = true;
  const SimResult thirteen = RunStream(c);
  c.options = Timed();
  const SimResult fourteen = RunStream(c);
  EXPECT_EQ(fourteen.updates, thirteen.updates);
  EXPECT_GE(fourteen.bytes, thirteen.bytes);
  EXPECT_LE(fourteen.bytes, thirteen.bytes + fourteen.updates / 8 + fourteen.packets);
  EXPECT_TRUE(fourteen.converged);
}

TEST(DeltaTimedCodec, EncoderSendsFormat14AndRefusesTimesOutOfRange) {
  const auto params = MakeQuantizationParams(QuantizationConfig{});
  ASSERT_TRUE(params.ok());
  std::vector<uint8_t> buf(kMaxUnreliablePayload);
  EntityState s;
  s.entity_id = 3;
  DeltaEncoder fourteen(*params, Timed());
  EXPECT_TRUE(fourteen.record_times());
  fourteen.Begin(buf, 5000);
  EXPECT_FALSE(fourteen.AddAt(s, nullptr, 5001));                    // after the payload
  EXPECT_FALSE(fourteen.AddAt(s, nullptr, 5000 - kMaxRecordAgeMs - 1));  // too old
  EXPECT_EQ(fourteen.count(), 0u);
  ASSERT_TRUE(fourteen.AddAt(s, nullptr, 5000 - kMaxRecordAgeMs));
  const size_t size = fourteen.Finish();
  ASSERT_GT(size, 0u);
  EXPECT_EQ(buf[0], kTimedDeltaStateFormat);
  // Decoded at the time sent.
  DeltaDecoder dec(*params);
  StateBatch batch;
  ASSERT_TRUE(dec.Decode(std::span<const uint8_t>(buf.data(), size), &batch).ok());
  ASSERT_EQ(batch.times_ms.size(), 1u);
  EXPECT_EQ(batch.times_ms[0], 5000 - kMaxRecordAgeMs);
  EXPECT_EQ(batch.time_ms, 5000u);
  // Without record_times AddAt refuses; velocities take precedence over record times.
  DeltaEncoderOptions previous;
  previous.previous_reference = true;
  DeltaEncoder thirteen(*params, previous);
  thirteen.Begin(buf, 5000);
  EXPECT_FALSE(thirteen.AddAt(s, nullptr, 4990));
  DeltaEncoderOptions both = Timed();
  both.velocities = true;
  DeltaEncoder twelve(*params, both);
  EXPECT_FALSE(twelve.record_times());
  twelve.Begin(buf, 1);
  ASSERT_TRUE(twelve.Add(s));
  ASSERT_GT(twelve.Finish(), 0u);
  EXPECT_EQ(buf[0], kVelocityDeltaStateFormat);
}

// A hand-made format-14 payload: one keyframe at an offset of `back + 1` ms.
std::vector<uint8_t> ForgedKeyframe(const QuantizationParams& p, uint16_t counter, uint32_t back,
                                    bool own_time = true) {
  std::vector<uint8_t> out(256, 0);
  out[0] = kTimedDeltaStateFormat;
  StoreU32LE(out.data() + 1, 100000u + counter);
  StoreU16LE(out.data() + 5, counter);
  StoreU16LE(out.data() + 7, static_cast<uint16_t>((1 << 6) | (1 << 7)));
  out[kDeltaHeaderSize] = 1;
  BitWriter w(std::span<uint8_t>(out).subspan(kDeltaHeaderSize + 1));
  EXPECT_TRUE(w.WriteExpGolomb(7, 0));  // id
  EXPECT_TRUE(w.WriteExpGolomb(1, 0));  // keyframe
  for (int a = 0; a < 3; ++a) EXPECT_TRUE(w.WriteBits(p.max_index[a] / 2, p.position_bits[a]));
  EXPECT_TRUE(w.WriteBits(3, 2));
  for (int c = 0; c < 3; ++c) EXPECT_TRUE(w.WriteBits(static_cast<uint32_t>(p.rotation_max), p.rotation_bits));
  EXPECT_TRUE(w.WriteBit(own_time));
  if (own_time) {
    EXPECT_TRUE(w.WriteExpGolomb(back, 4));
  }
  out.resize(kDeltaHeaderSize + 1 + w.byte_size());
  return out;
}

TEST(DeltaTimedCodec, ForgedTimesAreRefusedAndCountedWithoutOutput) {
  const auto params = MakeQuantizationParams(QuantizationConfig{});
  ASSERT_TRUE(params.ok());
  DeltaDecoder dec(*params);
  StateBatch batch;
  // The largest offset allowed decodes, at its time.
  ASSERT_TRUE(dec.Decode(ForgedKeyframe(*params, 1, kMaxRecordAgeMs - 1), &batch).ok());
  ASSERT_EQ(batch.times_ms.size(), 1u);
  EXPECT_EQ(batch.times_ms[0], 100001u - kMaxRecordAgeMs);
  // Beyond it, and far beyond: refused, counted, nothing output.
  for (uint32_t back : {kMaxRecordAgeMs, kMaxRecordAgeMs + 1, 100000u, 1u << 24}) {
    batch.states.clear();
    batch.times_ms.clear();
    EXPECT_EQ(dec.Decode(ForgedKeyframe(*params, 2, back), &batch).code(), StatusCode::kMalformed);
    EXPECT_TRUE(batch.states.empty());
    EXPECT_TRUE(batch.times_ms.empty());
  }
  EXPECT_EQ(dec.stats().record_times_refused, 4u);
  EXPECT_EQ(dec.stats().malformed, 4u);
  // The stream goes on: a valid payload after them decodes.
  batch.states.clear();
  ASSERT_TRUE(dec.Decode(ForgedKeyframe(*params, 3, 0, /*own_time=*/false), &batch).ok());
  ASSERT_EQ(batch.states.size(), 1u);
  EXPECT_EQ(batch.times_ms.back(), 100003u);
}

TEST(DeltaTimedCodec, TruncationsAndGarbageAreRefusedWithoutOutput) {
  const auto params = MakeQuantizationParams(QuantizationConfig{});
  ASSERT_TRUE(params.ok());
  // A real payload, cut at every length.
  std::vector<uint8_t> buf(kMaxUnreliablePayload);
  DeltaEncoder enc(*params, Timed());
  enc.Begin(buf, 9000);
  for (uint32_t id = 1; id <= 20; ++id) {
    EntityState s;
    s.entity_id = id;
    s.position = {0.1f * id, 1, 2};
    ASSERT_TRUE(enc.AddAt(s, nullptr, 9000 - 17 * (id % 4)));
  }
  const size_t size = enc.Finish();
  ASSERT_GT(size, 0u);
  for (size_t n = 0; n < size; ++n) {
    DeltaDecoder dec(*params);
    StateBatch batch;
    EXPECT_FALSE(dec.Decode(std::span<const uint8_t>(buf.data(), n), &batch).ok()) << n;
    EXPECT_TRUE(batch.states.empty());
    EXPECT_TRUE(batch.times_ms.empty());
  }
  // Random bodies behind a format-14 header: refused or decoded, never a crash; whatever is
  // output holds at most kMaxRecordAgeMs before the payload's time.
  std::mt19937_64 rng(14);
  DeltaDecoder dec(*params);
  for (int i = 0; i < 3000; ++i) {
    std::vector<uint8_t> junk(kDeltaHeaderSize + 1 + rng() % 64);
    for (uint8_t& b : junk) b = static_cast<uint8_t>(rng());
    junk[0] = kTimedDeltaStateFormat;
    StateBatch batch;
    if (!dec.Decode(junk, &batch).ok()) {
      EXPECT_TRUE(batch.states.empty());
      continue;
    }
    ASSERT_EQ(batch.times_ms.size(), batch.states.size());
    for (uint32_t t : batch.times_ms) EXPECT_LE(batch.time_ms - t, kMaxRecordAgeMs);
  }
}

}  // namespace
}  // namespace edgephys
