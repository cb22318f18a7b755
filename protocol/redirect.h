// Signed redirects: how a relay of a cluster sends a connecting client to the relay that holds
// its room (docs/protocol.md, "Redirect"), and how the client SDK checks one.
//
// The MAC is HMAC-SHA256 under a key derived from the token's session secret
// (HMAC-SHA256(secret, "edgephys redirect key")): only a relay (which decrypts the secret from
// the token) or the client (which got it beside the token) can make or check it; an observer
// who saw the token in a Connect cannot, so a datagram spoofed by anyone else is refused. It
// covers "EPRD" | u8 version (1) | u8 room length | room | u64
// token nonce | u64 expiry | u16 address length | address. A redirect is bound to one token
// (room and nonce) and expires (the relay gives it kRedirectLifetimeS).
//
// Thread-safety: free functions, thread-safe. Untrusted input: any bytes give a Status.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "edgephys/schema/control_generated.h"
#include "protocol/join_token.h"
#include "protocol/status.h"

namespace edgephys {

inline constexpr double kRedirectLifetimeS = 30.0;
inline constexpr size_t kMaxRedirectAddressSize = 128;

struct RedirectTicket {
  std::string address;  // host:port
  std::string room;
  uint64_t token_nonce = 0;
  uint64_t expiry_unix_s = 0;
  std::array<uint8_t, 32> mac{};
};

// Signs a redirect to `address` for the holder of `token` (a token relay part the caller has
// verified, and the session secret it carried). kInvalidArgument on a malformed token or an
// address outside 1..kMaxRedirectAddressSize.
Result<RedirectTicket> SignRedirect(std::span<const uint8_t> token, const SessionSecret& secret,
                                    std::string_view address, uint64_t expiry_unix_s);
// OK if `ticket` was signed for `token` (its relay part) under `secret` and has not expired at
// `now_unix_s`; else kUnauthenticated ("forged redirect": MAC, room or nonce mismatch;
// "expired redirect").
Status VerifyRedirect(const RedirectTicket& ticket, std::span<const uint8_t> token,
                      const SessionSecret& secret, uint64_t now_unix_s);

// The handshake datagram (PacketType::kReject, ControlMessage{Redirect}) carrying `ticket`.
std::vector<uint8_t> BuildRedirectPacket(const RedirectTicket& ticket);
// Reads a verified ControlMessage{Redirect}; kMalformed on a missing field or a MAC that is not
// 32 bytes (the MAC itself is checked by VerifyRedirect).
Result<RedirectTicket> ParseRedirect(const schema::Redirect& message);

}  // namespace edgephys
