// The relay's view of what a room holds: entities (every entity's owner, spawn description and
// latest state) and members (who is in the room and through which link they are reached).
// Plain data, owned by a Room; the rules that change them live in RoomHost (relay/room_host.h).
#pragma once

#include <cstdint>
#include <memory>
#include <unordered_map>
#include <vector>

#include "physics_backend/room_physics.h"
#include "protocol/delta_codec.h"
#include "protocol/shared_delta_codec.h"
#include "protocol/state_codec.h"
#include "relay/room_budget.h"

namespace edgephys {

class MemberLink;


struct Entity {
  uint32_t id = 0;
  uint32_t owner = 0;            // player id; 0 = the room or PhyS (see physics)
  // Ownership changes (relay/room_ownership.cc): +1 per change of owner (0 at spawn); the
  // owner before the latest change (0: none or the room), whose later states are stale; whether
  // the owner lets other players take the entity at once (OwnershipAction::Request).
  uint32_t authority_seq = 0;
  uint32_t former_owner = 0;
  bool takeover_allowed = false;
  // What happens to it when its owner leaves (schema::OwnerLeave: 0 Default, 1 Stay, 2 PhyS,
  // 3 Despawn; see LeaveChoiceOf): from its spawn, changed by its owner (SetOwnerLeave).
  uint8_t on_owner_leave = 0;
  // TrackOwnerMotion's reference: an earlier accepted state of its owner and its relay time
  // (< 0: none yet).
  EntityState motion_from;
  double motion_from_time = -1;
  uint32_t creator = 0;          // the player who spawned it (may despawn PhyS-owned ones;
                                 // the room's budgets charge it `cost` until it is removed)
  uint32_t parent = 0;           // parent entity (Container.parent_id), 0: none
  // The parent it had when that parent was despawned (it is a root since): members present
  // then still show it under that id (clients keep a spawn's parent_id). 0: none.
  uint32_t former_parent = 0;
  uint32_t children = 0;         // entities whose parent this is
  EntityCost cost;
  PhysicsRole physics = PhysicsRole::kNone;
  uint32_t held_by = 0;          // hand entity holding it (grabbed), 0 if none
  std::vector<Vec3f> nodes;      // soft body particles (PhyS-simulated soft bodies)
  uint32_t nodes_version = 0;    // bumped when `nodes` change
  // Soft bodies after a PhyS failover: `nodes_restored` is set when the room fails over; the
  // first particles from the new world clear it and are kept as `resumed_nodes` (version
  // `resumed_version`, relay time `nodes_resumed_at`) for kResumeWindowS, so replication sends
  // every receiver that first version at once, not a later one at the next due time.
  static constexpr double kResumeWindowS = 0.25;
  bool nodes_restored = false;
  double nodes_resumed_at = -1e9;
  uint32_t resumed_version = 0;
  std::vector<Vec3f> resumed_nodes;
  Vec3f linear_velocity;         // last reported by PhyS (restored on failover)
  Vec3f angular_velocity;
  uint64_t spawn_seq = 0;        // order of arrival in the room (parents before children)
  uint32_t grab_requester = 0;   // player whose grab request is pending
  uint32_t flags = 0;            // schema::EntityFlags
  // Room-local slot (Room::AddEntity: a dense index reused after the entity is removed) and
  // the serial of this occupancy (unique in the room, never 0 once added). Receivers index
  // their per-entity records by slot and trust one only while its serial matches.
  uint32_t slot = 0;
  uint32_t serial = 0;
  uint32_t version = 1;          // bumped on every accepted state change
  double changed_at = 0;         // relay time of the last accepted change (resting detection)
  // Relay time at which `state` holds: an owner's update when it arrived (changed_at); PhyS's
  // the end of the step that produced it (PhysicsLink::StepOutput::state_time), which for an
  // asynchronous world is a step's computation earlier than its arrival. Bodies PhyS did not
  // report since still hold it, unmoved.
  double state_time = 0;
  // Relay time a user last interacted with it: grab, release, or a physics event naming it
  // (replication's ambient class). -inf-like until then.
  double interacted_at = -1e9;
  // Open Enter events (trigger overlaps, reported contacts) naming it, not yet exited.
  uint32_t touching = 0;
  EntityState state;
  std::vector<uint8_t> spawn;    // the ControlMessage{Spawn} as received, re-sent to joiners
  // `state` quantised for the edgephys format, shared by every receiver's encoder
  // (Room::PrepareStates); valid while `prepared_of` equals `state`.
  bool prepared_valid = false;
  EntityState prepared_of;
  PreparedState prepared;
  // Format 9 rooms (ReplicationConfig::shared_encoding): the entity's recent versions and this
  // tick's cached record bodies, shared by every receiver (Room::PrepareStates).
  std::shared_ptr<SharedEntity> shared;
};

// What a receiver's state stream reads of `e` (protocol/state_stream.h); valid while `e` is.
inline StreamEntity StreamView(const Entity& e) {
  return {e.id, e.version, &e.state, e.prepared_valid ? &e.prepared : nullptr, e.shared.get()};
}

using EntityTable = std::unordered_map<uint32_t, Entity>;

// The effective choice for `e` when its owner leaves: its on_owner_leave, with Default resolved
// by the Persistent flag (Stay) or its absence (Despawn). Values as schema::OwnerLeave.
inline constexpr uint8_t kOwnerLeaveStay = 1, kOwnerLeavePhyS = 2, kOwnerLeaveDespawn = 3;
inline uint8_t LeaveChoiceOf(const Entity& e) {
  if (e.on_owner_leave != 0) return e.on_owner_leave;
  return (e.flags & 1u) != 0 ? kOwnerLeaveStay : kOwnerLeaveDespawn;  // 1: EntityFlags::Persistent
}

// Records in `e` (mirrored in PhyS, simulated by its owner) the velocities its owner's states
// imply: from the reference state (e.motion_from, at least kMotionWindowS old) to `next`,
// arriving at `now` (relay time, s), which becomes the reference. Arrival times jitter by up to
// a tick, so this is an estimate (a few % over the window); a reference older than 0.5 s
// gives velocities 0. Used when its owner leaves and it goes to PhyS.
inline constexpr double kMotionWindowS = 0.1;
void TrackOwnerMotion(Entity& e, const EntityState& next, double now);

// What one room tick offers each of its receivers (Room::BuildFrame, once per room tick, so
// that no receiver walks or sorts the room's entity table itself). Built on the room's thread
// before the receivers' ticks; read-only during them (they may run in parallel). Pointers
// into the room's entity table, valid until the room's entities change.
struct ReplicationFrame {
  std::vector<const Entity*> by_id;  // every entity, by increasing id
  std::vector<const Entity*> soft;   // soft bodies with particles, by increasing id
  std::vector<Vec3f> hands;          // positions of the Hand entities (soft-body touch test)
};

struct Member {
  uint32_t player_id = 0;
  uint32_t slot = 0;             // 1..capacity; entity ids slot<<16 .. +65535 are the player's
  MemberLink* link = nullptr;    // how the room reaches the player (its session); not owned
  // States that arrived for the player's own, not yet spawned entities (the spawn travels on
  // the reliable channel and may arrive later). Bounded; applied when the spawn arrives.
  std::unordered_map<uint32_t, EntityState> early_states;
};

}  // namespace edgephys
