// Embedded PhyS off the relay's loop, end to end on real loopback UDP: a room whose physics
// steps far slower than real time (thousands of boxes in contact, several Bullet substeps per
// step) does not slow down another room's relaying, and still simulates, at a real-time factor
// below 1 that the relay reports. No assertion on speed: rates are compared with the same
// room's rate before, and every wait is bounded.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>

#include "tests/integration/harness.h"

namespace edgephys::testing {
namespace {

using schema::EntityFlags;
constexpr uint32_t F(EntityFlags f) { return static_cast<uint32_t>(f); }

struct UpdateCounter : ClientListener {
  std::map<uint32_t, int> updates;
  void OnEntityUpdated(const RemoteEntity& e) override { ++updates[e.id]; }
};

TEST(PhysicsOffload, AHeavyRoomNeitherStallsAnotherRoomNorStopsSimulating) {
  RelayConfig config = LoopbackWorld::DefaultConfig();
  config.physics_threads = 2;       // the relay's thread and one physics thread: the lean case
  config.physics.sleeping = false;  // the heavy scene never comes to rest...
  config.physics.substeps = 4;      // ... and every fixed step is four Bullet steps
  config.room_defaults.max_entities_per_player = 4096;
  config.room_defaults.budgets = RoomBudgets::Unlimited();
  config.limits.spawns_per_s = 0;
  config.limits.packets_per_s = 0;
  config.limits.bytes_per_s = 0;
  LoopbackWorld world(config);

  UpdateCounter a_seen;
  Client& a_sender = world.AddClient(MintToken("a", 1));
  Client& a_receiver = world.AddClient(MintToken("a", 2), &a_seen);
  Client& b_host = world.AddClient(MintToken("b", 3));
  const std::vector<std::pair<Client*, const char*>> joins = {
      {&a_sender, "a"}, {&a_receiver, "a"}, {&b_host, "b"}};
  for (auto [c, room] : joins) {
    ASSERT_TRUE(world.RunUntil([&] { return c->state() == ClientState::kConnected; }, 5.0));
    ASSERT_TRUE(c->JoinRoom(room).ok());
  }
  ASSERT_TRUE(world.RunUntil([&] {
    return a_sender.joined() && a_receiver.joined() && b_host.joined();
  }, 5.0));

  // Room A: a local-physics user's hand (mirrored into A's own PhyS), always moving.
  SpawnDesc hand{.position = {0, 1, 0}, .flags = F(EntityFlags::Hand)};
  hand.rigid_body = RigidBodySpec{};
  hand.colliders.push_back(SphereCollider(0.05f));
  auto hand_id = a_sender.Spawn(hand);
  ASSERT_TRUE(hand_id.ok());
  auto wave = [&](double now) {
    (void)a_sender.PublishTransform(*hand_id, {static_cast<float>(std::sin(now)), 1, 0}, {});
  };
  // A's receiver updates per second over `seconds`, with the relay's slowest update.
  double slowest_update = 0;
  auto a_rate = [&](double seconds) {
    world.RunFor(0.5, wave);  // settle
    a_seen.updates.clear();
    slowest_update = 0;
    const double end = world.Now() + seconds;
    while (world.Now() < end) {
      wave(world.Now());
      const auto t0 = std::chrono::steady_clock::now();
      world.Step();
      slowest_update = std::max(
          slowest_update,
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    }
    return a_seen.updates[*hand_id] / seconds;
  };
  world.RunUntil([&] {
    wave(world.Now());
    return a_seen.updates[*hand_id] > 0;
  }, 5.0);
  const double rate_before = a_rate(3.0);
  ASSERT_GT(rate_before, 5.0) << "room A's receiver gets no steady stream";
  const RelayCounters& counters = world.counters();
  EXPECT_GT(counters.PhysicsRealtimeFactor(), 0.9);  // A's PhyS alone keeps up

  // Room B: an offloaded block of 13 x 13 x 13 boxes resting on each other: every step solves
  // thousands of contacts, several times (~100+ ms a step on a 2-core VM; a tick is 33 ms).
  constexpr int n = 13;
  const uint32_t offloaded = F(EntityFlags::Offloaded);
  SpawnDesc ground{.position = {0, -0.5f, 0}, .flags = offloaded};
  ground.colliders.push_back(BoxCollider({20, 0.5f, 20}));
  ASSERT_TRUE(b_host.Spawn(ground).ok());
  std::vector<uint32_t> boxes;
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      for (int z = 0; z < n; ++z) {
        SpawnDesc box{.position = {0.2f * x, 0.1f + 0.2f * y, 0.2f * z}, .flags = offloaded};
        box.rigid_body = RigidBodySpec{};
        box.colliders.push_back(BoxCollider({0.1f, 0.1f, 0.1f}));
        auto id = b_host.Spawn(box);
        ASSERT_TRUE(id.ok()) << id.status().message();
        boxes.push_back(*id);
      }
    }
  }
  auto room_b = [&] { return world.relay().FindRoom("b"); };
  ASSERT_TRUE(world.RunUntil([&] {
    wave(world.Now());
    const Room* b = room_b();
    return b != nullptr && b->entities().size() == boxes.size() + 1;
  }, 120.0)) << "room B's scene did not arrive";
  const uint64_t steps_before = RelayCounters::Get(counters.physics_steps);
  ASSERT_TRUE(world.RunUntil([&] {
    wave(world.Now());
    return RelayCounters::Get(counters.physics_steps) > steps_before + 2;
  }, 30.0)) << "PhyS does not step";

