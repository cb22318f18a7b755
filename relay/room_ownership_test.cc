// Ownership rules (relay/room_ownership.cc) and a hostile member's ownership requests: grants,
// hand overs, releases, takeover settings, the authority sequence, stale states of a previous
// owner dropped and counted, late joiners, leaves, and every refusal counted. Without sockets:
// RoomHost driven through recording MemberLinks (relay/room_host_testing.h).
#include <gtest/gtest.h>

#include "relay/room_host_testing.h"

namespace edgephys {
namespace {

using namespace room_host_testing;  // NOLINT: the test doubles
using schema::OwnershipAction;

class RoomOwnershipTest : public RoomHostTest {
 protected:
  void Ask(RecordingMember& m, uint32_t entity, OwnershipAction action, uint32_t to = 0,
           bool takeover = false, double now = 1.0) {
    flatbuffers::FlatBufferBuilder fbb(64);
    FinishControl(fbb, schema::CreateOwnershipRequest(fbb, entity, action, to, takeover));
    const auto* msg = schema::GetControlMessage(fbb.GetBufferPointer());
    host_->Ownership(m, *msg->body_as_OwnershipRequest(), now);
  }
  // The last OwnershipChanged `m` was sent, or null.
  static const schema::OwnershipChanged* LastChange(const RecordingMember& m) {
    auto all = m.Of(Body::OwnershipChanged);
    return all.empty() ? nullptr : all.back()->body_as_OwnershipChanged();
  }
  void Move(RecordingMember& m, uint32_t id, float x) {
    host_->ApplyStates(m, StatePayload({{id, {x, 1, 1}, {0, 0, 0, 1}}}), 2.0);
  }
};

TEST_F(RoomOwnershipTest, HandOverMovesAuthorityAndDropsTheOldOwnersStates) {
  RecordingMember a(1), b(2), c(3);
  ASSERT_TRUE(host_->Join(a, 0));
  ASSERT_TRUE(host_->Join(b, 0));
  ASSERT_TRUE(host_->Join(c, 0));
  const uint32_t id = Base(a) + 1;
  Spawn(a, LocalBox(id, 1));
  Ask(a, id, OwnershipAction::HandOver, 2);
  ASSERT_TRUE(a.errors.empty());
  EXPECT_EQ(Find(id)->owner, 2u);
  EXPECT_EQ(Find(id)->authority_seq, 1u);
  for (RecordingMember* m : {&a, &b, &c}) {
    const auto* ch = LastChange(*m);
    ASSERT_NE(ch, nullptr) << m->player_id();
    EXPECT_EQ(ch->entity_id(), id);
    EXPECT_EQ(ch->owner(), 2u);
    EXPECT_EQ(ch->previous_owner(), 1u);
    EXPECT_EQ(ch->authority_seq(), 1u);
  }
  // A's late state: dropped, counted as stale; B's: applied.
  Move(a, id, 5);
  EXPECT_EQ(Find(id)->state.position.x, 1.f);
  EXPECT_EQ(a.dropped_updates, std::vector<DropReason>{DropReason::kNotOwner});
  EXPECT_EQ(counters_.stale_owner_states.load(), 1u);
  EXPECT_EQ(host_->ownership_stats().stale, 1u);
  Move(b, id, 7);
  EXPECT_EQ(Find(id)->state.position.x, 7.f);
  // A third player's state is refused but is not a previous owner's.
  Move(c, id, 9);
  EXPECT_EQ(c.dropped_updates.size(), 1u);
  EXPECT_EQ(counters_.stale_owner_states.load(), 1u);
  // The new owner may despawn it; the creator no longer may.
  host_->Despawn(a, id);
  EXPECT_TRUE(a.HasError(RejectReason::NotOwner, id));
  EXPECT_EQ(counters_.ownership_changes.load(), 1u);
}

TEST_F(RoomOwnershipTest, RequestIsGrantedForRoomEntitiesAndWhenTakeoverIsAllowed) {
  RecordingMember a(1), b(2);
  uint32_t id = 0;
  ASSERT_NO_FATAL_FAILURE(JoinBothAndSpawnBox(a, b, &id));
  Ask(b, id, OwnershipAction::Request);  // A forbids takeover (the default)
  EXPECT_TRUE(b.HasError(RejectReason::TakeoverRefused, id));
  EXPECT_EQ(Find(id)->owner, 1u);
  Ask(a, id, OwnershipAction::SetTakeover, 0, true);
  EXPECT_TRUE(Find(id)->takeover_allowed);
  ASSERT_NE(LastChange(b), nullptr);
  EXPECT_TRUE(LastChange(b)->takeover_allowed());
  EXPECT_EQ(LastChange(b)->authority_seq(), 0u);  // a setting, not a change of owner
  Ask(b, id, OwnershipAction::Request);
  EXPECT_EQ(Find(id)->owner, 2u);
  EXPECT_EQ(LastChange(a)->authority_seq(), 1u);
  // Released to the room, anyone may take it.
  Ask(b, id, OwnershipAction::Release);
  EXPECT_EQ(Find(id)->owner, 0u);
  Ask(b, id, OwnershipAction::SetTakeover, 0, false);  // no longer b's: refused
  EXPECT_TRUE(b.HasError(RejectReason::NotOwner, id));
  Ask(a, id, OwnershipAction::Request);
  EXPECT_EQ(Find(id)->owner, 1u);
  EXPECT_EQ(Find(id)->authority_seq, 3u);
  // A request by the owner changes nothing and tells only it.
  const size_t b_before = b.Of(Body::OwnershipChanged).size();
  Ask(a, id, OwnershipAction::Request);
  EXPECT_EQ(Find(id)->authority_seq, 3u);
  EXPECT_EQ(b.Of(Body::OwnershipChanged).size(), b_before);
  EXPECT_EQ(LastChange(a)->authority_seq(), 3u);
  EXPECT_EQ(counters_.ownership_changes.load(), 3u);
}

TEST_F(RoomOwnershipTest, LateJoinerSeesTheCurrentOwnerAndSequence) {
  RecordingMember a(1), b(2), late(3);
  ASSERT_TRUE(host_->Join(a, 0));
  ASSERT_TRUE(host_->Join(b, 0));
  const uint32_t moved = Base(a) + 1, kept = Base(a) + 2;
  Spawn(a, LocalBox(moved, 1));
  Spawn(a, LocalBox(kept, 1));
  Ask(a, moved, OwnershipAction::HandOver, 2);
  ASSERT_TRUE(host_->Join(late, 0));
  std::map<uint32_t, uint32_t> spawn_owner;
  for (const auto* msg : late.Of(Body::Spawn)) {
    spawn_owner[msg->body_as_Spawn()->container()->entity_id()] =
        msg->body_as_Spawn()->container()->owner();
  }
  EXPECT_EQ(spawn_owner[moved], 2u);
  EXPECT_EQ(spawn_owner[kept], 1u);
  auto changes = late.Of(Body::OwnershipChanged);
  ASSERT_EQ(changes.size(), 1u);  // only the entity whose owner changed
  EXPECT_EQ(changes[0]->body_as_OwnershipChanged()->entity_id(), moved);
  EXPECT_EQ(changes[0]->body_as_OwnershipChanged()->authority_seq(), 1u);
  // After its spawn.
  const auto types = late.Types();
  const auto spawn_at = std::find(types.begin(), types.end(), Body::Spawn);
  const auto change_at = std::find(types.begin(), types.end(), Body::OwnershipChanged);
  EXPECT_LT(spawn_at - types.begin(), change_at - types.begin());
}

TEST_F(RoomOwnershipTest, LeavingOwnersEntities) {
  RecordingMember a(1), b(2);
  ASSERT_TRUE(host_->Join(a, 0));
  ASSERT_TRUE(host_->Join(b, 0));
  const uint32_t plain = Base(a) + 1, kept = Base(a) + 2, released = Base(a) + 3;
  Spawn(a, LocalBox(plain, 1));
  Spawn(a, LocalBox(kept, 1, kPersistent));
  Spawn(a, LocalBox(released, 1));
  Ask(a, released, OwnershipAction::Release);
  // B gained one of A's: it is B's to keep when A leaves.
  Ask(a, plain, OwnershipAction::HandOver, 2);
  b.Clear();
  host_->Leave(a, 3.0);
  ASSERT_NE(Find(plain), nullptr);
  EXPECT_EQ(Find(plain)->owner, 2u);
  ASSERT_NE(Find(kept), nullptr);  // Persistent: the room's, and the others are told
  EXPECT_EQ(Find(kept)->owner, 0u);
  EXPECT_EQ(Find(kept)->authority_seq, 1u);
  ASSERT_NE(LastChange(b), nullptr);
  EXPECT_EQ(LastChange(b)->entity_id(), kept);
  EXPECT_EQ(LastChange(b)->owner(), 0u);
  ASSERT_NE(Find(released), nullptr);  // released to the room: stays though its creator left
  EXPECT_TRUE(b.Of(Body::Despawn).empty());
  // B leaves: its gained, non-persistent entity goes with it.
  host_->Leave(b, 4.0);
  EXPECT_EQ(Find(plain), nullptr);
}

TEST_F(RoomOwnershipTest, HostileRequestsAreRefusedAndCounted) {
  RecordingMember a(1), b(2), spectator(3, /*permissions=*/0);
  ASSERT_TRUE(host_->Join(a, 0));
  ASSERT_TRUE(host_->Join(b, 0));
  ASSERT_TRUE(host_->Join(spectator, 0));
  const uint32_t id = Base(a) + 1;
  Spawn(a, LocalBox(id, 1));
  Ask(b, 0xdead, OwnershipAction::Request);  // unknown id
  EXPECT_TRUE(b.HasError(RejectReason::UnknownEntity, 0xdead));
  Ask(b, id, OwnershipAction::HandOver, 2);  // not b's
  EXPECT_TRUE(b.HasError(RejectReason::NotOwner, id));
  Ask(b, id, OwnershipAction::Release);
  Ask(b, id, OwnershipAction::SetTakeover, 0, true);
  EXPECT_EQ(b.errors.size(), 4u);
  Ask(a, id, OwnershipAction::HandOver, 77);  // not in the room
  EXPECT_TRUE(a.HasError(RejectReason::UnknownPlayer, id));
  Ask(a, id, OwnershipAction::HandOver, 0);
  Ask(a, id, OwnershipAction::HandOver, 1);  // itself
  EXPECT_TRUE(a.HasError(RejectReason::InvalidMessage, id));
  Ask(a, id, OwnershipAction::HandOver, 3);  // a spectator's token may not own
  EXPECT_TRUE(a.HasError(RejectReason::NotPermitted, id));
  Ask(spectator, id, OwnershipAction::Request);
  EXPECT_TRUE(spectator.HasError(RejectReason::NotPermitted, id));
  Ask(a, id, static_cast<OwnershipAction>(200));
  EXPECT_EQ(a.errors.size(), 5u);
  EXPECT_EQ(Find(id)->owner, 1u);
  EXPECT_EQ(Find(id)->authority_seq, 0u);
  EXPECT_TRUE(b.Of(Body::OwnershipChanged).empty());
  EXPECT_EQ(host_->ownership_stats().refused, 10u);
}

// A body its owner simulates locally (mirrored in PhyS) is offloaded on release, at its pose and
// the owner's velocities, and reclaimed by a request, at PhyS's pose and velocities; no despawn.
TEST_F(RoomOwnershipTest, ReleaseOffloadsADynamicBodyToPhySAndARequestReclaimsIt) {
  RecordingMember a(1), b(2);
  ASSERT_TRUE(host_->Join(a, 0));
  ASSERT_TRUE(host_->Join(b, 0));
  EntitySpec box = DynamicBox(Base(a) + 1, {0, 1, 0}, {0.1f, 0.1f, 0.1f}, 1.0f);
  box.owner = 1;  // not Offloaded: A simulates it, PhyS mirrors it
  Spawn(a, box);
  const uint32_t id = box.id;
  ASSERT_EQ(Find(id)->physics, PhysicsRole::kMirrored);
  ScriptedPhysics& phys = *placement_.links.at(0);
  Move(a, id, 2);
  const auto release = [&](RecordingMember& m, Vec3f linear, Vec3f angular) {
    flatbuffers::FlatBufferBuilder fbb(96);
    const schema::Vec3 lin(linear.x, linear.y, linear.z), ang(angular.x, angular.y, angular.z);
    FinishControl(fbb, schema::CreateOwnershipRequest(fbb, id, OwnershipAction::Release, 0, false,
                                                      &lin, &ang));
    host_->Ownership(m, *schema::GetControlMessage(fbb.GetBufferPointer())->body_as_OwnershipRequest(),
                     3.0);
  };
  release(a, {std::nanf(""), 0, 0}, {});
  EXPECT_TRUE(a.HasError(RejectReason::InvalidMessage, id));
  release(a, {1e6f, 0, 0}, {});
  EXPECT_EQ(a.errors.size(), 2u);
  EXPECT_EQ(Find(id)->owner, 1u);
  release(a, {1, 0, 0.5f}, {0, 2, 0});
  ASSERT_EQ(a.errors.size(), 2u);
  EXPECT_EQ(Find(id)->owner, 0u);
  EXPECT_EQ(Find(id)->physics, PhysicsRole::kSimulated);
  EXPECT_EQ(phys.removed, std::vector<uint32_t>{id});
  ASSERT_FALSE(phys.added.empty());
  EXPECT_EQ(phys.added.back(), std::make_pair(id, PhysicsRole::kSimulated));
  EXPECT_EQ(phys.restored_state.at(id).position.x, 2.f);
  EXPECT_EQ(phys.restored_linear.at(id).z, 0.5f);
  const auto* off = LastChange(b);
  ASSERT_NE(off, nullptr);
  EXPECT_TRUE(off->simulated());
  EXPECT_EQ(off->owner(), 0u);
  EXPECT_EQ(off->pose()->position().x(), 2.f);
  EXPECT_EQ(off->linear_velocity()->x(), 1.f);
  EXPECT_EQ(off->angular_velocity()->y(), 2.f);
  EXPECT_TRUE(b.Of(Body::Despawn).empty());
  // PhyS moves it; B reclaims it where PhyS has it, with PhyS's velocities.
  PhysicsLink::StepOutput out;
  out.moved.push_back({{id, {2.5f, 1, 1}, {0, 0, 0, 1}}, {1, 0, 0.5f}, {0, 2, 0}});
  host_->ApplyPhysics(out, 3.5);
  EXPECT_EQ(Find(id)->state.position.x, 2.5f);
  Ask(b, id, OwnershipAction::Request, 0, false, 4.0);
  ASSERT_TRUE(b.errors.empty());
  EXPECT_EQ(Find(id)->owner, 2u);
  EXPECT_EQ(Find(id)->physics, PhysicsRole::kMirrored);
  EXPECT_EQ(phys.added.back(), std::make_pair(id, PhysicsRole::kMirrored));
  EXPECT_EQ(phys.driven.at(id).position.x, 2.5f);
  const auto* back = LastChange(a);
  EXPECT_FALSE(back->simulated());
  EXPECT_EQ(back->owner(), 2u);
  EXPECT_EQ(back->authority_seq(), 2u);
  EXPECT_EQ(back->pose()->position().x(), 2.5f);
  EXPECT_EQ(back->linear_velocity()->z(), 0.5f);
  // PhyS's output for it no longer counts; B's states drive it.
  out.moved[0].state.position.x = 9;
  host_->ApplyPhysics(out, 4.5);
  EXPECT_EQ(Find(id)->state.position.x, 2.5f);
  Move(b, id, 3);
  EXPECT_EQ(Find(id)->state.position.x, 3.f);
  EXPECT_EQ(phys.driven.at(id).position.x, 3.f);
  // A body PhyS does not simulate with physics of its own is released as before.
  const uint32_t plain = Base(b) + 1;
  Spawn(b, LocalBox(plain, 2));
  Ask(b, plain, OwnershipAction::Release);
  EXPECT_EQ(Find(plain)->physics, PhysicsRole::kNone);
  EXPECT_FALSE(LastChange(a)->simulated());
  // Offloaded again, it is the room's: it stays when its creator leaves.
  Ask(b, id, OwnershipAction::Release, 0, false, 5.0);
  EXPECT_EQ(Find(id)->physics, PhysicsRole::kSimulated);
  host_->Leave(a, 6.0);
  ASSERT_NE(Find(id), nullptr);
  EXPECT_EQ(Find(id)->owner, 0u);
}

TEST_F(RoomOwnershipTest, RequestsOverTheRateAreRefused) {
  config_.budgets.ownership_requests_per_s_per_player = 10;  // burst 20
  Rebuild();
  RecordingMember a(1), b(2);
  uint32_t id = 0;
  ASSERT_NO_FATAL_FAILURE(JoinBothAndSpawnBox(a, b, &id));
  Ask(a, id, OwnershipAction::SetTakeover, 0, true);
  for (int i = 0; i < 100; ++i) Ask(b, id, OwnershipAction::Request, 0, false, 1.0);
  size_t limited = 0;
  for (const auto& e : b.errors) limited += e.first == RejectReason::RateLimited;
  EXPECT_EQ(limited, 80u);
  // The budget refills with time.
  Ask(b, id, OwnershipAction::HandOver, 1, false, 5.0);
  EXPECT_EQ(Find(id)->owner, 1u);
}

}  // namespace
}  // namespace edgephys
