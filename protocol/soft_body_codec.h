// Soft-body particle payloads (state format 5) on the unreliable channel, relay -> clients.
//
// A soft body's particles travel in chunks, one chunk per datagram payload:
//   u8 format (5) | u32 time (ms) | varint entity id | varint total particles |
//   varint first particle | varint count | 3 x f32 chunk origin (m) |
//   count x { 3 x u16 offset from the origin, in position steps }
// With the default 1 mm step a chunk spans up to 65.5 m per axis (larger spans are clamped; the
// stability guard keeps real soft bodies far smaller). Error per axis <= step / 2.
//
// Thread-safety: pure functions. Cost: O(particles in the chunk), no allocation in Encode.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "protocol/state_codec.h"

namespace edgephys {

inline constexpr uint8_t kSoftBodyFormat = static_cast<uint8_t>(StateFormat::kSoftBody);

// Encodes particles [first, first + n) of `nodes` (as many as fit in `out`, n >= 1 unless
// `out` is too small for any) and returns the payload size; `*encoded` is set to n.
size_t EncodeSoftBodyChunk(uint32_t time_ms, uint32_t entity_id, std::span<const Vec3f> nodes,
                           uint32_t first, float step_m, std::span<uint8_t> out, uint32_t* encoded);

struct SoftBodyChunk {
  uint32_t time_ms = 0;
  uint32_t entity_id = 0;
  uint32_t total = 0;
  uint32_t first = 0;
  std::vector<Vec3f> positions;  // the chunk's particles, reused between decodes
};

// Untrusted input: kMalformed on truncation, trailing bytes, first + count > total, a total
// above `max_total`, or non-finite origins.
Status DecodeSoftBodyChunk(std::span<const uint8_t> payload, float step_m, uint32_t max_total,
                           SoftBodyChunk* out);

}  // namespace edgephys
