// Format 9, relay side: acknowledgements are one flag per payload, and each entity's record
// takes them in from its last SharedDeltaStream::kRememberedSends sends when the entity is next
// considered (Need, Add). Reordered and duplicated acks keep the newest acknowledged send as the
// baseline; an ack that comes after newer sends still counts; a payload that never left is never
// a baseline, even when a later payload's ack arrives; and the room's per-age memo of the
// selective-sync answers (HeldWithin) matches a direct test for every reference age.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <utility>
#include <vector>

#include "protocol/shared_delta_codec.h"
#include "protocol/testing/codec_test_util.h"
#include "protocol/testing/shared_delta_harness.h"

namespace edgephys {
namespace {

using testing_util::PositionError;

EntityState At(float x) { return {0, {x, 1, 2}, {0, 0, 0, 1}}; }

using Harness = testing_util::SharedDeltaHarness;

// One tick of `h` with `e` at At(x), sent to receiver 5 and decoded there into *got: the
// send's sequence and the reference distance Decode returns.
std::pair<uint16_t, int64_t> SendOne(Harness& h, SharedEntity* e, float x, EntityState* got) {
  h.Tick({{e, At(x)}});
  auto [seq, payload] = h.Send({{5, e}});
  return {seq, h.Decode(payload, 5, got)};
}

TEST(SharedDeltaAcks, ReorderedAndDuplicatedAcksKeepTheNewestSendAsBaseline) {
  Harness h;
  auto a = std::make_unique<SharedEntity>();
  a->BindSlot(0, 1);
  std::vector<uint16_t> seqs;
  EntityState got;
  for (int i = 0; i < 3; ++i) {
    const uint16_t s = SendOne(h, a.get(), 0.01f * i, &got).first;
    seqs.push_back(s);
  }
  // Acks arrive newest first, then the older ones, then the newest again.
  h.stream.OnPacketAcked(seqs[2]);
  h.stream.OnPacketAcked(seqs[0]);
  h.stream.OnPacketAcked(seqs[1]);
  h.stream.OnPacketAcked(seqs[2]);
  EXPECT_EQ(h.stream.stats().acks_unmatched, 1u) << "the duplicate";
  EXPECT_EQ(SendOne(h, a.get(), 0.05f, &got).second, 1)
      << "not against the newest acknowledged send";
  EXPECT_LE(PositionError(At(0.05f).position, got.position), h.params.step);
  EXPECT_EQ(h.decoder.stats().unresolved_references, 0u);
}

TEST(SharedDeltaAcks, AnAckAfterNewerSendsStillMakesItsSendTheBaseline) {
  Harness h;
  auto a = std::make_unique<SharedEntity>();
  a->BindSlot(0, 1);
  EntityState got;
  uint16_t first = 0;
  // Four sends (all remembered); only the first is acknowledged, after the fourth left.
  for (int i = 0; i < 4; ++i) {
    const uint16_t s = SendOne(h, a.get(), 0.01f * i, &got).first;
    if (i == 0) first = s;
  }
  h.stream.OnPacketAcked(first);
  EXPECT_EQ(SendOne(h, a.get(), 0.08f, &got).second, 4) << "the late ack was not taken in";
  EXPECT_LE(PositionError(At(0.08f).position, got.position), h.params.step);

  // An ack of a send older than the remembered ones counts as lost: the baseline stays the
  // acknowledged send at tick 1 (11 ticks back), not the one the late ack names (6 back).
  uint16_t old = 0;
  for (int i = 0; i < 6; ++i) {
    const uint16_t s = SendOne(h, a.get(), 0.1f + 0.01f * i, &got).first;
    if (i == 0) old = s;
  }
  h.stream.OnPacketAcked(old);
  EXPECT_EQ(SendOne(h, a.get(), 0.2f, &got).second, 11);
  EXPECT_LE(PositionError(At(0.2f).position, got.position), h.params.step);
  EXPECT_EQ(h.decoder.stats().unresolved_references, 0u);
}

TEST(SharedDeltaAcks, APayloadThatNeverLeftIsNeverABaseline) {
  Harness h;
  auto a = std::make_unique<SharedEntity>();
  auto b = std::make_unique<SharedEntity>();
  a->BindSlot(0, 1);
  b->BindSlot(1, 2);
  EntityState got;
  h.Tick({{a.get(), At(1.0f)}, {b.get(), At(2.0f)}});
  auto [s1, p1] = h.Send({{5, a.get()}, {9, b.get()}});
  (void)h.Decode(p1, 5, &got);
  h.stream.OnPacketAcked(s1);
  // A's next payload is encoded but never handed to the connection (e.g. a send error).
  h.Tick({{a.get(), At(1.01f)}, {b.get(), At(2.01f)}});
  (void)h.Send({{5, a.get()}}, /*sent=*/false);
  // The next payload carries only B, and is acknowledged.
  h.Tick({{a.get(), At(1.02f)}, {b.get(), At(2.02f)}});
  auto [s3, p3] = h.Send({{9, b.get()}});
  (void)h.Decode(p3, 9, &got);
  h.stream.OnPacketAcked(s3);
  // A must be coded against its first (delivered) send, not the one that never left.
  h.Tick({{a.get(), At(1.03f)}, {b.get(), At(2.03f)}});
  auto [s4, p4] = h.Send({{5, a.get()}});
  EXPECT_EQ(h.Decode(p4, 5, &got), 3);
  EXPECT_LE(PositionError(At(1.03f).position, got.position), h.params.step);
  EXPECT_EQ(h.decoder.stats().unresolved_references, 0u);
}

// Selective sync is memoised per entity by the reference's age in ticks. Over a history whose
// versions are irregular (changes in runs of consecutive ticks, with gaps), every reference age
// must answer as a direct comparison with the version current at that tick would.
TEST(SharedDeltaAcks, HeldWithinAnswersEveryAgeOfAnIrregularHistory) {
  const QuantizationParams params = *MakeQuantizationParams(QuantizationConfig{});
  SharedDeltaRoom room(params, /*versions_per_entity=*/64);
  SharedEntity e;
  std::vector<float> x_at_tick(1, 0.0f);  // by tick; tick 0 unused
  float x = 0.5f;
  for (int t = 1; t <= 60; ++t) {
    if (t % 7 != 0 && t % 11 != 0) x += 0.004f;  // 4 mm: a new version; else unchanged
    room.BeginTick(static_cast<uint32_t>(t * 16));
    room.PrepareEntity(e, PrepareState(params, At(x)));
    x_at_tick.push_back(x);
  }
  const double pos2 = 0.001 * 0.001;
  const double min_dot = std::cos(0.1 * 3.14159265358979323846 / 360.0);
  const double reach = 0.5 * std::sqrt(3.0) * params.step * 1.01;
  const double lattice_min_dot = std::cos(0.1 * 1.01 * 3.14159265358979323846 / 360.0);
  // In each further tick (no new version), the truth is one past state; every reference is
  // asked twice (the second answer from the memo).
  for (int truth_tick = 1; truth_tick <= 60; truth_tick += 3) {
    room.BeginTick(static_cast<uint32_t>((61 + truth_tick) * 16));
    const EntityState truth = At(x_at_tick[truth_tick]);
    for (int pass = 0; pass < 2; ++pass) {
      for (int ref = 1; ref <= 60; ++ref) {
        const bool expect = std::fabs(x_at_tick[ref] - x_at_tick[truth_tick]) < 0.0005f;
        EXPECT_EQ(room.HeldWithin(e, static_cast<uint32_t>(ref), truth, pos2, min_dot,
                                  reach * reach, lattice_min_dot),
                  expect)
            << "truth tick " << truth_tick << " ref " << ref << " pass " << pass;
      }
    }
  }
}

}  // namespace
}  // namespace edgephys
