// Room rules against a hostile member (issue 14): spawn validation (scale, parents), entity
// accounting that survives leave and rejoin, and the room's budgets. Without sockets: RoomHost
// driven through recording MemberLinks (relay/room_host_testing.h).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "relay/room_host_testing.h"

namespace edgephys {
namespace {

using namespace room_host_testing;  // NOLINT: the test doubles

class RoomHostHostileTest : public RoomHostTest {
 protected:
  uint64_t Refused(BudgetKind kind) const {
    return counters_.budget_refusals[static_cast<size_t>(kind)].load();
  }
  static EntitySpec SoftBody(uint32_t id, uint32_t owner, size_t particles) {
    EntitySpec s = LocalBox(id, owner, kOffloaded);
    SoftBodySpec sb;
    for (size_t i = 0; i < particles; ++i) {
      sb.particles.insert(sb.particles.end(), {float(i % 64) * 0.01f, 1.f, float(i / 64) * 0.01f});
    }
    s.soft_body = sb;
    return s;
  }
};

// Finding 6: a spawn's scale was forwarded whatever it was.
TEST_F(RoomHostHostileTest, ScaleMustBeFiniteAndWithinBounds) {
  RecordingMember a(1), b(2);
  ASSERT_TRUE(host_->Join(a, 0));
  ASSERT_TRUE(host_->Join(b, 0));
  const float inf = std::numeric_limits<float>::infinity();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const std::vector<Vec3f> bad = {{nan, 1, 1}, {1, inf, 1}, {0, 0, 0}, {1, 1, 0},
                                  {-1, 1, 1},  {1e38f, 1, 1}, {1, 1, 2e4f}, {1e-6f, 1, 1}};
  uint32_t id = Base(a);
  for (const Vec3f& scale : bad) {
    EntitySpec s = LocalBox(++id, 1);
    s.scale = scale;
    Spawn(a, s);
    EXPECT_TRUE(a.HasError(RejectReason::InvalidMessage, id)) << scale.x << " " << scale.z;
  }
  EntitySpec ok = LocalBox(++id, 1);
  ok.scale = {0.01f, 100.f, 1.f};
  Spawn(a, ok);
  EXPECT_EQ(a.errors.size(), bad.size());
  EXPECT_EQ(host_->room().entities().size(), 1u);
  EXPECT_EQ(b.Of(Body::Spawn).size(), 1u);  // nothing bad was forwarded
}

// Finding 6: unknown parents and parent cycles were accepted for entities without physics.
TEST_F(RoomHostHostileTest, ParentsMustExistAndCanNeverFormACycle) {
  config_.max_entities_per_player = 16;
  Rebuild();
  RecordingMember a(1), b(2);
  ASSERT_TRUE(host_->Join(a, 0));
  const uint32_t p = Base(a) + 1, c = Base(a) + 2;
  EntitySpec orphan = LocalBox(c, 1);
  orphan.parent_id = Base(a) + 50;
  Spawn(a, orphan);
  EXPECT_TRUE(a.HasError(RejectReason::UnknownEntity, c));
  EntitySpec self = LocalBox(c, 1);
  self.parent_id = c;
  Spawn(a, self);
  EXPECT_EQ(a.errors.size(), 2u);
  EXPECT_TRUE(host_->room().entities().empty());

  Spawn(a, LocalBox(p, 1));
  EntitySpec child = LocalBox(c, 1);
  child.parent_id = p;
  Spawn(a, child);
  ASSERT_EQ(a.errors.size(), 2u);
  // The parent goes; the id comes back as the child's child. The child became a root in the
  // relay and in what a late joiner is sent, but `a` (present when the child spawned) still
  // shows it under p: p -> c -> p would be a cycle in its view. Refused, for every member.
  host_->Despawn(a, p);
  EXPECT_EQ(Find(c)->parent, 0u);
  EntitySpec again = LocalBox(p, 1);
  again.parent_id = c;
  Spawn(a, again);
  ASSERT_EQ(a.errors.size(), 3u);
  EXPECT_TRUE(a.HasError(RejectReason::InvalidMessage, p));
  EXPECT_EQ(Find(p), nullptr);
  ASSERT_TRUE(host_->Join(b, 0));
  for (const auto* msg : b.Of(Body::Spawn)) {
    const auto* container = msg->body_as_Spawn()->container();
    EXPECT_NE(container->entity_id(), p);
    if (container->entity_id() == c) {
      EXPECT_EQ(container->parent_id(), 0u);
    }
  }
  // Also refused now that a late joiner (to whom c is a root) is present: one rule for all.
  Spawn(a, again);
  EXPECT_EQ(a.errors.size(), 4u);
  // The id itself is free: as a root, or under an unrelated parent, it comes back.
  const uint32_t other = Base(a) + 3;
  Spawn(a, LocalBox(other, 1));
  EntitySpec elsewhere = LocalBox(p, 1);
  elsewhere.parent_id = other;
  Spawn(a, elsewhere);
  EXPECT_EQ(a.errors.size(), 4u);
  ASSERT_NE(Find(p), nullptr);
  EXPECT_EQ(Find(p)->parent, other);
}

// A longer chain: g <- p <- c, then p goes; p coming back as c's grandchild (under c's new
// child q) closes p -> q -> c -> p in the view of members present: refused. A new id under q
// is fine.
TEST_F(RoomHostHostileTest, FormerParentsCountAlongTheWholeChain) {
  config_.max_entities_per_player = 16;
  Rebuild();
  RecordingMember a(1);
  ASSERT_TRUE(host_->Join(a, 0));
  const uint32_t g = Base(a) + 1, p = Base(a) + 2, c = Base(a) + 3, q = Base(a) + 4;
  Spawn(a, LocalBox(g, 1));
  EntitySpec ps = LocalBox(p, 1);
  ps.parent_id = g;
  Spawn(a, ps);
  EntitySpec cs = LocalBox(c, 1);
  cs.parent_id = p;
  Spawn(a, cs);
  host_->Despawn(a, p);  // c: root, former parent p
  EntitySpec qs = LocalBox(q, 1);
  qs.parent_id = c;
  Spawn(a, qs);
  ASSERT_TRUE(a.errors.empty());
  EntitySpec back = LocalBox(p, 1);  // p under q: q -> c -> p(former) -> ... is p itself
  back.parent_id = q;
  Spawn(a, back);
  EXPECT_TRUE(a.HasError(RejectReason::InvalidMessage, p));
  EntitySpec g2 = LocalBox(Base(a) + 5, 1);  // a new id under q: no cycle
  g2.parent_id = q;
  Spawn(a, g2);
  EXPECT_EQ(a.errors.size(), 1u);
}

// Finding 3: persistent entities, leave, rejoin with a fresh id block and a reset counter,
// repeat: one token filled the room. They now count against the player identity.
TEST_F(RoomHostHostileTest, PersistentEntitiesCountAgainstTheirCreatorAcrossRejoins) {
  RecordingMember honest(9);
  ASSERT_TRUE(host_->Join(honest, 0));
  size_t refused = 0;
  for (int cycle = 0; cycle < 5; ++cycle) {
    RecordingMember a(1);
    ASSERT_TRUE(host_->Join(a, 0));
    for (uint32_t i = 1; i <= 4; ++i) Spawn(a, LocalBox(Base(a) + i, 1, kPersistent));
    for (const auto& e : a.errors) refused += e.first == RejectReason::EntityLimit;
    host_->Leave(a, 0);
  }
  EXPECT_EQ(host_->room().entities().size(), 4u);  // the limit (4), not 5 x 4
  EXPECT_EQ(refused, 16u);
  EXPECT_EQ(host_->room().ledger().Of(1).entities, 4u);
  EXPECT_EQ(Refused(BudgetKind::kPlayerEntities), 16u);
  // Despawning one (as its creator, after a rejoin) gives the budget back.
  RecordingMember a(1);
  ASSERT_TRUE(host_->Join(a, 0));
  const uint32_t old = host_->room().entities().begin()->first;
  host_->Despawn(a, old);
  EXPECT_TRUE(a.errors.empty());
  Spawn(a, LocalBox(Base(a) + 1, 1));
  EXPECT_TRUE(a.errors.empty());
  Spawn(a, LocalBox(Base(a) + 2, 1));
  EXPECT_TRUE(a.HasError(RejectReason::EntityLimit, Base(a) + 2));
  // Honest players are not charged for it.
  Spawn(honest, LocalBox(Base(honest) + 1, 9));
  EXPECT_TRUE(honest.errors.empty());
}

TEST_F(RoomHostHostileTest, TheRoomWideEntityCapHoldsWhateverThePlayers) {
  config_.budgets.max_entities = 6;
  Rebuild();
  RecordingMember a(1), b(2);
  ASSERT_TRUE(host_->Join(a, 0));
  ASSERT_TRUE(host_->Join(b, 0));
  for (uint32_t i = 1; i <= 4; ++i) Spawn(a, LocalBox(Base(a) + i, 1));
  for (uint32_t i = 1; i <= 4; ++i) Spawn(b, LocalBox(Base(b) + i, 2));
  EXPECT_EQ(host_->room().entities().size(), 6u);
  EXPECT_TRUE(b.HasError(RejectReason::OverBudget, Base(b) + 3));
  EXPECT_TRUE(b.HasError(RejectReason::OverBudget, Base(b) + 4));
  EXPECT_EQ(Refused(BudgetKind::kRoomEntities), 2u);
}

// Finding 1's cause: any number of 4,096-particle soft bodies from one player, each within
// the per-body limits. PhyS work is now budgeted per player and per room.
TEST_F(RoomHostHostileTest, PhysicsWorkIsBudgetedPerPlayerAndPerRoom) {
  config_.max_entities_per_player = 64;
  config_.budgets.max_particles_per_player = 8192;
  config_.budgets.max_particles = 12288;
  config_.budgets.max_bodies_per_player = 5;
  config_.budgets.max_joints_per_player = 2;
  Rebuild();
  RecordingMember a(1), b(2);
  ASSERT_TRUE(host_->Join(a, 0));
  ASSERT_TRUE(host_->Join(b, 0));
  for (uint32_t i = 1; i <= 20; ++i) Spawn(a, SoftBody(Base(a) + i, 1, 4096));
  EXPECT_EQ(host_->room().ledger().Of(1).particles, 8192u);
  EXPECT_TRUE(a.HasError(RejectReason::OverBudget, Base(a) + 3));
  EXPECT_EQ(Refused(BudgetKind::kPlayerParticles), 18u);
  Spawn(b, SoftBody(Base(b) + 1, 2, 4096));
  Spawn(b, SoftBody(Base(b) + 2, 2, 4096));
  EXPECT_TRUE(b.HasError(RejectReason::OverBudget, Base(b) + 2));
  EXPECT_EQ(Refused(BudgetKind::kRoomParticles), 1u);
  EXPECT_EQ(host_->room().ledger().total().particles, 12288u);
  // Bodies: a has 2 soft bodies; 3 more boxes fit, the 4th does not.
  for (uint32_t i = 30; i < 34; ++i) {
    EntitySpec box = DynamicBox(Base(a) + i, {0, 1, 0}, {0.1f, 0.1f, 0.1f}, 1);
    box.owner = 1;
    Spawn(a, box);
  }
  EXPECT_TRUE(a.HasError(RejectReason::OverBudget, Base(a) + 33));
  EXPECT_EQ(Refused(BudgetKind::kPlayerBodies), 1u);
  // Joints: 3 on one body exceed 2.
  EntitySpec jointed = DynamicBox(Base(b) + 40, {0, 1, 0}, {0.1f, 0.1f, 0.1f}, 1);
  jointed.owner = 2;
  jointed.joints.resize(3);
  Spawn(b, jointed);
  EXPECT_TRUE(b.HasError(RejectReason::OverBudget, Base(b) + 40));
  EXPECT_EQ(Refused(BudgetKind::kPlayerJoints), 1u);
  // Leaving refunds what was despawned.
  host_->Leave(a, 0);
  EXPECT_EQ(host_->room().ledger().Of(1).particles, 0u);
  EXPECT_EQ(host_->room().ledger().total().particles, 4096u);
}

TEST_F(RoomHostHostileTest, NameLengthAndStoredBytesAreBudgeted) {
  config_.max_entities_per_player = 64;
  config_.budgets.max_name_bytes = 100;
  config_.budgets.max_bytes_per_player = 4000;
  Rebuild();
  RecordingMember a(1);
  ASSERT_TRUE(host_->Join(a, 0));
  EntitySpec named = LocalBox(Base(a) + 1, 1);
  named.name = std::string(101, 'n');
  Spawn(a, named);
  EXPECT_TRUE(a.HasError(RejectReason::OverBudget, Base(a) + 1));
  EXPECT_EQ(Refused(BudgetKind::kNameLength), 1u);
  named.name = std::string(100, 'n');
  for (uint32_t i = 2; i < 40; ++i) {
    named.id = Base(a) + i;
    Spawn(a, named);
  }
  EXPECT_EQ(Refused(BudgetKind::kPlayerBytes), 38u - host_->room().entities().size());
  EXPECT_LE(host_->room().ledger().Of(1).bytes, 4000u);
  EXPECT_GT(host_->room().ledger().Of(1).bytes, 3000u);
}

}  // namespace
}  // namespace edgephys

