// Room rules without sockets: RoomHost driven through recording MemberLinks and a scripted
// PhysicsLink. What a member is sent is decoded from the very bytes RoomHost queued.
#include "relay/room_host.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <map>

#include "protocol/container_builder.h"
#include "protocol/handshake.h"
#include "protocol/join_token.h"

namespace edgephys {
namespace {

using schema::Body;
using schema::RejectReason;
constexpr uint32_t kPersistent = static_cast<uint32_t>(schema::EntityFlags::Persistent);
constexpr uint32_t kOffloaded = static_cast<uint32_t>(schema::EntityFlags::Offloaded);
constexpr uint32_t kHand = static_cast<uint32_t>(schema::EntityFlags::Hand);

// A member that records everything the room sends it.
class RecordingMember final : public MemberLink {
 public:
  explicit RecordingMember(uint32_t player, uint32_t permissions = kPermissionSpawn)
      : player_(player), permissions_(permissions) {}

  uint32_t player_id() const override { return player_; }
  uint32_t permissions() const override { return permissions_; }
  bool AllowSpawn(double) override { return spawns_left_ == 0 ? false : (--spawns_left_, true); }
  bool SendReliable(std::span<const uint8_t> message) override {
    if (reliable_capacity_ == 0) {
      overflowed = true;
      return false;
    }
    --reliable_capacity_;
    reliable.emplace_back(message.begin(), message.end());
    return true;
  }
  void SendError(RejectReason reason, uint32_t entity_id, std::string_view) override {
    errors.push_back({reason, entity_id});
  }
  void DropPayload(DropReason reason) override { dropped_payloads.push_back(reason); }
  void DropUpdate(DropReason reason) override { dropped_updates.push_back(reason); }
  void StartReplication(const ReplicationConfig&) override {
    ++replication_starts;
    start_after_messages = reliable.size();
  }
  bool ReadyForStates() const override { return ready; }
  void Replicate(const EntityTable&, double, RelayCounters&, bool) override {}
  void FlushReplication() override {}
  void Forget(uint32_t entity_id) override { forgotten.push_back(entity_id); }

  // The recorded reliable messages of one body type, in order.
  std::vector<const schema::ControlMessage*> Of(Body type) const {
    std::vector<const schema::ControlMessage*> out;
    for (const auto& m : reliable) {
      const auto* msg = schema::GetControlMessage(m.data());
      if (msg->body_type() == type) out.push_back(msg);
    }
    return out;
  }
  std::vector<Body> Types() const {
    std::vector<Body> out;
    for (const auto& m : reliable) out.push_back(schema::GetControlMessage(m.data())->body_type());
    return out;
  }
  bool HasError(RejectReason reason, uint32_t entity) const {
    for (const auto& e : errors) {
      if (e.first == reason && e.second == entity) return true;
    }
    return false;
  }
  void Clear() {
    reliable.clear();
    errors.clear();
    forgotten.clear();
    dropped_updates.clear();
  }

  std::vector<std::vector<uint8_t>> reliable;
  std::vector<std::pair<RejectReason, uint32_t>> errors;
  std::vector<DropReason> dropped_payloads, dropped_updates;
  std::vector<uint32_t> forgotten;
  int replication_starts = 0;
  size_t start_after_messages = 0;
  bool ready = true;
  bool overflowed = false;
  size_t reliable_capacity_ = 1u << 20;
  int spawns_left_ = 1 << 20;

 private:
  uint32_t player_;
  uint32_t permissions_;
};

// A PhyS link that records the commands it is given and is told what to answer.
class ScriptedPhysics final : public PhysicsLink {
 public:
  explicit ScriptedPhysics(uint32_t worker) : worker_(worker) {}
  Status Add(const schema::Container& c, PhysicsRole role) override {
    if (refuse_adds) return Status::InvalidArgument("invalid physics components", "scripted");
    added.push_back({c.entity_id(), role});
    return Status::Ok();
  }
  void Remove(uint32_t id) override { removed.push_back(id); }
  void Drive(uint32_t id, const EntityState& s) override { driven[id] = s; }
  void RequestGrab(uint32_t entity, uint32_t hand, bool force) override {
    grabs.push_back({entity, hand, force});
  }
  void Release(uint32_t entity) override { released.push_back(entity); }
  void Restore(uint32_t id, const EntityState& s, const Vec3f& l, const Vec3f&) override {
    restored.push_back(id);
    restored_state[id] = s;
    restored_linear[id] = l;
  }
  void Advance(double, StepOutput* out) override { out->Clear(); }
  bool Healthy(double) const override { return healthy; }
  uint32_t worker() const override { return worker_; }
  physics::PhysicsCounters counters() const override { return {}; }

