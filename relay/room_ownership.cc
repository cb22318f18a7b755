// RoomHost::Ownership and the late joiner's ownership state (relay/room_host.h,
// docs/protocol.md "Ownership"): requests, hand overs, releases and takeover settings of an
// entity's owner, each change bumping the entity's authority sequence.
#include <flatbuffers/flatbuffers.h>

#include <cmath>

#include "protocol/handshake.h"
#include "protocol/join_token.h"
#include "relay/room_host.h"

namespace edgephys {
namespace {

// With `motion`, the velocities the new owner starts from (a switch between local physics and
// PhyS); the pose always.
void BuildOwnershipChanged(flatbuffers::FlatBufferBuilder& fbb, const Entity& e,
                           bool motion = false) {
  fbb.Clear();
  const EntityState& s = e.state;
  const schema::Pose pose(e.id, schema::Vec3(s.position.x, s.position.y, s.position.z),
                          schema::Quat(s.rotation.x, s.rotation.y, s.rotation.z, s.rotation.w));
  const Vec3f lin = motion ? e.linear_velocity : Vec3f{};
  const Vec3f ang = motion ? e.angular_velocity : Vec3f{};
  const schema::Vec3 linear(lin.x, lin.y, lin.z), angular(ang.x, ang.y, ang.z);
  FinishControl(fbb, schema::CreateOwnershipChanged(
                         fbb, e.id, e.owner, e.authority_seq, e.former_owner, e.takeover_allowed,
                         &pose, motion ? &linear : nullptr, motion ? &angular : nullptr,
                         e.physics == PhysicsRole::kSimulated,
                         static_cast<schema::OwnerLeave>(e.on_owner_leave)));
}

const schema::Container* ContainerOf(const Entity& e) {
  return schema::GetControlMessage(e.spawn.data())->body_as_Spawn()->container();
}

// Whether PhyS can take `e` over when its owner releases it: a body the owner simulates
// locally (mirrored in PhyS as kinematic) with a dynamic rigid body.
bool Offloadable(const Entity& e) {
  if (e.physics != PhysicsRole::kMirrored) return false;
  const schema::Container* c = ContainerOf(e);
  const schema::RigidBody* rb = c != nullptr ? c->rigid_body() : nullptr;
  return rb != nullptr && !rb->kinematic() && rb->mass() > 0 && c->soft_body() == nullptr;
}

bool Finite(const Vec3f& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }
float Length(const Vec3f& v) { return std::sqrt(v.x * v.x + v.y * v.y + v.z * v.z); }

// Velocities above this are refused (m/s, rad/s): no body in a room moves that fast.
constexpr float kMaxOffloadSpeed = 1000.f;

Vec3f Read(const schema::Vec3* v) { return v != nullptr ? Vec3f{v->x(), v->y(), v->z()} : Vec3f{}; }

// Rewrites the owner recorded in a stored ControlMessage{Spawn} (in place; same size), so a
// late joiner's Spawn names the current owner.
void SetSpawnOwner(std::vector<uint8_t>& spawn, uint32_t owner) {
  auto* msg = schema::GetMutableControlMessage(spawn.data());
  auto* container = static_cast<schema::Spawn*>(msg->mutable_body())->mutable_container();
  if (container != nullptr) container->mutate_owner(owner);
}

}  // namespace

void RoomHost::Ownership(MemberLink& link, const schema::OwnershipRequest& request, double now) {
  using schema::OwnershipAction;
  using schema::RejectReason;
  const uint32_t player = link.player_id();
  const uint32_t id = request.entity_id();
  const auto refuse = [&](RejectReason reason, std::string_view detail) {
    ++ownership_stats_.refused;
    link.SendError(reason, id, detail);
  };
  const RoomBudgets& budgets = room_.config().budgets;
  if (!TakeKeyedToken(ownership_rates_, player, budgets.ownership_requests_per_s_per_player, now)) {
    return refuse(RejectReason::RateLimited, "too many ownership requests from this player; slow down");
  }
  const OwnershipAction action = request.action();
  if (action > OwnershipAction::MAX) return refuse(RejectReason::InvalidMessage, "unknown ownership action");
  if ((link.permissions() & kPermissionSpawn) == 0) {
    return refuse(RejectReason::NotPermitted, "the join token does not allow owning entities");
  }
  Entity* e = room_.FindEntity(id);
  if (e == nullptr) return refuse(RejectReason::UnknownEntity, "no such entity");
  if (action == OwnershipAction::Request) {
    if (e->owner == player) {  // already granted: tell the requester again, nothing changes
      flatbuffers::FlatBufferBuilder fbb(64);
      BuildOwnershipChanged(fbb, *e);
      (void)link.SendReliable({fbb.GetBufferPointer(), fbb.GetSize()});
      return;
    }
    if (e->physics == PhysicsRole::kSimulated) {
      // Reclaim: the requester's local physics takes the body over from PhyS, at PhyS's last
      // pose and velocities.
      if (e->held_by != 0 || !e->nodes.empty() || ContainerOf(*e)->soft_body() != nullptr) {
        return refuse(RejectReason::TakeoverRefused,
                      "PhyS simulates it and a hand holds it (or it is a soft body)");
      }
      if (!SwitchPhysics(*e, PhysicsRole::kMirrored, e->linear_velocity, e->angular_velocity,
                         now)) {
        return refuse(RejectReason::TakeoverRefused, "PhyS could not hand the body over");
      }
      return ChangeOwner(*e, player, 0, /*motion=*/true);
    }
    if (e->owner != 0 && !e->takeover_allowed) {
      return refuse(RejectReason::TakeoverRefused, "the owner does not allow takeover");
    }
    return ChangeOwner(*e, player);
  }
  if (e->owner != player) return refuse(RejectReason::NotOwner, "not your entity");
  switch (action) {
    case OwnershipAction::HandOver: {
      MemberLink* to = FindMember(request.to_player());
      if (request.to_player() == 0 || to == nullptr) {
        return refuse(RejectReason::UnknownPlayer, "no such player in the room");
      }
      if ((to->permissions() & kPermissionSpawn) == 0) {
        return refuse(RejectReason::NotPermitted, "that player's join token does not allow owning entities");
      }
      if (request.to_player() == player) return refuse(RejectReason::InvalidMessage, "already yours");
      return ChangeOwner(*e, request.to_player());
    }
    case OwnershipAction::Release: {
      const Vec3f linear = Read(request.linear_velocity());
      const Vec3f angular = Read(request.angular_velocity());
      if (!Finite(linear) || !Finite(angular) || Length(linear) > kMaxOffloadSpeed ||
          Length(angular) > kMaxOffloadSpeed) {
        return refuse(RejectReason::InvalidMessage, "release velocities not finite or too large");
      }
      // Offload: PhyS simulates a released dynamic body from its pose and these velocities.
      const bool offload = Offloadable(*e) && SwitchPhysics(*e, PhysicsRole::kSimulated, linear,
                                                            angular, now);
      return ChangeOwner(*e, 0, 0, offload);
    }
    case OwnershipAction::SetTakeover:
    case OwnershipAction::SetOwnerLeave: {
      if (action == OwnershipAction::SetOwnerLeave) {
        const auto choice = request.on_owner_leave();
        if (choice > schema::OwnerLeave::MAX) {
          return refuse(RejectReason::InvalidMessage, "unknown on_owner_leave value");
        }
        if (e->on_owner_leave == static_cast<uint8_t>(choice)) return;
        e->on_owner_leave = static_cast<uint8_t>(choice);
      } else {
        if (e->takeover_allowed == request.takeover_allowed()) return;
        e->takeover_allowed = request.takeover_allowed();
      }
      flatbuffers::FlatBufferBuilder fbb(64);
      BuildOwnershipChanged(fbb, *e);
      BroadcastReliable({fbb.GetBufferPointer(), fbb.GetSize()}, 0);
      return;
    }
    default: return;
  }
}

bool RoomHost::SwitchPhysics(Entity& e, PhysicsRole role, const Vec3f& linear,
                             const Vec3f& angular, double now) {
  PhysicsLink* link = room_.physics();
  const schema::Container* c = ContainerOf(e);
  if (link == nullptr || c == nullptr || e.physics == role) return false;
  link->Remove(e.id);
  if (Status added = link->Add(*c, role); !added.ok()) {
    (void)link->Add(*c, e.physics);  // as it was
    link->Restore(e.id, e.state, e.linear_velocity, e.angular_velocity);
    return false;
  }
  e.physics = role;
  e.linear_velocity = linear;
  e.angular_velocity = angular;
  e.changed_at = now;
  if (role == PhysicsRole::kSimulated) {
    link->Restore(e.id, e.state, linear, angular);
  } else {
    // Kinematic at its pose until its new owner moves it (as FailOver restores mirrored ones).
    link->Restore(e.id, e.state, {}, {});
    link->Drive(e.id, e.state, now);
  }
  return true;
}

void RoomHost::ChangeOwner(Entity& e, uint32_t owner, uint32_t except_player, bool motion) {
  e.former_owner = e.owner;
  e.owner = owner;
  ++e.authority_seq;
  SetSpawnOwner(e.spawn, owner);
  ++ownership_stats_.changes;
  RelayCounters::Inc(env_.counters->ownership_changes);
  flatbuffers::FlatBufferBuilder fbb(64);
  BuildOwnershipChanged(fbb, e, motion);
  BroadcastReliable({fbb.GetBufferPointer(), fbb.GetSize()}, except_player);
}

void RoomHost::HandOffLeaversEntities(uint32_t leaver, double now) {
  std::vector<Entity*> owned;
  for (auto& [id, e] : room_.entities()) {
    if (e.owner == leaver) owned.push_back(room_.FindEntity(id));
  }
  for (Entity* e : owned) {
    const uint8_t choice = LeaveChoiceOf(*e);
    if (choice == kOwnerLeaveDespawn) continue;  // Room::RemoveMember despawns it
    // PhyS: a dynamic body the leaver simulated carries on in PhyS from its last pose and the
    // velocities its states implied; anything else stays with the room at rest.
    const bool offload = choice == kOwnerLeavePhyS && Offloadable(*e) &&
                         Finite(e->linear_velocity) && Finite(e->angular_velocity) &&
                         SwitchPhysics(*e, PhysicsRole::kSimulated, e->linear_velocity,
                                       e->angular_velocity, now);
    if (!offload) e->linear_velocity = e->angular_velocity = Vec3f{};
    ChangeOwner(*e, 0, leaver, offload);
    ++(offload ? ownership_stats_.left_to_phys : ownership_stats_.left_to_room);
  }
}

void TrackOwnerMotion(Entity& e, const EntityState& next, double now) {
  const double dt = now - e.motion_from_time;
  if (e.motion_from_time >= 0 && dt < kMotionWindowS) return;
  const EntityState from = e.motion_from;
  e.motion_from = next;
  e.motion_from_time = now;
  if (!(dt > 0 && dt <= 0.5)) {
    e.linear_velocity = e.angular_velocity = Vec3f{};
    return;
  }
  const float inv = static_cast<float>(1.0 / dt);
  const Vec3f& a = from.position;
  const Vec3f& b = next.position;
  e.linear_velocity = {(b.x - a.x) * inv, (b.y - a.y) * inv, (b.z - a.z) * inv};
  // Rotation from the reference to the next: d = next * conj(reference), the short way round.
  const Quatf& p = from.rotation;
  const Quatf& q = next.rotation;
  float dw = q.w * p.w + q.x * p.x + q.y * p.y + q.z * p.z;
  float dx = -q.w * p.x + q.x * p.w - q.y * p.z + q.z * p.y;
  float dy = -q.w * p.y + q.x * p.z + q.y * p.w - q.z * p.x;
  float dz = -q.w * p.z - q.x * p.y + q.y * p.x + q.z * p.w;
  if (dw < 0) dw = -dw, dx = -dx, dy = -dy, dz = -dz;
  const float sin_half = std::sqrt(dx * dx + dy * dy + dz * dz);
  if (sin_half < 1e-7f) {
    e.angular_velocity = Vec3f{};
    return;
  }
  const float angle = 2.f * std::atan2(sin_half, dw);
  const float k = angle / sin_half * inv;
  e.angular_velocity = {dx * k, dy * k, dz * k};
  if (!Finite(e.linear_velocity) || !Finite(e.angular_velocity)) {
    e.linear_velocity = e.angular_velocity = Vec3f{};
  }
}

void RoomHost::SendJoinOwnership(uint32_t player_id) {
  auto member = room_.members().find(player_id);
  if (member == room_.members().end()) return;
  flatbuffers::FlatBufferBuilder fbb(64);
  for (const auto& [id, e] : room_.entities()) {
    const schema::Container* c = ContainerOf(e);
    const uint8_t spawned_choice = c != nullptr ? static_cast<uint8_t>(c->on_owner_leave()) : 0;
    if (e.authority_seq == 0 && !e.takeover_allowed && e.on_owner_leave == spawned_choice) continue;
    BuildOwnershipChanged(fbb, e);
    SendToMember(player_id, member->second, {fbb.GetBufferPointer(), fbb.GetSize()});
  }
}

}  // namespace edgephys