namespace edgephys {
namespace {

class NullChannel final : public WorkerChannel {
 public:
  bool SendToWorker(std::span<const uint8_t>) override {
    ++sent;
    return true;
  }
  bool WorkerConnected() const override { return true; }
  int sent = 0;
};

// Last session's finding: a child container (with a parent) skipped every component check on
// a remote worker's link, because the validator's "unknown parent" was cleared first.
TEST(RemotePhysicsLinkHostile, AChildContainerGetsEveryComponentCheck) {
  NullChannel channel;
  physics::PhysicsConfig config;
  RemotePhysicsLink link(&channel, 7, 1, config, 0.0);
  EntitySpec parent = DynamicBox(1001, {0, 1, 0}, {0.1f, 0.1f, 0.1f}, 1);
  ASSERT_TRUE(link.Add(AsContainer(BuildContainer(parent)), PhysicsRole::kSimulated).ok());
  const int sent = channel.sent;
  EntitySpec child = DynamicBox(1002, {0, 1, 0}, {0.1f, 0.1f, 0.1f}, 1);
  child.parent_id = 1001;
  child.rigid_body->mass = std::numeric_limits<float>::quiet_NaN();
  EXPECT_FALSE(link.Add(AsContainer(BuildContainer(child)), PhysicsRole::kSimulated).ok());
  child.rigid_body->mass = -1;
  EXPECT_FALSE(link.Add(AsContainer(BuildContainer(child)), PhysicsRole::kSimulated).ok());
  child.rigid_body->mass = 1;
  child.colliders[0].half_extents = {-1, 1, 1};
  EXPECT_FALSE(link.Add(AsContainer(BuildContainer(child)), PhysicsRole::kSimulated).ok());
  EXPECT_EQ(channel.sent, sent);  // nothing reached the worker
  child.colliders[0].half_extents = {0.1f, 0.1f, 0.1f};
  child.parent_id = 999;  // unknown
  EXPECT_FALSE(link.Add(AsContainer(BuildContainer(child)), PhysicsRole::kSimulated).ok());
  child.parent_id = 1001;
  EXPECT_TRUE(link.Add(AsContainer(BuildContainer(child)), PhysicsRole::kSimulated).ok());
  EXPECT_FALSE(link.Add(AsContainer(BuildContainer(child)), PhysicsRole::kSimulated).ok());  // dup
  EXPECT_EQ(channel.sent, sent + 1);
}

}  // namespace
}  // namespace edgephys

