// State format 12 (velocities, dead reckoning) through the real relay, PhyS and SDK on the
// simulated network: what a receiver shows against PhyS's truth, and how often it is sent.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "protocol/delta_codec.h"
#include "tests/integration/sim_world.h"

namespace edgephys::testing {
namespace {

struct Counter : ClientListener {
  int updates = 0;
  uint32_t watch = 0;
  void OnEntityUpdated(const RemoteEntity& e) override { updates += e.id == watch ? 1 : 0; }
};

double Dist(const Vec3f& a, const Vec3f& b) {
  return std::sqrt((a.x - b.x) * (a.x - b.x) + (a.y - b.y) * (a.y - b.y) +
                   (a.z - b.z) * (a.z - b.z));
}

// A ball rolls on PhyS's ground, nobody touching it (ambient class). With velocities the
// receiver's state, extrapolated with its velocity to the relay's present, stays within the
// dead-reckoning threshold (plus what one check interval and the horizon add) of PhyS's state,
// at fewer sends than the ambient rate; without them, the latest state strays far more.
TEST(VelocityReplication, ExtrapolationHoldsTheBoundAtFewerSendsThanTheAmbientRate) {
  double max_err[2] = {0, 0};
  int updates[2] = {0, 0};
  for (int with : {0, 1}) {
    ReplicationConfig r;
    r.velocities = with == 1;
    RelayConfig c = LoopbackWorld::DefaultConfig();
    c.room_defaults.tick_rate_hz = 60;
    c.room_defaults.replication = r;
    c.physics_threads = 1;  // PhyS steps in the relay's update: deterministic on the fake clock
    SimWorld world({}, c);
    Counter counter;
    Client& a = world.AddClient(MintToken("vel", 1));
    Client& b = world.AddClient(MintToken("vel", 2), &counter);
    ASSERT_TRUE(world.RunUntil([&] {
      return a.state() == ClientState::kConnected && b.state() == ClientState::kConnected;
    }, 5.0));
    ASSERT_TRUE(a.JoinRoom("vel").ok());
    ASSERT_TRUE(b.JoinRoom("vel").ok());
    ASSERT_TRUE(world.RunUntil([&] { return a.joined() && b.joined(); }, 5.0));
    const uint32_t offloaded = static_cast<uint32_t>(schema::EntityFlags::Offloaded);
    SpawnDesc ground{.position = {0, -0.5f, 0}, .flags = offloaded};
    ground.colliders.push_back(BoxCollider({50, 0.5f, 50}));
    ASSERT_TRUE(a.Spawn(ground).ok());
    SpawnDesc ball{.position = {0, 0.1f, 0}, .flags = offloaded};
    ball.rigid_body = RigidBodySpec{};
    ball.rigid_body->linear_velocity = {0.5f, 0, 0};
    ball.colliders.push_back(SphereCollider(0.1f));
    auto id = a.Spawn(ball);
    ASSERT_TRUE(id.ok());
    counter.watch = *id;
    world.RunFor(r.interaction_linger_s + 0.5);  // ambient from here on
    counter.updates = 0;
    world.RunFor(3.0, [&](double now) {
      const Room* room = world.relay().FindRoom("vel");
      ASSERT_NE(room, nullptr);
      const Entity& truth = room->entities().at(*id);
      const RemoteEntity* e = b.FindEntity(*id);
      if (e == nullptr || !e->has_state) return;
      ASSERT_EQ(e->has_velocity, with == 1);
      const double age = now - e->state_time_ms / 1000.0;
      const EntityState shown = ExtrapolateState(e->state, e->velocity, age);
      max_err[with] = std::max(max_err[with], Dist(shown.position, truth.state.position));
    });
    updates[with] = counter.updates;
    const double speed = world.relay().FindRoom("vel")->entities().at(*id).linear_velocity.x;
    ASSERT_GT(speed, 0.1) << "the ball must still roll";
  }
  EXPECT_LT(max_err[1], 0.025) << "with velocities";
  EXPECT_GT(max_err[0], 0.04) << "without";
  EXPECT_LT(updates[1], 10);
  EXPECT_GT(updates[0], 14);  // ~6 Hz for 3 s
}

}  // namespace
}  // namespace edgephys::testing