  // While B's PhyS is heavy, A's receiver keeps its rate...
  std::map<uint32_t, uint32_t> versions;
  for (uint32_t id : boxes) versions[id] = room_b()->entities().at(id).version;
  const uint64_t b_steps0 = RelayCounters::Get(counters.physics_steps);
  const double step_sum0 = counters.physics_step_seconds.sum();
  const double rate_during = a_rate(4.0);
  const uint64_t steps = RelayCounters::Get(counters.physics_steps) - b_steps0;
  const double step_seconds = counters.physics_step_seconds.sum() - step_sum0;
  std::printf("A's receiver: %.1f updates/s before, %.1f while B is heavy; slowest relay update "
              "%.1f ms; %llu PhyS steps of %.1f ms on average\n",
              rate_before, rate_during, slowest_update * 1000,
              static_cast<unsigned long long>(steps),
              steps ? 1000 * step_seconds / static_cast<double>(steps) : 0.0);
  EXPECT_GE(rate_during, 0.8 * rate_before)
      << "room A slowed down while room B's physics was heavy";

  // ... and B still simulates: its boxes move, at a real-time factor below 1, reported.
  EXPECT_GT(steps, 0u);
  size_t moved = 0;
  for (uint32_t id : boxes) moved += room_b()->entities().at(id).version != versions[id];
  EXPECT_GT(moved, boxes.size() / 10) << "B's boxes stopped moving";
  const PhysicsLink* b_physics = room_b()->physics();
  ASSERT_NE(b_physics, nullptr);
  const double b_factor = b_physics->realtime_factor();
  std::printf("room B real-time factor %.3f; exported %.3f\n", b_factor,
              counters.PhysicsRealtimeFactor());
  ASSERT_FALSE(std::isnan(b_factor));
  EXPECT_LT(b_factor, 1.0);
  EXPECT_GT(b_factor, 0.0);
  EXPECT_LE(counters.PhysicsRealtimeFactor(), b_factor);  // the slowest room's
  const PhysicsLink* a_physics = world.relay().FindRoom("a")->physics();
  ASSERT_NE(a_physics, nullptr) << "A's hand should be mirrored into A's PhyS";
}

}  // namespace
}  // namespace edgephys::testing
