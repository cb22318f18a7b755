// Format 9 ("shared delta"): round trips, convergence of several receivers on lossy, duplicating,
// reordering links, forged references, malformed payloads, the room's body cache, and the
// size against format 2 on the same motion.
#include "protocol/shared_delta_codec.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <random>
#include <thread>
#include <vector>

#include "protocol/byte_io.h"
#include "protocol/testing/codec_test_util.h"
#include "protocol/testing/delta_stream_sim.h"

namespace edgephys {
namespace {

using namespace testing_util;  // NOLINT(google-build-using-namespace): test helpers

constexpr size_t kPacketOverhead = 18 + 3;  // connection header + unreliable chunk header

QuantizationParams DefaultParams() { return *MakeQuantizationParams(QuantizationConfig{}); }

double PosBound(const QuantizationParams& p, const Vec3f& at) {
  const double m = std::max({std::fabs(at.x), std::fabs(at.y), std::fabs(at.z)});
  return p.step * std::sqrt(3.0) / 2.0 + FloatSlack(m) + 1e-9;
}

// The room side of a test: entities with their truth, prepared once per tick.
struct TestRoom {
  explicit TestRoom(size_t versions = kSharedVersionWindow) : room(params, versions) {}
  QuantizationParams params = DefaultParams();
  SharedDeltaRoom room;
  std::map<uint32_t, std::unique_ptr<SharedEntity>> shared;
  std::map<uint32_t, EntityState> truth;
  std::map<uint32_t, PreparedState> prepared;

  void Set(uint32_t id, const EntityState& s) {
    truth[id] = s;
    truth[id].entity_id = id;
    if (!shared.count(id)) shared[id] = std::make_unique<SharedEntity>();
  }
  void Remove(uint32_t id) {
    truth.erase(id);
    shared.erase(id);
    prepared.erase(id);
  }
  void Tick(uint32_t time_ms) {
    room.BeginTick(time_ms);
    for (auto& [id, s] : truth) {
      prepared[id] = PrepareState(params, s);
      room.PrepareEntity(*shared[id], prepared[id]);
    }
  }
};

// One receiver: the relay's stream for it and its decoder, joined by a payload log.
struct Receiver {
  explicit Receiver(const QuantizationParams& p) : stream(p), decoder(p) {}
  SharedDeltaStream stream;
  SharedDeltaDecoder decoder;
  uint16_t next_seq = 0;
  std::map<uint32_t, EntityState> decoded;  // latest output per entity

  // Encodes `ids` (increasing) into payloads of at most `mtu` bytes; returns (seq, payload).
  std::vector<std::pair<uint16_t, std::vector<uint8_t>>> Send(TestRoom& r,
                                                              const std::vector<uint32_t>& ids,
                                                              double now, size_t mtu = 1179) {
    std::vector<std::pair<uint16_t, std::vector<uint8_t>>> out;
    std::vector<uint8_t> buf(mtu);
    auto flush = [&]() {
      const size_t n = stream.Finish();
      if (n == 0) return;
      const uint16_t seq = next_seq++;
      stream.OnSent(seq, now);
      out.emplace_back(seq, std::vector<uint8_t>(buf.begin(), buf.begin() + n));
    };
    stream.Begin(buf, 0);
    for (uint32_t id : ids) {
      if (!stream.Add(id, *r.shared[id])) {
        flush();
        stream.Begin(buf, 0);
        EXPECT_TRUE(stream.Add(id, *r.shared[id])) << id;
      }
    }
    flush();
    return out;
  }
  bool Receive(const std::vector<uint8_t>& payload) {
    StateBatch batch;
    if (!decoder.Decode(payload, &batch).ok()) return false;
    for (const EntityState& s : batch.states) decoded[s.entity_id] = s;
    return true;
  }
};

// A TestRoom with bodies 1..entities on TestMotion paths (seed `seed`; family i % 2 if
// `both_families`, else 0) and `receivers` receivers.
struct Crowd {
  Crowd(int receivers, uint32_t entities, uint64_t seed, bool both_families,
        size_t versions = kSharedVersionWindow)
      : r(versions) {
    for (int i = 0; i < receivers; ++i) rx.push_back(std::make_unique<Receiver>(r.params));
    for (uint32_t i = 0; i < entities; ++i) {
      motion.emplace_back(seed, i, 1.5, 90.0, both_families ? static_cast<int>(i % 2) : 0);
      ids.push_back(i + 1);
    }
  }
  // Moves every body to motion time `t` (s) and prepares the room's tick at `time_ms`.
  void Advance(double t, uint32_t time_ms) {
    for (size_t i = 0; i < motion.size(); ++i) r.Set(ids[i], motion[i].AdvanceTo(t));
    r.Tick(time_ms);
  }
  // Bodies the receivers' streams took from the room's cache.
  uint64_t CacheHits() const {
    uint64_t hits = 0;
    for (const auto& x : rx) hits += x->stream.stats().cache_hits;
    return hits;
  }

