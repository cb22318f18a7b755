// Unreliable application messages through a real relay (simulated network, fake clock): each
// arrives at most once, never out of order per sender, with the sender's id, at exactly the
// addressed players, also under 20 % loss, reordering and duplication. Oversized, over-rate,
// unpermitted, misaddressed and malformed ones are refused with their reason and counted, and
// reach nobody; the relay never forwards more than the budget.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <vector>

#include "client/client_testing.h"
#include "protocol/app_message_codec.h"
#include "relay/room_host.h"
#include "tests/integration/join_all.h"
#include "tests/integration/message_inbox.h"
#include "tests/integration/sim_world.h"

namespace edgephys::testing {
namespace {

constexpr uint8_t kFillerStep = 7;
std::vector<uint8_t> Payload(uint8_t tag, uint32_t seq, size_t size = 5) {
  return TaggedPayload(tag, seq, size, kFillerStep);
}

struct Inbox : MessageInbox {  // records the unreliable ones
  Inbox() : MessageInbox(kFillerStep) {}
  size_t reliable = 0;  // reliable ones (none expected)
  void OnMessage(uint32_t, std::span<const uint8_t>) override { ++reliable; }
  void OnUnreliableMessage(uint32_t sender, std::span<const uint8_t> payload) override {
    Record(sender, payload);
  }
};

// Strictly increasing (never twice, never out of order), within [0, n), and at least `min`.
void ExpectOrderedSubset(const std::vector<uint32_t>& seqs, uint32_t n, size_t min,
                         const char* what) {
  SCOPED_TRACE(what);
  for (size_t i = 1; i < seqs.size(); ++i) EXPECT_LT(seqs[i - 1], seqs[i]);
  for (uint32_t s : seqs) EXPECT_LT(s, n);
  EXPECT_GE(seqs.size(), min);
}

constexpr uint8_t kToRoom = 1, kToOthers = 2, kToPlayer = 3, kFull = 4;

TEST(UnreliableMessages, AtMostOnceInOrderAtExactlyTheAddressedPlayersUnderLossReorderingDuplication) {
  SimWorld world(LossyLink());
  Inbox ia, ib, ic;
  auto [a, b, c] = AddJoined(world, "chat", ia, ib, ic);
  world.RunFor(1.0);  // every member has acknowledged its Joined (ready for datagrams)
  constexpr uint32_t kN = 100;
  for (uint32_t i = 0; i < kN; ++i) {
    ASSERT_TRUE(a.SendMessageUnreliable(MessageTarget::kRoom, 0, Payload(kToRoom, i)).ok());
    ASSERT_TRUE(b.SendMessageUnreliable(MessageTarget::kOthers, 0, Payload(kToOthers, i)).ok());
    ASSERT_TRUE(c.SendMessageUnreliable(MessageTarget::kPlayer, 1, Payload(kToPlayer, i)).ok());
    if (i % 10 == 0) {  // the largest payload one datagram carries
      ASSERT_TRUE(a.SendMessageUnreliable(MessageTarget::kOthers, 0,
                                          Payload(kFull, i, kMaxUnreliableMessageBytes))
                      .ok());
    }
    world.RunFor(0.01);
  }
  world.RunFor(2.0);  // everything that will arrive has arrived; nothing arrives twice after
  // At most 64 % of a stream survives two lossy hops (0.8 x 0.8); with 20 ms of jitter over
  // 10 ms of spacing many are reordered, and a message that arrives after a later one of the
  // same sender is dropped (in order per sender, at the relay and at the receiver): about
  // 35-40 % arrive. States interleaved on the same channel do not make messages stale.
  const size_t min = kN / 4;
  // A: its own room messages, B's, C's to player 1; not its own full-size ones.
  ExpectOrderedSubset(ia.Stream(1, kToRoom), kN, min, "a <- a room");
  ExpectOrderedSubset(ia.Stream(2, kToOthers), kN, min, "a <- b others");
  ExpectOrderedSubset(ia.Stream(3, kToPlayer), kN, min, "a <- c player 1");
  EXPECT_TRUE(ia.Stream(1, kFull).empty());
  // B: A's room and full-size messages; not its own, not C's to player 1.
  ExpectOrderedSubset(ib.Stream(1, kToRoom), kN, min, "b <- a room");
  ExpectOrderedSubset(ib.Stream(1, kFull), kN, 1, "b <- a full");
  EXPECT_TRUE(ib.Stream(2, kToOthers).empty());
  EXPECT_TRUE(ib.Stream(3, kToPlayer).empty());
  // C: A's room and full-size messages, B's; not its own to player 1.
  ExpectOrderedSubset(ic.Stream(1, kToRoom), kN, min, "c <- a room");
  ExpectOrderedSubset(ic.Stream(1, kFull), kN, 1, "c <- a full");
  ExpectOrderedSubset(ic.Stream(2, kToOthers), kN, min, "c <- b others");
  EXPECT_TRUE(ic.Stream(3, kToPlayer).empty());
  // Per sender across streams: A's room and full-size messages reach C in the order A sent
  // them (the relay numbers them in arrival order; the receiver drops older ones).
  EXPECT_EQ(ia.reliable + ib.reliable + ic.reliable, 0u);
  EXPECT_TRUE(ia.errors.empty() && ib.errors.empty() && ic.errors.empty());
  const size_t total = ia.got.size() + ib.got.size() + ic.got.size();
  EXPECT_EQ(a.unreliable_messages_received() + b.unreliable_messages_received() +
                c.unreliable_messages_received(),
            total);
  EXPECT_EQ(a.unreliable_messages_malformed() + b.unreliable_messages_malformed() +
                c.unreliable_messages_malformed(),
            0u);
  const RoomHost::MessageStats& stats = world.relay().rooms().at("chat")->message_stats();
  EXPECT_EQ(stats.refused, 0u);
  EXPECT_EQ(stats.unreliable, stats.forwarded);
  EXPECT_LE(stats.forwarded, 3 * kN + kN / 10);
  EXPECT_GE(stats.delivered, total);  // sent by the relay; some lost on the way
}

TEST(UnreliableMessages, OversizedOverRateUnpermittedMisaddressedMalformedRefusedAndCounted) {
  RelayConfig config = LoopbackWorld::DefaultConfig();
  config.room_defaults.budgets.max_message_bytes = 500;
  config.room_defaults.budgets.messages_per_s_per_player = 50;  // burst 100
  SimWorld world({}, config);
  Inbox ia, ib, ic;
  // c may spawn but not send messages
  auto [a, b, c] = AddJoined(world, "r", ia, ib, Joiner{&ic, kPermissionSpawn});
  world.RunFor(1.0);
  // Oversized: over one datagram, refused by the SDK naming the limit; over the room's budget,
  // refused by the relay.
  const Status too_large =
      a.SendMessageUnreliable(MessageTarget::kOthers, 0, Payload(kFull, 0, kMaxUnreliableMessageBytes + 1));
  EXPECT_EQ(too_large.code(), StatusCode::kTooLarge);
  EXPECT_NE(too_large.ToString().find("1165"), std::string::npos) << too_large.ToString();
  ASSERT_TRUE(a.SendMessageUnreliable(MessageTarget::kOthers, 0, Payload(kFull, 1, 501)).ok());
  // Unpermitted, misaddressed.
  ASSERT_TRUE(c.SendMessageUnreliable(MessageTarget::kRoom, 0, Payload(kToRoom, 0)).ok());
  ASSERT_TRUE(b.SendMessageUnreliable(MessageTarget::kPlayer, 99, Payload(kToPlayer, 0)).ok());
  // Malformed: shorter than the header; an unknown target.
  const double now = world.Now();
  const std::vector<uint8_t> short_payload = {kAppMessageFormat, 0, 0, 0};
  ASSERT_TRUE(ClientTesting::SendUnreliableRaw(b, short_payload, now).ok());
  std::vector<uint8_t> bad_target(kAppMessageHeaderSize + 5);
  AppMessageHeader h;
  h.target = 7;
  ASSERT_EQ(EncodeAppMessage(h, Payload(kToRoom, 1), bad_target), bad_target.size());
  world.RunFor(0.1);
  ASSERT_TRUE(ClientTesting::SendUnreliableRaw(b, bad_target, world.Now()).ok());
  world.RunFor(0.5);
  EXPECT_EQ(ia.Count(schema::RejectReason::OverBudget), 1u);
  EXPECT_EQ(ic.Count(schema::RejectReason::NotPermitted), 1u);
  EXPECT_EQ(ib.Count(schema::RejectReason::UnknownPlayer), 1u);
  EXPECT_EQ(ib.Count(schema::RejectReason::InvalidMessage), 1u);
  EXPECT_EQ(Rejected(world.counters(), DropReason::kMalformed), 1u);
  EXPECT_TRUE(ia.got.empty() && ib.got.empty() && ic.got.empty());
  const RoomHost& room = *world.relay().rooms().at("r");
  EXPECT_EQ(room.message_stats().refused, 5u);
  EXPECT_EQ(room.message_stats().forwarded, 0u);

  // Over the rate: 400, one per simulation step (5 ms, 2 s in all): the 100-message burst plus
  // the refill (50/s) pass, the rest is refused; the relay forwards no more than that. Then 50
  // reliable messages at once: the budget is shared, so nearly all are refused too.
  constexpr uint32_t kFlood = 400, kReliable = 50;
  const double started = world.Now();
  for (uint32_t i = 0; i < kFlood; ++i) {
    ASSERT_TRUE(a.SendMessageUnreliable(MessageTarget::kOthers, 0, Payload(kToOthers, i)).ok());
    world.RunFor(0.002);
  }
  const double elapsed = world.Now() - started;
  for (uint32_t i = 0; i < kReliable; ++i) {
    ASSERT_TRUE(a.SendMessage(MessageTarget::kOthers, 0, Payload(kToOthers, 1000 + i)).ok());
  }
  world.RunFor(1.0);
  const size_t limited = ia.Count(schema::RejectReason::RateLimited);
  const std::vector<uint32_t> got_b = ib.Stream(1, kToOthers);
  const std::vector<uint32_t> got_c = ic.Stream(1, kToOthers);
  EXPECT_GT(limited, 150u + kReliable - 5);
  EXPECT_LE(ib.reliable, 5u);  // the reliable burst met a spent budget
  // No loss here: what passed arrived, once, in order.
  EXPECT_EQ(got_b.size() + ib.reliable + limited, kFlood + kReliable);
  EXPECT_EQ(got_b, got_c);
  ExpectOrderedSubset(got_b, kFlood, 100, "b <- a flood");
  EXPECT_LE(static_cast<double>(room.message_stats().forwarded), 100 + 50 * elapsed + 1);
  EXPECT_EQ(room.message_stats().forwarded, got_b.size() + ib.reliable);
  EXPECT_EQ(room.message_stats().unreliable, got_b.size());
  EXPECT_EQ(room.message_stats().refused, 5u + limited);
  EXPECT_EQ(RequestsRejected(world.counters(), schema::RejectReason::RateLimited), limited);

  // Replayed or reordered on the way in: the relay forwards a connection's numbered message
  // only when it is newer than the newest it forwarded from there; the older one is counted.
  std::vector<uint8_t> numbered(kAppMessageHeaderSize + 5);
  h = AppMessageHeader{.target = 1, .sequence = 1000};  // Others
  ASSERT_EQ(EncodeAppMessage(h, Payload(kToOthers, 5000), numbered), numbered.size());
  ASSERT_TRUE(ClientTesting::SendUnreliableRaw(b, numbered, world.Now()).ok());
  world.RunFor(0.1);
  h.sequence = 999;
  ASSERT_EQ(EncodeAppMessage(h, Payload(kToOthers, 5001), numbered), numbered.size());
  ASSERT_TRUE(ClientTesting::SendUnreliableRaw(b, numbered, world.Now()).ok());
  world.RunFor(0.5);
  EXPECT_EQ(ia.Stream(2, kToOthers), std::vector<uint32_t>{5000});
  EXPECT_EQ(UpdatesRejected(world.counters(), DropReason::kStale), 1u);
}

// The SDK drops an unreliable message from a sender that is not newer than the last one it
// delivered from that sender (a relay replaying or reordering across connections), counting it.
TEST(UnreliableMessages, ReceiverDropsDuplicatesAndOlderPerSenderAndCountsThem) {
  SimWorld world;
  Inbox ia, ib;
  auto [a, b] = AddJoined(world, "r", ia, ib);
  world.RunFor(1.0);
  for (uint32_t i = 0; i < 3; ++i) {
    ASSERT_TRUE(a.SendMessageUnreliable(MessageTarget::kOthers, 0, Payload(kToOthers, i)).ok());
    world.RunFor(0.05);
  }
  ASSERT_EQ(ib.Stream(1, kToOthers), (std::vector<uint32_t>{0, 1, 2}));
  // Relay -> client payloads as the relay writes them, delivered to B's SDK directly: sender 1
  // with sequences 3 (new), 3 (duplicate), 2 (older), 4 (new); sender 7, 1 (new).
  const auto deliver = [&](uint32_t sender, uint32_t sequence, uint32_t tag_seq) {
    AppMessageHeader h;
    h.target = 1;
    h.sender = sender;
    h.sequence = sequence;
    std::vector<uint8_t> p(kAppMessageHeaderSize + 5);
    ASSERT_EQ(EncodeAppMessage(h, Payload(kToPlayer, tag_seq), p), p.size());
    ClientTesting::DeliverUnreliable(b, p);
  };
  deliver(1, 4, 10);
  deliver(1, 4, 11);
  deliver(1, 3, 12);
  deliver(1, 5, 13);
  deliver(7, 1, 14);
  ClientTesting::DeliverUnreliable(b, std::vector<uint8_t>{kAppMessageFormat, 1, 2});
  EXPECT_EQ(ib.Stream(1, kToPlayer), (std::vector<uint32_t>{10, 13}));
  EXPECT_EQ(ib.Stream(7, kToPlayer), (std::vector<uint32_t>{14}));
  EXPECT_EQ(b.unreliable_messages_stale(), 2u);
  EXPECT_EQ(b.unreliable_messages_malformed(), 1u);
  EXPECT_EQ(b.unreliable_messages_received(), 6u);
}

}  // namespace
}  // namespace edgephys::testing
