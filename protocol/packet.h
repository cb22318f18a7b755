// Packet framing shared by every edgephys datagram (docs/protocol.md, "Packet prefix").
//
//   offset size field
//   0      4    protocol id, little-endian 0x59485045 ("EPHY" on the wire)
//   4      1    protocol version (kProtocolVersion)
//   5      1    packet type (PacketType)
//   6      4    connection id, little-endian (0 before the handshake completes)
//
// Data and disconnect packets continue with the connection header (see connection.h).
// Parsing never trusts its input: every failure is a DropReason, never an assert.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>

#include "protocol/status.h"

namespace edgephys {

inline constexpr uint32_t kProtocolId = 0x59485045u;  // bytes 'E' 'P' 'H' 'Y'
inline constexpr uint8_t kProtocolVersion = 1;
// Largest datagram edgephys sends or accepts (bytes of UDP payload).
inline constexpr size_t kMaxPacketSize = 1200;
inline constexpr size_t kPacketPrefixSize = 10;
// A Hello datagram must be at least this large: the server's Challenge reply is smaller, so
// the relay can never be used to amplify traffic towards a spoofed address.
inline constexpr size_t kMinHelloPacketSize = 1000;

enum class PacketType : uint8_t {
  kHello = 1,       // client -> server, payload: ControlMessage{Hello}, padded
  kChallenge = 2,   // server -> client, payload: ControlMessage{Challenge}
  kConnect = 3,     // client -> server, payload: ControlMessage{Connect}
  kAccept = 4,      // server -> client, payload: ControlMessage{Accept}
  kReject = 5,      // server -> client, payload: ControlMessage{Reject}
  kData = 16,       // either way, connection header + chunks (connection.h)
  kDisconnect = 17, // either way, connection header + 1 byte DisconnectReason
};

// Why an incoming datagram was dropped. Stable numbers; the metrics label is DropReasonName().
enum class DropReason : uint8_t {
  kTooShort = 0,
  kTooLarge,
  kBadProtocolId,
  kBadVersion,
  kUnknownType,
  kUnknownConnection,  // data for a connection id the receiver does not have
  kWrongAddress,       // a known connection id from another address
  kMalformed,          // body failed to parse or verify
  kStale,              // older than the newest unreliable packet already delivered
  kDuplicate,          // a packet sequence already received
  kHelloTooSmall,      // anti-amplification: hello below kMinHelloPacketSize
  kBadCookie,
  kBadToken,
  kNotOwner,           // state update for an entity the sender does not own
  kInvalidValue,       // NaN / infinite / out-of-range value in a message
  kRateLimited,
  kUnknownEntity,      // state update for an entity id the room does not have
  kNotJoined,          // state update from a connection that has joined no room
  kBadAuth,            // a sealed packet whose AEAD tag does not verify (forged, corrupted)
  kReplayed,           // a sealed packet already received, or older than the replay window
  kReassemblyFull,     // reliable units that would pass the connection's reassembly memory
                       // bound (ConnectionConfig::max_held_reliable_bytes); resent by the peer
  kSessionHeld,        // a Connect with another token from an address holding a live session
  kCount               // number of reasons; not a reason
};

std::string_view DropReasonName(DropReason reason);

struct PacketPrefix {
  PacketType type;
  uint32_t connection_id;
};

// Parses the prefix of `packet`. On failure returns false and sets `*reason`.
bool ParsePacketPrefix(std::span<const uint8_t> packet, PacketPrefix* prefix, DropReason* reason);

// Writes the prefix into `out` (at least kPacketPrefixSize bytes). Returns bytes written.
size_t WritePacketPrefix(PacketType type, uint32_t connection_id, std::span<uint8_t> out);

}  // namespace edgephys