  TestRoom r;
  std::vector<std::unique_ptr<Receiver>> rx;
  std::vector<TestMotion> motion;
  std::vector<uint32_t> ids;
};

void ExpectWithin(const QuantizationParams& p, const EntityState& truth, const EntityState& got,
                  const char* what) {
  EXPECT_LE(PositionError(truth.position, got.position), PosBound(p, truth.position))
      << what << " id " << truth.entity_id;
  EXPECT_LE(RotationErrorDeg(truth.rotation, got.rotation), p.config.rotation_error_deg * 1.0001)
      << what << " id " << truth.entity_id;
}

TEST(SharedDeltaCodec, RandomTransformsRoundTripWithinTheLatticeBound) {
  TestRoom r;
  Receiver rx(r.params);
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<float> pos(-999.f, 999.f), step(-0.05f, 0.05f), u(0.f, 1.f);
  std::vector<uint32_t> ids;
  for (uint32_t i = 0; i < 64; ++i) {
    ids.push_back(1000 + i * 3);
    r.Set(ids.back(), {0, {pos(rng), pos(rng), pos(rng)}, RandomRotation(rng)});
  }
  uint64_t checked = 0;
  for (int tick = 0; tick < 400; ++tick) {
    for (uint32_t id : ids) {
      EntityState s = r.truth[id];
      if (u(rng) < 0.05f) {  // teleport and random rotation
        s.position = {pos(rng), pos(rng), pos(rng)};
        s.rotation = RandomRotation(rng);
      } else {  // small random motion
        s.position = {s.position.x + step(rng), s.position.y + step(rng), s.position.z + step(rng)};
        if (u(rng) < 0.3f) s.rotation = RandomRotation(rng);
      }
      r.Set(id, s);
    }
    r.Tick(static_cast<uint32_t>(tick * 16));
    for (auto& [seq, payload] : rx.Send(r, ids, tick / 60.0, 300)) {
      ASSERT_TRUE(rx.Receive(payload));
      rx.stream.OnPacketAcked(seq);
    }
    for (uint32_t id : ids) {
      ASSERT_TRUE(rx.decoded.count(id));
      ExpectWithin(r.params, r.truth[id], rx.decoded[id], "round trip");
      ++checked;
    }
  }
  EXPECT_EQ(checked, 400u * 64u);
  EXPECT_EQ(rx.decoder.stats().malformed, 0u);
  EXPECT_EQ(rx.decoder.stats().unresolved_references, 0u);
  EXPECT_GT(rx.stream.stats().entities - rx.stream.stats().keyframes, 300u * 64u);  // deltas
}

// Several receivers with different send phases and link qualities: 20 % loss, 10 %
// duplication, reordering (random extra delay), lost acks. Every receiver ends within the
// bound of the truth, and the room's cache was shared.
TEST(SharedDeltaCodec, SeveralReceiversConvergeUnderLossDuplicationAndReordering) {
  constexpr int kReceivers = 6;
  constexpr uint32_t kEntities = 40;
  Crowd crowd(kReceivers, kEntities, 7, true);
  TestRoom& r = crowd.r;
  auto& rx = crowd.rx;
  std::mt19937_64 rng(99);
  std::uniform_real_distribution<double> u(0, 1);
  struct InFlight {
    int receiver;
    int deliver_tick;
    uint16_t seq;
    std::vector<uint8_t> payload;
  };
  struct Ack {
    int receiver;
    int deliver_tick;
    uint16_t seq;
  };
  std::vector<InFlight> flight;
  std::vector<Ack> acks;
  const double tick_hz = 60;
  const int motion_ticks = 600, settle_ticks = 900;
  for (int tick = 0; tick < motion_ticks + settle_ticks; ++tick) {
    const double now = tick / tick_hz;
    crowd.Advance(std::min(tick, motion_ticks) / tick_hz, static_cast<uint32_t>(now * 1000));
    for (int k = 0; k < kReceivers; ++k) {
      Receiver& x = *rx[k];
      // Receiver k is sent at 12 Hz (every 5th tick) with its own phase; receivers 0..2 share
      // a phase (and so, mostly, baselines).
      const int phase = k < 3 ? 0 : k - 2;
      if ((tick + phase) % 5 != 0) continue;
      std::vector<uint32_t> ids;
      for (uint32_t id = 1; id <= kEntities; ++id) {
        if (x.stream.Need(id, *r.shared[id], r.truth[id], 0.001f, 0.1f, now, 0.2) ==
            SharedDeltaStream::UpdateNeed::kSend) {
          ids.push_back(id);
        }
      }
      for (auto& [seq, payload] : x.Send(r, ids, now, 400)) {
        const int rtt_ticks = 1 + k;  // different round trips: different newest acked
        if (u(rng) < 0.2) continue;   // lost
        const int copies = u(rng) < 0.1 ? 2 : 1;
        for (int c = 0; c < copies; ++c) {
          flight.push_back({k, tick + rtt_ticks / 2 + static_cast<int>(u(rng) * 4), seq, payload});
        }
      }
    }
    // Deliver (in random order within a tick), acknowledge what was decoded.
    std::shuffle(flight.begin(), flight.end(), rng);
    for (auto it = flight.begin(); it != flight.end();) {
      if (it->deliver_tick > tick) {
        ++it;
        continue;
      }
      Receiver& x = *rx[it->receiver];
      ASSERT_TRUE(x.Receive(it->payload));
      if (u(rng) >= 0.2) acks.push_back({it->receiver, tick + 1 + it->receiver / 2, it->seq});
      it = flight.erase(it);
    }
    for (auto it = acks.begin(); it != acks.end();) {
      if (it->deliver_tick > tick) {
        ++it;
        continue;
      }
      rx[it->receiver]->stream.OnPacketAcked(it->seq);
      it = acks.erase(it);
    }
  }
  for (int k = 0; k < kReceivers; ++k) {
    for (uint32_t id = 1; id <= kEntities; ++id) {
      ASSERT_TRUE(rx[k]->decoded.count(id)) << "receiver " << k << " id " << id;
      ExpectWithin(r.params, r.truth[id], rx[k]->decoded[id], "converged");
    }
    EXPECT_EQ(rx[k]->decoder.stats().malformed, 0u);
    // Only acknowledged (= decoded) versions are referenced.
    EXPECT_EQ(rx[k]->decoder.stats().unresolved_references, 0u) << "receiver " << k;
  }
  const auto& st = r.room.stats();
  const uint64_t hits = crowd.CacheHits();
  std::printf("cache: %llu encodes, %llu hits, %llu uncached, %llu missing versions\n",
              static_cast<unsigned long long>(st.encodes.load()),
              static_cast<unsigned long long>(hits),
              static_cast<unsigned long long>(st.uncached.load()),
              static_cast<unsigned long long>(st.missing_versions.load()));
  EXPECT_GT(hits, 0u);  // harsh links: little sharing (see the next test)
}

// Receivers with one send phase and the same round trip on a mildly lossy link (2 %): most
// bodies are encoded once and appended by the others.
TEST(SharedDeltaCodec, ReceiversInPhaseMostlyShareUnderMildLoss) {
  constexpr int kReceivers = 10;
  constexpr uint32_t kEntities = 50;
  Crowd crowd(kReceivers, kEntities, 4, true);
  auto& [r, rx, motion, ids] = crowd;
  std::mt19937_64 rng(8);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<std::vector<uint16_t>> pending(kReceivers);
  for (int tick = 0; tick < 60 * 10; ++tick) {
    crowd.Advance(tick / 60.0, static_cast<uint32_t>(tick * 1000 / 60));
    if (tick % 5 != 0) continue;
    for (int k = 0; k < kReceivers; ++k) {
      for (uint16_t s : pending[k]) rx[k]->stream.OnPacketAcked(s);  // one send later
      pending[k].clear();
      for (auto& [seq, payload] : rx[k]->Send(r, ids, tick / 60.0, 300)) {
        if (u(rng) < 0.02) continue;
        ASSERT_TRUE(rx[k]->Receive(payload));
        pending[k].push_back(seq);
      }
    }
  }
  const auto& st = r.room.stats();
  const uint64_t hits = crowd.CacheHits();
  const double shared = static_cast<double>(hits) /
                        static_cast<double>(hits + st.encodes.load() + st.uncached.load());
  std::printf("in phase, 2 %% loss: %.1f %% of bodies from the cache (%llu encodes)\n",
              100 * shared, static_cast<unsigned long long>(st.encodes.load()));
  EXPECT_GT(shared, 0.75);
}

// N receivers holding the same baselines: one encode per (entity, key) per tick, every other
// receiver appends the cached bits; their payloads are byte-identical.
TEST(SharedDeltaCodec, ReceiversOnTheSameBaselineShareOneEncode) {
  constexpr int kReceivers = 10;
  constexpr uint32_t kEntities = 50;
  Crowd crowd(kReceivers, kEntities, 3, false);
  auto& [r, rx, motion, ids] = crowd;
  for (int tick = 0; tick < 100; ++tick) {
    crowd.Advance(tick / 60.0, static_cast<uint32_t>(tick * 1000 / 60));
    const uint64_t encodes_before = r.room.stats().encodes.load();
    const uint64_t hits_before = crowd.CacheHits();
    std::vector<std::vector<uint8_t>> first;
    for (int k = 0; k < kReceivers; ++k) {
      auto sent = rx[k]->Send(r, ids, tick / 60.0);
      for (size_t p = 0; p < sent.size(); ++p) {
        if (k == 0) {
          first.push_back(sent[p].second);
        } else {
          ASSERT_EQ(sent[p].second, first[p]) << "tick " << tick << " receiver " << k;
        }
        ASSERT_TRUE(rx[k]->Receive(sent[p].second));
        rx[k]->stream.OnPacketAcked(sent[p].first);
      }
    }
    EXPECT_EQ(r.room.stats().encodes.load() - encodes_before, kEntities) << "tick " << tick;
    const uint64_t hits = crowd.CacheHits();
    EXPECT_EQ(hits - hits_before, (kReceivers - 1) * kEntities);
  }
  EXPECT_EQ(r.room.stats().uncached.load(), 0u);
  for (int k = 0; k < kReceivers; ++k) {
    for (uint32_t id : ids) ExpectWithin(r.params, r.truth[id], rx[k]->decoded[id], "shared");
  }
}

// Receivers' ticks run in parallel (as on the relay's pool): the cache hands out each body
// once and every receiver decodes within the bound. (Meaningful under -fsanitize=thread too.)
TEST(SharedDeltaCodec, ParallelReceiversShareTheCacheSafely) {
  constexpr int kReceivers = 8;
  constexpr uint32_t kEntities = 60;
  Crowd crowd(kReceivers, kEntities, 6, true);
  auto& [r, rx, motion, ids] = crowd;
  constexpr int kTicks = 120;
  for (int tick = 0; tick < kTicks; ++tick) {
    crowd.Advance(tick / 60.0, static_cast<uint32_t>(tick * 1000 / 60));
    auto work = [&](int first) {
      for (int k = first; k < kReceivers; k += 2) {
        for (auto& [seq, payload] : rx[k]->Send(r, ids, tick / 60.0, 500)) {
          EXPECT_TRUE(rx[k]->Receive(payload));
          rx[k]->stream.OnPacketAcked(seq);
        }
      }
    };
    std::thread t0(work, 0), t1(work, 1);
    t0.join();
    t1.join();
  }
  for (int k = 0; k < kReceivers; ++k) {
    for (uint32_t id : ids) ExpectWithin(r.params, r.truth[id], rx[k]->decoded[id], "parallel");
  }
  const auto& st = r.room.stats();
  // Two threads may both code a body they found being built: at most one extra per pair.
  EXPECT_LE(st.encodes.load() + st.uncached.load(), 2u * kTicks * kEntities);
  const uint64_t hits = crowd.CacheHits();
  EXPECT_GE(hits, (kReceivers - 2u) * kTicks * kEntities);
}

// A 240 Hz room whose entities change every tick, sent at 6 Hz to receivers spread over every
// phase: the keys' versions lie up to ~0.5 s back. SharedVersionWindowFor(240) keeps them (no
// fallback keyframes); the 60 Hz default window of 64 would not.
TEST(SharedDeltaCodec, HighTickRatesKeepEnoughVersionsForSlowReceivers) {
  for (size_t window : {kSharedVersionWindow, SharedVersionWindowFor(240)}) {
    constexpr int kReceivers = 20;
    Crowd crowd(kReceivers, 10, 2, false, window);
    auto& [r, rx, motion, ids] = crowd;
    std::vector<std::vector<uint16_t>> pending(kReceivers);
    uint64_t keyframes = 0;
    for (int tick = 0; tick < 240 * 6; ++tick) {
      crowd.Advance(tick / 240.0, static_cast<uint32_t>(tick * 1000 / 240));
      for (int k = 0; k < kReceivers; ++k) {
        if ((tick + 2 * k) % 40 != 0) continue;  // 6 Hz, phases 2 ticks apart
        for (uint16_t s : pending[k]) rx[k]->stream.OnPacketAcked(s);
        pending[k].clear();
        for (auto& [seq, payload] : rx[k]->Send(r, ids, tick / 240.0)) {
          ASSERT_TRUE(rx[k]->Receive(payload));
          pending[k].push_back(seq);
        }
      }
    }
    for (auto& x : rx) {
      keyframes += x->stream.stats().keyframes - x->stream.stats().refresh_keyframes;
      for (uint32_t id : ids) ASSERT_TRUE(x->decoded.count(id));
    }
    const uint64_t missing = r.room.stats().missing_versions.load();
    std::printf("window %zu: %llu missing versions, %llu non-refresh keyframes\n", window,
                static_cast<unsigned long long>(missing),
                static_cast<unsigned long long>(keyframes));
    if (window == kSharedVersionWindow) {
      EXPECT_GT(missing, 0u);
    } else {
      EXPECT_EQ(missing, 0u);
      EXPECT_EQ(keyframes, static_cast<uint64_t>(kReceivers) * ids.size());  // the first only
    }
  }
}

// More distinct keys than cache slots: the extra receivers encode privately, correctly.
TEST(SharedDeltaCodec, MoreKeysThanSlotsStillEncodeCorrectly) {
  TestRoom r;
  const int n = static_cast<int>(kSharedCacheSlots) + 4;
  std::vector<std::unique_ptr<Receiver>> rx;
  for (int i = 0; i < n; ++i) rx.push_back(std::make_unique<Receiver>(r.params));
  TestMotion motion(5, 0, 1.5, 90.0, 0);
  for (int tick = 0; tick < 200; ++tick) {
    r.Set(1, motion.AdvanceTo(tick / 60.0));
    r.Tick(static_cast<uint32_t>(tick * 1000 / 60));
    for (int k = 0; k < n; ++k) {
      // Receiver k acknowledges only every (k+1)-th tick: all on different baselines.
      for (auto& [seq, payload] : rx[k]->Send(r, {1}, tick / 60.0)) {
        ASSERT_TRUE(rx[k]->Receive(payload));
        if (tick % (k + 1) == 0) rx[k]->stream.OnPacketAcked(seq);
      }
      ExpectWithin(r.params, r.truth[1], rx[k]->decoded[1], "many keys");
    }
  }
  EXPECT_GT(r.room.stats().uncached.load(), 0u);
}

// ---- Hand-built payloads for forged references and malformed input ----

struct Rec {
  uint32_t id;
  bool keyframe;
  QuantizedState q;       // keyframe
  uint32_t distance = 1;  // delta (zero residuals, both masks set)
};

std::vector<uint8_t> Build(const QuantizationParams& p, uint32_t tick, uint32_t time_ms,
                           const std::vector<Rec>& recs) {
  std::vector<uint8_t> bits(512, 0);
  BitWriter w(bits);
  uint32_t prev_id = 0, prev_d = 1;
  for (size_t i = 0; i < recs.size(); ++i) {
    const Rec& rc = recs[i];
    w.WriteExpGolomb(i == 0 ? rc.id : rc.id - prev_id - 1, 0);
    prev_id = rc.id;
    if (rc.keyframe) {
      w.WriteExpGolomb(1, 0);
      for (int a = 0; a < 3; ++a) w.WriteBits(rc.q.position[a], p.position_bits[a]);
      w.WriteBits(rc.q.rotation.largest, 2);
      for (int c = 0; c < 3; ++c) {
        w.WriteBits(static_cast<uint32_t>(rc.q.rotation.c[c] + p.rotation_max), p.rotation_bits);
      }
    } else {
      const int32_t diff = static_cast<int32_t>(rc.distance) - static_cast<int32_t>(prev_d);
      w.WriteExpGolomb(diff == 0 ? 0 : ZigZag(diff) + 1, 0);
      prev_d = rc.distance;
      w.WriteBit(false);  // position: prediction
      w.WriteBit(false);  // rotation: prediction
    }
  }
  std::vector<uint8_t> out(kSharedDeltaHeaderSize);
  out[0] = kSharedDeltaStateFormat;
  StoreU32LE(out.data() + 1, time_ms);
  StoreU32LE(out.data() + 5, tick);
  // k 2/1, masks on, order 2/2
  StoreU16LE(out.data() + 9, static_cast<uint16_t>(2 | (1 << 3) | (1 << 6) | (1 << 7) | (2 << 8) |
                                                   (2 << 10)));
  uint8_t cnt[5];
  const size_t cn = PutVarint32(static_cast<uint32_t>(recs.size()), cnt);
  out.insert(out.end(), cnt, cnt + cn);
  out.insert(out.end(), bits.begin(), bits.begin() + w.byte_size());
  return out;
}

QuantizedState Q(const QuantizationParams& p, float x) {
  QuantizedState q;
  EXPECT_TRUE(QuantizeState(p, {0, {x, 1, 2}, {0, 0, 0, 1}}, &q));
  return q;
}

TEST(SharedDeltaCodec, ForgedReferencesAreDroppedAndCounted) {
  const QuantizationParams p = DefaultParams();
  SharedDeltaDecoder d(p);
  StateBatch b;
  // Entity 5 held at ticks 100, 102, ..., 130 (16 versions).
  for (uint32_t t = 100; t <= 130; t += 2) {
    ASSERT_TRUE(d.Decode(Build(p, t, t * 16, {{5, true, Q(p, t * 0.01f)}}), &b).ok());
  }
  const size_t outputs = b.states.size();
  ASSERT_EQ(outputs, 16u);
  auto delta = [&](uint32_t id, uint32_t tick, uint32_t distance) {
    return d.Decode(Build(p, tick, tick * 16, {{id, false, {}, distance}}), &b);
  };
  // Unknown entity's baseline.
  ASSERT_TRUE(delta(6, 131, 1).ok());
  EXPECT_EQ(d.stats().unknown_entity, 1u);
  // Stale: older than everything held (tick 50).
  ASSERT_TRUE(delta(5, 200, 150).ok());
  EXPECT_EQ(d.stats().stale_references, 1u);
  // From the future: newer than anything held (135, 95904).
  ASSERT_TRUE(delta(5, 140, 5).ok());
  ASSERT_TRUE(delta(5, 100000, 4096).ok());
  EXPECT_EQ(d.stats().future_references, 2u);
  // Inside the held range but never held (odd tick).
  ASSERT_TRUE(delta(5, 140, 25).ok());
  EXPECT_EQ(d.stats().missing_references, 1u);
  EXPECT_EQ(d.stats().unresolved_references, 5u);
  EXPECT_EQ(b.states.size(), outputs) << "a forged reference produced a state";
  // Distances outside 1..4096 are malformed.
  EXPECT_FALSE(delta(5, 140, 0).ok());
  EXPECT_FALSE(delta(5, 140, 4097).ok());
  EXPECT_EQ(d.stats().malformed, 2u);
  // A genuine reference still decodes: zero residual against tick 130 (an isolated keyframe
  // history predicts itself).
  ASSERT_TRUE(d.Decode(Build(p, 131, 131 * 16, {{5, false, {}, 1}}), &b).ok());
  ASSERT_EQ(b.states.size(), outputs + 1);
  EXPECT_EQ(b.states.back().entity_id, 5u);
  EXPECT_NEAR(b.states.back().position.x, 1.30f, 0.001f);
}

TEST(SharedDeltaCodec, MalformedAndTruncatedPayloadsChangeNothing) {
  Crowd crowd(1, 20, 9, false);
  TestRoom& r = crowd.r;
  Receiver& rx = *crowd.rx[0];
  std::vector<uint8_t> last;
  for (int tick = 0; tick < 30; ++tick) {
    crowd.Advance(tick / 60.0, static_cast<uint32_t>(tick * 16));
    auto sent = rx.Send(r, crowd.ids, tick / 60.0);
    ASSERT_EQ(sent.size(), 1u);
    if (tick == 29) {
      last = sent[0].second;  // a delta payload, not yet decoded
      break;
    }
    ASSERT_TRUE(rx.Receive(sent[0].second));
    rx.stream.OnPacketAcked(sent[0].first);
  }
  const SharedDeltaDecoder before = rx.decoder;
  auto expect_rejected = [&](const std::vector<uint8_t>& bad, const char* what) {
    StateBatch b;
    b.states.push_back({});  // must stay untouched
    EXPECT_FALSE(rx.decoder.Decode(bad, &b).ok()) << what;
    EXPECT_EQ(b.states.size(), 1u) << what;
    EXPECT_EQ(rx.decoder.stats().payloads, before.stats().payloads) << what;
  };
  for (size_t n = 0; n < last.size(); ++n) {
    expect_rejected(std::vector<uint8_t>(last.begin(), last.begin() + n), "truncated");
  }
  auto extra = last;
  extra.push_back(0);
  expect_rejected(extra, "trailing byte");
  auto fmt = last;
  fmt[0] = kDeltaStateFormat;
  expect_rejected(fmt, "format 2 byte");
  auto reserved = last;
  reserved[10] |= 0x80;
  expect_rejected(reserved, "reserved params bits");
  auto order3 = last;
  order3[10] = static_cast<uint8_t>((order3[10] & ~0x03) | 0x03);
  expect_rejected(order3, "order 3");
  auto zero = last;
  zero[kSharedDeltaHeaderSize] = 0;
  expect_rejected(zero, "count 0");
  auto big = last;
  big[kSharedDeltaHeaderSize] = 0x7f;
  expect_rejected(big, "count too large");
  auto pad = last;
  pad.back() |= 0x80;
  // Either the last byte's top bit was padding (malformed) or a residual bit (decodes).
  {
    SharedDeltaDecoder copy = before;
    StateBatch b;
    (void)copy.Decode(pad, &b);
  }
  // After all that, the genuine payload decodes exactly as it would have before.
  SharedDeltaDecoder reference = before;
  StateBatch want, got;
  ASSERT_TRUE(reference.Decode(last, &want).ok());
  ASSERT_TRUE(rx.decoder.Decode(last, &got).ok());
  ASSERT_EQ(want.states.size(), got.states.size());
  ASSERT_EQ(got.states.size(), 20u);
  for (size_t i = 0; i < got.states.size(); ++i) {
    EXPECT_EQ(want.states[i].position.x, got.states[i].position.x);
    EXPECT_EQ(want.states[i].rotation.w, got.states[i].rotation.w);
  }
  // Random corruption: never a crash; accepted or rejected as a whole.
  std::mt19937_64 rng(5);
  for (int i = 0; i < 2000; ++i) {
    auto bad = last;
    bad[rng() % bad.size()] ^= static_cast<uint8_t>(1u << (rng() % 8));
    SharedDeltaDecoder copy = before;
    StateBatch b;
    (void)copy.Decode(bad, &b);
  }
}

TEST(SharedDeltaCodec, DespawnedEntityStartsOverWithAKeyframe) {
  TestRoom r;
  Receiver rx(r.params);
  for (int tick = 0; tick < 10; ++tick) {
    r.Set(7, {0, {tick * 0.01f, 0, 0}, {0, 0, 0, 1}});
    r.Tick(static_cast<uint32_t>(tick * 16));
    for (auto& [seq, payload] : rx.Send(r, {7}, tick / 60.0)) {
      ASSERT_TRUE(rx.Receive(payload));
      rx.stream.OnPacketAcked(seq);
    }
  }
  const uint64_t keyframes = rx.stream.stats().keyframes;
  r.Remove(7);
  rx.stream.Forget(7);
  rx.decoder.Forget(7);
  r.Set(7, {0, {5, 5, 5}, {0, 0, 0, 1}});
  r.Tick(200);
  for (auto& [seq, payload] : rx.Send(r, {7}, 1.0)) ASSERT_TRUE(rx.Receive(payload));
  EXPECT_EQ(rx.stream.stats().keyframes, keyframes + 1);
  ExpectWithin(r.params, r.truth[7], rx.decoded[7], "respawned");
}

// Bytes per update against format 2 on the acceptance motion (12 Hz sends in a 60 Hz room,
// acks one send later, 5 % loss): format 9 codes the same residuals with room-wide parameters
// and 32-bit ticks; the target is at most +15 %.
TEST(SharedDeltaCodec, BytesPerUpdateWithinFifteenPercentOfFormat2) {
  for (int n : {32, 128, 512}) {
    for (double loss : {0.0, 0.05}) {
      TestRoom r;
      Receiver rx(r.params);
      DeltaEncoder f2(r.params);
      DeltaDecoder f2d(r.params);
      std::vector<TestMotion> motion;
      std::vector<uint32_t> ids;
      for (int i = 0; i < n; ++i) {
        motion.emplace_back(11, static_cast<uint32_t>(i), 1.5, 90.0, i % 2);
        ids.push_back(static_cast<uint32_t>(i + 1));
      }
      std::mt19937_64 rng(17);
      std::uniform_real_distribution<double> u(0, 1);
      uint64_t bytes9 = 0, bytes2 = 0, updates = 0;
      uint16_t seq2 = 0;
      std::vector<uint16_t> pending9, pending2;  // acked one send later
      std::vector<uint8_t> buf(1179);
      double max_err = 0;
      for (int tick = 0; tick < 60 * 20; ++tick) {
        const double now = tick / 60.0;
        for (int i = 0; i < n; ++i) r.Set(ids[i], motion[i].AdvanceTo(now));
        r.Tick(static_cast<uint32_t>(tick * 1000 / 60));
        if (tick % 5 != 0) continue;
        for (uint16_t s : pending9) rx.stream.OnPacketAcked(s);
        for (uint16_t s : pending2) f2.OnPacketAcked(s);
        pending9.clear();
        pending2.clear();
        for (auto& [seq, payload] : rx.Send(r, ids, now)) {
          bytes9 += payload.size() + kPacketOverhead;
          if (u(rng) < loss) continue;
          ASSERT_TRUE(rx.Receive(payload));
          pending9.push_back(seq);
        }
        // Format 2, same states and time.
        const uint32_t time_ms = r.room.time_ms();
        auto flush2 = [&]() {
          const size_t size = f2.Finish();
          if (size == 0) return;
          bytes2 += size + kPacketOverhead;
          f2.OnSent(seq2, now);
          StateBatch b;
          if (u(rng) >= loss) {
            EXPECT_TRUE(f2d.Decode({buf.data(), size}, &b).ok());
            pending2.push_back(seq2);
          }
          ++seq2;
        };
        f2.Begin(buf, time_ms);
        for (uint32_t id : ids) {
          if (!f2.Add(r.truth[id], &r.prepared[id])) {
            flush2();
            f2.Begin(buf, time_ms);
            ASSERT_TRUE(f2.Add(r.truth[id], &r.prepared[id]));
          }
        }
        flush2();
        updates += ids.size();
        for (uint32_t id : ids) {
          if (loss == 0 && rx.decoded.count(id)) {
            max_err = std::max(max_err, PositionError(r.truth[id].position,
                                                      rx.decoded[id].position));
          }
        }
      }
      const double b9 = static_cast<double>(bytes9) / updates;
      const double b2 = static_cast<double>(bytes2) / updates;
      std::printf("N=%d loss=%.2f: format 9 %.3f bytes/update, format 2 %.3f (%+.1f %%), "
                  "keyframes %llu, max err %.3f mm\n",
                  n, loss, b9, b2, 100.0 * (b9 / b2 - 1),
                  static_cast<unsigned long long>(rx.stream.stats().keyframes), max_err * 1e3);
      EXPECT_LE(b9, b2 * 1.15) << "N=" << n << " loss=" << loss;
      EXPECT_EQ(rx.decoder.stats().unresolved_references, 0u);
    }
  }
}

}  // namespace
}  // namespace edgephys

