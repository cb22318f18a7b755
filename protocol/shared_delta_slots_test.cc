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
#include "protocol/testing/shared_delta_harness.h"

namespace edgephys {
namespace {

using testing_util::PositionError;

using Harness = testing_util::SharedDeltaHarness;

EntityState At(float x) { return {0, {x, 1, 2}, {0, 0, 0, 1}}; }

// Entity `e` (id `id`) ticked at x = 0, 0.01, ... and sent, decoded and acknowledged, `times`
// times: the stream's track of it holds an acked baseline.
void SendAcked(Harness& h, SharedEntity* e, uint32_t id, int times) {
  for (int i = 0; i < times; ++i) {
    h.Tick({{e, At(0.01f * i)}});
    auto [s, payload] = h.Send({{id, e}});
    (void)h.Decode(payload, id);
    h.stream.OnPacketAcked(s);
  }
}

TEST(SharedDeltaSlots, AReusedSlotNeverAliasesItsPreviousOccupant) {
  Harness h;
  auto a = std::make_unique<SharedEntity>();
  a->BindSlot(0, 1);
  SendAcked(h, a.get(), 5, 5);  // A (id 5) has an acked baseline
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
  SendAcked(h, first.get(), 7, 4);
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
