#include "protocol/packet.h"

#include "protocol/byte_io.h"

namespace edgephys {
namespace {

bool IsKnownType(uint8_t type) {
  switch (static_cast<PacketType>(type)) {
    case PacketType::kHello:
    case PacketType::kChallenge:
    case PacketType::kConnect:
    case PacketType::kAccept:
    case PacketType::kReject:
    case PacketType::kData:
    case PacketType::kDisconnect:
      return true;
  }
  return false;
}

bool Fail(DropReason* reason, DropReason value) {
  if (reason != nullptr) *reason = value;
  return false;
}

}  // namespace

std::string_view DropReasonName(DropReason reason) {
  switch (reason) {
    case DropReason::kBadAuth:
      return "bad_auth";
    case DropReason::kReplayed:
      return "replayed";
    case DropReason::kReassemblyFull:
      return "reassembly_full";
    case DropReason::kSessionHeld:
      return "session_held";
    case DropReason::kTooShort:
      return "too_short";
    case DropReason::kTooLarge:
      return "too_large";
    case DropReason::kBadProtocolId:
      return "bad_protocol_id";
    case DropReason::kBadVersion:
      return "bad_version";
    case DropReason::kUnknownType:
      return "unknown_type";
    case DropReason::kUnknownConnection:
      return "unknown_connection";
    case DropReason::kWrongAddress:
      return "wrong_address";
    case DropReason::kMalformed:
      return "malformed";
    case DropReason::kStale:
      return "stale";
    case DropReason::kDuplicate:
      return "duplicate";
    case DropReason::kHelloTooSmall:
      return "hello_too_small";
    case DropReason::kBadCookie:
      return "bad_cookie";
    case DropReason::kBadToken:
      return "bad_token";
    case DropReason::kNotOwner:
      return "not_owner";
    case DropReason::kInvalidValue:
      return "invalid_value";
    case DropReason::kRateLimited:
      return "rate_limited";
    case DropReason::kUnknownEntity:
      return "unknown_entity";
    case DropReason::kNotJoined:
      return "not_joined";
    case DropReason::kCount:
      break;
  }
  return "unknown";
}

bool ParsePacketPrefix(std::span<const uint8_t> packet, PacketPrefix* prefix, DropReason* reason) {
  if (packet.size() < kPacketPrefixSize) return Fail(reason, DropReason::kTooShort);
  if (packet.size() > kMaxPacketSize) return Fail(reason, DropReason::kTooLarge);
  const uint8_t* p = packet.data();
  if (LoadU32LE(p) != kProtocolId) return Fail(reason, DropReason::kBadProtocolId);
  if (p[4] != kProtocolVersion) return Fail(reason, DropReason::kBadVersion);
  if (!IsKnownType(p[5])) return Fail(reason, DropReason::kUnknownType);
  prefix->type = static_cast<PacketType>(p[5]);
  prefix->connection_id = LoadU32LE(p + 6);
  return true;
}

size_t WritePacketPrefix(PacketType type, uint32_t connection_id, std::span<uint8_t> out) {
  if (out.size() < kPacketPrefixSize) return 0;
  uint8_t* p = out.data();
  StoreU32LE(p, kProtocolId);
  p[4] = kProtocolVersion;
  p[5] = static_cast<uint8_t>(type);
  StoreU32LE(p + 6, connection_id);
  return kPacketPrefixSize;
}

}  // namespace edgephys
