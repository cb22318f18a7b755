// Application messages through a real relay: to the room, to the others, to one player; each
// arrives once, in the order its sender sent it, with the sender's id, at exactly the addressed
// players, also under 20 % loss, reordering and duplication (simulated network, fake clock).
// Oversized, over-rate, unpermitted, misaddressed and malformed messages are refused with
// their reason and counted, and reach nobody.
#include <gtest/gtest.h>

#include <flatbuffers/flatbuffers.h>

#include <algorithm>
#include <cstring>
#include <map>
#include <vector>

#include "client/client_testing.h"
#include "protocol/handshake.h"
#include "relay/room_host.h"
#include "tests/integration/join_all.h"
#include "tests/integration/message_inbox.h"
#include "tests/integration/sim_world.h"

namespace edgephys::testing {
namespace {

constexpr uint8_t kFillerStep = 31;
std::vector<uint8_t> Payload(uint8_t tag, uint32_t seq, size_t size = 5) {
  return TaggedPayload(tag, seq, size, kFillerStep);
}

struct Inbox : MessageInbox {
  Inbox() : MessageInbox(kFillerStep) {}
  void OnMessage(uint32_t sender, std::span<const uint8_t> payload) override {
    Record(sender, payload);
  }
};

std::vector<uint32_t> Iota(uint32_t n) {
  std::vector<uint32_t> v(n);
  for (uint32_t i = 0; i < n; ++i) v[i] = i;
  return v;
}

constexpr uint8_t kToRoom = 1, kToOthers = 2, kToPlayer = 3, kBig = 4;

TEST(Messages, ArriveOnceInOrderAtExactlyTheAddressedPlayersUnderLossReorderingDuplication) {
  SimWorld world(LossyLink());
  Inbox ia, ib, ic;
  auto [a, b, c] = AddJoined(world, "chat", ia, ib, ic);
  world.RunFor(0.5);  // the join streams have drained
  constexpr uint32_t kN = 60;
  for (uint32_t i = 0; i < kN; ++i) {
    ASSERT_TRUE(a.SendMessage(MessageTarget::kRoom, 0, Payload(kToRoom, i)).ok());
    ASSERT_TRUE(b.SendMessage(MessageTarget::kOthers, 0, Payload(kToOthers, i)).ok());
    ASSERT_TRUE(c.SendMessage(MessageTarget::kPlayer, 1, Payload(kToPlayer, i)).ok());
    if (i % 20 == 0) {  // 40 KiB: fragmented by the reliable channel
      ASSERT_TRUE(a.SendMessage(MessageTarget::kOthers, 0, Payload(kBig, i, 40000)).ok());
    }
    world.RunFor(0.02);
  }
  const size_t want_a = 3 * kN, want_b = kN + 3, want_c = 2 * kN + 3;
  ASSERT_TRUE(world.RunUntil([&] {
    return ia.got.size() >= want_a && ib.got.size() >= want_b && ic.got.size() >= want_c;
  }, 30.0)) << ia.got.size() << " " << ib.got.size() << " " << ic.got.size();
  world.RunFor(1.0);  // nothing more (no duplicates) arrives
  // A: its own room messages and B's; C's messages to player 1. Not its own big ones.
  EXPECT_EQ(ia.Stream(1, kToRoom), Iota(kN));
  EXPECT_EQ(ia.Stream(2, kToOthers), Iota(kN));
  EXPECT_EQ(ia.Stream(3, kToPlayer), Iota(kN));
  EXPECT_TRUE(ia.Stream(1, kBig).empty());
  EXPECT_EQ(ia.got.size(), want_a);
  // B: A's room and big messages; not its own, not C's to player 1.
  EXPECT_EQ(ib.Stream(1, kToRoom), Iota(kN));
  EXPECT_EQ(ib.Stream(1, kBig), (std::vector<uint32_t>{0, 20, 40}));
  EXPECT_TRUE(ib.Stream(2, kToOthers).empty());
  EXPECT_TRUE(ib.Stream(3, kToPlayer).empty());
  EXPECT_EQ(ib.got.size(), want_b);
  // C: A's room and big messages and B's; not its own to player 1.
  EXPECT_EQ(ic.Stream(1, kToRoom), Iota(kN));
  EXPECT_EQ(ic.Stream(1, kBig), (std::vector<uint32_t>{0, 20, 40}));
  EXPECT_EQ(ic.Stream(2, kToOthers), Iota(kN));
  EXPECT_TRUE(ic.Stream(3, kToPlayer).empty());
  EXPECT_EQ(ic.got.size(), want_c);
  EXPECT_TRUE(ia.errors.empty() && ib.errors.empty() && ic.errors.empty());
  const RoomHost::MessageStats& stats = world.relay().rooms().at("chat")->message_stats();
  EXPECT_EQ(stats.forwarded, 3 * kN + 3);
  EXPECT_EQ(stats.refused, 0u);
}

TEST(Messages, UnpermittedMisaddressedAndMalformedAreRefusedCountedAndReachNobody) {
  SimWorld world;
  Inbox ia, ib;
  // a may spawn but not send messages
  auto [a, b] = AddJoined(world, "r", Joiner{&ia, kPermissionSpawn}, ib);
  ASSERT_TRUE(a.SendMessage(MessageTarget::kRoom, 0, Payload(kToRoom, 0)).ok());
  ASSERT_TRUE(b.SendMessage(MessageTarget::kPlayer, 99, Payload(kToPlayer, 0)).ok());
  // Malformed: an unknown target, and a buffer that fails verification.
  flatbuffers::FlatBufferBuilder fbb(64);
  const auto body = fbb.CreateVector(Payload(kToRoom, 1));
  FinishControl(fbb, schema::CreateAppMessage(fbb, static_cast<schema::MessageTarget>(7), 0, 0, body));
  std::vector<uint8_t> bad(fbb.GetBufferPointer(), fbb.GetBufferPointer() + fbb.GetSize());
  ASSERT_TRUE(ClientTesting::SendReliableUnchecked(b, bad).ok());
  bad.resize(bad.size() - 6);
  ASSERT_TRUE(ClientTesting::SendReliableUnchecked(b, bad).ok());
  ASSERT_TRUE(world.RunUntil([&] { return ia.errors.size() + ib.errors.size() >= 4; }, 5.0));
  world.RunFor(0.5);
  EXPECT_EQ(ia.Count(schema::RejectReason::NotPermitted), 1u);
  EXPECT_EQ(ib.Count(schema::RejectReason::UnknownPlayer), 1u);
  EXPECT_EQ(ib.Count(schema::RejectReason::InvalidMessage), 2u);
  EXPECT_TRUE(ia.got.empty());
  EXPECT_TRUE(ib.got.empty());
  ExpectRequestsRejected(world.counters(), {{schema::RejectReason::NotPermitted, 1},
                                            {schema::RejectReason::UnknownPlayer, 1}});
  // The unverifiable one is refused by the session, before any room.
  EXPECT_EQ(world.relay().rooms().at("r")->message_stats().refused, 3u);
  EXPECT_EQ(world.relay().rooms().at("r")->message_stats().forwarded, 0u);
}

TEST(Messages, OversizedAndOverRateAreRefusedAndCountedTheRestDelivered) {
  RelayConfig config = LoopbackWorld::DefaultConfig();
  config.room_defaults.budgets.max_message_bytes = 1000;
  config.room_defaults.budgets.messages_per_s_per_player = 50;  // burst 100
  SimWorld world({}, config);
  Inbox ia, ib;
  auto [a, b] = AddJoined(world, "r", ia, ib);
  ASSERT_TRUE(a.SendMessage(MessageTarget::kOthers, 0, Payload(kBig, 0, 1001)).ok());
  EXPECT_FALSE(a.SendMessage(MessageTarget::kOthers, 0, Payload(kBig, 1, 65537)).ok());
  constexpr uint32_t kFlood = 400;  // at once: over the 100-message burst
  for (uint32_t i = 0; i < kFlood; ++i) {
    ASSERT_TRUE(a.SendMessage(MessageTarget::kOthers, 0, Payload(kToOthers, i)).ok());
  }
  world.RunFor(2.0);
  const size_t limited = ia.Count(schema::RejectReason::RateLimited);
  EXPECT_EQ(ia.Count(schema::RejectReason::OverBudget), 1u);
  EXPECT_GT(limited, 150u);  // the burst is 100; the rest of 400 over ~1 s of refill at 50/s
  EXPECT_LT(limited, kFlood);
  // What was not refused arrived, once each, in order.
  const std::vector<uint32_t> got = ib.Stream(1, kToOthers);
  EXPECT_EQ(got.size() + limited, kFlood);
  EXPECT_TRUE(std::is_sorted(got.begin(), got.end()));
  EXPECT_TRUE(ib.Stream(1, kBig).empty());
  const RoomHost::MessageStats& stats = world.relay().rooms().at("r")->message_stats();
  EXPECT_EQ(stats.refused, limited + 1);
  EXPECT_EQ(stats.forwarded, got.size());
  EXPECT_EQ(RequestsRejected(world.counters(), schema::RejectReason::RateLimited), limited);
}

}  // namespace
}  // namespace edgephys::testing