namespace edgephys {
namespace {

using namespace room_host_testing;  // NOLINT: the test doubles

// Finding 2: a member's large persistent entities made every late joiner overflow its reliable
// queue at once. The join now streams within the joiner's queue, resumable across ticks, with
// the room's live broadcasts held until the stream is through.
TEST_F(RoomHostTest, ALateJoinStreamsWithinTheJoinersReliableBudget) {
  config_.max_entities_per_player = 64;
  Rebuild();
  RecordingMember a(1), b(2);
  ASSERT_TRUE(host_->Join(a, 0));
  std::vector<uint32_t> order;
  for (uint32_t i = 10; i > 0; --i) {  // spawn order differs from id order
    EntitySpec s = LocalBox(Base(a) + i, 1, kPersistent);
    s.name = std::string(1000, 'x');
    Spawn(a, s);
    order.push_back(Base(a) + i);
  }
  ASSERT_TRUE(a.errors.empty());
  b.capacity_bytes = 5000;  // room for ~2 spawns in the half the stream may use
  ASSERT_TRUE(host_->Join(b, 0));
  EXPECT_EQ(b.Of(Body::Spawn).size(), 2u);
  Spawn(a, LocalBox(Base(a) + 20, 1));  // live traffic during the stream: held
  EXPECT_EQ(b.Of(Body::Spawn).size(), 2u);
  std::vector<MemberLink*> receivers;
  host_->BeginTick(0.1, &receivers);  // nothing acknowledged: nothing more
  EXPECT_EQ(b.Of(Body::Spawn).size(), 2u);
  for (int tick = 0; tick < 20 && b.Of(Body::Spawn).size() < 11; ++tick) {
    b.pending_bytes = 0;  // acknowledged
    host_->BeginTick(0.2 + tick * 0.1, &receivers);
    EXPECT_LE(b.pending_bytes, 5000u / 2 + 1200u);
  }
  EXPECT_FALSE(b.overflowed);
  const auto spawns = b.Of(Body::Spawn);
  ASSERT_EQ(spawns.size(), 11u);
  for (size_t i = 0; i < order.size(); ++i) {
    EXPECT_EQ(spawns[i]->body_as_Spawn()->container()->entity_id(), order[i]) << i;
  }
  EXPECT_EQ(spawns.back()->body_as_Spawn()->container()->entity_id(), Base(a) + 20);
}

// A joiner that never acknowledges is dropped once the room's live traffic held for it would
// exceed its queue: held messages are bounded.
TEST_F(RoomHostTest, AJoinerThatNeverAcknowledgesIsDroppedNotBufferedForever) {
  config_.max_entities_per_player = 1024;
  Rebuild();
  RecordingMember a(1), b(2);
  ASSERT_TRUE(host_->Join(a, 0));
  EntitySpec big = LocalBox(Base(a) + 1, 1);
  big.name = std::string(1000, 'x');
  Spawn(a, big);
  b.capacity_bytes = 4000;
  b.pending_bytes = 3000;  // stalled
  ASSERT_TRUE(host_->Join(b, 0));
  for (uint32_t i = 2; i < 40 && !b.overflowed; ++i) Spawn(a, LocalBox(Base(a) + i, 1));
  EXPECT_TRUE(b.overflowed);
}

}  // namespace
}  // namespace edgephys
