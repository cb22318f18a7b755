// A leaving owner's entities through a real relay (docs/protocol.md "Ownership", schema
// OwnerLeave): each entity goes where its owner chose, at spawn or later: Stay (the room's, at
// rest where it was), PhyS (PhyS simulates a dynamic body on from its last pose and velocity),
// Despawn. The same whether the owner leaves or its connection times out, as another member and
// a late joiner see it; unknown choices, non-owners and unknown entities are refused and counted.
#include <gtest/gtest.h>

#include <cmath>

#include "client/client_testing.h"
#include "protocol/container_builder.h"
#include "relay/room_host.h"
#include "tests/integration/property_inbox.h"
#include "tests/integration/sim_world.h"

namespace edgephys::testing {
namespace {

using schema::RejectReason;

const Entity* RelayEntity(SimWorld& world, const char* room, uint32_t id) {
  const auto& entities = world.relay().rooms().at(room)->room().entities();
  const auto it = entities.find(id);
  return it == entities.end() ? nullptr : &it->second;
}

EntitySpec FloatingBox(Vec3f at, uint8_t on_owner_leave, uint32_t flags = 0) {
  EntitySpec box = DynamicBox(0, at, {0.1f, 0.1f, 0.1f}, 1.0f);
  box.rigid_body->use_gravity = false;
  box.flags = flags;
  box.on_owner_leave = on_owner_leave;
  return box;
}

enum class Exit { kLeave, kTimeout };

class OwnerLeave : public ::testing::TestWithParam<Exit> {};

TEST_P(OwnerLeave, EachEntityGoesWhereItsOwnerChose) {
  RelayConfig config = LoopbackWorld::DefaultConfig();
  config.physics_threads = 1;  // PhyS steps on the relay's thread: in step with the fake clock
  SimWorld world({}, config);
  PropertyInbox ia, ib, ic;
  auto [a, b] = AddJoined(world, "leave", ia, ib);
  // Stay chosen at spawn; PhyS chosen later by the owner; Despawn overriding Persistent.
  Result<uint32_t> stay = a.Spawn(FloatingBox({-2, 1, 0}, 1));
  Result<uint32_t> phys = a.Spawn(FloatingBox({0, 1, 0}, 0));
  Result<uint32_t> gone = a.Spawn(FloatingBox({2, 1, 0}, 3, entity_flags::kPersistent));
  ASSERT_TRUE(stay.ok() && phys.ok() && gone.ok());
  ASSERT_TRUE(world.RunUntil([&] {
    return b.FindEntity(*stay) && b.FindEntity(*phys) && b.FindEntity(*gone);
  }, 5.0));
  ASSERT_TRUE(a.SetOwnerLeave(*phys, 2).ok());
  ASSERT_TRUE(world.RunUntil([&] { return RelayEntity(world, "leave", *phys)->on_owner_leave == 2; }, 2.0));
  EXPECT_EQ(RelayEntity(world, "leave", *stay)->on_owner_leave, 1);
  // A's local physics moves `phys` uniformly (published every step) and leaves `stay` alone.
  const Vec3f v{1.0f, 0, 0.5f};
  Vec3f p{0, 1, 0};
  // It is still moving when A goes.
  for (int i = 0; i < 100; ++i) {
    p = {p.x + v.x * 0.005f, p.y, p.z + v.z * 0.005f};
    ASSERT_TRUE(a.PublishTransform(*phys, p, {0, 0, 0, 1}).ok());
    world.Step();
  }
  const Vec3f last = RelayEntity(world, "leave", *phys)->state.position;
  ASSERT_GT(last.x, 0.3f);

  if (GetParam() == Exit::kLeave) {
    ASSERT_TRUE(a.LeaveRoom().ok());
  } else {
    world.Freeze(0);  // A's process stops; the relay times its connection out
  }
  ASSERT_TRUE(world.RunUntil([&] {
    return world.relay().rooms().at("leave")->room().members().size() == 1;
  }, 15.0));

  const Entity* s = RelayEntity(world, "leave", *stay);
  ASSERT_NE(s, nullptr);
  EXPECT_EQ(s->owner, 0u);
  EXPECT_EQ(s->physics, PhysicsRole::kMirrored);  // not simulated: at rest where it was
  EXPECT_EQ(s->state.position.x, -2.f);
  const Entity* f = RelayEntity(world, "leave", *phys);
  ASSERT_NE(f, nullptr);
  EXPECT_EQ(f->owner, 0u);
  EXPECT_EQ(f->physics, PhysicsRole::kSimulated);
  // PhyS started from the velocity A's states implied (within 10 %: over a 0.1 s window, arrival times are a step off).
  EXPECT_NEAR(f->linear_velocity.x, v.x, 0.1f * v.x);
  EXPECT_NEAR(f->linear_velocity.z, v.z, 0.1f * v.x);
  EXPECT_EQ(RelayEntity(world, "leave", *gone), nullptr);
  const auto& stats = world.relay().rooms().at("leave")->ownership_stats();
  EXPECT_EQ(stats.left_to_room, 1u);
  EXPECT_EQ(stats.left_to_phys, 1u);

  // B: the despawn, both ownership changes, and `phys` carried on by PhyS along A's motion.
  ASSERT_TRUE(world.RunUntil([&] {
    return b.FindEntity(*gone) == nullptr && b.OwnerOf(*stay) == 0 && b.OwnerOf(*phys) == 0 &&
           b.FindEntity(*phys)->state.position.x > last.x + 0.2f;
  }, 5.0));
  const RemoteEntity* seen = b.FindEntity(*phys);
  const float travelled = seen->state.position.x - last.x;
  EXPECT_NEAR(seen->state.position.z - last.z, travelled * v.z / v.x, 0.01f);
  EXPECT_NEAR(seen->state.position.y, 1.f, 0.002f);
  EXPECT_NEAR(b.FindEntity(*stay)->state.position.x, -2.f, 0.002f);

  // A late joiner: the two that stayed, owned by the room, `phys` still moving; no `gone`.
  Client& c = world.AddClient(MintToken("leave", 3), &ic);
  JoinAll(world, {&c}, "leave");
  ASSERT_TRUE(world.RunUntil([&] { return c.FindEntity(*stay) && c.FindEntity(*phys); }, 5.0));
  world.RunFor(0.3);
  EXPECT_EQ(c.FindEntity(*gone), nullptr);
  EXPECT_EQ(c.OwnerOf(*stay), 0u);
  EXPECT_EQ(c.OwnerOf(*phys), 0u);
  const float seen_at = c.FindEntity(*phys)->state.position.x;
  ASSERT_TRUE(world.RunUntil([&] { return c.FindEntity(*phys)->state.position.x > seen_at + 0.1f; }, 2.0));
  EXPECT_TRUE(ib.errors.empty() && ic.errors.empty());
}

INSTANTIATE_TEST_SUITE_P(LeaveAndTimeout, OwnerLeave, ::testing::Values(Exit::kLeave, Exit::kTimeout),
                         [](const auto& param_info) {
                           return param_info.param == Exit::kLeave ? std::string("Leave")
                                                                   : std::string("Timeout");
                         });

// Without a choice, the Persistent flag decides as before; a choice survives a hand over.
TEST(OwnerLeaveChoice, DefaultFollowsPersistentAndTheChoiceStaysWithTheEntityAcrossOwners) {
  SimWorld world;
  PropertyInbox ia, ib, ic;
  auto [a, b, c] = AddJoined(world, "leave2", ia, ib, ic);
  Result<uint32_t> kept = a.Spawn({.position = {0, 1, 0}, .flags = entity_flags::kPersistent});
  Result<uint32_t> plain = a.Spawn({.position = {1, 1, 0}});
  Result<uint32_t> handed = a.Spawn({.position = {2, 1, 0}});
  ASSERT_TRUE(kept.ok() && plain.ok() && handed.ok());
  ASSERT_TRUE(world.RunUntil([&] { return b.FindEntity(*handed) && c.FindEntity(*handed); }, 5.0));
  ASSERT_TRUE(a.SetOwnerLeave(*handed, 1).ok());  // stay
  ASSERT_TRUE(a.HandOver(*handed, 2).ok());
  ASSERT_TRUE(world.RunUntil([&] { return b.Owns(*handed); }, 5.0));
  ASSERT_TRUE(a.LeaveRoom().ok());
  ASSERT_TRUE(world.RunUntil([&] { return c.FindEntity(*plain) == nullptr && c.OwnerOf(*kept) == 0; }, 5.0));
  ASSERT_TRUE(b.LeaveRoom().ok());  // B owns `handed` now; A's choice decides
  ASSERT_TRUE(world.RunUntil([&] {
    return world.relay().rooms().at("leave2")->room().members().size() == 1 && c.OwnerOf(*handed) == 0;
  }, 5.0));
  EXPECT_NE(c.FindEntity(*handed), nullptr);
  EXPECT_NE(c.FindEntity(*kept), nullptr);
}

TEST(OwnerLeaveChoice, BadChoicesAreRefusedAndCounted) {
  SimWorld world;
  PropertyInbox ia, ib;
  auto [a, b] = AddJoined(world, "leave3", ia, ib);
  Result<uint32_t> id = a.Spawn({.position = {0, 1, 0}});
  ASSERT_TRUE(id.ok());
  ASSERT_TRUE(world.RunUntil([&] { return b.FindEntity(*id) != nullptr; }, 5.0));
  const auto raw = [&](Client& from, uint32_t entity, uint8_t choice) {
    flatbuffers::FlatBufferBuilder fbb(64);
    FinishControl(fbb, schema::CreateOwnershipRequest(
                           fbb, entity, schema::OwnershipAction::SetOwnerLeave, 0, false, nullptr,
                           nullptr, static_cast<schema::OwnerLeave>(choice)));
    ASSERT_TRUE(ClientTesting::SendReliableUnchecked(from, {fbb.GetBufferPointer(), fbb.GetSize()}).ok());
  };
  raw(a, *id, 4);           // unknown choice
  raw(a, 0xdeadbeef, 1);    // unknown entity
  raw(b, *id, 3);           // not the owner
  // A spawn with an unknown choice, sent raw (the builder takes any byte).
  EntitySpec bad;
  bad.id = *id + 1;
  bad.owner = 1;
  bad.on_owner_leave = 200;
  flatbuffers::FlatBufferBuilder fbb(256);
  FinishControl(fbb, schema::CreateSpawn(fbb, AddContainer(fbb, bad)));
  ASSERT_TRUE(ClientTesting::SendReliableUnchecked(a, {fbb.GetBufferPointer(), fbb.GetSize()}).ok());
  ASSERT_TRUE(world.RunUntil([&] { return ia.errors.size() == 3 && ib.errors.size() == 1; }, 5.0));
  EXPECT_EQ(ia.Count(RejectReason::InvalidMessage), 2u);
  EXPECT_EQ(ia.Count(RejectReason::UnknownEntity), 1u);
  EXPECT_EQ(ib.Count(RejectReason::NotOwner), 1u);
  EXPECT_EQ(world.relay().rooms().at("leave3")->ownership_stats().refused, 3u);
  EXPECT_EQ(RelayEntity(world, "leave3", *id)->on_owner_leave, 0);
  EXPECT_EQ(RelayEntity(world, "leave3", *id + 1), nullptr);
  // The client refuses what it can tell is wrong without sending.
  EXPECT_EQ(a.SetOwnerLeave(*id, 4).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(b.SetOwnerLeave(*id, 1).code(), StatusCode::kNotFound);
}

}  // namespace
}  // namespace edgephys::testing
