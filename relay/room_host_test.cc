// Room rules without sockets: RoomHost driven through recording MemberLinks and a scripted
// PhysicsLink. What a member is sent is decoded from the very bytes RoomHost queued.
#include "relay/room_host_testing.h"

namespace edgephys {
namespace {

using namespace room_host_testing;  // NOLINT: the test doubles

TEST_F(RoomHostTest, JoinSendsJoinedThenRoomStateThenEveryEntityAndTellsTheOthers) {
  RecordingMember a(7), b(8);
  ASSERT_TRUE(host_->Join(a, 0));
  Spawn(a, LocalBox(Base(a) + 1, 7));
  Spawn(a, LocalBox(Base(a) + 2, 7));
  ASSERT_TRUE(a.errors.empty());
  a.Clear();
  ASSERT_TRUE(host_->Join(b, 0));

  ASSERT_EQ(b.Types(), (std::vector<Body>{Body::Joined, Body::RoomState, Body::Spawn, Body::Spawn}));
  const auto* joined = b.Of(Body::Joined)[0]->body_as_Joined();
  EXPECT_EQ(joined->player_id(), 8u);
  EXPECT_EQ(joined->entity_id_base(), Base(b));
  EXPECT_NE(Base(a), Base(b));
  const auto* state = b.Of(Body::RoomState)[0]->body_as_RoomState();
  EXPECT_EQ(state->entity_count(), 2u);
  EXPECT_EQ(state->players()->size(), 2u);
  // Replication starts after Joined is queued (states wait for its acknowledgement).
  EXPECT_EQ(b.replication_starts, 1);
  EXPECT_EQ(b.start_after_messages, 1u);
  ASSERT_EQ(a.Of(Body::PlayerJoined).size(), 1u);
  EXPECT_EQ(a.Of(Body::PlayerJoined)[0]->body_as_PlayerJoined()->player_id(), 8u);
  EXPECT_TRUE(b.Of(Body::PlayerJoined).empty());  // not told about itself
}

TEST_F(RoomHostTest, AFullRoomRefusesTheJoinAndKeepsItsMembers) {
  RecordingMember a(1), b(2), c(3), d(4);
  for (RecordingMember* m : {&a, &b, &c}) ASSERT_TRUE(host_->Join(*m, 0));
  EXPECT_FALSE(host_->Join(d, 0));
  EXPECT_TRUE(d.HasError(RejectReason::RoomFull, 0));
  EXPECT_EQ(host_->room().size(), 3u);
  EXPECT_EQ(host_->FindMember(4), nullptr);
  EXPECT_TRUE(a.Of(Body::PlayerJoined).size() == 2u);  // b and c, never d
}

TEST_F(RoomHostTest, SpawnRulesRefuseWhatThePlayerIsNotEntitledTo) {
  RecordingMember a(1), b(2), viewer(3, /*permissions=*/0);
  for (RecordingMember* m : {&a, &b, &viewer}) ASSERT_TRUE(host_->Join(*m, 0));
  Spawn(a, LocalBox(Base(b) + 1, 1));  // b's id block
  EXPECT_TRUE(a.HasError(RejectReason::NotOwner, Base(b) + 1));
  Spawn(a, LocalBox(Base(a) + 1, 2));  // claims b as owner
  EXPECT_TRUE(a.HasError(RejectReason::NotOwner, Base(a) + 1));
  Spawn(viewer, LocalBox(Base(viewer) + 1, 3));
  EXPECT_TRUE(viewer.HasError(RejectReason::NotOwner, Base(viewer) + 1));
  EntitySpec nan = LocalBox(Base(a) + 9, 1);
  nan.position.x = std::numeric_limits<float>::quiet_NaN();
  Spawn(a, nan);
  EXPECT_TRUE(a.HasError(RejectReason::InvalidMessage, Base(a) + 9));
  Spawn(a, LocalBox(Base(a) + 1, 1));
  Spawn(a, LocalBox(Base(a) + 1, 1));
  EXPECT_TRUE(a.HasError(RejectReason::DuplicateEntity, Base(a) + 1));
  for (uint32_t i = 2; i <= 5; ++i) Spawn(a, LocalBox(Base(a) + i, 1));
  EXPECT_TRUE(a.HasError(RejectReason::EntityLimit, Base(a) + 5));  // limit 4
  a.spawns_left_ = 0;
  Spawn(a, LocalBox(Base(a) + 6, 1));
  EXPECT_TRUE(a.HasError(RejectReason::RateLimited, Base(a) + 6));
  EXPECT_EQ(host_->room().entities().size(), 4u);
  EXPECT_EQ(counters_.entities.load(), 4);
  // Only accepted spawns reached the others, and never their sender.
  EXPECT_EQ(b.Of(Body::Spawn).size(), 4u);
  EXPECT_TRUE(a.Of(Body::Spawn).empty());
}

TEST_F(RoomHostTest, OnlyTheOwnerMovesAnEntityAndBadStatesAreDroppedAndCounted) {
  RecordingMember a(1), b(2);
  uint32_t id = 0;
  ASSERT_NO_FATAL_FAILURE(JoinBothAndSpawnBox(a, b, &id));
  const uint32_t version = Find(id)->version;

  host_->ApplyStates(b, StatePayload({{id, {9, 9, 9}, {0, 0, 0, 1}}}), 2.0);
  EXPECT_EQ(b.dropped_updates, (std::vector<DropReason>{DropReason::kNotOwner}));
  EXPECT_EQ(Find(id)->state.position.x, 1.0f);

  const float nan = std::numeric_limits<float>::quiet_NaN();
  host_->ApplyStates(a, StatePayload({{id, {nan, 0, 0}, {0, 0, 0, 1}}}), 2.0);
  EXPECT_EQ(a.dropped_updates, (std::vector<DropReason>{DropReason::kInvalidValue}));
  host_->ApplyStates(a, StatePayload({{Base(b) + 3, {0, 0, 0}, {0, 0, 0, 1}}}), 2.0);
  EXPECT_EQ(a.dropped_updates.back(), DropReason::kUnknownEntity);
  const uint8_t garbage[] = {1, 0xff, 0xff};
  host_->ApplyStates(a, garbage, 2.0);
  EXPECT_EQ(a.dropped_payloads, (std::vector<DropReason>{DropReason::kMalformed}));

  host_->ApplyStates(a, StatePayload({{id, {4, 5, 6}, {0, 0, 0, 1}}}), 3.0);
  EXPECT_EQ(Find(id)->state.position.x, 4.0f);
  EXPECT_EQ(Find(id)->version, version + 1);
  EXPECT_EQ(Find(id)->changed_at, 3.0);
}

TEST_F(RoomHostTest, AStateThatOvertakesItsSpawnIsHeldAndAppliedWhenTheSpawnArrives) {
  RecordingMember a(1);
  ASSERT_TRUE(host_->Join(a, 0));
  const uint32_t id = Base(a) + 4;
  host_->ApplyStates(a, StatePayload({{id, {7, 7, 7}, {0, 0, 0, 1}}}), 1.0);
  EXPECT_TRUE(a.dropped_updates.empty());
  EXPECT_EQ(Find(id), nullptr);
  Spawn(a, LocalBox(id, 1));
  ASSERT_NE(Find(id), nullptr);
  EXPECT_EQ(Find(id)->state.position.x, 7.0f);  // the later state, not the spawn's transform
}

TEST_F(RoomHostTest, LeavingDespawnsTheLeaversEntitiesExceptPersistentOnesWhichPassToTheRoom) {
  RecordingMember a(1), b(2);
  ASSERT_TRUE(host_->Join(a, 0));
  ASSERT_TRUE(host_->Join(b, 0));
  const uint32_t gone = Base(a) + 1, kept = Base(a) + 2;
  Spawn(a, LocalBox(gone, 1));
  Spawn(a, LocalBox(kept, 1, kPersistent));
  b.Clear();
  host_->Leave(a, 5.0);

  EXPECT_EQ(Find(gone), nullptr);
  ASSERT_NE(Find(kept), nullptr);
  EXPECT_EQ(Find(kept)->owner, 0u);
  ASSERT_EQ(b.Of(Body::Despawn).size(), 1u);
  EXPECT_EQ(b.Of(Body::Despawn)[0]->body_as_Despawn()->entity_id(), gone);
  EXPECT_EQ(b.forgotten, (std::vector<uint32_t>{gone}));  // baselines of the gone entity dropped
  ASSERT_EQ(b.Of(Body::PlayerLeft).size(), 1u);
  EXPECT_EQ(counters_.entities.load(), 1);

  // A late joiner is told the persistent entity belongs to the room now.
  RecordingMember c(3);
  ASSERT_TRUE(host_->Join(c, 6.0));
  ASSERT_EQ(c.Of(Body::Spawn).size(), 1u);
  EXPECT_EQ(c.Of(Body::Spawn)[0]->body_as_Spawn()->container()->owner(), 0u);
  // And the persistent entity's id block is not handed out again.
  EXPECT_NE(Base(c), kept / kEntityIdBlock * kEntityIdBlock);

  // A stale link of a player (an older session) does not remove the current member.
  RecordingMember b_old(2);
  host_->Leave(b_old, 7.0);
  EXPECT_NE(host_->FindMember(2), nullptr);
  host_->Leave(b, 8.0);
  host_->Leave(c, 9.0);
  EXPECT_FALSE(host_->IdleExpired(9.0 + config_.idle_ttl_s - 1));
  EXPECT_TRUE(host_->IdleExpired(9.0 + config_.idle_ttl_s));
}

TEST_F(RoomHostTest, OnlyTheOwnerDespawnsAndEveryMemberForgetsTheEntity) {
  RecordingMember a(1), b(2);
  uint32_t id = 0;
  ASSERT_NO_FATAL_FAILURE(JoinBothAndSpawnBox(a, b, &id));
  host_->Despawn(b, id);
  EXPECT_TRUE(b.HasError(RejectReason::NotOwner, id));
  host_->Despawn(b, 12345);
  EXPECT_TRUE(b.HasError(RejectReason::UnknownEntity, 12345));
  ASSERT_NE(Find(id), nullptr);
  b.Clear();
  host_->Despawn(a, id);
  EXPECT_EQ(Find(id), nullptr);
  EXPECT_EQ(b.Of(Body::Despawn).size(), 1u);
  EXPECT_TRUE(a.Of(Body::Despawn).empty());
  EXPECT_EQ(a.forgotten, (std::vector<uint32_t>{id}));
  EXPECT_EQ(b.forgotten, (std::vector<uint32_t>{id}));
  Spawn(a, LocalBox(id, 1));  // the count went back down: the id and a slot are free again
  EXPECT_TRUE(a.errors.empty());
}

TEST_F(RoomHostTest, GrabsGoToPhysSAndTheAnswerIsBroadcastOrReturnedToTheRequester) {
  RecordingMember a(1), b(2);
  ASSERT_TRUE(host_->Join(a, 0));
  ASSERT_TRUE(host_->Join(b, 0));
  const uint32_t hand = Base(a) + 1, cube = Base(a) + 2, local = Base(a) + 3;
  EntitySpec hand_spec = LocalBox(hand, 1, kHand);
  hand_spec.colliders.push_back(SphereCollider(0.1f));
  hand_spec.colliders.back().is_trigger = true;
  hand_spec.rigid_body = RigidBodySpec{};
  hand_spec.rigid_body->kinematic = true;
  Spawn(a, hand_spec);
  EntitySpec cube_spec = DynamicBox(cube, {0, 1, 0}, {0.1f, 0.1f, 0.1f}, 1.0f);
  cube_spec.owner = 1;
  cube_spec.flags = kOffloaded;
  Spawn(a, cube_spec);
  Spawn(a, LocalBox(local, 1));
  ASSERT_TRUE(a.errors.empty());
  ASSERT_EQ(placement_.links.size(), 1u);
  ScriptedPhysics& phys = *placement_.links[0];
  EXPECT_EQ(Find(hand)->physics, PhysicsRole::kMirrored);
  EXPECT_EQ(Find(cube)->physics, PhysicsRole::kSimulated);
  EXPECT_EQ(Find(cube)->owner, 0u);  // PhyS is the authority
  // The creator is told too (with owner 0), since it no longer owns it.
  ASSERT_EQ(a.Of(Body::Spawn).size(), 1u);
  EXPECT_EQ(a.Of(Body::Spawn)[0]->body_as_Spawn()->container()->owner(), 0u);

  host_->Grab(a, local, hand);
  EXPECT_TRUE(a.HasError(RejectReason::GrabRefused, local));
  host_->Grab(b, cube, hand);
  EXPECT_TRUE(b.HasError(RejectReason::NotOwner, hand));
  host_->Grab(a, cube, hand);
  ASSERT_EQ(phys.grabs.size(), 1u);
  EXPECT_FALSE(phys.grabs[0].force);

  PhysicsLink::StepOutput out;
  out.grabs.push_back({cube, hand, true, ""});
  a.Clear();
  b.Clear();
  host_->ApplyPhysics(out, 2.0);
  EXPECT_EQ(Find(cube)->held_by, hand);
  for (RecordingMember* m : {&a, &b}) {
    ASSERT_EQ(m->Of(Body::PhysicsEvent).size(), 1u);
    EXPECT_EQ(m->Of(Body::PhysicsEvent)[0]->body_as_PhysicsEvent()->kind(),
              schema::PhysicsEventKind::Grabbed);
  }
  EXPECT_EQ(Find(cube)->interacted_at, 2.0);

  host_->Release(b, cube, 3.0);
  EXPECT_TRUE(b.HasError(RejectReason::NotOwner, cube));
  host_->Release(a, cube, 3.0);
  EXPECT_EQ(phys.released, (std::vector<uint32_t>{cube}));
  EXPECT_EQ(Find(cube)->held_by, 0u);
  EXPECT_EQ(b.Of(Body::PhysicsEvent).back()->body_as_PhysicsEvent()->kind(),
            schema::PhysicsEventKind::Released);

  // A refused grab goes back to the requester only.
  host_->Grab(a, cube, hand);
  out.grabs = {{cube, hand, false, "not hovering"}};
  b.Clear();
  host_->ApplyPhysics(out, 4.0);
  EXPECT_TRUE(a.HasError(RejectReason::GrabRefused, cube));
  EXPECT_TRUE(b.errors.empty());
  EXPECT_TRUE(b.Of(Body::PhysicsEvent).empty());
}

TEST_F(RoomHostTest, PhysicsOutputMovesOnlySimulatedEntitiesAndReportsOnlyWantedContacts) {
  RecordingMember a(1);
  ASSERT_TRUE(host_->Join(a, 0));
  const uint32_t c1 = Base(a) + 1, c2 = Base(a) + 2, local = Base(a) + 3;
  for (uint32_t id : {c1, c2}) {
    EntitySpec s = DynamicBox(id, {0, 1, 0}, {0.1f, 0.1f, 0.1f}, 1.0f);
    s.owner = 1;
    s.flags = kOffloaded;
    Spawn(a, s);
  }
  Spawn(a, LocalBox(local, 1));
  PhysicsLink::StepOutput out;
  out.moved.push_back({{c1, {0, 0.5f, 0}, {0, 0, 0, 1}}, {0, -1, 0}, {}});
  out.moved.push_back({{local, {5, 5, 5}, {0, 0, 0, 1}}, {}, {}});  // not PhyS's to move
  out.events.push_back({physics::PhysicsEventType::kCollisionEnter, {}, c1, c2, 1});
  out.events.push_back({physics::PhysicsEventType::kGuardReset, {}, c2, 0, 1});
  a.Clear();
  host_->ApplyPhysics(out, 2.0);
  EXPECT_EQ(Find(c1)->state.position.y, 0.5f);
  EXPECT_EQ(Find(c1)->linear_velocity.y, -1.0f);
  EXPECT_EQ(Find(local)->state.position.x, 1.0f);
  // The contact of two boxes nobody asked about stays inside PhyS; the guard reset does not.
  ASSERT_EQ(a.Of(Body::PhysicsEvent).size(), 1u);
  EXPECT_EQ(a.Of(Body::PhysicsEvent)[0]->body_as_PhysicsEvent()->kind(),
            schema::PhysicsEventKind::GuardReset);
  EXPECT_EQ(counters_.guard_resets.load(), 1u);
  EXPECT_EQ(Find(c1)->touching, 0u);
}

TEST_F(RoomHostTest, FailOverRebuildsPhysSElsewhereFromWhatTheRoomHolds) {
  RecordingMember a(1);
  ASSERT_TRUE(host_->Join(a, 0));
  const uint32_t hand = Base(a) + 1, cube = Base(a) + 2, ball = Base(a) + 3;
  EntitySpec hand_spec = LocalBox(hand, 1, kHand);
  hand_spec.colliders.push_back(SphereCollider(0.1f));
  Spawn(a, hand_spec);
  for (uint32_t id : {cube, ball}) {
    EntitySpec s = DynamicBox(id, {0, 1, 0}, {0.1f, 0.1f, 0.1f}, 1.0f);
    s.owner = 1;
    s.flags = kOffloaded;
    Spawn(a, s);
  }
  ScriptedPhysics& first = *placement_.links.at(0);
  host_->Grab(a, cube, hand);
  PhysicsLink::StepOutput out;
  out.grabs.push_back({cube, hand, true, ""});
  out.moved.push_back({{ball, {3, 0.2f, 0}, {0, 0, 0, 1}}, {2, 0, 0}, {}});
  host_->ApplyPhysics(out, 1.0);
  host_->ApplyStates(a, StatePayload({{hand, {0.5f, 1, 0}, {0, 0, 0, 1}}}), 1.0);

  EXPECT_EQ(host_->PreparePhysics(1.5), &first);  // healthy: kept
  const uint32_t first_worker = first.worker();
  first.healthy = false;  // `first` is destroyed by the failover
  PhysicsLink* second_link = host_->PreparePhysics(2.0);
  ASSERT_EQ(placement_.links.size(), 2u);
  ScriptedPhysics& second = *placement_.links[1];
  EXPECT_EQ(second_link, &second);
  EXPECT_EQ(placement_.excluded.back(), first_worker);  // not back on the failed worker
  // Every physics entity re-added in spawn order; simulated ones restored with their last
  // state and velocity, mirrored ones driven to theirs; the grab re-established by force.
  ASSERT_EQ(second.added.size(), 3u);
  EXPECT_EQ(second.added[0].first, hand);
  EXPECT_EQ(second.added[1].first, cube);
  EXPECT_EQ(second.added[2].first, ball);
  EXPECT_EQ(second.restored_state.at(ball).position.x, 3.0f);
  EXPECT_EQ(second.restored_linear.at(ball).x, 2.0f);
  EXPECT_EQ(second.driven.at(hand).position.x, 0.5f);
  EXPECT_EQ(second.restored_state.at(hand).position.x, 0.5f);  // teleported there first
  ASSERT_EQ(second.grabs.size(), 1u);
  EXPECT_TRUE(second.grabs[0].force);
  EXPECT_EQ(second.grabs[0].entity, cube);
  EXPECT_EQ(counters_.physics_failovers.load(), 1u);
  EXPECT_EQ(host_->room().entities().size(), 3u);  // nothing lost
}

// A soft body fails over with the particles the relay last received (its deformed state), not
// with its spawn shape; a soft body PhyS never reported is re-added from its spawn alone.
TEST_F(RoomHostTest, FailOverRestoresASoftBodyFromItsLastParticles) {
  RecordingMember a(1);
  ASSERT_TRUE(host_->Join(a, 0));
  const uint32_t jelly = Base(a) + 1, fresh = Base(a) + 2;
  for (uint32_t id : {jelly, fresh}) {
    EntitySpec s;
    s.id = id;
    s.owner = 1;
    s.flags = kOffloaded;
    s.soft_body = SoftBodySpec{};
    s.soft_body->particles = {0, 1, 0, 0.1f, 1, 0, 0, 1.1f, 0, 0, 1, 0.1f};
    s.soft_body->masses = {0.1f, 0.1f, 0.1f, 0.1f};
    s.soft_body->springs = {0, 1, 0, 2, 0, 3, 1, 2};
    s.soft_body->stiffness = 100;
    s.soft_body->damping = 0.1f;
    Spawn(a, s);
  }
  ASSERT_EQ(host_->room().entities().size(), 2u) << "the soft bodies were refused";
  ScriptedPhysics& first = *placement_.links.at(0);
  PhysicsLink::StepOutput out;
  const std::vector<Vec3f> squashed = {{0, 0.5f, 0}, {0.12f, 0.5f, 0}, {0, 0.52f, 0}, {0, 0.5f, 0.12f}};
  // Reported in two parts, as PhyS may cut a large body.
  out.soft.push_back({jelly, 4, 0, {squashed[0], squashed[1]}});
  out.soft.push_back({jelly, 4, 2, {squashed[2], squashed[3]}});
  host_->ApplyPhysics(out, 1.0);
  first.healthy = false;
  host_->PreparePhysics(2.0);
  ASSERT_EQ(placement_.links.size(), 2u);
  ScriptedPhysics& second = *placement_.links[1];
  ASSERT_EQ(second.added.size(), 2u);
  ASSERT_EQ(second.restored_nodes.count(jelly), 1u);
  const std::vector<Vec3f>& got = second.restored_nodes.at(jelly);
  ASSERT_EQ(got.size(), squashed.size());
  for (size_t i = 0; i < got.size(); ++i) {
    EXPECT_EQ(got[i].x, squashed[i].x);
    EXPECT_EQ(got[i].y, squashed[i].y);
    EXPECT_EQ(got[i].z, squashed[i].z);
  }
  EXPECT_EQ(second.restored_state.count(jelly), 0u);  // no rigid pose restore for a soft body
  EXPECT_EQ(second.restored_nodes.count(fresh), 0u);  // nothing reported: its spawn shape
  EXPECT_EQ(counters_.physics_failovers.load(), 1u);
}

// A room "r" with shared encoding on or off, and a member (player 7) that has not joined yet.
struct OneMemberRoom {
  explicit OneMemberRoom(bool shared)
      : config(WithSharedEncoding(shared)),
        host("r", config, RoomHostEnv{&limits, &counters, &placement}, 0.0) {}
  static RoomConfig WithSharedEncoding(bool shared) {
    RoomConfig c;
    c.replication.shared_encoding = shared;
    return c;
  }
  AbuseLimits limits;
  RelayCounters counters;
  ScriptedPlacement placement;
  RoomConfig config;
  RoomHost host;
  RecordingMember a{7};
};

// The state format a room tells its members follows the shared-encoding flag, and a format-9
// room's tick prepares every entity's shared version (and nothing of the kind otherwise).
TEST(RoomHostSharedEncoding, JoinedCarriesTheFormatAndBeginTickPreparesSharedVersions) {
  for (bool shared : {false, true}) {
    OneMemberRoom r(shared);
    auto& [limits, counters, placement, config, host, a] = r;
    ASSERT_TRUE(host.Join(a, 0));
    const auto* joined = a.Of(Body::Joined)[0]->body_as_Joined();
    EXPECT_EQ(joined->state_format(), shared ? kSharedDeltaStateFormat : kDeltaStateFormat);
    auto msg = SpawnMessage(LocalBox(host.room().members().at(7).slot * kEntityIdBlock + 1, 7));
    host.Spawn(a, msg, *schema::GetControlMessage(msg.data())->body_as_Spawn(), 0.5);
    std::vector<MemberLink*> receivers;
    host.BeginTick(1.0, &receivers);
    ASSERT_EQ(host.room().entities().size(), 1u);
    const Entity& e = host.room().entities().begin()->second;
    EXPECT_TRUE(e.prepared_valid);
    EXPECT_EQ(e.shared != nullptr, shared);
    EXPECT_EQ(host.room().shared_encoding() != nullptr, shared);
    if (shared) {
      EXPECT_EQ(e.shared->room(), host.room().shared_encoding());
      EXPECT_EQ(e.shared->current_tick(), host.room().shared_encoding()->tick());
    }
  }
}

// The format a room tells its members: format 9 by default, format 2 with shared_encoding off.
TEST(RoomHostFormats, JoinedCarriesFormat9ByDefaultAndFormat2WithoutSharedEncoding) {
  EXPECT_TRUE(RoomConfig().replication.shared_encoding);  // the default
  for (bool shared : {true, false}) {
    const uint8_t want = shared ? kSharedDeltaStateFormat : kDeltaStateFormat;
    OneMemberRoom r(shared);
    auto& [limits, counters, placement, config, host, a] = r;
    ASSERT_TRUE(host.Join(a, 0));
    const auto* joined = a.Of(Body::Joined)[0]->body_as_Joined();
    EXPECT_EQ(joined->state_format(), want) << shared;
    EXPECT_EQ(UsesSharedEncoding(config.replication), shared);
    std::vector<MemberLink*> receivers;
    host.BeginTick(1.0, &receivers);  // a format-9 room makes its shared state on its first tick
    EXPECT_EQ(host.room().shared_encoding() != nullptr, shared);
  }
}

TEST_F(RoomHostTest, BeginTickPicksReadyMembersAndSchedulesTheNextTick) {
  RecordingMember a(1), b(2);
  ASSERT_TRUE(host_->Join(a, 0));
  ASSERT_TRUE(host_->Join(b, 0));
  b.ready = false;  // Joined not acknowledged yet
  EXPECT_TRUE(host_->TickDue(0.0));
  std::vector<MemberLink*> receivers;
  host_->BeginTick(0.0, &receivers);
  EXPECT_EQ(receivers, (std::vector<MemberLink*>{&a}));
  EXPECT_FALSE(host_->TickDue(0.5 / config_.tick_rate_hz));
  EXPECT_TRUE(host_->TickDue(1.0 / config_.tick_rate_hz));
}

TEST_F(RoomHostTest, AJoinerWhoseReliableQueueOverflowsStopsReceivingTheBacklog) {
  RecordingMember a(1), b(2);
  ASSERT_TRUE(host_->Join(a, 0));
  for (uint32_t i = 1; i <= 4; ++i) Spawn(a, LocalBox(Base(a) + i, 1));
  b.reliable_capacity_ = 3;  // Joined, RoomState, one Spawn
  ASSERT_TRUE(host_->Join(b, 0));
  EXPECT_TRUE(b.overflowed);
  EXPECT_EQ(b.Of(Body::Spawn).size(), 1u);  // stopped at the first refusal, not one per entity
}

}  // namespace
}  // namespace edgephys

namespace edgephys {
namespace {

TEST_F(RoomHostTest, ARoomWithPhysicsOffRefusesPhysicsComponentsButNotPlainEntities) {
  config_.physics = false;  // the admin API's {"physics": false}
  Rebuild();
  RecordingMember a(1);
  ASSERT_TRUE(host_->Join(a, 0));
  EntitySpec cube = DynamicBox(Base(a) + 1, {0, 1, 0}, {0.1f, 0.1f, 0.1f}, 1.0f);
  cube.owner = 1;
  cube.flags = kOffloaded;
  Spawn(a, cube);
  ASSERT_EQ(a.errors.size(), 1u);
  EXPECT_EQ(a.errors[0].first, schema::RejectReason::InvalidContainer);
  EXPECT_EQ(Find(Base(a) + 1), nullptr);
  EXPECT_TRUE(placement_.links.empty()) << "no PhyS made for a room with physics off";
  Spawn(a, LocalBox(Base(a) + 2, 1));
  EXPECT_EQ(a.errors.size(), 1u);
  EXPECT_NE(Find(Base(a) + 2), nullptr);
}

}  // namespace
}  // namespace edgephys
