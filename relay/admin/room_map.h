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
// its players. `bounds` covers every entity, listed or not. O(entities log limit).
//
// Thread-safety: reads the Room, so the relay's thread only (RelayAdmin runs it as a command).
#pragma once

#include <cstddef>

#include <nlohmann/json.hpp>

#include "relay/room.h"

namespace edgephys::admin {

// Entities listed per map at most by default (about 130 bytes of JSON each).
inline constexpr size_t kMaxMapEntities = 2000;

// {"room", "entities": [{"id", "owner", "creator", "kind", "x", "y", "z", "simulated"}...],
//  "listed", "total", "truncated", "limit", "players": [member ids],
//  "bounds": {"min": [x,y,z], "max": [x,y,z]} or null when the room has no entity}.
nlohmann::json RoomMapJson(const Room& room, size_t limit = kMaxMapEntities);

// The map kind of one entity (the list above).
const char* MapKindOf(const Entity& e);

}  // namespace edgephys::admin