  struct GrabCall {
    uint32_t entity, hand;
    bool force;
  };
  std::vector<std::pair<uint32_t, PhysicsRole>> added;
  std::vector<uint32_t> removed, released, restored;
  std::map<uint32_t, EntityState> driven, restored_state;
  std::map<uint32_t, Vec3f> restored_linear;
  std::vector<GrabCall> grabs;
  bool healthy = true;
  bool refuse_adds = false;

 private:
  uint32_t worker_;
};

class ScriptedPlacement final : public PhysicsPlacement {
 public:
  std::unique_ptr<PhysicsLink> Place(uint32_t exclude_worker, double) override {
    excluded.push_back(exclude_worker);
    auto link = std::make_unique<ScriptedPhysics>(next_worker++);
    links.push_back(link.get());
    return link;
  }
  std::vector<uint32_t> excluded;
  std::vector<ScriptedPhysics*> links;  // owned by the room
  uint32_t next_worker = 100;
};

std::vector<uint8_t> SpawnMessage(const EntitySpec& spec) {
  flatbuffers::FlatBufferBuilder fbb(256);
  FinishControl(fbb, schema::CreateSpawn(fbb, AddContainer(fbb, spec)));
  return {fbb.GetBufferPointer(), fbb.GetBufferPointer() + fbb.GetSize()};
}

EntitySpec LocalBox(uint32_t id, uint32_t owner, uint32_t flags = 0) {
  EntitySpec s;
  s.id = id;
  s.owner = owner;
  s.flags = flags;
  s.position = {1, 2, 3};
  return s;
}

std::vector<uint8_t> StatePayload(std::vector<EntityState> states) {
  std::vector<uint8_t> out(kMaxPacketSize);
  FloatStateEncoder enc;
  enc.Begin(out, 0);
  for (const auto& s : states) EXPECT_TRUE(enc.Add(s));
  out.resize(enc.Finish());
  return out;
}

class RoomHostTest : public ::testing::Test {
 protected:
  RoomHostTest() {
    config_.capacity = 3;
    config_.max_entities_per_player = 4;
    host_ = std::make_unique<RoomHost>("r", config_, RoomHostEnv{&limits_, &counters_, &placement_},
                                       0.0);
  }
  // Spawns `spec` for `m` and returns the errors it got.
  void Spawn(RecordingMember& m, const EntitySpec& spec) {
    auto msg = SpawnMessage(spec);
    host_->Spawn(m, msg, *schema::GetControlMessage(msg.data())->body_as_Spawn(), 1.0);
  }
  uint32_t Base(const RecordingMember& m) const {
    return host_->room().members().at(m.player_id()).slot * kEntityIdBlock;
  }
  const Entity* Find(uint32_t id) const {
    auto it = host_->room().entities().find(id);
    return it == host_->room().entities().end() ? nullptr : &it->second;
  }

  RoomConfig config_;
  AbuseLimits limits_;
  RelayCounters counters_;
  ScriptedPlacement placement_;
  std::unique_ptr<RoomHost> host_;
};

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
  ASSERT_TRUE(host_->Join(a, 0));
  ASSERT_TRUE(host_->Join(b, 0));
  const uint32_t id = Base(a) + 1;
  Spawn(a, LocalBox(id, 1));
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
  ASSERT_TRUE(host_->Join(a, 0));
  ASSERT_TRUE(host_->Join(b, 0));
  const uint32_t id = Base(a) + 1;
  Spawn(a, LocalBox(id, 1));
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
  ASSERT_EQ(second.grabs.size(), 1u);
  EXPECT_TRUE(second.grabs[0].force);
  EXPECT_EQ(second.grabs[0].entity, cube);
  EXPECT_EQ(counters_.physics_failovers.load(), 1u);
  EXPECT_EQ(host_->room().entities().size(), 3u);  // nothing lost
}

// The state format a room tells its members follows the shared-encoding flag, and a format-9
// room's tick prepares every entity's shared version (and nothing of the kind otherwise).
TEST(RoomHostSharedEncoding, JoinedCarriesTheFormatAndBeginTickPreparesSharedVersions) {
  for (bool shared : {false, true}) {
    AbuseLimits limits;
    RelayCounters counters;
    ScriptedPlacement placement;
    RoomConfig config;
    config.replication.shared_encoding = shared;
    RoomHost host("r", config, RoomHostEnv{&limits, &counters, &placement}, 0.0);
    RecordingMember a(7);
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
  host_ = std::make_unique<RoomHost>("r", config_, RoomHostEnv{&limits_, &counters_, &placement_},
                                     0.0);
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
