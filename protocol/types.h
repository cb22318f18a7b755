// Plain value types and constants shared by every layer (protocol, relay, PhyS, client SDK,
// load generator): vectors, rotations, an entity's transform, and how entity ids are divided
// between the players of a room. No behaviour beyond construction; see state_codec.h for
// validation (IsValidState) and the wire format.
//
// Thread-safety: values. Cost: none (aggregates, no allocation).
#pragma once

#include <cstdint>

namespace edgephys {

// A position, extent or velocity: metres (or m/s, rad/s) in the room frame unless a field says
// otherwise.
struct Vec3f {
  float x = 0, y = 0, z = 0;
};

// A rotation as a quaternion (x, y, z, w); unit length where a field says "unit quaternion".
// Default: identity.
struct Quatf {
  float x = 0, y = 0, z = 0, w = 1;
};

// One entity's transform, as it travels on the unreliable channel.
struct EntityState {
  uint32_t entity_id = 0;
  Vec3f position;   // metres, room frame
  Quatf rotation;   // unit quaternion
};

// An entity's velocity: m/s and rad/s, room (world) frame.
struct EntityVelocity {
  Vec3f linear;
  Vec3f angular;
};

// Entity ids are divided into blocks of kEntityIdBlock ids, one block per player slot of a
// room: slot s owns the ids s * kEntityIdBlock .. s * kEntityIdBlock + 65535 (the relay tells a
// player its block base in Joined.entity_id_base). Slot 0 is the room's own: no player is given
// it, so no player's entity id is below kEntityIdBlock. The slot of an id is id / kEntityIdBlock.
inline constexpr uint32_t kEntityIdBlock = 1u << 16;

}  // namespace edgephys
