// Room: the relay's single point of truth for one shared scene: who is in it and every
// entity's owner, spawn description and latest state. Owned by one thread (the relay's);
// no locking. Entities of players who leave are despawned unless flagged Persistent, in which
// case the room takes them over (owner 0), so a session outlives its users.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "protocol/delta_codec.h"
#include "protocol/state_codec.h"
#include "relay/physics_link.h"
#include "relay/relay_config.h"

namespace edgephys {

struct Entity {
  uint32_t id = 0;
  uint32_t owner = 0;            // player id; 0 = the room or PhyS (see physics)
  uint32_t creator = 0;          // the player who spawned it (may despawn PhyS-owned ones)
  PhysicsRole physics = PhysicsRole::kNone;
  uint32_t held_by = 0;          // hand entity holding it (grabbed), 0 if none
  std::vector<Vec3f> nodes;      // soft body particles (PhyS-simulated soft bodies)
  uint32_t nodes_version = 0;    // bumped when `nodes` change
  Vec3f linear_velocity;         // last reported by PhyS (restored on failover)
  Vec3f angular_velocity;
  uint64_t spawn_seq = 0;        // order of arrival in the room (parents before children)
  uint32_t grab_requester = 0;   // player whose grab request is pending
  uint32_t flags = 0;            // schema::EntityFlags
  uint32_t version = 1;          // bumped on every accepted state change
  double changed_at = 0;         // relay time of the last accepted change (resting detection)
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
};

struct Member {
  uint32_t player_id = 0;
  uint32_t slot = 0;             // 1..capacity; entity ids slot<<16 .. +65535 are the player's
  uint32_t session = 0;          // connection id of the player's session
  uint32_t entity_count = 0;
};

class Room {
 public:
  Room(std::string name, const RoomConfig& config, double now);

  const std::string& name() const { return name_; }
  const RoomConfig& config() const { return config_; }
  bool empty() const { return members_.empty(); }
  size_t size() const { return members_.size(); }

  // Adds a player; returns its slot, or 0 when the room is full.
  uint32_t AddMember(uint32_t player_id, uint32_t session);
  // Removes a player. Its entities (those it owns, and PhyS-owned ones it created) are
  // despawned (ids appended to `despawned`) unless Persistent, which pass to the room.
  void RemoveMember(uint32_t player_id, std::vector<uint32_t>* despawned);
  Member* FindMember(uint32_t player_id);
  const std::map<uint32_t, Member>& members() const { return members_; }

  Entity* FindEntity(uint32_t id);
  // Inserts a new entity (the caller validated ownership and id range).
  Entity& AddEntity(Entity entity);
  void RemoveEntity(uint32_t id);
  const std::unordered_map<uint32_t, Entity>& entities() const { return entities_; }

  // PhyS for this room (embedded or on a worker); null until the first physics entity.
  PhysicsLink* physics() const { return physics_.get(); }
  void set_physics(std::unique_ptr<PhysicsLink> link) { physics_ = std::move(link); }
  std::unique_ptr<PhysicsLink> TakePhysics() { return std::move(physics_); }
  uint64_t NextSpawnSeq() { return ++spawn_seq_; }

  // Before a replication tick: quantises every entity whose state changed since the last
  // call, once for all receivers (edgephys mode only; a no-op otherwise). O(entities), no
  // allocation after the first call. Not thread-safe: call on the room's thread before the
  // clients' ticks, which then only read the result.
  void PrepareStates();

  // Tick scheduling: due when now >= next_tick().
  double next_tick() const { return next_tick_; }
  void ScheduleNextTick(double now);
  // Time the room became empty (for the idle TTL); meaningful only when empty().
  double empty_since() const { return empty_since_; }
  void set_empty_since(double t) { empty_since_ = t; }

 private:
  std::string name_;
  RoomConfig config_;
  std::map<uint32_t, Member> members_;  // by player id
  std::unordered_map<uint32_t, Entity> entities_;
  std::unique_ptr<PhysicsLink> physics_;
  uint64_t spawn_seq_ = 0;
  std::optional<QuantizationParams> quantization_;  // edgephys rooms, made on first use
  bool quantization_tried_ = false;
  double next_tick_;
  double empty_since_;
};

}  // namespace edgephys
