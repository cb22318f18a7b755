// The soft-body relay tests' stage: a bunny on the ground under a kinematic plate, spawned by
// one client of a LoopbackWorld room while another receives it. The tests then lower the plate
// to squash the bunny (physics_worker_test's failover, soft_rate_test's send rates).
#pragma once

#include <gtest/gtest.h>

#include <string>

#include "loadgen/scenes/scenes.h"
#include "tests/integration/harness.h"

namespace edgephys::testing {

struct PlatedBunny {
  Client* host = nullptr;      // spawned everything; drives the plate with PublishTransform
  Client* receiver = nullptr;  // listens with the listener given
  uint32_t bunny = 0, plate = 0;
  size_t particles = 0;        // the bunny's
  float plate_y = 1.5f;        // the plate's spawn height (its face is 0.05 m below)
};

// Players 1 (host) and 2 (receiver, `listener`) join `room` with tokens for it; the host spawns
// an offloaded 10 x 1 x 10 m ground, an offloaded bunny (physics::MakeBunnySoftBody centred at
// y 0.6) and a kinematic 2 x 0.1 x 2 m plate at y 1.5. Fails (fatally) on any refusal; wrap
// the call in ASSERT_NO_FATAL_FAILURE.
inline void StagePlatedBunny(LoopbackWorld& world, const std::string& room,
                             ClientListener* listener, PlatedBunny* out) {
  Client& a = world.AddClient(MintToken(room, 1));
  Client& b = world.AddClient(MintToken(room, 2), listener);
  for (Client* c : {&a, &b}) {
    ASSERT_TRUE(world.RunUntil([&] { return c->state() == ClientState::kConnected; }, 3.0));
    ASSERT_TRUE(c->JoinRoom(room).ok());
  }
  ASSERT_TRUE(world.RunUntil([&] { return a.joined() && b.joined(); }, 3.0));
  const uint32_t offloaded = static_cast<uint32_t>(schema::EntityFlags::Offloaded);
  SpawnDesc ground{.position = {0, -0.5f, 0}, .flags = offloaded};
  ground.colliders.push_back(BoxCollider({5, 0.5f, 5}));
  ASSERT_TRUE(a.Spawn(ground).ok());
  physics::BunnyParams params;
  params.center = {0, 0.6f, 0};
  SpawnDesc bunny{.position = {0, 0, 0}, .flags = offloaded, .name = "bunny"};
  bunny.soft_body = physics::MakeBunnySoftBody(params);
  auto bunny_id = a.Spawn(bunny);
  ASSERT_TRUE(bunny_id.ok()) << bunny_id.status().message();
  SpawnDesc plate{.position = {0, out->plate_y, 0}, .name = "plate"};
  plate.rigid_body = RigidBodySpec{};
  plate.rigid_body->kinematic = true;
  plate.rigid_body->mass = 0;
  plate.colliders.push_back(BoxCollider({1, 0.05f, 1}));
  auto plate_id = a.Spawn(plate);
  ASSERT_TRUE(plate_id.ok()) << plate_id.status().message();
  out->host = &a;
  out->receiver = &b;
  out->bunny = *bunny_id;
  out->plate = *plate_id;
  out->particles = bunny.soft_body->particles.size() / 3;
}

}  // namespace edgephys::testing
