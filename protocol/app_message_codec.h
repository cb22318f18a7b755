// Unreliable application messages: the payload format 15 of the unreliable channel
// (docs/protocol.md, "Unreliable application messages"). One message per datagram, both
// directions, the same 14-byte header:
//   u8 format = 15, u8 target (0 room, 1 others, 2 player), u32 to_player, u32 sender,
//   u32 sequence, then the application's bytes to the end of the payload.
// Client -> relay: sender is 0 (ignored); sequence numbers the client's unreliable messages on
// this connection (1, 2, ...; 0 = unnumbered) and the relay drops one not newer than the
// newest it forwarded from that connection. Relay -> member: sender is the sending
// player's id, sequence numbers that player's unreliable messages (1, 2, ...; per player
// identity, across rejoins) so a receiver drops any older than the newest it delivered.
//
// Thread-safety: plain functions over caller-owned memory. Cost: O(payload), no allocation.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include "protocol/byte_io.h"
#include "protocol/connection.h"

namespace edgephys {

inline constexpr uint8_t kAppMessageFormat = kUnorderedPayloadFormat;  // any order on the wire
inline constexpr size_t kAppMessageHeaderSize = 14;
// Largest payload of an unreliable message: one datagram (kMaxUnreliablePayload) less the
// header. 1165 bytes.
inline constexpr size_t kMaxUnreliableMessagePayload =
    kMaxUnreliablePayload - kAppMessageHeaderSize;

struct AppMessageHeader {
  uint8_t target = 0;
  uint32_t to_player = 0;
  uint32_t sender = 0;
  uint32_t sequence = 0;
};

// Writes header + `payload` into `out`; returns the bytes written, 0 when `out` is too small
// or the payload is over kMaxUnreliableMessagePayload.
inline size_t EncodeAppMessage(const AppMessageHeader& h, std::span<const uint8_t> payload,
                               std::span<uint8_t> out) {
  const size_t n = kAppMessageHeaderSize + payload.size();
  if (payload.size() > kMaxUnreliableMessagePayload || out.size() < n) return 0;
  out[0] = kAppMessageFormat;
  out[1] = h.target;
  StoreU32LE(&out[2], h.to_player);
  StoreU32LE(&out[6], h.sender);
  StoreU32LE(&out[10], h.sequence);
  for (size_t i = 0; i < payload.size(); ++i) out[kAppMessageHeaderSize + i] = payload[i];
  return n;
}

// Reads a format-15 payload: false when it is shorter than the header, not format 15, or
// longer than one datagram allows. The target is returned as sent (the caller checks it).
// `*payload` points into `in`.
inline bool DecodeAppMessage(std::span<const uint8_t> in, AppMessageHeader* h,
                             std::span<const uint8_t>* payload) {
  if (in.size() < kAppMessageHeaderSize || in[0] != kAppMessageFormat) return false;
  if (in.size() - kAppMessageHeaderSize > kMaxUnreliableMessagePayload) return false;
  h->target = in[1];
  h->to_player = LoadU32LE(&in[2]);
  h->sender = LoadU32LE(&in[6]);
  h->sequence = LoadU32LE(&in[10]);
  *payload = in.subspan(kAppMessageHeaderSize);
  return true;
}

// Whether sequence `a` is newer than `b` (wrap-around arithmetic over 2^32).
inline bool AppSequenceNewer(uint32_t a, uint32_t b) {
  return static_cast<int32_t>(a - b) > 0;
}

}  // namespace edgephys
