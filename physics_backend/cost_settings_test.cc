// The cost settings of PhysicsConfig ("model no more than the scene needs"): each must keep
// what the world computes correct, only cheaper. Speed itself is measured in
// bench/physics_cost_report.cc, not here.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "physics_backend/testing/physics_test_util.h"

namespace edgephys::physics {
namespace {

using testing::Add;
using testing::Ground;
using testing::Pos;

// Steps until the body sleeps; returns the simulated seconds, or -1 after `max_seconds`.
double SecondsUntilAsleep(PhysicsWorld& world, double max_seconds) {
  const int max_steps = static_cast<int>(max_seconds * 60);
  for (int i = 1; i <= max_steps; ++i) {
    world.Step();
    if (world.counters().sleeping_bodies == 1) return i / 60.0;
  }
  return -1;
}

TEST(CostSettingsTest, DeactivationTimeIsEmulatedPerWorld) {
  auto settle = [](float deactivation_time) {
    PhysicsConfig cfg;
    cfg.deactivation_time = deactivation_time;
    cfg.rest_freeze = false;  // Bullet's own sleeping is under test, not freezing
    PhysicsWorld world(cfg);
    EXPECT_TRUE(Add(world, Ground(1)).ok());
    EXPECT_TRUE(Add(world, DynamicBox(2, {0, 0.2f, 0}, {0.2f, 0.2f, 0.2f}, 1.0f)).ok());
    return SecondsUntilAsleep(world, 10.0);
  };
  const double at_2s = settle(2.0f);
  const double at_half = settle(0.5f);
  const double at_4s = settle(4.0f);
  // The box lands at rest at once: it sleeps about deactivation_time after it comes to rest.
  ASSERT_GT(at_2s, 0);
  ASSERT_GT(at_half, 0);
  ASSERT_GT(at_4s, 0);
  EXPECT_NEAR(at_2s - at_half, 1.5, 0.1);
  EXPECT_NEAR(at_4s - at_2s, 2.0, 0.1);
  // Another world in the same process is not affected (Bullet's global stays 2 s).
  EXPECT_NEAR(settle(2.0f), at_2s, 1e-9);
}

// Rows of small boxes resting on the ground, more than the sweep's first capacity (1,024).
void AddBoxGrid(PhysicsWorld& world, int n, uint32_t first_id) {
  const int side = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(n))));
  for (int i = 0; i < n; ++i) {
    const float x = -20.0f + 0.5f * static_cast<float>(i % side);
    const float z = -20.0f + 0.5f * static_cast<float>(i / side);
    ASSERT_TRUE(Add(world, DynamicBox(first_id + static_cast<uint32_t>(i), {x, 0.1f, z},
                                      {0.1f, 0.1f, 0.1f}, 1.0f))
                    .ok());
  }
}

TEST(CostSettingsTest, AxisSweepGrowsPastItsCapacityAndKeepsEveryContact) {
  PhysicsConfig cfg;
  cfg.broadphase = PhysicsConfig::Broadphase::kAxisSweep;
  cfg.world_half_extent = 100.0f;
  PhysicsWorld world(cfg);
  ASSERT_TRUE(Add(world, Ground(1)).ok());
  // A trigger zone and a sphere that will fall through it, added before the growth.
  EntitySpec zone = StaticBox(2, {10, 5, 10}, {0.5f, 0.5f, 0.5f});
  zone.colliders[0].is_trigger = true;
  ASSERT_TRUE(Add(world, zone).ok());
  for (int i = 0; i < 30; ++i) world.Step();
  AddBoxGrid(world, 2500, 1000);  // grows 1,024 -> 2,048 -> 4,096 while boxes rest on the ground
  ASSERT_TRUE(Add(world, DynamicSphere(3, {10, 7, 10}, 0.1f, 1.0f)).ok());
  std::vector<PhysicsEvent> events;
  for (int i = 0; i < 120; ++i) world.Step();
  world.DrainEvents(&events);
  // Every box still stands on the ground (none fell through after the re-homing).
  for (uint32_t id = 1000; id < 3500; ++id) {
    ASSERT_NEAR(Pos(world, id).y, 0.1f, 0.01f) << "box " << id;
  }
  // The sphere landed on the ground after passing the trigger: enter, exit and a contact.
  EXPECT_NEAR(Pos(world, 3).y, 0.1f, 0.01f);
  int enter = 0, exit = 0, landed = 0;
  for (const PhysicsEvent& ev : events) {
    if (ev.type == PhysicsEventType::kTriggerEnter && ev.entity_a == 2 && ev.entity_b == 3) ++enter;
    if (ev.type == PhysicsEventType::kTriggerExit && ev.entity_a == 2 && ev.entity_b == 3) ++exit;
    if (ev.type == PhysicsEventType::kCollisionEnter && ev.entity_a == 1 && ev.entity_b == 3) {
      ++landed;
    }
  }
  EXPECT_EQ(enter, 1);
  EXPECT_EQ(exit, 1);
  EXPECT_EQ(landed, 1);
  // Removing entities after the growth keeps the world consistent.
  for (uint32_t id = 1000; id < 1100; ++id) ASSERT_TRUE(world.RemoveEntity(id).ok());
  for (int i = 0; i < 10; ++i) world.Step();
  EXPECT_EQ(world.counters().dynamic_bodies, 2401u);
}

TEST(CostSettingsTest, BroadphasesAgreeOnASimpleScene) {
  // Boxes dropped apart and one aligned two-box stack: no chaotic toppling, so both
  // broadphases must give the same resting poses.
  auto drop = [](PhysicsConfig::Broadphase b) {
    PhysicsConfig cfg;
    cfg.broadphase = b;
    return testing::DropSceneRestingPositions(cfg);
  };
  const std::vector<Vec3f> dbvt = drop(PhysicsConfig::Broadphase::kDbvt);
  const std::vector<Vec3f> sweep = drop(PhysicsConfig::Broadphase::kAxisSweep);
  for (size_t i = 0; i < dbvt.size(); ++i) {
    EXPECT_LT(testing::Dist(dbvt[i], sweep[i]), 0.01f) << "body " << i;
  }
  EXPECT_NEAR(sweep[4].y, 0.1f, 0.01f);  // the stack stands: 0.1 and 0.3
  EXPECT_NEAR(sweep[5].y, 0.3f, 0.01f);
}

}  // namespace
}  // namespace edgephys::physics
