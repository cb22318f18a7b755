// RoomMap: a room's entities as the admin API's map view (docs/admin-api.md:
// GET /v1/rooms/{id}/map), which the monitor page draws top-down.
//
// Each entity: id, owner (player id; 0 = the room or PhyS), creator, kind, position (metres,
// room frame, the entity's latest accepted state) and whether PhyS simulates it. The kind is
// what the relay knows of the entity, first match wins:
//   "soft_body"    its spawn carried a soft body (PhyS particles)
//   "hand"         EntityFlags::Hand
//   "avatar"       EntityFlags::Avatar (a head or a body: the relay does not tell them apart)
//   "physics_body" PhyS simulates it (an offloaded dynamic body; owner 0)
//   "object"       anything else
//
// Size: at most `limit` entities are listed (`truncated` says when more exist); hands and
// avatars come first, then the rest, each by increasing id, so a crowded room still shows
// its players. `bounds` covers every entity, listed or not.
//
// Two steps, so that the relay's thread only copies: TakeRoomMap reads the Room (the relay's
// thread only; RelayAdmin runs it as a command), O(entities log limit) and one allocation of
// `limit` small records; RoomMapJson turns the copy into JSON on any thread (the HTTP one).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "relay/room.h"

namespace edgephys::admin {

// Entities listed per map at most (about 130 bytes of JSON each).
inline constexpr size_t kMaxMapEntities = 2000;

enum class MapKind : uint8_t { kObject, kAvatar, kHand, kPhysicsBody, kSoftBody };
const char* MapKindName(MapKind kind);
MapKind MapKindOf(const Entity& e);

struct RoomMapSnapshot {
  struct Item {
    uint32_t id = 0, owner = 0, creator = 0;
    MapKind kind = MapKind::kObject;
    bool simulated = false;
    Vec3f position;  // metres, room frame
  };
  std::string room;
  std::vector<Item> entities;     // the listed ones, in listing order
  size_t total = 0;               // entities in the room
  size_t limit = kMaxMapEntities;
  std::vector<uint32_t> players;  // member ids, increasing
  bool has_bounds = false;        // false: no entity
  Vec3f min, max;                 // over every entity
};

// Relay thread: copies what the map shows of `room`, at most `limit` entities.
RoomMapSnapshot TakeRoomMap(const Room& room, size_t limit = kMaxMapEntities);

// Any thread: {"room", "entities": [{"id", "owner", "creator", "kind", "x", "y", "z",
// "simulated"}...], "listed", "total", "truncated", "limit", "players": [member ids],
// "bounds": {"min": [x,y,z], "max": [x,y,z]} or null when the room has no entity}.
nlohmann::json RoomMapJson(const RoomMapSnapshot& map);

}  // namespace edgephys::admin
