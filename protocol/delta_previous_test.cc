// State format 13 (format 2 with "the previous version" references; protocol/delta_codec.h):
// round trips over irregular send gaps, 20 % loss with reordering, and forged references.
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

DeltaEncoderOptions Previous() {
  DeltaEncoderOptions o;
  o.previous_reference = true;
  return o;
}

double ReferenceBitsPerDelta(const SimResult& r) {
  return static_cast<double>(r.enc.record_part_bits[kRecordPartReference]) /
         static_cast<double>(r.enc.entities - r.enc.keyframes);
}

// Every entity sent in a random fifth of the ticks (the irregular gaps of key samples), many
// seeds and motions: every decoded state is the one sent (within the lattice), the stream
// converges, and "previous" references cost fewer bits than format 2's distances.
TEST(DeltaPreviousCodec, IrregularGapsRoundTripAndReferencesCostLessThanFormat2) {
  for (uint64_t seed = 1; seed <= 8; ++seed) {
    SimConfig c = IrregularSendsSim(seed, 0.05 + 0.05 * static_cast<double>(seed % 4));
    SimResult two = RunStream(c);
    c.options = Previous();
    SimResult thirteen = RunStream(c);
    std::printf("seed %llu p %.2f: reference bits per delta %.2f (format 2) %.2f (13); "
                "bytes/update %.2f / %.2f\n",
                static_cast<unsigned long long>(seed), c.send_probability,
                ReferenceBitsPerDelta(two), ReferenceBitsPerDelta(thirteen), two.BytesPerUpdate(),
                thirteen.BytesPerUpdate());
    ExpectWithinBounds(thirteen, c.quant);
    EXPECT_EQ(thirteen.bad_references, 0u);
    EXPECT_EQ(thirteen.dec.unresolved_references, 0u);
    EXPECT_EQ(thirteen.dec.malformed, 0u);
    EXPECT_TRUE(thirteen.converged);
    // The same states go (the simulator's draws do not depend on the format).
    EXPECT_EQ(thirteen.updates, two.updates);
    EXPECT_LT(ReferenceBitsPerDelta(thirteen), 0.5 * ReferenceBitsPerDelta(two));
    EXPECT_LT(thirteen.BytesPerUpdate(), two.BytesPerUpdate());
  }
}

TEST(DeltaPreviousCodec, LossyReorderedStreamConvergesWithinBoundsAndOnlyReferencesAckedStates) {
  for (uint64_t seed : {1, 2, 3, 4}) {
    SimConfig c = LossyReorderedSim(seed);
    c.send_probability = seed <= 2 ? 0.3 : 1.0;  // sparse (mostly "previous") and every tick
    c.options = Previous();
    SimResult r = RunStream(c);
    ExpectConvergedUnderLoss(r, c.quant, seed);
  }
}

TEST(DeltaPreviousCodec, EncoderSendsFormat13AndVelocitiesTakePrecedence) {
  const auto params = MakeQuantizationParams(QuantizationConfig{});
  ASSERT_TRUE(params.ok());
  std::vector<uint8_t> buf(kMaxUnreliablePayload);
  EntityState s;
  s.entity_id = 3;
  DeltaEncoder thirteen(*params, Previous());
  thirteen.Begin(buf, 1);
  ASSERT_TRUE(thirteen.Add(s));
  ASSERT_GT(thirteen.Finish(), 0u);
  EXPECT_EQ(buf[0], kPreviousDeltaStateFormat);
  DeltaEncoderOptions both = Previous();
  both.velocities = true;
  DeltaEncoder twelve(*params, both);
  twelve.Begin(buf, 1);
  ASSERT_TRUE(twelve.Add(s));
  ASSERT_GT(twelve.Finish(), 0u);
  EXPECT_EQ(buf[0], kVelocityDeltaStateFormat);
}

// Hand-made format-13 payloads: k = 0, both masks, order 0 (a delta record with both mask bits
// clear is its reference's state).
struct Forge {
  std::vector<uint8_t> out = std::vector<uint8_t>(256, 0);
  BitWriter w;
  explicit Forge(uint16_t counter, uint32_t count) {
    out[0] = kPreviousDeltaStateFormat;
    StoreU32LE(out.data() + 1, 1000u + counter);
    StoreU16LE(out.data() + 5, counter);
    StoreU16LE(out.data() + 7, static_cast<uint16_t>((1 << 6) | (1 << 7)));
    out[kDeltaHeaderSize] = static_cast<uint8_t>(count);
    w = BitWriter(std::span<uint8_t>(out).subspan(kDeltaHeaderSize + 1));
  }
  void Keyframe(const QuantizationParams& p, uint32_t id_code) {
    EXPECT_TRUE(w.WriteExpGolomb(id_code, 0));
    EXPECT_TRUE(w.WriteExpGolomb(1, 0));
    for (int a = 0; a < 3; ++a) EXPECT_TRUE(w.WriteBits(p.max_index[a] / 2 + 10u * a, p.position_bits[a]));
    EXPECT_TRUE(w.WriteBits(3, 2));
    for (int c = 0; c < 3; ++c) EXPECT_TRUE(w.WriteBits(static_cast<uint32_t>(p.rotation_max), p.rotation_bits));
  }
  // A delta record with reference symbol `sym` and zero residuals.
  void Delta(uint32_t id_code, uint32_t sym) {
    EXPECT_TRUE(w.WriteExpGolomb(id_code, 0));
    EXPECT_TRUE(w.WriteExpGolomb(sym, 0));
    EXPECT_TRUE(w.WriteBit(false));
    EXPECT_TRUE(w.WriteBit(false));
  }
  std::vector<uint8_t> Done() {
    out.resize(kDeltaHeaderSize + 1 + w.byte_size());
    return out;
  }
};

