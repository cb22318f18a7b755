// Test doubles for RoomHost rule tests (relay/room_host_test.cc, room_host_hostile_test.cc):
// recording MemberLinks, a scripted PhysicsLink and placement, and the fixture. What a member
// is sent is decoded from the very bytes RoomHost queued. Test-only.
#pragma once

#include "relay/room_host.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <map>

#include "protocol/container_builder.h"
#include "protocol/handshake.h"
#include "protocol/join_token.h"

namespace edgephys::room_host_testing {

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
    pending_bytes += message.size();  // until the test "acknowledges" (sets it to 0)
    reliable.emplace_back(message.begin(), message.end());
    return true;
  }
  size_t ReliablePending() const override { return pending_bytes; }
  size_t ReliableCapacity() const override { return capacity_bytes; }
  void Overflow() override { overflowed = true; }
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
  void Replicate(const ReplicationFrame&, double, RelayCounters&, bool) override {}
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
  size_t reliable_capacity_ = 1u << 20;  // messages
  size_t pending_bytes = 0;               // what ReliablePending() reports
  size_t capacity_bytes = 8u << 20;
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
  void Drive(uint32_t id, const EntityState& s, double /*time*/) override { driven[id] = s; }
  void RequestGrab(uint32_t entity, uint32_t hand, bool force) override {
    grabs.push_back({entity, hand, force});
  }
  void Release(uint32_t entity) override { released.push_back(entity); }
  void Restore(uint32_t id, const EntityState& s, const Vec3f& l, const Vec3f&) override {
    restored.push_back(id);
    restored_state[id] = s;
    restored_linear[id] = l;
  }
  void RestoreSoftBody(uint32_t id, std::span<const Vec3f> nodes) override {
    restored.push_back(id);
    restored_nodes[id].assign(nodes.begin(), nodes.end());
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
  std::map<uint32_t, std::vector<Vec3f>> restored_nodes;
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

inline std::vector<uint8_t> SpawnMessage(const EntitySpec& spec) {
  flatbuffers::FlatBufferBuilder fbb(256);
  FinishControl(fbb, schema::CreateSpawn(fbb, AddContainer(fbb, spec)));
  return {fbb.GetBufferPointer(), fbb.GetBufferPointer() + fbb.GetSize()};
}

inline EntitySpec LocalBox(uint32_t id, uint32_t owner, uint32_t flags = 0) {
  EntitySpec s;
  s.id = id;
  s.owner = owner;
  s.flags = flags;
  s.position = {1, 2, 3};
  return s;
}

inline std::vector<uint8_t> StatePayload(std::vector<EntityState> states) {
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
    Rebuild();
  }
  // A new host of room "r" (no members, no entities) under config_ as it is now.
  void Rebuild() {
    host_ = std::make_unique<RoomHost>("r", config_, RoomHostEnv{&limits_, &counters_, &placement_},
                                       0.0);
  }
  // Joins `a` and then `b`, and spawns a box owned by `a` (LocalBox) at Base(a) + 1,
  // stored in `*id`. Fails (fatally) if a join is refused.
  void JoinBothAndSpawnBox(RecordingMember& a, RecordingMember& b, uint32_t* id) {
    ASSERT_TRUE(host_->Join(a, 0));
    ASSERT_TRUE(host_->Join(b, 0));
    *id = Base(a) + 1;
    Spawn(a, LocalBox(*id, a.player_id()));
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

}  // namespace edgephys::room_host_testing
