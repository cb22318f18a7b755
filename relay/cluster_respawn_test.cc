// A relay failover with spawns the lost relay never snapshotted (issue 35): relays in a cluster
// over a real redis-server, in one process on real loopback UDP. After the resume the SDK
// spawns again what the restored room lacks; what the new relay refuses is reported to the
// game as lost; what the room already holds is neither duplicated nor reported.
#include <gtest/gtest.h>

#include <chrono>
#include <functional>
#include <set>
#include <thread>

#include "client/client.h"
#include "client/client_endpoint.h"
#include "cluster/testing/redis_server.h"
#include "protocol/endpoint.h"
#include "protocol/udp_socket.h"
#include "relay/cluster_hook.h"
#include "relay/relay.h"
#include "relay/testing/cluster_world.h"
#include "tests/integration/harness.h"

namespace edgephys {
namespace {

constexpr char kSecret[] = "respawn-secret";
constexpr char kRoom[] = "r";
constexpr uint32_t kPersistent = static_cast<uint32_t>(schema::EntityFlags::Persistent);

struct LossListener : ClientListener {
  std::set<uint32_t> lost;  // OnError "lost in failover: ..."
  std::vector<std::string> other_errors;
  int joined = 0;
  void OnJoined(std::string_view, uint32_t) override { ++joined; }
  void OnError(uint16_t, uint32_t entity_id, std::string_view detail) override {
    if (detail.rfind("lost in failover: ", 0) == 0) {
      lost.insert(entity_id);
    } else {
      other_errors.emplace_back(detail);
    }
  }
};

class RespawnWorld : public testing::Pumped<RespawnWorld> {
 public:
  // `relays` relay addresses (sockets), started one by one (StartRelay); clients know them all.
  RespawnWorld(uint16_t redis_port, int relays) : redis_port_(redis_port) {
    for (int i = 0; i < relays; ++i) nodes_.AddNode();
  }

  // Starts relay `i`, its rooms allowing `max_entities_per_player` per player, writing
  // snapshots every `snapshot_s`.
  void StartRelay(int i, uint32_t max_entities_per_player, double snapshot_s = 0.1) {
    RelayConfig config = testing::ClusterNodes::Config(kSecret);
    config.room_defaults.max_entities_per_player = max_entities_per_player;
    nodes_.StartRelay(i, config, redis_port_, "relay" + std::to_string(i), snapshot_s);
  }

  Client& AddClient(uint32_t player, LossListener* listener) {
    auto token = testing::MintToken(kRoom, player, 3600, kDefaultPermissions, kSecret);
    return clients_.Add(nodes_.ResumingClientConfig(), listener,
                        ToRelayAddress(nodes_.endpoint(0)), token, Now());
  }

