// A rogue client in a room: it cannot move, grab or despawn others' entities, and its flood is
// throttled without hurting the other users' update rate.
#include <gtest/gtest.h>

#include <map>

#include "tests/integration/harness.h"
#include "client/client_testing.h"

namespace edgephys::testing {
namespace {

using schema::RejectReason;

struct Counts : ClientListener {
  std::map<uint32_t, int> updates;
  std::vector<uint16_t> errors;
  void OnEntityUpdated(const RemoteEntity& e) override { ++updates[e.id]; }
  void OnError(uint16_t reason, uint32_t, std::string_view) override { errors.push_back(reason); }
};

TEST(Abuse, RogueClientCannotTouchOthersEntitiesAndItsFloodIsThrottled) {
  RelayConfig config = LoopbackWorld::DefaultConfig();
  config.limits.packets_per_s = 400;
  LoopbackWorld world(config);
  Counts a_log, b_log, rogue_log;
  Client& a = world.AddClient(MintToken("r", 1), &a_log);
  Client& b = world.AddClient(MintToken("r", 2), &b_log);
  Client& rogue = world.AddClient(MintToken("r", 3), &rogue_log);
  for (Client* c : {&a, &b, &rogue}) {
    ASSERT_TRUE(world.RunUntil([&] { return c->state() == ClientState::kConnected; }, 3.0));
    ASSERT_TRUE(c->JoinRoom("r").ok());
  }
  ASSERT_TRUE(world.RunUntil([&] { return a.joined() && b.joined() && rogue.joined(); }, 3.0));
  std::vector<uint32_t> ids;
  for (int i = 0; i < 4; ++i) ids.push_back(*a.Spawn({.position = {float(i), 0, 0}}));
  auto rogue_id = rogue.Spawn({});
  ASSERT_TRUE(rogue_id.ok());
  ASSERT_TRUE(world.RunUntil([&] { return b.entities().size() == 5 && rogue.entities().size() == 4; }, 3.0));

  auto move_phase = [&](double seconds, bool flood) {
    b_log.updates.clear();
    double next = world.Now();
    uint64_t sent = 0;
    world.RunFor(seconds, [&](double now) {
      if (now >= next) {
        next += 1.0 / 12.0;
        for (uint32_t id : ids) (void)a.PublishTransform(id, {float(now), 1, float(id % 5)}, {});
      }
      if (flood) {
        for (int k = 0; k < 60; ++k, ++sent) {
          (void)ClientTesting::SendStateUnchecked(rogue, {*rogue_id, {float(k), 0, 0}, {0, 0, 0, 1}}, now);
        }
      }
    });
    int total = 0;
    for (uint32_t id : ids) total += b_log.updates[id];
    return std::make_pair(total / seconds, sent);
  };
  auto [baseline, unused] = move_phase(3.0, false);
  uint64_t limited_before = Rejected(world.counters(), DropReason::kRateLimited);
  auto [under_flood, flood_packets] = move_phase(3.0, true);
  EXPECT_GT(flood_packets, 10000u);
  EXPECT_GT(Rejected(world.counters(), DropReason::kRateLimited) - limited_before, flood_packets / 2)
      << "the flood was not throttled";
  EXPECT_NEAR(under_flood, baseline, baseline * 0.10)
      << "others' update rate changed under the flood: " << baseline << " -> " << under_flood;
  EXPECT_GT(baseline, 4 * 12 * 0.9);

  // The rogue cannot move, despawn or grab A's entities.
  uint64_t not_owner = UpdatesRejected(world.counters(), DropReason::kNotOwner);
  world.RunFor(0.5);  // let the rogue's bucket refill
  ASSERT_TRUE(ClientTesting::SendStateUnchecked(rogue, {ids[0], {50, 50, 50}, {0, 0, 0, 1}}, world.Now()).ok());
  flatbuffers::FlatBufferBuilder despawn;
  FinishControl(despawn, schema::CreateDespawn(despawn, ids[1]));
  ASSERT_TRUE(ClientTesting::SendReliableUnchecked(rogue, {despawn.GetBufferPointer(), despawn.GetSize()}).ok());
  ASSERT_TRUE(rogue.Grab(ids[2], ids[3]).ok());  // a hand that is not the rogue's
  ASSERT_TRUE(world.RunUntil([&] { return rogue_log.errors.size() >= 2; }, 3.0));
  world.RunFor(0.3);
  EXPECT_EQ(UpdatesRejected(world.counters(), DropReason::kNotOwner), not_owner + 1);
  EXPECT_EQ(rogue_log.errors[rogue_log.errors.size() - 2], static_cast<uint16_t>(RejectReason::NotOwner));
  EXPECT_EQ(rogue_log.errors.back(), static_cast<uint16_t>(RejectReason::NotOwner));
  const Room* room = world.relay().FindRoom("r");
  EXPECT_EQ(room->entities().count(ids[1]), 1u);
  EXPECT_NE(room->entities().at(ids[0]).state.position.x, 50.0f);
}

TEST(Abuse, ConnectionsThatNeverJoinExpireAndPerAddressLimitsHold) {
  RelayConfig config = LoopbackWorld::DefaultConfig();
  config.limits.join_timeout_s = 0.5;
  config.limits.max_sessions_per_address = 2;
  LoopbackWorld world(config);
  Client& idle = world.AddClient(MintToken("x", 1));
  Client& second = world.AddClient(MintToken("x", 2));
  ASSERT_TRUE(world.RunUntil([&] {
    return idle.state() == ClientState::kConnected && second.state() == ClientState::kConnected;
  }, 3.0));
  Client& third = world.AddClient(MintToken("x", 3));
  ASSERT_TRUE(world.RunUntil([&] { return third.state() == ClientState::kRejected; }, 3.0));
  EXPECT_EQ(third.reject_reason(), static_cast<uint16_t>(RejectReason::RateLimited));
  ASSERT_TRUE(second.JoinRoom("x").ok());
  ASSERT_TRUE(world.RunUntil([&] { return idle.state() == ClientState::kDisconnected; }, 3.0));
  EXPECT_EQ(idle.disconnect_reason(), DisconnectReason::kKicked);
  EXPECT_EQ(second.state(), ClientState::kConnected);  // it joined in time
  EXPECT_EQ(world.relay().session_count(), 1u);
}

TEST(Abuse, HandshakeFloodFromOneAddressIsRateLimited) {
  LoopbackWorld world;
  auto socket = std::move(*UdpSocket::Open(Endpoint(asio::ip::make_address("127.0.0.1"), 0)));
  flatbuffers::FlatBufferBuilder fbb;
  FinishControl(fbb, schema::CreateHello(fbb, 1));
  auto hello = BuildHandshakePacket(PacketType::kHello, fbb, kMinHelloPacketSize);
  for (int i = 0; i < 500; ++i) {
    (void)socket->SendTo(world.relay_endpoint(), hello);
    if (i % 50 == 0) world.Step();
  }
  world.RunFor(0.2);
  std::vector<uint8_t> buf(2048);
  Endpoint from;
  int challenges = 0;
  while (socket->ReceiveFrom(&from, buf) > 0) ++challenges;
  EXPECT_LE(challenges, 60);  // a burst of 40, then 20/s
  EXPECT_GE(challenges, 20);
  EXPECT_GE(Rejected(world.counters(), DropReason::kRateLimited), 400u);
}

}  // namespace
}  // namespace edgephys::testing
