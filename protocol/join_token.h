// Join tokens: what an operator's backend hands a player so that the relay admits them, and
// the session secret that lets the player and the relay authenticate each other
// (docs/protocol.md §2, §3a, §6).
//
// SignJoinToken mints a *client token*: the relay part, then a random 32-byte session secret.
// The backend hands the whole client token to its player over its own secure channel; the SDK
// sends only the relay part (in Connect) and keeps the secret. The relay part grants one player
// id one room until an expiry, with permissions, carries the same session secret encrypted
// for relays (ChaCha20-Poly1305 under a key derived from the operator's secret), and is signed
// with HMAC-SHA256 under the operator's secret (shared by the backend and the relays; never
// sent). Relay part layout (little-endian), version 2:
//   u8 version (2) | u32 player_id | u32 permissions | u64 expiry (unix seconds) | u64 nonce
//   | u8 room length (1..64) | room bytes | 12-byte seal nonce | 32-byte encrypted session
//   secret | 16-byte Poly1305 tag | 32-byte HMAC-SHA256 of all before it
// Client token = relay part | 32-byte session secret (in clear: it never travels to a relay).
// Printable forms (CLI, HTTP, the C API) are unpadded base64url of those bytes.
//
// Thread-safety: the free functions are thread-safe; ReplayGuard is not (one owner thread).
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "protocol/status.h"

namespace edgephys {

inline constexpr size_t kMaxRoomNameSize = 64;
inline constexpr uint8_t kJoinTokenVersion = 2;
inline constexpr size_t kJoinTokenFieldsSize = 1 + 4 + 4 + 8 + 8 + 1;  // before the room name
inline constexpr size_t kSessionSecretSize = 32;
inline constexpr size_t kTokenSealNonceSize = 12;
inline constexpr size_t kTokenSealTagSize = 16;
// The encrypted session secret: seal nonce, ciphertext, tag.
inline constexpr size_t kTokenSealedSecretSize =
    kTokenSealNonceSize + kSessionSecretSize + kTokenSealTagSize;
inline constexpr size_t kJoinTokenMacSize = 32;
// A relay part's size for a room name of `room_size` bytes.
inline constexpr size_t JoinTokenSize(size_t room_size) {
  return kJoinTokenFieldsSize + room_size + kTokenSealedSecretSize + kJoinTokenMacSize;
}
inline constexpr size_t kMinJoinTokenSize = JoinTokenSize(1);                  // 119
inline constexpr size_t kMaxJoinTokenSize = JoinTokenSize(kMaxRoomNameSize);   // 182
inline constexpr size_t kMaxClientTokenSize = kMaxJoinTokenSize + kSessionSecretSize;  // 214

using SessionSecret = std::array<uint8_t, kSessionSecretSize>;

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
  // The secret the client and the relay prove to each other in the handshake and mix into the
  // packet keys. SignJoinToken: all zero (the default) draws a fresh random one (what a
  // backend wants); any other value is sealed as given (deterministic tests and fuzz seeds).
  // VerifyJoinToken: the secret decrypted from the token.
  SessionSecret session_secret{};
};

// Mints the client token for `token` under the operator's `secret`: the signed relay part with
// the session secret sealed in it, then the session secret. Fails (kInvalidArgument) on an
// empty secret, a zero player id, or a room name outside 1..kMaxRoomNameSize bytes;
// kResourceExhausted if OpenSSL's KDF or cipher fails. Aborts if OpenSSL's RNG fails.
Result<std::vector<uint8_t>> SignJoinToken(const JoinToken& token, std::string_view secret);

// A client token split into what goes to the relay and what the client keeps.
struct ClientToken {
  std::span<const uint8_t> relay_token;  // points into the split bytes
  SessionSecret session_secret{};
};
// Splits SignJoinToken's output. Checks the layout only (version, the relay part's size from its
// room length, then exactly kSessionSecretSize bytes): the MAC is for relays to check.
// kMalformed naming the cause otherwise (e.g. a relay part alone, without its secret).
// Untrusted input; O(1), no allocation.
Result<ClientToken> SplitClientToken(std::span<const uint8_t> client_token);

// Checks a relay part: layout, MAC (constant time), the sealed session secret (decrypted into
// the result's session_secret) and expiry against `now_unix_s`. Untrusted input: any bytes give
// a result, never a crash. Every failure is kUnauthenticated with a detail naming its cause
// (truncated or extended, wrong version, MAC mismatch: a wrong operator secret or altered bytes,
// a session secret that does not decrypt, player id 0). IsExpiredToken() is true for a
// well-formed, correctly signed token whose expiry is <= `now_unix_s` (schema RejectReason
// ExpiredToken; the detail names both times), false for anything else (BadToken).
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
