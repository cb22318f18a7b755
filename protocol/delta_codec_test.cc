#include "protocol/delta_codec.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <deque>
#include <map>
#include <new>
#include <random>
#include <vector>

#include "protocol/testing/allocation_counter_test_util.h"
#include "protocol/testing/codec_test_util.h"
#include "protocol/connection.h"
#include "protocol/testing/delta_stream_sim.h"

namespace edgephys {
namespace {

using namespace testing_util;  // NOLINT(google-build-using-namespace): test helpers

// A format-2 encoder and decoder at the default quantization, with a payload buffer, an
// entity's state (id `id`) to send and a batch to decode into.
struct Codec {
  explicit Codec(uint32_t id = 0) { s.entity_id = id; }
  QuantizationParams params = *MakeQuantizationParams(QuantizationConfig{});
  DeltaEncoder enc{params};
  DeltaDecoder dec{params};
  std::vector<uint8_t> buf = std::vector<uint8_t>(kMaxUnreliablePayload);
  EntityState s;
  StateBatch batch;
};

TEST(DeltaCodec, UnknownBaselineIsRejectedCleanly) {
  auto params = MakeQuantizationParams(QuantizationConfig{});
  ASSERT_TRUE(params.ok());
  DeltaEncoder enc(*params);
  DeltaDecoder dec(*params);
  std::vector<uint8_t> a(kMaxUnreliablePayload), b(kMaxUnreliablePayload);
  EntityState s;
  s.entity_id = 5;
  enc.Begin(a, 0);
  ASSERT_TRUE(enc.Add(s));
  const size_t sa = enc.Finish();
  enc.OnSent(1, 0);
  enc.OnPacketAcked(1);  // acked, but the decoder never sees it
  s.position.x = 0.5f;
  enc.Begin(b, 100);
  ASSERT_TRUE(enc.Add(s));
  const size_t sb = enc.Finish();
  enc.OnSent(2, 0.1);
  StateBatch batch;
  ASSERT_TRUE(dec.Decode({b.data(), sb}, &batch).ok());
  EXPECT_TRUE(batch.states.empty());
  EXPECT_EQ(dec.stats().unresolved_references, 1u);
  // Delivering the baseline late makes later deltas decodable again; the late one is not lost.
  ASSERT_TRUE(dec.Decode({a.data(), sa}, &batch).ok());
  ASSERT_EQ(batch.states.size(), 1u);
  EXPECT_NEAR(batch.states[0].position.x, 0.f, 1e-3);
  // A fresh decoder that sees a delta first skips it too.
  DeltaDecoder fresh(*params);
  batch.states.clear();
  ASSERT_TRUE(fresh.Decode({b.data(), sb}, &batch).ok());
  EXPECT_TRUE(batch.states.empty());
  EXPECT_EQ(fresh.stats().unresolved_references, 1u);
}

TEST(DeltaCodec, EncoderNeverReferencesUnackedStates) {
  Codec codec(9);
  auto& [params, enc, dec, buf, s, batch] = codec;
  // Nothing acked: every send is a keyframe.
  for (int i = 0; i < 5; ++i) {
    s.position.x = 0.01f * i;
    enc.Begin(buf, static_cast<uint32_t>(i * 10));
    ASSERT_TRUE(enc.Add(s));
    const size_t n = enc.Finish();
    enc.OnSent(static_cast<uint16_t>(i), i * 0.01);
    ASSERT_TRUE(dec.Decode({buf.data(), n}, &batch).ok());
    ASSERT_EQ(dec.last_references().size(), 1u);
    EXPECT_EQ(dec.last_references()[0].reference, -1);
  }
  EXPECT_EQ(enc.stats().keyframes, 5u);
  enc.OnPacketAcked(2);
  enc.Begin(buf, 60);
  ASSERT_TRUE(enc.Add(s));
  const size_t n = enc.Finish();
  ASSERT_TRUE(dec.Decode({buf.data(), n}, &batch).ok());
  ASSERT_EQ(dec.last_references().size(), 1u);
  EXPECT_EQ(dec.last_references()[0].version - dec.last_references()[0].reference, 3);
  EXPECT_EQ(enc.stats().acks_unmatched, 0u);
  enc.OnPacketAcked(77);  // never sent
  EXPECT_EQ(enc.stats().acks_unmatched, 1u);
}

// A state prepared once (PrepareState) and handed to several encoders gives byte for byte the
// payloads each encoder writes when it quantises the truth itself, across keyframes, deltas,
// acknowledgements and stats sampling; one prepared on another lattice is ignored.
TEST(DeltaCodec, PreparedStatesEncodeExactlyAsTheEncoderWouldItself) {
  auto params = MakeQuantizationParams(QuantizationConfig{});
  QuantizationConfig coarse_config;
  coarse_config.position_step_m = 0.004f;
  auto coarse = MakeQuantizationParams(coarse_config);
  ASSERT_TRUE(params.ok() && coarse.ok());
  DeltaEncoder plain(*params), with_prepared(*params), with_foreign(*params);
  std::vector<uint8_t> a(kMaxUnreliablePayload), b(kMaxUnreliablePayload), c(kMaxUnreliablePayload);
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<float> pos(-50.f, 50.f), step(-0.05f, 0.05f);
  std::vector<EntityState> states(40);
  for (size_t i = 0; i < states.size(); ++i) {
    states[i].entity_id = static_cast<uint32_t>(3 * i + 1);
    states[i].position = {pos(rng), pos(rng), pos(rng)};
    states[i].rotation = RandomRotation(rng);
  }
  states[5].position.x = 5000.f;  // clamped: counted the same way on both paths
  size_t compared_bytes = 0;
  for (uint16_t p = 0; p < 300; ++p) {
    const uint32_t t = p * 33u;
    plain.Begin(a, t);
    with_prepared.Begin(b, t);
    with_foreign.Begin(c, t);
    for (EntityState& s : states) {
      if (rng() % 3 == 0) continue;  // not every entity in every payload
      s.position = {s.position.x + step(rng), s.position.y + step(rng), s.position.z + step(rng)};
      if (rng() % 4 == 0) s.rotation = RandomRotation(rng);
      const PreparedState prepared = PrepareState(*params, s);
      const PreparedState foreign = PrepareState(*coarse, s);
      const bool added = plain.Add(s);
      ASSERT_EQ(with_prepared.Add(s, &prepared), added);
      ASSERT_EQ(with_foreign.Add(s, &foreign), added);
    }
    const size_t na = plain.Finish(), nb = with_prepared.Finish(), nc = with_foreign.Finish();
    ASSERT_EQ(na, nb);
    ASSERT_EQ(na, nc);
    ASSERT_TRUE(std::equal(a.begin(), a.begin() + na, b.begin())) << "payload " << p;
    ASSERT_TRUE(std::equal(a.begin(), a.begin() + na, c.begin())) << "payload " << p;
    compared_bytes += na;
    for (DeltaEncoder* e : {&plain, &with_prepared, &with_foreign}) {
      e->OnSent(p, p * 0.033);
      if (p % 5 != 2) e->OnPacketAcked(p);  // some packets lost
    }
  }
  EXPECT_GT(compared_bytes, 20000u);  // ~8,000 entity records compared
  EXPECT_EQ(plain.stats().positions_clamped, with_prepared.stats().positions_clamped);
  EXPECT_GT(with_prepared.stats().positions_clamped, 0u);
  EXPECT_GT(plain.stats().keyframes, 0u);
  EXPECT_LT(plain.stats().keyframes, plain.stats().entities / 4);  // mostly deltas
  // The threshold test agrees too (it reads the dequantised state the prepared path filled in).
  for (const EntityState& s : states) {
    EXPECT_EQ(plain.Need(s.entity_id, s, 0.001f, 0.1f, 10.0, 0.05),
              with_prepared.Need(s.entity_id, s, 0.001f, 0.1f, 10.0, 0.05));
  }
}

TEST(DeltaCodec, FillsPayloadsAndRefusesNonIncreasingIds) {
  auto params = MakeQuantizationParams(QuantizationConfig{});
  DeltaEncoder enc(*params);
  std::vector<uint8_t> storage(kMaxUnreliablePayload + 8, 0xCC);
  std::span<uint8_t> buf(storage.data(), kMaxUnreliablePayload);
  std::mt19937_64 rng(4);
  enc.Begin(buf, 0);
  EntityState s;
  uint32_t id = 10;
  size_t added = 0;
  for (;; ++added) {
    s.entity_id = id;
    id += 1 + static_cast<uint32_t>(rng() % 3);
    s.rotation = RandomRotation(rng);
    if (!enc.Add(s)) break;
  }
  EXPECT_GT(added, 50u);  // keyframes: ~13 bytes each
  EXPECT_EQ(enc.count(), added);
  s.entity_id = 3;
  EXPECT_FALSE(enc.Add(s));
  const size_t size = enc.Finish();
  EXPECT_LE(size, kMaxUnreliablePayload);
  EXPECT_GT(size, kMaxUnreliablePayload - 20);
  for (size_t i = kMaxUnreliablePayload; i < storage.size(); ++i) EXPECT_EQ(storage[i], 0xCC);
  EXPECT_FALSE(enc.Add(s));  // finished
  // Tiny buffers never overflow.
  for (size_t cap = 0; cap < 32; ++cap) {
    std::vector<uint8_t> tiny(cap + 4, 0xCC);
    enc.Begin(std::span<uint8_t>(tiny.data(), cap), 0);
    s.entity_id = 1;
    const bool ok = enc.Add(s);
    const size_t n = enc.Finish();
    EXPECT_EQ(ok, n > 0);
    EXPECT_LE(n, cap);
    for (size_t i = cap; i < tiny.size(); ++i) EXPECT_EQ(tiny[i], 0xCC);
  }
  // Same id twice in one payload.
  enc.Begin(buf, 0);
  s.entity_id = 4;
  EXPECT_TRUE(enc.Add(s));
  EXPECT_FALSE(enc.Add(s));
}

TEST(DeltaCodec, MalformedInputIsRejectedWithoutCrashing) {
  auto params = MakeQuantizationParams(QuantizationConfig{});
  DeltaEncoder enc(*params);
  std::vector<std::vector<uint8_t>> good;
  std::vector<uint8_t> buf(kMaxUnreliablePayload);
  std::mt19937_64 rng(8);
  EntityState s;
  for (int p = 0; p < 30; ++p) {
    enc.Begin(buf, static_cast<uint32_t>(p * 83));
    for (uint32_t i = 0; i < 40; ++i) {
      s.entity_id = i;
      s.position = {0.1f * p + i, 0.05f * p, 1.f};
      s.rotation = RandomRotation(rng);
      enc.Add(s);
    }
    const size_t n = enc.Finish();
    enc.OnSent(static_cast<uint16_t>(p), p * 0.083);
    enc.OnPacketAcked(static_cast<uint16_t>(p));
    good.emplace_back(buf.begin(), buf.begin() + static_cast<long>(n));
  }
  // Truncations and trailing bytes of valid payloads are malformed; the decoder is unchanged.
  DeltaDecoder dec(*params);
  StateBatch batch;
  for (const auto& g : good) {
    for (size_t n = 0; n < g.size(); ++n) {
      batch.states.clear();
      ASSERT_FALSE(dec.Decode({g.data(), n}, &batch).ok()) << n;
      ASSERT_TRUE(batch.states.empty());
    }
    std::vector<uint8_t> longer = g;
    longer.push_back(0);
    ASSERT_FALSE(dec.Decode(longer, &batch).ok());
    ASSERT_TRUE(dec.Decode(g, &batch).ok());  // the real one still decodes fully
  }
  EXPECT_EQ(dec.stats().unresolved_references, 0u);
  EXPECT_EQ(dec.stats().entities, 30u * 40u);
  std::vector<uint8_t> bad_format = good[0];
  bad_format[0] = 1;
  EXPECT_FALSE(dec.Decode(bad_format, &batch).ok());
  // Random and mutated payloads: never crash, never output out-of-range garbage.
  DeltaDecoder fuzz(*params, 4096);
  for (int i = 0; i < 60000; ++i) {
    std::vector<uint8_t> p;
    if (i % 3 == 0) {
      p.resize(rng() % 200);
      for (auto& b : p) b = static_cast<uint8_t>(rng());
      if (!p.empty()) p[0] = 2;
    } else {
      p = good[rng() % good.size()];
      const int flips = 1 + static_cast<int>(rng() % 4);
      for (int f = 0; f < flips; ++f)
        p[rng() % p.size()] ^= static_cast<uint8_t>(1u << (rng() % 8));
      if (rng() % 4 == 0) p.resize(rng() % (p.size() + 1));
    }
    batch.states.clear();
    if (fuzz.Decode(p, &batch).ok()) {
      for (const EntityState& st : batch.states) ASSERT_TRUE(IsValidState(st));
    } else {
      ASSERT_TRUE(batch.states.empty());
    }
  }
  // The stateless dispatcher refuses format 2 explicitly.
  Status st = DecodeStateBatch(good[0], &batch);
  EXPECT_EQ(st.code(), StatusCode::kInvalidArgument);
}

TEST(DeltaCodec, NeedsUpdateFollowsAcknowledgedState) {
  auto params = MakeQuantizationParams(QuantizationConfig{});
  DeltaEncoder enc(*params);
  std::vector<uint8_t> buf(kMaxUnreliablePayload);
  EntityState s;
  s.entity_id = 1;
  EXPECT_TRUE(enc.NeedsUpdate(1, s, 0.01f, 1.f, 0, 0.2));  // never sent
  enc.Begin(buf, 0);
  enc.Add(s);
  enc.Finish();
  enc.OnSent(10, 0.0);
  // In flight and equal: wait for it, until the resend time.
  EXPECT_FALSE(enc.NeedsUpdate(1, s, 0.01f, 1.f, 0.1, 0.2));
  EXPECT_TRUE(enc.NeedsUpdate(1, s, 0.01f, 1.f, 0.25, 0.2));
  EntityState moved = s;
  moved.position.x = 0.05f;
  EXPECT_TRUE(enc.NeedsUpdate(1, moved, 0.01f, 1.f, 0.1, 0.2));  // in flight, but differs
  enc.OnPacketAcked(10);
  EXPECT_FALSE(enc.NeedsUpdate(1, s, 0.01f, 1.f, 5.0, 0.2));
  EntityState nudged = s;
  nudged.position.x = 0.005f;
  EXPECT_FALSE(enc.NeedsUpdate(1, nudged, 0.01f, 1.f, 5.0, 0.2));  // under the threshold
  EXPECT_TRUE(enc.NeedsUpdate(1, moved, 0.01f, 1.f, 5.0, 0.2));
  EntityState turned = s;
  turned.rotation = {0.f, std::sin(0.02f), 0.f, std::cos(0.02f)};  // ~2.3 degrees
  EXPECT_TRUE(enc.NeedsUpdate(1, turned, 0.01f, 1.f, 5.0, 0.2));
  EXPECT_FALSE(enc.NeedsUpdate(1, turned, 0.01f, 3.f, 5.0, 0.2));
  enc.Forget(1);
  EXPECT_TRUE(enc.NeedsUpdate(1, s, 0.01f, 1.f, 5.0, 0.2));
}

// The encoder keeps its newest acknowledged and newest sent state per entity incrementally
// (no scan): late and reordered acks, acks of states the ring has overwritten and unsent
// payloads must all leave it pointing at the right state.
TEST(DeltaCodec, NeedTracksNewestAckedStateThroughReorderedAndStaleAcks) {
  auto params = MakeQuantizationParams(QuantizationConfig{});
  DeltaEncoder enc(*params);
  std::vector<uint8_t> buf(kMaxUnreliablePayload);
  using Need = DeltaEncoder::UpdateNeed;
  auto at = [](float x) {
    EntityState s;
    s.entity_id = 7;
    s.position.x = x;
    return s;
  };
  // 40 payloads (more than the 16-state window), position x = i cm, packet sequence 100 + i.
  for (int i = 0; i < 40; ++i) {
    enc.Begin(buf, static_cast<uint32_t>(i * 20));
    ASSERT_TRUE(enc.Add(at(0.01f * i)));
    ASSERT_GT(enc.Finish(), 0u);
    enc.OnSent(static_cast<uint16_t>(100 + i), 0.02 * i);
  }
  const double now = 0.8;
  // Nothing acked; the newest sent (x = 39 cm) is in flight and equal: wait for it.
  EXPECT_EQ(enc.Need(7, at(0.39f), 0.001f, 0.1f, now, 0.2), Need::kInFlightWithin);
  EXPECT_EQ(enc.Need(7, at(0.30f), 0.001f, 0.1f, now, 0.2), Need::kSend);
  // An ack of a state the ring overwrote long ago changes nothing.
  enc.OnPacketAcked(101);
  EXPECT_EQ(enc.Need(7, at(0.01f), 0.001f, 0.1f, now, 0.2), Need::kSend);
  // Acks out of order: the newest acknowledged one (x = 35 cm) is the reference.
  enc.OnPacketAcked(135);
  enc.OnPacketAcked(130);
  EXPECT_EQ(enc.Need(7, at(0.35f), 0.001f, 0.1f, now, 0.2), Need::kAckedWithin);
  EXPECT_EQ(enc.Need(7, at(0.30f), 0.001f, 0.1f, now, 0.2), Need::kSend);
  // A finished payload never reported through OnSent is not "in flight".
  enc.Begin(buf, 900);
  ASSERT_TRUE(enc.Add(at(0.5f)));
  ASSERT_GT(enc.Finish(), 0u);
  EXPECT_EQ(enc.Need(7, at(0.5f), 0.001f, 0.1f, now, 0.2), Need::kSend);
  // 16 more sent states push x = 35 cm out of the window: no acked reference remains, so the
  // next record is a keyframe, and the newest sent one is what an equal truth waits for.
  for (int i = 0; i < 16; ++i) {
    enc.Begin(buf, static_cast<uint32_t>(1000 + i * 20));
    ASSERT_TRUE(enc.Add(at(0.6f + 0.01f * i)));
    ASSERT_GT(enc.Finish(), 0u);
    enc.OnSent(static_cast<uint16_t>(200 + i), 1.0 + 0.02 * i);
  }
  EXPECT_EQ(enc.Need(7, at(0.35f), 0.001f, 0.1f, 1.3, 0.2), Need::kSend);
  EXPECT_EQ(enc.Need(7, at(0.75f), 0.001f, 0.1f, 1.3, 0.2), Need::kInFlightWithin);
  const uint64_t keyframes = enc.stats().keyframes;
  enc.Begin(buf, 2000);
  ASSERT_TRUE(enc.Add(at(0.8f)));
  ASSERT_GT(enc.Finish(), 0u);
  EXPECT_EQ(enc.stats().keyframes, keyframes + 1);
  // The newest ack then makes that state the reference again.
  enc.OnPacketAcked(215);
  EXPECT_EQ(enc.Need(7, at(0.75f), 0.001f, 0.1f, 1.3, 0.2), Need::kAckedWithin);
}

// Thresholds finer than the lattice: a resting entity whose truth sits 0.57 mm from its
// lattice point must not be resent forever (the client already has the best state the codec
// can give it); a truth on another lattice point beyond the threshold still is.
TEST(DeltaCodec, NeedDoesNotResendWhatQuantisesToTheAcknowledgedState) {
  auto params = MakeQuantizationParams(QuantizationConfig{});  // 1 mm lattice, 0.1 degree
  DeltaEncoder enc(*params);
  std::vector<uint8_t> buf(kMaxUnreliablePayload);
  using Need = DeltaEncoder::UpdateNeed;
  EntityState s;
  s.entity_id = 3;
  s.position = {1.2f, 0.5f, -0.25f};
  s.rotation = {0.f, std::sin(0.3f), 0.f, std::cos(0.3f)};
  enc.Begin(buf, 0);
  ASSERT_TRUE(enc.Add(s));
  ASSERT_GT(enc.Finish(), 0u);
  enc.OnSent(1, 0.0);
  enc.OnPacketAcked(1);
  std::array<uint32_t, 3> lattice{};
  QuantizePosition(*params, s.position, &lattice);
  const Vec3f point = DequantizePosition(*params, lattice);
  EntityState off = s;  // same lattice point, 0.57 mm from it
  off.position = {point.x + 0.0004f, point.y + 0.0004f, point.z};
  EXPECT_EQ(enc.Need(3, off, 0.0005f, 0.05f, 1.0, 0.2), Need::kAckedWithin);
  EntityState moved = s;  // the next lattice point on x, 0.6 mm from the acknowledged one
  moved.position = {point.x + 0.0006f, point.y, point.z};
  EXPECT_EQ(enc.Need(3, moved, 0.0005f, 0.05f, 1.0, 0.2), Need::kSend);
  // Rotation: a change well inside one quantisation cell but above a 0.001 degree threshold.
  EntityState turned = s;
  turned.rotation = {0.f, std::sin(0.3f + 1e-5f), 0.f, std::cos(0.3f + 1e-5f)};
  EXPECT_EQ(enc.Need(3, turned, 0.0005f, 0.001f, 1.0, 0.2), Need::kAckedWithin);
  turned.rotation = {0.f, std::sin(0.31f), 0.f, std::cos(0.31f)};  // 1.1 degrees
  EXPECT_EQ(enc.Need(3, turned, 0.0005f, 0.05f, 1.0, 0.2), Need::kSend);
}

TEST(DeltaCodec, UnchangedFieldsCostAboutOneBit) {
  auto params = MakeQuantizationParams(QuantizationConfig{});
  DeltaEncoderOptions no_refresh;
  no_refresh.keyframe_refresh_sends = 0;
  DeltaEncoder enc(*params, no_refresh);
  DeltaDecoder dec(*params);
  std::vector<uint8_t> buf(4096);
  std::mt19937_64 rng(12);
  std::vector<EntityState> st(200);
  for (size_t i = 0; i < st.size(); ++i) {
    st[i].entity_id = static_cast<uint32_t>(i);
    st[i].rotation = RandomRotation(rng);
    st[i].position = {static_cast<float>(i), 1.f, 2.f};
  }
  StateBatch batch;
  size_t last = 0;
  for (int t = 0; t < 20; ++t) {
    enc.Begin(buf, static_cast<uint32_t>(t * 83));
    for (const auto& s : st) ASSERT_TRUE(enc.Add(s));
    last = enc.Finish();
    enc.OnSent(static_cast<uint16_t>(t), t);
    enc.OnPacketAcked(static_cast<uint16_t>(t));
    ASSERT_TRUE(dec.Decode({buf.data(), last}, &batch).ok());
  }
  // Resting entities: id gap, reference and two mask bits = 4 bits each (+ header).
  std::printf("200 resting entities: %zu bytes (params 0x%02x%02x)\n", last, buf[8], buf[7]);
  EXPECT_LE(last, 200 * 4 / 8 + 16u);
}

TEST(DeltaCodec, ForgetStartsOverWithAKeyframe) {
  Codec codec(42);
  auto& [params, enc, dec, buf, s, batch] = codec;
  for (int t = 0; t < 6; ++t) {
    if (t == 3) {
      enc.Forget(42);
      dec.Forget(42);
    }
    s.position.x = 0.1f * t;
    enc.Begin(buf, static_cast<uint32_t>(t * 83));
    ASSERT_TRUE(enc.Add(s));
    const size_t n = enc.Finish();
    enc.OnSent(static_cast<uint16_t>(t), t);
    enc.OnPacketAcked(static_cast<uint16_t>(t));
    batch.states.clear();
    ASSERT_TRUE(dec.Decode({buf.data(), n}, &batch).ok());
    ASSERT_EQ(batch.states.size(), 1u);
    EXPECT_NEAR(batch.states[0].position.x, s.position.x, 1e-3);
  }
  EXPECT_EQ(enc.stats().keyframes, 2u);
}

TEST(DeltaCodec, SteadyStateAllocatesNothing) {
  Codec codec;
  auto& [params, enc, dec, buf, s, batch] = codec;
  std::vector<TestMotion> motions;
  for (uint32_t i = 0; i < 300; ++i) motions.emplace_back(5, i, 1.5, 90, 0);
  std::vector<EntityState> truth(motions.size());
  batch.states.reserve(1024);
  uint16_t seq = 0;
  std::vector<uint16_t> to_ack;
  to_ack.reserve(64);
  long counted = 0;
  for (int tick = 0; tick < 600; ++tick) {
    const uint32_t time_ms = static_cast<uint32_t>(tick * 1000 / 12);
    for (size_t i = 0; i < motions.size(); ++i) {
      truth[i] = motions[i].AdvanceTo(time_ms / 1000.0);
      truth[i].entity_id = static_cast<uint32_t>(i);
    }
    const bool count = tick >= 300;  // after ring buffers and records reached steady size
    if (count) g_counting = true;
    for (uint16_t a : to_ack) enc.OnPacketAcked(a);
    to_ack.clear();
    size_t i = 0;
    while (i < truth.size()) {
      enc.Begin(buf, time_ms);
      while (i < truth.size() && enc.Add(truth[i])) ++i;
      const size_t n = enc.Finish();
      enc.OnSent(seq, tick / 12.0);
      batch.states.clear();
      EXPECT_TRUE(dec.Decode({buf.data(), n}, &batch).ok());
      to_ack.push_back(seq++);
    }
    if (count) {
      g_counting = false;
      counted = g_allocations.load();
    }
  }
  EXPECT_EQ(counted, 0);
}

// ---------------------------------------------------------------------------------------------
// Acceptance motion (docs: issue #3): smooth paths at 1.5 m/s, 90 deg/s about a slowly varying
// axis, every entity sent at 12 Hz, N = 32..512 per tick, 1179-byte payloads, 21 bytes of
// packet overhead counted per packet.
}  // namespace
}  // namespace edgephys