namespace edgephys {
namespace {

// Selective sync against the room's versions: the answer for a reference tick is memoised per
// tick, so it must follow the truth from one tick to the next, and a version the room no
// longer holds is never "within".
TEST(SharedDeltaRoomTest, HeldWithinFollowsTheTruthAcrossTicks) {
  TestRoom r(/*versions=*/4);
  const double pos2 = 0.001 * 0.001;
  const double min_dot = std::cos(0.1 * 3.14159265358979323846 / 360.0);
  const double reach = 0.5 * std::sqrt(3.0) * r.params.step * 1.01;
  const double lattice_min_dot = std::cos(0.1 * 1.01 * 3.14159265358979323846 / 360.0);
  auto within = [&](uint32_t ref) {
    return r.room.HeldWithin(*r.shared[1], ref, r.truth[1], pos2, min_dot, reach * reach,
                             lattice_min_dot);
  };
  EntityState s;
  s.position = {1.0f, 1.0f, 1.0f};
  r.Set(1, s);
  r.Tick(0);  // tick 1: version at (1, 1, 1)
  EXPECT_TRUE(within(1));
  r.Tick(16);  // tick 2: unchanged
  EXPECT_TRUE(within(1));
  EXPECT_TRUE(within(2));
  s.position.x += 0.005f;  // 5 mm: beyond the 1 mm threshold
  r.Set(1, s);
  r.Tick(33);                // tick 3
  EXPECT_FALSE(within(1));   // tick 2's memo for reference 1 must not answer for tick 3
  EXPECT_FALSE(within(1));   // and the memo of tick 3 says the same
  EXPECT_TRUE(within(3));
  s.rotation = {0.0f, 0.0f, 0.0087265f, 0.9999619f};  // 1 deg about z
  r.Set(1, s);
  r.Tick(50);  // tick 4
  EXPECT_FALSE(within(3));
  for (uint32_t t = 0; t < 6; ++t) {  // four more versions: tick 4's falls out of the window
    s.position.y += 0.01f;
    r.Set(1, s);
    r.Tick(66 + 16 * t);
  }
  EXPECT_FALSE(within(4));                      // no longer held: never within
  EXPECT_TRUE(within(r.room.tick()));  // the current version is
}

}  // namespace
}  // namespace edgephys
