// Churn: players joining, spawning and leaving a room while another member stays. What the
// relay holds per member for the room's entities (ClientReplicator: views, delta encoder
// tracks) must follow the entities that exist, not every entity ever seen: when a leaving
// player's entities are despawned, the members who stay forget them.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "tests/integration/harness.h"

namespace edgephys {
namespace {

using testing::LoopbackWorld;
using testing::MintToken;
using testing::WithinPrecision;

constexpr char kRoom[] = "churn";
constexpr uint32_t kStayer = 1;

// Connects a client with a token for kRoom and joins; false on timeout.
bool ConnectAndJoin(LoopbackWorld& world, Client& c) {
  if (!world.RunUntil([&] { return c.state() == ClientState::kConnected; }, 2.0)) return false;
  (void)c.JoinRoom(kRoom);
  return world.RunUntil([&] { return c.joined(); }, 2.0);
}

// True once `observer` has a state (not just the spawn) of every id in `ids`, at `position`.
bool HasStates(const Client& observer, const std::vector<uint32_t>& ids, const Vec3f& position) {
  for (uint32_t id : ids) {
    const RemoteEntity* e = observer.FindEntity(id);
    if (e == nullptr || !e->has_state) return false;
    if (!WithinPrecision(e->state, EntityState{id, position, Quatf{}})) return false;
  }
  return true;
}

TEST(RelayChurn, MembersWhoStayForgetTheEntitiesOfPlayersWhoLeave) {
  LoopbackWorld world;
  Client& stayer = world.AddClient(MintToken(kRoom, kStayer));
  ASSERT_TRUE(ConnectAndJoin(world, stayer));
  constexpr int kCycles = 8;
  for (int cycle = 1; cycle <= kCycles; ++cycle) {
    // Each visitor spawns `cycle` entities: ids base+1 .. base+cycle of the same slot, so
    // over the cycles the stayer is sent kCycles distinct ids.
    Client& visitor = world.AddClient(MintToken(kRoom, 100 + static_cast<uint32_t>(cycle)));
    ASSERT_TRUE(ConnectAndJoin(world, visitor)) << cycle;
    std::vector<uint32_t> ids;
    for (int k = 0; k < cycle; ++k) {
      SpawnDesc d;
      d.position = {static_cast<float>(k), 1, 0};
      auto id = visitor.Spawn(d);
      ASSERT_TRUE(id.ok()) << cycle;
      ids.push_back(*id);
    }
    const Vec3f moved{5, 2, static_cast<float>(cycle)};
    ASSERT_TRUE(world.RunUntil(
        [&] {
          for (uint32_t id : ids) (void)visitor.PublishTransform(id, moved, Quatf{});
          return HasStates(stayer, ids, moved);
        },
        3.0))
        << cycle;
    EXPECT_EQ(world.relay().ReplicatedEntityCount(kStayer), ids.size()) << cycle;

    (void)visitor.LeaveRoom();
    visitor.Disconnect();
    ASSERT_TRUE(world.RunUntil([&] { return stayer.entities().empty(); }, 2.0)) << cycle;
    world.RunFor(0.1);
    // Nothing left in the room: nothing held for the stayer (without forgetting: `cycle`).
    EXPECT_EQ(world.relay().ReplicatedEntityCount(kStayer), 0u) << cycle;
  }
}

TEST(RelayChurn, AnEntityIdReusedAfterItsOwnerLeftReachesTheMembersWhoStayed) {
  LoopbackWorld world;
  Client& stayer = world.AddClient(MintToken(kRoom, kStayer));
  ASSERT_TRUE(ConnectAndJoin(world, stayer));
  uint32_t first_id = 0;
  for (uint32_t visit = 1; visit <= 2; ++visit) {
    // Both visitors get the slot after the stayer's, hence the same first entity id.
    Client& visitor = world.AddClient(MintToken(kRoom, 100 + visit));
    ASSERT_TRUE(ConnectAndJoin(world, visitor)) << visit;
    SpawnDesc d;
    d.position = {0, 1, 0};
    auto id = visitor.Spawn(d);
    ASSERT_TRUE(id.ok());
    if (visit == 1) first_id = *id;
    ASSERT_EQ(*id, first_id) << "the second visitor should reuse the first one's id";
    // The stayer must see the new owner's motion promptly (with the first owner's baseline
    // still held on the relay, it was delta-coded against a state the stayer's client had
    // dropped with the Despawn, and skipped until a keyframe refresh).
    const Vec3f moved{3, 2, static_cast<float>(visit)};
    EXPECT_TRUE(world.RunUntil(
        [&] {
          (void)visitor.PublishTransform(*id, moved, Quatf{});
          return HasStates(stayer, {*id}, moved);
        },
        1.5))
        << visit;
    (void)visitor.LeaveRoom();
    visitor.Disconnect();
    ASSERT_TRUE(world.RunUntil([&] { return stayer.entities().empty(); }, 2.0)) << visit;
  }
}

}  // namespace
}  // namespace edgephys
