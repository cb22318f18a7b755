// PhyS end to end on real loopback UDP: an offloaded client dissects a scene into the relay's
// embedded PhyS and a local-physics client in the same room sees and touches it.
#include <gtest/gtest.h>

#include <cmath>
#include <map>

#include "loadgen/scenes/scenes.h"
#include "tests/integration/harness.h"

namespace edgephys::testing {
namespace {

using schema::EntityFlags;
using schema::PhysicsEventKind;

constexpr uint32_t F(EntityFlags f) { return static_cast<uint32_t>(f); }

struct EventLog : ClientListener {
  std::vector<std::tuple<uint8_t, uint32_t, uint32_t>> events;
  std::vector<uint16_t> errors;
  int soft_updates = 0;
  void OnPhysicsEvent(uint8_t kind, uint32_t a, uint32_t b) override { events.emplace_back(kind, a, b); }
  void OnError(uint16_t reason, uint32_t, std::string_view) override { errors.push_back(reason); }
  void OnSoftBodyUpdated(const RemoteEntity&) override { ++soft_updates; }
  bool Has(PhysicsEventKind kind, uint32_t a, uint32_t b) const {
    for (auto& [k, x, y] : events) {
      if (k == static_cast<uint8_t>(kind) && x == a && y == b) return true;
    }
    return false;
  }
};

ColliderSpec Trigger(float radius) {
  ColliderSpec c = SphereCollider(radius);
  c.is_trigger = true;
  return c;
}

// Spread of the particles around their centroid: changes when the body deforms.
std::vector<Vec3f> Relative(const std::vector<Vec3f>& nodes) {
  Vec3f c{};
  for (const Vec3f& n : nodes) c = {c.x + n.x, c.y + n.y, c.z + n.z};
  float k = 1.0f / static_cast<float>(nodes.size());
  c = {c.x * k, c.y * k, c.z * k};
  std::vector<Vec3f> out;
  for (const Vec3f& n : nodes) out.push_back({n.x - c.x, n.y - c.y, n.z - c.z});
  return out;
}

TEST(PhysicsRoom, OffloadedSceneIsSimulatedSharedPushedGrabbedAndStoppedByAWall) {
  LoopbackWorld world;
  EventLog a_log, b_log;
  Client& a = world.AddClient(MintToken("phys", 1), &a_log);  // offloaded (headset)
  Client& b = world.AddClient(MintToken("phys", 2), &b_log);  // local physics (desktop)
  for (Client* c : {&a, &b}) {
    ASSERT_TRUE(world.RunUntil([&] { return c->state() == ClientState::kConnected; }, 3.0));
    ASSERT_TRUE(c->JoinRoom("phys").ok());
  }
  ASSERT_TRUE(world.RunUntil([&] { return a.joined() && b.joined(); }, 3.0));

  // A dissects its scene: static ground and wall, a physics-less parent with an interactable
  // cube under it, a kinematic hand with a trigger, and a soft bunny.
  SpawnDesc ground{.position = {0, -0.5f, 0}, .flags = F(EntityFlags::Offloaded)};
  ground.colliders.push_back(BoxCollider({10, 0.5f, 10}));
  SpawnDesc wall{.position = {1.5f, 1, 0}, .flags = F(EntityFlags::Offloaded)};
  wall.colliders.push_back(BoxCollider({0.1f, 1, 2}));
  SpawnDesc parent{.position = {0, 0, 0}, .flags = F(EntityFlags::Offloaded), .name = "table"};
  auto ground_id = a.Spawn(ground), wall_id = a.Spawn(wall), parent_id = a.Spawn(parent);
  ASSERT_TRUE(ground_id.ok() && wall_id.ok() && parent_id.ok());
  SpawnDesc cube{.position = {0, 2, 0}, .parent_id = *parent_id,
                 .flags = F(EntityFlags::Offloaded) | F(EntityFlags::Interactable) |
                          F(EntityFlags::ReportContacts),
                 .name = "cube"};
  cube.rigid_body = RigidBodySpec{};
  cube.colliders.push_back(BoxCollider({0.1f, 0.1f, 0.1f}));
  SpawnDesc hand{.position = {0, 1.5f, 3}, .flags = F(EntityFlags::Offloaded) | F(EntityFlags::Hand),
                 .name = "right hand"};
  hand.rigid_body = RigidBodySpec{};
  hand.rigid_body->kinematic = true;
  hand.rigid_body->mass = 0;
  hand.colliders.push_back(Trigger(0.2f));
  physics::BunnyParams bunny_params;
  bunny_params.center = {-3, 1, 0};
  SpawnDesc bunny{.position = {0, 0, 0}, .flags = F(EntityFlags::Offloaded), .name = "bunny"};
  bunny.soft_body = physics::MakeBunnySoftBody(bunny_params);  // ~500 particles, a large spawn
  auto cube_id = a.Spawn(cube), hand_id = a.Spawn(hand), bunny_id = a.Spawn(bunny);
  ASSERT_TRUE(cube_id.ok() && hand_id.ok() && bunny_id.ok())
      << cube_id.status().message() << hand_id.status().message() << bunny_id.status().message();

  // B (local physics) sees the cube fall onto the ground, PhyS-owned, under its parent.
  ASSERT_TRUE(world.RunUntil([&] {
    const RemoteEntity* e = b.FindEntity(*cube_id);
    return e && e->spawned && e->has_state && e->state.position.y < 0.15f;
  }, 5.0)) << "the cube did not fall for B";
  EXPECT_EQ(b.FindEntity(*cube_id)->owner, 0u);  // PhyS owns it
  EXPECT_EQ(b.FindEntity(*cube_id)->parent, *parent_id);
  EXPECT_NEAR(b.FindEntity(*cube_id)->state.position.y, 0.1f, 0.01f);
  ASSERT_TRUE(world.RunUntil([&] {
    return b_log.Has(PhysicsEventKind::CollisionEnter, std::min(*ground_id, *cube_id),
                     std::max(*ground_id, *cube_id));
  }, 1.0))
      << [&] {
           std::string s = "ground " + std::to_string(*ground_id) + " cube " + std::to_string(*cube_id) + ":";
           for (auto& [k, x, y] : b_log.events) s += " " + std::to_string(k) + "(" + std::to_string(x) + "," + std::to_string(y) + ")";
           return s;
         }();

  // ... and the soft body land and deform.
  ASSERT_TRUE(world.RunUntil([&] {
    const RemoteEntity* e = b.FindEntity(*bunny_id);
    return e && e->nodes.size() == bunny.soft_body->particles.size() / 3 && b_log.soft_updates > 5;
  }, 5.0));
  world.RunFor(1.5);
  {
    std::vector<Vec3f> initial;
    const auto& p = bunny.soft_body->particles;
    for (size_t i = 0; i + 2 < p.size(); i += 3) initial.push_back({p[i], p[i + 1], p[i + 2]});
    auto before = Relative(initial), after = Relative(b.FindEntity(*bunny_id)->nodes);
    float max_change = 0, min_y = 1e9f;
    for (size_t i = 0; i < before.size(); ++i) {
      float dx = after[i].x - before[i].x, dy = after[i].y - before[i].y, dz = after[i].z - before[i].z;
      max_change = std::max(max_change, std::sqrt(dx * dx + dy * dy + dz * dz));
      min_y = std::min(min_y, b.FindEntity(*bunny_id)->nodes[i].y);
    }
    EXPECT_GT(max_change, 0.01f) << "the bunny did not deform";
    EXPECT_GT(min_y, -0.05f) << "the bunny fell through the ground";
    EXPECT_LT(min_y, 0.1f) << "the bunny did not land";
  }

  // B's kinematic hand (mirrored into PhyS) pushes the PhyS-owned cube along +x.
  SpawnDesc b_hand{.position = {-1, 0.1f, 0}, .flags = F(EntityFlags::Hand)};
  b_hand.rigid_body = RigidBodySpec{};
  b_hand.rigid_body->kinematic = true;
  b_hand.rigid_body->mass = 0;
  b_hand.colliders.push_back(BoxCollider({0.05f, 0.05f, 0.2f}));
  auto b_hand_id = b.Spawn(b_hand);
  ASSERT_TRUE(b_hand_id.ok());
  world.RunFor(0.3);
  double start = world.Now();
  world.RunFor(1.5, [&](double now) {
    float x = static_cast<float>(-1.0 + 0.8 * (now - start));  // 0.8 m/s towards +x
    (void)b.PublishTransform(*b_hand_id, {x, 0.1f, 0}, {});
  });
  world.RunFor(0.5);
  const RemoteEntity* pushed = b.FindEntity(*cube_id);
  EXPECT_GT(pushed->state.position.x, 0.05f) << "the local hand did not push the cube";
  const float cube_x = pushed->state.position.x;
  (void)b.PublishTransform(*b_hand_id, {-3, 0.1f, 2}, {});  // out of the way
  world.RunFor(0.3);

  // A's hand hovers the cube (trigger), grabs it, and drags it into the wall: it stops there.
  ASSERT_TRUE(a.PublishTransform(*hand_id, {cube_x, 0.25f, 0}, {}).ok());
  ASSERT_TRUE(world.RunUntil([&] { return a_log.Has(PhysicsEventKind::TriggerEnter, *hand_id, *cube_id); }, 2.0));
  ASSERT_TRUE(a.Grab(*cube_id, *hand_id).ok());
  ASSERT_TRUE(world.RunUntil([&] { return a_log.Has(PhysicsEventKind::Grabbed, *cube_id, *hand_id); }, 2.0))
      << "grab refused: " << (a_log.errors.empty() ? 0 : a_log.errors.back());
  start = world.Now();
  world.RunFor(2.0, [&](double now) {
    float x = std::min(3.0f, static_cast<float>(cube_x + 1.5 * (now - start)));
    (void)a.PublishTransform(*hand_id, {x, 0.4f, 0}, {});
  });
  const RemoteEntity* held = b.FindEntity(*cube_id);
  // The wall's face is at x = 1.4; the cube's half size is 0.1.
  EXPECT_LE(held->state.position.x, 1.3f + 0.03f) << "the grabbed cube went through the wall";
  EXPECT_GE(held->state.position.x, 1.3f - 0.1f) << "the grabbed cube did not reach the wall";
  EXPECT_GT(held->state.position.y, 0.2f) << "the grabbed cube did not follow the hand up";
  ASSERT_TRUE(a.Release(*cube_id).ok());
  ASSERT_TRUE(world.RunUntil([&] { return b_log.Has(PhysicsEventKind::Released, *cube_id, *hand_id); }, 2.0));
  world.RunFor(1.0);

  // Events: every pair's Enter and Exit alternate, starting with Enter — once each, in order.
  for (const EventLog* log : {&a_log, &b_log}) {
    std::map<std::tuple<int, uint32_t, uint32_t>, int> open;  // (family, a, b) -> Enter - Exit
    for (auto& [kind, x, y] : log->events) {
      int family = kind <= 1 ? 0 : kind <= 3 ? 1 : -1;
      if (family < 0) continue;
      bool enter = kind == 0 || kind == 2;
      int& depth = open[{family, x, y}];
      depth += enter ? 1 : -1;
      ASSERT_TRUE(depth == 0 || depth == 1) << "pair " << x << "-" << y << " kind " << int(kind);
    }
  }
  EXPECT_EQ(a_log.events, b_log.events);  // everyone sees the same events in the same order
  EXPECT_EQ(world.counters().guard_resets.load(), 0u);
}

TEST(PhysicsRoom, InvalidContainersAndBadGrabsAreRefusedWithReasons) {
  LoopbackWorld world;
  EventLog log;
  Client& a = world.AddClient(MintToken("bad", 1), &log);
  ASSERT_TRUE(world.RunUntil([&] { return a.state() == ClientState::kConnected; }, 3.0));
  ASSERT_TRUE(a.JoinRoom("bad").ok());
  ASSERT_TRUE(world.RunUntil([&] { return a.joined(); }, 3.0));
  SpawnDesc negative{.flags = F(EntityFlags::Offloaded)};
  negative.rigid_body = RigidBodySpec{};
  negative.rigid_body->mass = -1;
  negative.colliders.push_back(BoxCollider({0.1f, 0.1f, 0.1f}));
  SpawnDesc nan_box{.flags = F(EntityFlags::Offloaded)};
  nan_box.rigid_body = RigidBodySpec{};
  nan_box.colliders.push_back(BoxCollider({std::nanf(""), 0.1f, 0.1f}));
  SpawnDesc fine{.position = {0, 1, 0}, .flags = F(EntityFlags::Offloaded)};  // not Interactable
  fine.rigid_body = RigidBodySpec{};
  fine.colliders.push_back(BoxCollider({0.1f, 0.1f, 0.1f}));
  auto bad1 = a.Spawn(negative), bad2 = a.Spawn(nan_box), ok = a.Spawn(fine);
  ASSERT_TRUE(bad1.ok() && bad2.ok() && ok.ok());
  ASSERT_TRUE(world.RunUntil([&] { return log.errors.size() >= 2; }, 3.0));
  EXPECT_EQ(log.errors[0], static_cast<uint16_t>(schema::RejectReason::InvalidContainer));
  EXPECT_EQ(log.errors[1], static_cast<uint16_t>(schema::RejectReason::InvalidContainer));
  const Room* room = world.relay().FindRoom("bad");
  EXPECT_EQ(room->entities().count(*bad1), 0u);
  EXPECT_EQ(room->entities().count(*ok), 1u);  // nothing else in the room was affected
  // Grabbing with a hand that is not ours, or something not hovered, is refused.
  ASSERT_TRUE(a.Grab(*ok, *ok).ok());
  ASSERT_TRUE(world.RunUntil([&] { return log.errors.size() >= 3; }, 3.0));
  EXPECT_EQ(log.errors[2], static_cast<uint16_t>(schema::RejectReason::NotOwner));
}

}  // namespace
}  // namespace edgephys::testing
