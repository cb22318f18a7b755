// Room: the data of one shared scene, the relay's single point of truth for it: who is in it
// and every entity's owner, spawn description and latest state, its PhyS link and its tick
// schedule. The rules that change it (admission to the room, authority, physics output,
// fan-out) live in RoomHost (relay/room_host.h), which owns the Room.
// Thread-safety: one thread (the relay's); no locking. Entities of players who leave are
// despawned or taken over by the room (owner 0), as each entity's leave choice says
// (LeaveChoiceOf: by default Persistent ones stay), so a session outlives its users.
#pragma once

#include <algorithm>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "protocol/delta_codec.h"
#include "protocol/shared_delta_codec.h"
#include "protocol/state_codec.h"
#include "relay/entity.h"
#include "relay/physics_link.h"
#include "relay/relay_config.h"
#include "relay/relay_counters.h"

namespace edgephys {

class Room {
 public:
  Room(std::string name, const RoomConfig& config, double now);

  const std::string& name() const { return name_; }
  const RoomConfig& config() const { return config_; }
  bool empty() const { return members_.empty(); }
  size_t size() const { return members_.size(); }

  // Adds a player reached through `link` (not owned; valid until RemoveMember); returns its
  // slot, or 0 when the room is full. A player with a reserved slot (ReserveSlot) gets it back
  // if no member holds it.
  uint32_t AddMember(uint32_t player_id, MemberLink* link);
  // Cluster failover (relay/cluster_hook.h): `player_id` gets `slot` (its entity id block) when
  // it joins, so the entities a restored room holds for it stay its own.
  void ReserveSlot(uint32_t player_id, uint32_t slot) { reserved_slots_[player_id] = slot; }
  const std::map<uint32_t, uint32_t>& reserved_slots() const { return reserved_slots_; }
  // Spawn sequence numbers continue after `seq` (restored entities keep theirs).
  void AdvanceSpawnSeq(uint64_t seq) { spawn_seq_ = std::max(spawn_seq_, seq); }
  // Removes a player. Its entities (those it owns, and PhyS-owned ones it created) are
  // despawned (ids appended to `despawned`) when LeaveChoiceOf says Despawn (by default: not
  // Persistent), else pass to the room. An
  // entity released to the room by an ownership change (owner 0, authority_seq > 0; PhyS may
  // simulate it) stays, whoever created it.
  void RemoveMember(uint32_t player_id, std::vector<uint32_t>* despawned);
  Member* FindMember(uint32_t player_id);
  const std::map<uint32_t, Member>& members() const { return members_; }

  Entity* FindEntity(uint32_t id);
  // Inserts a new entity (the caller validated ownership, id range, parent and budgets) and
  // charges its cost to its creator in ledger().
  Entity& AddEntity(Entity entity);
  // Removes an entity (from PhyS too) and refunds its creator; its children become roots
  // (their former_parent keeps the id members present now still show as their parent).
  void RemoveEntity(uint32_t id);
  // Whether an entity `id` under `parent` would close a parent cycle in any member's view:
  // `id` is reachable from `parent` through parents or former parents (Entity::former_parent:
  // a member that saw a child's spawn before its parent went still shows the child under that
  // id, so a new entity with that id as the child's child is a cycle there, and refused for
  // every member alike). O(ancestors); at most entities().size() steps.
  bool ParentWouldCycle(uint32_t id, uint32_t parent) const;
  // What the entities cost, by creator and in all (relay/room_budget.h).
  const RoomLedger& ledger() const { return ledger_; }
  const EntityTable& entities() const { return entities_; }
  // The entities by slot (Entity::slot; null: a free slot). Its size is the most entities the
  // room held at once: freed slots are reused first. Valid until the next AddEntity.
  const std::vector<Entity*>& slots() const { return slots_; }

  // PhyS for this room (embedded or on a worker); null until the first physics entity.
  PhysicsLink* physics() const { return physics_.get(); }
  void set_physics(std::unique_ptr<PhysicsLink> link) { physics_ = std::move(link); }
  std::unique_ptr<PhysicsLink> TakePhysics() { return std::move(physics_); }
  uint64_t NextSpawnSeq() { return ++spawn_seq_; }

  // Before a replication tick at `now` (seconds): quantises every entity whose state changed
  // since the last call, once for all receivers (edgephys mode only; a no-op otherwise). With
  // shared encoding (format 9) also starts the room's tick (SharedDeltaRoom::BeginTick) and
  // records each entity's version and empties its body cache. O(entities), no allocation
  // after the first call per entity. Not thread-safe: call on the room's thread before the
  // clients' ticks, which then only read the result (format 9 bodies are cached thread-safely).
  void PrepareStates(double now);
  // Builds frame() from the entities as they are now. O(entities) plus a sort by id only when
  // entities came or went since the last call. Room thread, before the receivers' ticks.
  void BuildFrame();
  const ReplicationFrame& frame() const { return frame_; }
  // Format 9 rooms: the tick clock and body cache; null otherwise (or before the first tick).
  const SharedDeltaRoom* shared_encoding() const { return shared_.get(); }

  // Tick scheduling: due when now >= next_tick().
  double next_tick() const { return next_tick_; }
  void ScheduleNextTick(double now);
  // Time the room became empty (for the idle TTL); meaningful only when empty().
  double empty_since() const { return empty_since_; }
  void set_empty_since(double t) { empty_since_ = t; }

 private:
  void ReleaseSlot(const Entity& e);

  std::string name_;
  RoomConfig config_;
  std::map<uint32_t, Member> members_;  // by player id
  std::map<uint32_t, uint32_t> reserved_slots_;  // player id -> slot (failover)
  EntityTable entities_;
  std::vector<Entity*> slots_;       // by Entity::slot (nodes of entities_: stable)
  std::vector<uint32_t> free_slots_;
  uint32_t serials_ = 0;             // Entity::serial of the last entity added
  ReplicationFrame frame_;
  bool frame_stale_ = true;          // entities came or went since BuildFrame
  RoomLedger ledger_;
  std::unique_ptr<PhysicsLink> physics_;
  uint64_t spawn_seq_ = 0;
  std::optional<QuantizationParams> quantization_;  // edgephys rooms, made on first use
  bool quantization_tried_ = false;
  std::unique_ptr<SharedDeltaRoom> shared_;  // format 9 rooms
  double next_tick_;
  double empty_since_;
};

}  // namespace edgephys
