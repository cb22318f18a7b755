// Format 9, relay side: the per-receiver records live in arrays indexed by the entity's
// room-local slot (SharedEntity::slot) and are trusted only while the slot's serial matches.
// A reused slot never aliases its previous occupant (no delta against the old entity's
// versions, late acks of the old occupant's packets change nothing), a respawn under the same
// id starts over with a keyframe, and spawn/despawn churn keeps the arrays bounded.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <vector>

#include "protocol/shared_delta_codec.h"
#include "protocol/testing/codec_test_util.h"

namespace edgephys {
namespace {

using testing_util::PositionError;

QuantizationParams Params() { return *MakeQuantizationParams(QuantizationConfig{}); }

struct Harness {
  QuantizationParams params = Params();
  SharedDeltaRoom room{params};
  SharedDeltaStream stream{params};
  SharedDeltaDecoder decoder{params};
  uint16_t seq = 0;
  uint32_t time_ms = 0;
  std::vector<uint8_t> buf = std::vector<uint8_t>(1179);

  void Tick(const std::vector<std::pair<SharedEntity*, EntityState>>& entities) {
    time_ms += 16;
    room.BeginTick(time_ms);
    for (const auto& [e, s] : entities) room.PrepareEntity(*e, PrepareState(params, s));
  }
  // Sends `ids` (increasing) in one payload; returns its sequence and bytes.
  std::pair<uint16_t, std::vector<uint8_t>> Send(
      const std::vector<std::pair<uint32_t, SharedEntity*>>& ids) {
    stream.Begin(buf, time_ms);
    for (const auto& [id, e] : ids) EXPECT_TRUE(stream.Add(id, *e)) << id;
    const size_t n = stream.Finish();
    EXPECT_GT(n, 0u);
    const uint16_t s = seq++;
    stream.OnSent(s, time_ms / 1000.0);
    return {s, std::vector<uint8_t>(buf.begin(), buf.begin() + n)};
  }
  EntityState Decode(const std::vector<uint8_t>& payload, uint32_t id) {
    StateBatch batch;
    EXPECT_TRUE(decoder.Decode(payload, &batch).ok());
    for (const EntityState& s : batch.states) {
      if (s.entity_id == id) return s;
    }
    ADD_FAILURE() << "entity " << id << " not decoded";
    return {};
  }
};

EntityState At(float x) { return {0, {x, 1, 2}, {0, 0, 0, 1}}; }

TEST(SharedDeltaSlots, AReusedSlotNeverAliasesItsPreviousOccupant) {
  Harness h;
  auto a = std::make_unique<SharedEntity>();
  a->BindSlot(0, 1);
  // A (id 5) is sent and acknowledged a few times: its track holds an acked baseline.
  for (int i = 0; i < 5; ++i) {
    h.Tick({{a.get(), At(0.01f * i)}});
    auto [s, payload] = h.Send({{5, a.get()}});
    (void)h.Decode(payload, 5);
    h.stream.OnPacketAcked(s);
  }
  // One more send of A whose ack comes late.
  h.Tick({{a.get(), At(0.2f)}});
  const uint16_t late = h.Send({{5, a.get()}}).first;
  // A is gone (no Forget: the stream only learns it from the serial); B (id 9) gets slot 0.
  a.reset();
  auto b = std::make_unique<SharedEntity>();
  b->BindSlot(0, 2);
  const uint64_t keyframes = h.stream.stats().keyframes;
  h.Tick({{b.get(), At(40.f)}});
  auto [s1, p1] = h.Send({{9, b.get()}});
  EXPECT_EQ(h.stream.stats().keyframes, keyframes + 1) << "B coded against A's versions";
  EXPECT_LE(PositionError(At(40.f).position, h.Decode(p1, 9).position), h.params.step);
  // A's late ack marks A's payload; A's sends went with A's record, so it gives B no baseline.
  h.stream.OnPacketAcked(late);
  h.Tick({{b.get(), At(40.5f)}});
  auto [s2, p2] = h.Send({{9, b.get()}});
  EXPECT_EQ(h.stream.stats().keyframes, keyframes + 2) << "B referenced A's acked send";
  EXPECT_LE(PositionError(At(40.5f).position, h.Decode(p2, 9).position), h.params.step);
  // B's own ack makes the next send a delta again.
  h.stream.OnPacketAcked(s2);
  h.Tick({{b.get(), At(40.6f)}});
  auto [s3, p3] = h.Send({{9, b.get()}});
  EXPECT_EQ(h.stream.stats().keyframes, keyframes + 2);
  EXPECT_LE(PositionError(At(40.6f).position, h.Decode(p3, 9).position), h.params.step);
  EXPECT_EQ(h.stream.tracked_entities(), 1u);
  EXPECT_EQ(h.stream.track_slots(), 1u);
}

TEST(SharedDeltaSlots, ARespawnUnderTheSameIdAndSlotStartsOverWithAKeyframe) {
  Harness h;
  auto first = std::make_unique<SharedEntity>();
  first->BindSlot(3, 10);
  for (int i = 0; i < 4; ++i) {
    h.Tick({{first.get(), At(0.01f * i)}});
    auto [s, payload] = h.Send({{7, first.get()}});
    (void)h.Decode(payload, 7);
    h.stream.OnPacketAcked(s);
  }
  auto second = std::make_unique<SharedEntity>();  // id 7 again, same slot, next serial
  second->BindSlot(3, 11);
  const uint64_t keyframes = h.stream.stats().keyframes;
  h.Tick({{second.get(), At(-3.f)}});
  auto [s, payload] = h.Send({{7, second.get()}});
  EXPECT_EQ(h.stream.stats().keyframes, keyframes + 1);
  h.decoder.Forget(7);  // the client drops what it held on the Despawn
  EXPECT_LE(PositionError(At(-3.f).position, h.Decode(payload, 7).position), h.params.step);
  EXPECT_EQ(h.stream.tracked_entities(), 1u);
}

TEST(SharedDeltaSlots, ThousandSpawnDespawnCyclesKeepTheRecordsBounded) {
  Harness h;
  constexpr uint32_t kLive = 6;
  uint32_t serial = 0;
  uint32_t next_id = 1;
  for (int cycle = 0; cycle < 1000; ++cycle) {
    // kLive entities in slots 0..kLive-1 (as a room reuses freed slots), new ids each cycle.
    std::vector<std::unique_ptr<SharedEntity>> live;
    std::vector<std::pair<uint32_t, SharedEntity*>> ids;
    std::vector<std::pair<SharedEntity*, EntityState>> states;
    for (uint32_t s = 0; s < kLive; ++s) {
      live.push_back(std::make_unique<SharedEntity>());
      live.back()->BindSlot(s, ++serial);
      ids.emplace_back(next_id++, live.back().get());
      states.emplace_back(live.back().get(), At(static_cast<float>(s)));
    }
    for (int tick = 0; tick < 2; ++tick) {
      h.Tick(states);
      auto [seq, payload] = h.Send(ids);
      if (tick == 0) h.stream.OnPacketAcked(seq);
    }
    // Despawn: half are forgotten explicitly, half only replaced by the next occupants.
    for (size_t i = 0; i < ids.size(); i += 2) h.stream.Forget(ids[i].first);
    ASSERT_LE(h.stream.tracked_entities(), kLive) << cycle;
    ASSERT_EQ(h.stream.track_slots(), kLive) << cycle;
  }
  EXPECT_EQ(h.stream.stats().entities, 1000u * 2 * kLive);
}

}  // namespace
}  // namespace edgephys
