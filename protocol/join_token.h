// Join tokens: what an operator's backend hands a player so that the relay admits them.
//
// A token grants one player id one room until an expiry, with permissions, and is signed with
// HMAC-SHA256 under the operator's secret (shared by the backend and the relay; never sent).
// Binary layout (little-endian), docs/protocol.md "Join tokens":
//   u8 version (1) | u32 player_id | u32 permissions | u64 expiry (unix seconds)
//   | u64 nonce | u8 room length (1..64) | room bytes | 32-byte HMAC-SHA256 of all before it
// Its printable form (CLI, HTTP) is unpadded base64url of those bytes.
//
// Thread-safety: the free functions are thread-safe; ReplayGuard is not (one owner thread).
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "protocol/status.h"

namespace edgephys {

inline constexpr size_t kMaxRoomNameSize = 64;
inline constexpr size_t kJoinTokenMacSize = 32;
inline constexpr size_t kMaxJoinTokenSize = 1 + 4 + 4 + 8 + 8 + 1 + kMaxRoomNameSize + kJoinTokenMacSize;

// Permission bits.
inline constexpr uint32_t kPermissionSpawn = 1u << 0;     // may spawn and publish entities
inline constexpr uint32_t kPermissionOperator = 1u << 1;  // may create rooms with custom settings
inline constexpr uint32_t kPermissionWorker = 1u << 2;    // a remote PhyS worker (edgephys-phys)
inline constexpr uint32_t kPermissionMessage = 1u << 3;   // may send application messages
inline constexpr uint32_t kPermissionProperty = 1u << 4;  // may write room/entity properties
inline constexpr uint32_t kDefaultPermissions =
    kPermissionSpawn | kPermissionMessage | kPermissionProperty;

struct JoinToken {
  std::string room;          // 1..kMaxRoomNameSize bytes
  uint32_t player_id = 0;    // non-zero, unique per player within the operator's game
  uint32_t permissions = kDefaultPermissions;
  uint64_t expiry_unix_s = 0;
  uint64_t nonce = 0;        // random; a relay accepts each nonce once (replay protection)
};

// Signs `token` with `secret`. Fails (kInvalidArgument) on an empty secret, a zero player id,
// or a room name outside 1..kMaxRoomNameSize bytes.
Result<std::vector<uint8_t>> SignJoinToken(const JoinToken& token, std::string_view secret);

// Checks layout, MAC (constant time) and expiry against `now_unix_s`. Untrusted input: any
// bytes give a result, never a crash. Every failure is kUnauthenticated: IsExpiredToken() is
// true for a well-formed, correctly signed token whose expiry is <= `now_unix_s` (schema
// RejectReason ExpiredToken; the detail names both times), false for anything else (BadToken).
Result<JoinToken> VerifyJoinToken(std::span<const uint8_t> bytes, std::string_view secret,
                                  uint64_t now_unix_s);
// True if `status` is VerifyJoinToken's "expired token" failure.
bool IsExpiredToken(const Status& status);

// Why a token was refused; maps onto schema RejectReason BadToken / ExpiredToken.
enum class TokenError { kNone, kBad, kExpired };
// Transitional form for callers not yet converted (relay/relay.cc, tests/fuzz): the same
// result, and `*error` set from it (kNone on success). Prefer the form above.
Result<JoinToken> VerifyJoinToken(std::span<const uint8_t> bytes, std::string_view secret,
                                  uint64_t now_unix_s, TokenError* error);

// The routing fields of a token, read without checking its MAC or expiry (for a router that
// must send every Connect carrying one token to the same place; never for admission).
// Applies exactly VerifyJoinToken's layout checks, so a token that verifies always peeks, with
// the same values. Returns false on a malformed layout. Untrusted input; O(1), no allocation.
struct JoinTokenRoute {
  std::string_view room;  // points into the peeked bytes
  uint32_t permissions = 0;
  uint64_t nonce = 0;
};
bool PeekJoinToken(std::span<const uint8_t> bytes, JoinTokenRoute* route);

std::string Base64UrlEncode(std::span<const uint8_t> bytes);
// Returns kMalformed on characters outside the base64url alphabet.
Result<std::vector<uint8_t>> Base64UrlDecode(std::string_view text);

// Remembers the nonces of accepted tokens until they expire, so a token admits one connection.
// Memory is bounded by `capacity`; when full, Admit() refuses new nonces (kResourceExhausted)
// rather than forget one that has not expired.
class ReplayGuard {
 public:
  explicit ReplayGuard(size_t capacity = 1 << 20) : capacity_(capacity) {}
  // OK if `nonce` was not seen (and records it); kAlreadyExists if it was.
  Status Admit(uint64_t nonce, uint64_t expiry_unix_s, uint64_t now_unix_s);
  size_t size() const { return seen_.size(); }

 private:
  void Prune(uint64_t now_unix_s);
  size_t capacity_;
  uint64_t last_prune_s_ = 0;
  std::unordered_map<uint64_t, uint64_t> seen_;  // nonce -> expiry
};

}  // namespace edgephys