  double Now() const { return clock_.Now(); }
  void Step() {
    const double now = Now();
    nodes_.Update(now);
    clients_.Update(now, [](Client*) { return std::string(kRoom); });
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
  // Destroys relay `i` at once: nothing more is read from its socket, no last snapshot.
  void Kill(int i) { nodes_.Kill(i); }
  Relay* relay(int i) { return nodes_.relay(i); }
  const RelayCounters& counters(int i) const { return nodes_.counters(i); }

 private:
  uint16_t redis_port_;
  testing::WallClock clock_;
  testing::ClusterNodes nodes_;
  testing::AutoJoiningClients clients_;
};

Result<uint32_t> SpawnAt(Client& c, float x) {
  SpawnDesc d;
  d.flags = kPersistent;
  d.position = {x, 1, 0};
  return c.Spawn(d);
}

struct Case {
  uint32_t new_relay_entity_limit;  // per player, on the relay that restores the room
  size_t expect_lost;               // of the 2 spawns the snapshot lacks
};

class ClusterRespawnTest : public ::testing::TestWithParam<Case> {
 protected:
  void SetUp() override { ASSERT_TRUE(redis_.Start()) << "redis-server did not start"; }
  cluster::testing::RedisServer redis_;
};

// Player A spawns 3 entities (snapshotted), then 2 more that the owner never reads before it
// dies; B watches. The room is restored on the second relay; A resumes and re-sends all 5.
TEST_P(ClusterRespawnTest, SpawnsTheSnapshotLacksComeBackOrAreReportedLost) {
  const Case param = GetParam();
  RespawnWorld world(redis_.port(), 2);
  world.StartRelay(0, 1024);
  world.RunUntil([] { return false; }, 0.2);  // registered
  LossListener la, lb;
  Client& a = world.AddClient(1, &la);
  Client& b = world.AddClient(2, &lb);
  ASSERT_TRUE(world.RunUntil([&] { return a.joined() && b.joined(); }, 10.0));
  std::vector<uint32_t> ids;
  for (int i = 0; i < 3; ++i) ids.push_back(*SpawnAt(a, static_cast<float>(i)));
  ASSERT_TRUE(world.RunUntil([&] { return b.entities().size() == 3; }, 5.0));
  world.RunUntil([] { return false; }, 0.4);  // snapshotted (every 0.1 s)
  // Now the relay that will restore the room (it holds no room, so the failover picks it).
  world.StartRelay(1, param.new_relay_entity_limit);
  world.RunUntil([] { return false; }, 0.3);
  // Two more spawns queued, and the owner dies before it reads them.
  for (int i = 3; i < 5; ++i) ids.push_back(*SpawnAt(a, static_cast<float>(i)));
  world.Kill(0);
  ASSERT_TRUE(world.RunUntil([&] { return a.resumes() == 1 && b.resumes() == 1 &&
                                          a.joined() && b.joined(); }, 15.0));
  // Every re-spawn answered (a refusal or a duplicate), and B holds what A still owns.
  auto settled = [&] {
    if (a.respawns_duplicate() + la.lost.size() < 3 + param.expect_lost) return false;
    for (uint32_t id : ids) {
      if (la.lost.count(id) == 0 && b.entities().count(id) == 0) return false;
    }
    return true;
  };
  EXPECT_TRUE(world.RunUntil(settled, 5.0));
  world.RunUntil([] { return false; }, 0.3);  // nothing more arrives
  EXPECT_EQ(a.respawns_sent(), 5u);
  EXPECT_EQ(a.respawns_duplicate(), 3u);  // the snapshot's: neither duplicated nor reported
  EXPECT_EQ(la.lost.size(), param.expect_lost);
  EXPECT_EQ(a.entities_lost(), param.expect_lost);
  EXPECT_TRUE(la.other_errors.empty()) << la.other_errors.front();
  for (uint32_t id : ids) {
    if (la.lost.count(id) != 0) {
      EXPECT_NE(a.OwnerOf(id), a.player_id()) << id;  // no longer listed as owned
      EXPECT_EQ(b.entities().count(id), 0u) << id;
    } else {
      EXPECT_EQ(a.OwnerOf(id), a.player_id()) << id;
      ASSERT_EQ(b.entities().count(id), 1u) << id;
      EXPECT_EQ(b.entities().at(id).owner, a.player_id()) << id;
    }
  }
  // The two spawns the snapshot lacked, when taken back, are at the pose they were spawned at.
  if (param.expect_lost == 0) {
    EXPECT_NEAR(b.entities().at(ids[4]).state.position.x, 4.0f, 0.01f);  // quantised states
  }
  EXPECT_EQ(b.entities().size(), 5u - param.expect_lost);
  if (param.expect_lost == 0) {
    // Once the re-spawns' answers are due, an error about a re-spawned entity is the game's:
    // a Release of an entity no hand holds is refused (NotOwner) and the entity stays.
    world.RunUntil([] { return false; }, 1.5);
    ASSERT_TRUE(a.Release(ids[3]).ok());
    EXPECT_TRUE(world.RunUntil([&] { return !la.other_errors.empty(); }, 5.0));
    EXPECT_TRUE(la.lost.empty());
    EXPECT_EQ(a.OwnerOf(ids[3]), a.player_id());
  }
}

// The room comes back without a snapshot (the lost relay never wrote one), so the resuming
// player gets another id block: each entity it owned is reported lost before its second
// OnJoined, and none is left listed as owned.
TEST(ClusterRespawnNoSnapshotTest, AnotherIdBlockReportsEveryOwnedEntityLost) {
  cluster::testing::RedisServer redis;
  ASSERT_TRUE(redis.Start()) << "redis-server did not start";
  RespawnWorld world(redis.port(), 2);
  world.StartRelay(0, 1024, /*snapshot_s=*/1000.0);  // one (empty) write at start, then none
  world.RunUntil([] { return false; }, 0.2);
  // X takes the first id block and goes; A, in the second block, spawns two entities.
  LossListener lx, la;
  Client& x = world.AddClient(9, &lx);
  ASSERT_TRUE(world.RunUntil([&] { return x.joined(); }, 10.0));
  Client& a = world.AddClient(1, &la);
  ASSERT_TRUE(world.RunUntil([&] { return a.joined(); }, 10.0));
  const uint32_t first_base = a.entity_id_base();
  x.Disconnect();
  std::vector<uint32_t> ids = {*SpawnAt(a, 0), *SpawnAt(a, 1)};
  world.RunUntil([] { return false; }, 0.3);  // the relay holds them (no snapshot)
  world.StartRelay(1, 1024);
  world.RunUntil([] { return false; }, 0.3);
  world.Kill(0);
  ASSERT_TRUE(world.RunUntil([&] { return la.joined == 2 && a.joined(); }, 15.0));
  EXPECT_NE(a.entity_id_base(), first_base);
  EXPECT_EQ(la.lost, std::set<uint32_t>(ids.begin(), ids.end()));
  EXPECT_EQ(a.entities_lost(), 2u);
  for (uint32_t id : ids) EXPECT_NE(a.OwnerOf(id), a.player_id()) << id;
  EXPECT_EQ(a.respawns_sent(), 0u);
  EXPECT_TRUE(la.other_errors.empty());
}

INSTANTIATE_TEST_SUITE_P(Budgets, ClusterRespawnTest,
                         ::testing::Values(Case{1024, 0},  // both spawned again
                                           Case{3, 2}),    // the new relay refuses both
                         [](const ::testing::TestParamInfo<Case>& param_info) {
                           return std::string(param_info.param.expect_lost == 0
                                                  ? "TakenBack"
                                                  : "RefusedAndReported");
                         });

}  // namespace
}  // namespace edgephys
