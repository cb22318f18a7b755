// A grab that carries the hand's pose (Client::GrabAt, schema Grab.hand_pose) through a real
// relay and PhyS: moving the hand onto an object and grabbing it in the same frame is granted
// (the hover is judged where the hand is now); a forged pose far from the hand is refused with
// GrabRefused and counted; a non-finite pose never leaves the client.
#include <gtest/gtest.h>

#include <cmath>

#include "protocol/container_builder.h"
#include "relay/room_host.h"
#include "tests/integration/property_inbox.h"
#include "tests/integration/sim_world.h"

namespace edgephys::testing {
namespace {

using schema::PhysicsEventKind;
using schema::RejectReason;

struct Log : ClientListener {
  std::vector<std::tuple<uint8_t, uint32_t, uint32_t>> events;
  std::vector<uint16_t> errors;
  void OnPhysicsEvent(uint8_t kind, uint32_t a, uint32_t b) override { events.emplace_back(kind, a, b); }
  void OnError(uint16_t reason, uint32_t, std::string_view) override { errors.push_back(reason); }
  bool Has(PhysicsEventKind kind, uint32_t a, uint32_t b) const {
    for (auto& [k, x, y] : events) {
      if (k == static_cast<uint8_t>(kind) && x == a && y == b) return true;
    }
    return false;
  }
};

TEST(GrabAt, MovingTheHandAndGrabbingInOneFrameIsGrantedAndAForgedPoseRefused) {
  RelayConfig config = LoopbackWorld::DefaultConfig();
  config.physics_threads = 1;  // PhyS steps on the relay's thread: in step with the fake clock
  SimWorld world({}, config);
  Log log;
  Client& a = world.AddClient(MintToken("grab", 1), &log);
  JoinAll(world, {&a}, "grab");
  constexpr uint32_t kOffloaded = entity_flags::kOffloaded;
  SpawnDesc cube{.position = {0, 1, 0}, .flags = kOffloaded | entity_flags::kInteractable};
  cube.rigid_body = RigidBodySpec{};
  cube.rigid_body->use_gravity = false;
  cube.colliders.push_back(BoxCollider({0.1f, 0.1f, 0.1f}));
  // The hand's trigger (0.15 m) reaches 0.25 m from its centre to the cube's: at 0.45 m it
  // does not hover the cube.
  SpawnDesc hand = TriggerHand(0, {0.45f, 1, 0}, 0.15f);
  hand.flags = kOffloaded | entity_flags::kHand;
  Result<uint32_t> cube_id = a.Spawn(cube), hand_id = a.Spawn(hand);
  ASSERT_TRUE(cube_id.ok() && hand_id.ok());
  ASSERT_TRUE(world.RunUntil([&] {
    return world.relay().rooms().at("grab")->room().entities().size() == 2;
  }, 5.0));
  world.RunFor(0.3);
  ASSERT_FALSE(log.Has(PhysicsEventKind::TriggerEnter, *hand_id, *cube_id));
  const RoomHost& host = *world.relay().rooms().at("grab");

  // Same frame: the hand moves onto the cube and grabs it.
  ASSERT_TRUE(a.GrabAt(*cube_id, *hand_id, {0, 1, 0}, {0, 0, 0, 1}).ok());
  ASSERT_TRUE(world.RunUntil([&] { return log.Has(PhysicsEventKind::Grabbed, *cube_id, *hand_id); }, 2.0))
      << "grab refused: " << (log.errors.empty() ? 0 : log.errors.back());
  EXPECT_TRUE(log.errors.empty());
  EXPECT_EQ(host.grab_pose_stats().applied, 1u);
  ASSERT_TRUE(a.Release(*cube_id).ok());
  ASSERT_TRUE(world.RunUntil([&] { return log.Has(PhysicsEventKind::Released, *cube_id, *hand_id); }, 2.0));

  // A forged pose 3 m from the hand (which stays put at the relay before the grab): refused.
  ASSERT_TRUE(a.GrabAt(*cube_id, *hand_id, {3, 1, 0}, {0, 0, 0, 1}).ok());
  ASSERT_TRUE(world.RunUntil([&] { return !log.errors.empty(); }, 2.0));
  EXPECT_EQ(log.errors[0], static_cast<uint16_t>(RejectReason::GrabRefused));
  EXPECT_EQ(host.grab_pose_stats().refused, 1u);
  EXPECT_EQ(host.grab_pose_stats().applied, 1u);
  // Not finite, or not one's own hand: refused by the client before sending.
  EXPECT_EQ(a.GrabAt(*cube_id, *hand_id, {std::nanf(""), 1, 0}, {0, 0, 0, 1}).code(),
            StatusCode::kInvalidArgument);
  EXPECT_EQ(a.GrabAt(*cube_id, *cube_id + 999, {0, 1, 0}, {0, 0, 0, 1}).code(),
            StatusCode::kNotFound);
}

}  // namespace
}  // namespace edgephys::testing
