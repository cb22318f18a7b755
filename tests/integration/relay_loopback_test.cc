// End to end on real loopback UDP: spawn, move, fan-out, late join, ownership.
#include <gtest/gtest.h>

#include <cmath>

#include "tests/integration/harness.h"
#include "client/client_testing.h"

namespace edgephys::testing {
namespace {

// A smooth path per entity so every tick differs.
EntityState PathState(uint32_t id, int k, double t) {
  EntityState s;
  s.entity_id = id;
  s.position = {static_cast<float>(k + std::sin(t * 2.0)), static_cast<float>(1.0 + 0.5 * std::cos(t)),
                static_cast<float>(0.25 * k * t)};
  double half = 0.5 * (t + k);
  s.rotation = {0, static_cast<float>(std::sin(half)), 0, static_cast<float>(std::cos(half))};
  return s;
}

// The default (edgephys) encoder's stated precision: 1 mm lattice, 0.1 degree.
bool SameState(const EntityState& a, const EntityState& b) { return WithinPrecision(a, b); }

bool Connected(Client& c) { return c.state() == ClientState::kConnected; }

void ConnectAndJoin(LoopbackWorld& world, Client& c, const std::string& room) {
  ASSERT_TRUE(world.RunUntil([&] { return Connected(c); }, 5.0)) << "handshake did not finish";
  ASSERT_TRUE(c.JoinRoom(room).ok());
  ASSERT_TRUE(world.RunUntil([&] { return c.joined(); }, 5.0)) << "join did not finish";
}

// Players 1 (a) and 2 (b) connect to `world`; a joins `room`, then b (ConnectAndJoin each).
struct Pair {
  Client& a;
  Client& b;
};
Pair JoinTwo(LoopbackWorld& world, const std::string& room) {
  Client& a = world.AddClient(MintToken(room, 1));
  Client& b = world.AddClient(MintToken(room, 2));
  ConnectAndJoin(world, a, room);
  ConnectAndJoin(world, b, room);
  return {a, b};
}

TEST(RelayLoopback, FanOutLateJoinAndOwnership) {
  LoopbackWorld world;
  const Pair p = JoinTwo(world, "arena");
  Client &a = p.a, &b = p.b;
  EXPECT_NE(a.entity_id_base(), b.entity_id_base());

  std::vector<uint32_t> ids;
  for (int k = 0; k < 4; ++k) {
    auto id = a.Spawn({.position = PathState(0, k, 0).position, .rotation = PathState(0, k, 0).rotation});
    ASSERT_TRUE(id.ok());
    ids.push_back(*id);
  }

  // A moves its 4 entities for 2 s at 12 Hz.
  std::vector<EntityState> last(4);
  double start = world.Now();
  double next_move = start;
  int moves = 0;
  world.RunFor(2.0, [&](double now) {
    if (now < next_move) return;
    next_move += 1.0 / 12.0;
    ++moves;
    for (int k = 0; k < 4; ++k) {
      last[k] = PathState(ids[k], k, now - start);
      ASSERT_TRUE(a.PublishTransform(ids[k], last[k].position, last[k].rotation).ok());
    }
  });
  EXPECT_GE(moves, 23);

  // B ends at A's last state for every entity.
  ASSERT_TRUE(world.RunUntil(
      [&] {
        for (int k = 0; k < 4; ++k) {
          const RemoteEntity* e = b.FindEntity(ids[k]);
          if (e == nullptr || !e->spawned || !SameState(e->state, last[k])) return false;
        }
        return true;
      },
      3.0));
  for (int k = 0; k < 4; ++k) {
    const RemoteEntity* e = b.FindEntity(ids[k]);
    EXPECT_EQ(e->owner, a.player_id());
  }
  EXPECT_GE(world.counters().entity_updates_sent.load(), 4u * 20u);

  // A late joiner gets the full current state.
  Client& c = world.AddClient(MintToken("arena", 3));
  ConnectAndJoin(world, c, "arena");
  ASSERT_TRUE(world.RunUntil(
      [&] {
        for (int k = 0; k < 4; ++k) {
          const RemoteEntity* e = c.FindEntity(ids[k]);
          if (e == nullptr || !e->spawned || !SameState(e->state, last[k])) return false;
        }
        return c.players().size() == 3;
      },
      3.0));

  // B tries to move A's entity: dropped and counted; nobody sees the forged state.
  uint64_t not_owner_before = UpdatesRejected(world.counters(), DropReason::kNotOwner);
  EntityState forged = last[0];
  forged.position = {100, 100, 100};
  for (int i = 0; i < 5; ++i) {
    ASSERT_TRUE(ClientTesting::SendStateUnchecked(b, forged, world.Now()).ok());
    world.RunFor(0.02);
  }
  world.RunFor(0.3);
  EXPECT_EQ(UpdatesRejected(world.counters(), DropReason::kNotOwner), not_owner_before + 5);
  EXPECT_TRUE(SameState(c.FindEntity(ids[0])->state, last[0]));
  EXPECT_TRUE(SameState(b.FindEntity(ids[0])->state, last[0]));
  const Room* room = world.relay().FindRoom("arena");
  ASSERT_NE(room, nullptr);
  EXPECT_EQ(room->entities().at(ids[0]).state.position.x, last[0].position.x);  // relay: exact
}

TEST(RelayLoopback, DespawnAndLeavePropagate) {
  LoopbackWorld world;
  const Pair p = JoinTwo(world, "r");
  Client &a = p.a, &b = p.b;
  auto keep = a.Spawn({.flags = 1 /* Persistent */});
  auto gone = a.Spawn({});
  auto despawned = a.Spawn({});
  ASSERT_TRUE(keep.ok() && gone.ok() && despawned.ok());
  ASSERT_TRUE(world.RunUntil([&] { return b.entities().size() == 3; }, 3.0));

  ASSERT_TRUE(a.Despawn(*despawned).ok());
  ASSERT_TRUE(world.RunUntil([&] { return b.FindEntity(*despawned) == nullptr; }, 3.0));

  a.Disconnect();
  ASSERT_TRUE(world.RunUntil([&] { return b.FindEntity(*gone) == nullptr; }, 3.0));
  // The persistent entity outlives its owner and passes to the room.
  world.RunFor(0.2);
  ASSERT_NE(b.FindEntity(*keep), nullptr);
  EXPECT_EQ(world.relay().FindRoom("r")->entities().at(*keep).owner, 0u);
  EXPECT_EQ(world.counters().disconnects[static_cast<size_t>(DisconnectReason::kClientLeft)].load(), 1u);
}

TEST(RelayLoopback, WorksOverIpv6Loopback) {
  std::unique_ptr<LoopbackWorld> world;
  auto probe = UdpSocket::Open(Endpoint(asio::ip::make_address("::1"), 0));
  if (!probe.ok()) GTEST_SKIP() << "no IPv6 loopback on this machine";
  world = std::make_unique<LoopbackWorld>(LoopbackWorld::DefaultConfig(), "::1");
  const Pair p = JoinTwo(*world, "v6");
  Client &a = p.a, &b = p.b;
  auto id = a.Spawn({.position = {1, 2, 3}});
  ASSERT_TRUE(id.ok());
  ASSERT_TRUE(a.PublishTransform(*id, {4, 5, 6}, {}).ok());
  ASSERT_TRUE(world->RunUntil(
      [&] { auto* e = b.FindEntity(*id); return e && std::fabs(e->state.position.z - 6.0f) < 0.001f; }, 3.0));
}

}  // namespace
}  // namespace edgephys::testing