TEST(DeltaPreviousCodec, ForgedPreviousReferencesAreSkippedAndCountedNeverGuessed) {
  const auto made = MakeQuantizationParams(QuantizationConfig{});
  ASSERT_TRUE(made.ok());
  const QuantizationParams& p = *made;
  DeltaDecoder dec(p);
  StateBatch batch;
  {  // entity 5 at counter 10
    Forge f(10, 1);
    f.Keyframe(p, 5);
    ASSERT_TRUE(dec.Decode(f.Done(), &batch).ok());
    ASSERT_EQ(batch.states.size(), 1u);
  }
  const EntityState held = batch.states[0];
  {  // "previous" of an entity never held: skipped, counted
    Forge f(11, 1);
    f.Delta(77, 0);
    batch = {};
    ASSERT_TRUE(dec.Decode(f.Done(), &batch).ok());
    EXPECT_TRUE(batch.states.empty());
    EXPECT_EQ(dec.stats().unresolved_references, 1u);
  }
  {  // a payload below every version held (reordered): nothing below it to refer to
    Forge f(9, 1);
    f.Delta(5, 0);
    batch = {};
    ASSERT_TRUE(dec.Decode(f.Done(), &batch).ok());
    EXPECT_TRUE(batch.states.empty());
    EXPECT_EQ(dec.stats().unresolved_references, 2u);
  }
  {  // the genuine case: counter 12 refers to 10, the newest below it
    Forge f(12, 1);
    f.Delta(5, 0);
    batch = {};
    ASSERT_TRUE(dec.Decode(f.Done(), &batch).ok());
    ASSERT_EQ(batch.states.size(), 1u);
    EXPECT_EQ(batch.states[0].position.x, held.position.x);
    EXPECT_EQ(batch.states[0].position.z, held.position.z);
    ASSERT_EQ(dec.last_references().size(), 1u);
    EXPECT_EQ(dec.last_references()[0].counter - dec.last_references()[0].reference, 2);
  }
  {  // the newest held version (12) is more than kMaxReferenceDistance below: skipped
    for (uint16_t c : {3000, 6000}) {  // move the counter on (another entity's keyframes)
      Forge f(c, 1);
      f.Keyframe(p, 900);
      batch = {};
      ASSERT_TRUE(dec.Decode(f.Done(), &batch).ok());
    }
    Forge f(6001, 1);
    f.Delta(5, 0);
    batch = {};
    ASSERT_TRUE(dec.Decode(f.Done(), &batch).ok());
    EXPECT_TRUE(batch.states.empty());
    EXPECT_EQ(dec.stats().unresolved_references, 3u);
  }
  {  // an explicit distance (symbol 2 + zigzag) outside 1..4096 is malformed
    Forge f(6002, 1);
    f.Delta(5, 2 + ZigZag(-5));  // d = 1 - 5
    batch = {};
    EXPECT_FALSE(dec.Decode(f.Done(), &batch).ok());
    EXPECT_TRUE(batch.states.empty());
    EXPECT_EQ(dec.stats().malformed, 1u);
  }
  {  // an explicit distance naming a version not held: skipped, counted
    Forge f(6003, 1);
    f.Delta(5, 2 + ZigZag(6));  // d = 7: counter 5996
    batch = {};
    ASSERT_TRUE(dec.Decode(f.Done(), &batch).ok());
    EXPECT_TRUE(batch.states.empty());
    EXPECT_EQ(dec.stats().unresolved_references, 4u);
  }
}

TEST(DeltaPreviousCodec, TruncationsAndGarbageAreRefusedWithoutOutput) {
  const auto params = MakeQuantizationParams(QuantizationConfig{});
  ASSERT_TRUE(params.ok());
  DeltaEncoder enc(*params, Previous());
  DeltaDecoder dec(*params);
  std::vector<uint8_t> buf(kMaxUnreliablePayload);
  std::mt19937_64 rng(13);
  StateBatch batch;
  size_t size = 0;
  for (uint16_t seq = 0; seq < 3; ++seq) {  // keyframes, then "previous" deltas
    enc.Begin(buf, 100u * seq);
    for (uint32_t id = 1; id < 40; ++id) {
      EntityState s;
      s.entity_id = id;
      s.position = {0.01f * static_cast<float>(id) + 0.02f * seq, 1, 2};
      s.rotation = RandomRotation(rng);
      ASSERT_TRUE(enc.Add(s));
    }
    size = enc.Finish();
    enc.OnSent(seq, 0.1 * seq);
    if (seq < 2) {
      batch = {};
      ASSERT_TRUE(dec.Decode({buf.data(), size}, &batch).ok());
      enc.OnPacketAcked(seq);
    }
  }
  uint64_t malformed = dec.stats().malformed;
  for (size_t n = 0; n < size; ++n) {
    batch = {};
    EXPECT_FALSE(dec.Decode({buf.data(), n}, &batch).ok()) << n;
    EXPECT_TRUE(batch.states.empty());
    EXPECT_EQ(dec.stats().malformed, ++malformed);
  }
  batch = {};
  ASSERT_TRUE(dec.Decode({buf.data(), size}, &batch).ok());
  EXPECT_EQ(batch.states.size(), 39u);
  EXPECT_EQ(dec.stats().unresolved_references, 0u);
  for (int trial = 0; trial < 3000; ++trial) {
    std::vector<uint8_t> junk(1 + rng() % 200);
    for (uint8_t& b : junk) b = static_cast<uint8_t>(rng());
    junk[0] = kPreviousDeltaStateFormat;
    batch = {};
    if (!dec.Decode(junk, &batch).ok()) {
      EXPECT_TRUE(batch.states.empty());
    }
  }
}

}  // namespace
}  // namespace edgephys
