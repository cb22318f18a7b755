// Helpers shared by the physics tests (with the probes of testing/physics_probes.h).
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "physics_backend/container_builder.h"
#include "physics_backend/physics_world.h"
#include "physics_backend/testing/physics_probes.h"

namespace edgephys::physics::testing {

// The default PhysicsConfig with one switch (e.g. &PhysicsConfig::rest_freeze) set to `on`.
inline PhysicsConfig ConfigWith(bool PhysicsConfig::*option, bool on) {
  PhysicsConfig cfg;
  cfg.*option = on;
  return cfg;
}

// After the step that broke entity `id`: the world reported exactly one event, a guard reset
// of `id` for a non-finite state.
inline ::testing::AssertionResult OneNonFiniteGuardReset(PhysicsWorld& world, uint32_t id) {
  std::vector<PhysicsEvent> events;
  world.DrainEvents(&events);
  if (events.size() != 1) return ::testing::AssertionFailure() << events.size() << " events";
  const PhysicsEvent& e = events[0];
  if (e.type != PhysicsEventType::kGuardReset || e.cause != GuardCause::kNonFinite ||
      e.entity_a != id) {
    return ::testing::AssertionFailure()
           << "event type " << static_cast<int>(e.type) << ", cause " << static_cast<int>(e.cause)
           << ", entity " << e.entity_a;
  }
  return ::testing::AssertionSuccess();
}

inline Quatf AxisAngle(float ax, float ay, float az, float angle) {
  const float s = std::sin(angle * 0.5f);
  const float len = std::sqrt(ax * ax + ay * ay + az * az);
  return Quatf{ax / len * s, ay / len * s, az / len * s, std::cos(angle * 0.5f)};
}

inline float Dist(const Vec3f& a, const Vec3f& b) {
  const float dx = a.x - b.x, dy = a.y - b.y, dz = a.z - b.z;
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}

// Four boxes dropped apart and an aligned two-box stack on the ground, stepped 180 times under
// `cfg`: no chaotic toppling, so settings that only change how pairs are found or batched give
// the same resting poses. Returns the six boxes' positions (the stack's last: 0.1 and 0.3 m up).
inline std::vector<Vec3f> DropSceneRestingPositions(const PhysicsConfig& cfg) {
  PhysicsWorld world(cfg);
  EXPECT_TRUE(Add(world, Ground(1)).ok());
  for (uint32_t i = 0; i < 4; ++i) {
    EXPECT_TRUE(
        Add(world, DynamicBox(10 + i, {1.0f * i, 0.5f + 0.3f * i, 0}, {0.1f, 0.1f, 0.1f}, 1.0f))
            .ok());
  }
  EXPECT_TRUE(Add(world, DynamicBox(20, {0, 0.5f, 2}, {0.1f, 0.1f, 0.1f}, 1.0f)).ok());
  EXPECT_TRUE(Add(world, DynamicBox(21, {0, 0.75f, 2}, {0.1f, 0.1f, 0.1f}, 1.0f)).ok());
  for (int i = 0; i < 180; ++i) world.Step();
  std::vector<Vec3f> out;
  for (uint32_t id : {10u, 11u, 12u, 13u, 20u, 21u}) out.push_back(Pos(world, id));
  return out;
}

}  // namespace edgephys::physics::testing
