// RoomSnapshot: the persistent state of one room as a relay writes it to Redis for failover
// (cluster/directory.h) and another relay restores it (relay/cluster_hook.h): the players'
// entity id blocks (slots), and every entity's owner, creator, flags, spawn message (its
// containers: colliders, bodies, soft bodies), latest state, PhyS velocities and soft-body
// nodes.
//
// Binary layout (little-endian), "EPRS" version 1:
//   "EPRS" | u8 version | u8 room length | room | u64 written (unix ms)
//   | u32 slot count | { u32 player | u32 slot }*
//   | u32 entity count | { u32 id | u32 owner | u32 creator | u32 flags | u32 held_by
//       | u8 physics role | u64 spawn_seq | f32 x3 position | f32 x4 rotation
//       | f32 x3 linear velocity | f32 x3 angular velocity
//       | u32 node count | f32 x3 per node | u32 spawn length | spawn bytes }*
// Decode treats its input as untrusted (anything may sit in a Redis key): every length is
// checked against the bytes left and the limits below, floats must be finite; any violation
// is kMalformed, never a crash. Thread-safety: free functions, thread-safe.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "protocol/status.h"
#include "protocol/types.h"

namespace edgephys::cluster {

inline constexpr uint32_t kMaxSnapshotEntities = 1u << 20;
inline constexpr uint32_t kMaxSnapshotNodes = 1u << 16;      // per soft body
inline constexpr uint32_t kMaxSnapshotSpawnBytes = 1u << 20;  // per entity
inline constexpr uint32_t kMaxSnapshotSlots = 1u << 16;

struct EntitySnapshot {
  uint32_t id = 0;
  uint32_t owner = 0;    // player id; 0 = the room / PhyS
  uint32_t creator = 0;
  uint32_t flags = 0;    // schema::EntityFlags
  uint32_t held_by = 0;  // hand entity holding it
  uint8_t physics_role = 0;  // PhysicsRole
  uint64_t spawn_seq = 0;
  EntityState state;
  Vec3f linear_velocity;
  Vec3f angular_velocity;
  std::vector<Vec3f> nodes;
  std::vector<uint8_t> spawn;  // ControlMessage{Spawn} as the relay stores it
};

struct RoomSnapshot {
  std::string room;
  uint64_t written_unix_ms = 0;
  struct Slot {
    uint32_t player_id = 0;
    uint32_t slot = 0;
  };
  std::vector<Slot> slots;  // players' entity id blocks, kept across failover
  std::vector<EntitySnapshot> entities;
};

std::vector<uint8_t> EncodeRoomSnapshot(const RoomSnapshot& snapshot);
// kMalformed on any layout, limit or value violation (see above).
Result<RoomSnapshot> DecodeRoomSnapshot(std::span<const uint8_t> bytes);

}  // namespace edgephys::cluster
