// Worker -> relay state payloads on the unreliable channel (docs/protocol.md, "PhyS workers"):
//   format 6: u8 6 | u32 room handle | varint count |
//             count x { varint id | 3 x f32 position | 4 x f32 rotation | 3 x f32 linear
//                       velocity | 3 x f32 angular velocity }
//   format 8: u8 8 | u32 room handle | one format-5 soft-body chunk (soft_body_codec.h) with
//             a 0.1 mm step
// Exact floats (the relay re-encodes for clients); velocities let the relay restore a room on
// another worker without a jump.
//
// Thread-safety: pure functions. Cost: O(entities), no allocation when encoding.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "edgephys/schema/control_generated.h"
#include "physics_backend/room_physics.h"
#include "protocol/soft_body_codec.h"

namespace edgephys {

inline constexpr uint8_t kWorkerStateFormat = 6;
inline constexpr uint8_t kWorkerSoftFormat = 8;
inline constexpr float kWorkerSoftStepM = 0.0001f;

// Encodes bodies[first..] into `out` while they fit; returns the size and sets `*encoded`.
size_t EncodeWorkerStates(uint32_t room, std::span<const RoomPhysics::MovedBody> bodies,
                          size_t first, std::span<uint8_t> out, size_t* encoded);
// kMalformed on truncation, trailing bytes or a wrong format; values are not validated.
Status DecodeWorkerStates(std::span<const uint8_t> payload, uint32_t* room,
                          std::vector<RoomPhysics::MovedBody>* out);

// A soft-body chunk of nodes[first..] for room `room`; see EncodeSoftBodyChunk.
size_t EncodeWorkerSoftChunk(uint32_t room, uint32_t entity_id, std::span<const Vec3f> nodes,
                             uint32_t first, std::span<uint8_t> out, uint32_t* encoded);
Status DecodeWorkerSoftChunk(std::span<const uint8_t> payload, uint32_t* room,
                             SoftBodyChunk* chunk);

// A wire pose as a state. O(1).
EntityState FromPose(const schema::Pose& p);

// Applies a relay's WorkerDrive to `room`: each pose with its time (RoomPhysics::Drive) when
// the message carries one per pose, else `arrival` (the worker's clock). Poses with a
// non-finite time still drive the body; their time is ignored for velocities (PoseHistory).
// O(poses).
void ApplyWorkerDrive(const schema::WorkerDrive& message, RoomPhysics& room, double arrival);

}  // namespace edgephys
