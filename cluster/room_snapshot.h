// RoomSnapshot: the persistent state of one room as a relay writes it to Redis for failover
// (cluster/directory.h) and another relay restores it (relay/cluster_hook.h): the players'
// entity id blocks (slots), and every entity's owner, creator, flags, spawn message (its
// containers: colliders, bodies, soft bodies), latest state, PhyS velocities and soft-body
// nodes; and the room's properties (room and entity properties, protocol/property_value.h).
//
// Binary layout (little-endian), "EPRS" version 3 (versions 1, without the property section,
// and 2, without the ownership section, are still read; their entities get the defaults):
//   "EPRS" | u8 version | u8 room length | room | u64 written (unix ms)
//   | u32 slot count | { u32 player | u32 slot }*
//   | u32 entity count | { u32 id | u32 owner | u32 creator | u32 flags | u32 held_by
//       | u8 physics role | u64 spawn_seq | f32 x3 position | f32 x4 rotation
//       | f32 x3 linear velocity | f32 x3 angular velocity
//       | u32 node count | f32 x3 per node | u32 spawn length | spawn bytes }*
//   | u32 property count | { u32 entity id (0: room) | u8 key length | key | u8 type
//       | u8 authority | u32 version | u32 writer | u32 owner | u32 request id
//       | value: i64 (bool, int64) | f64 (double) | f32 x3 (vec3) | f32 x4 (quat)
//              | u32 length, bytes (string, bytes) }*
//   | u32 ownership count (= entity count) | { u32 entity id (the entity's at that index)
//       | u32 authority_seq | u32 former owner | u8 takeover allowed (0/1)
//       | u8 on_owner_leave (schema::OwnerLeave, <= kMaxOwnerLeave) }*
// Decode treats its input as untrusted (anything may sit in a Redis key): every length is
// checked against the bytes left and the limits below, floats must be finite, property keys
// and values must pass ValidatePropertyKey/Value, versions be non-zero; any violation
// is kMalformed, never a crash. Thread-safety: free functions, thread-safe.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "protocol/property_value.h"
#include "protocol/status.h"
#include "protocol/types.h"

namespace edgephys::cluster {

inline constexpr uint32_t kMaxSnapshotEntities = 1u << 20;
inline constexpr uint32_t kMaxSnapshotNodes = 1u << 16;      // per soft body
inline constexpr uint32_t kMaxSnapshotSpawnBytes = 1u << 20;  // per entity
inline constexpr uint32_t kMaxSnapshotSlots = 1u << 16;
inline constexpr uint32_t kMaxSnapshotProperties = 1u << 20;
inline constexpr uint8_t kMaxOwnerLeave = 3;  // schema::OwnerLeave::Despawn

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
  // Ownership (relay/entity.h): states of `former_owner` after the last change stay stale.
  uint32_t authority_seq = 0;
  uint32_t former_owner = 0;
  bool takeover_allowed = false;
  uint8_t on_owner_leave = 0;  // schema::OwnerLeave
};

struct PropertySnapshot {
  uint32_t entity_id = 0;  // 0: a room property
  std::string key;
  PropertyValue value;
  PropertyAuthority authority = PropertyAuthority::kOwner;
  uint32_t version = 0;
  uint32_t writer = 0;
  uint32_t owner = 0;
  uint32_t request_id = 0;
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
  std::vector<PropertySnapshot> properties;
};

std::vector<uint8_t> EncodeRoomSnapshot(const RoomSnapshot& snapshot);
// kMalformed on any layout, limit or value violation (see above).
Result<RoomSnapshot> DecodeRoomSnapshot(std::span<const uint8_t> bytes);

}  // namespace edgephys::cluster
