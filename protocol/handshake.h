// Handshake helpers shared by the relay and the client SDK (docs/protocol.md, "Handshake").
//
//   client                                   relay
//   Hello{nonce, padding} (>= 1000 bytes) -->
//                                         <-- Challenge{cookie}          (stateless, < hello)
//   Connect{cookie, token, nonce, client key, version, proof} -->
//                                         <-- Accept{connection id, ..., relay key, proof}
//                                             | Reject{reason}
//
// The relay keeps no state for an address until a Connect carries a cookie it issued to that
// address and nonce within kCookieLifetimeS, and never answers an unverified address with
// more bytes than the datagram that provoked the answer.
//
// Mutual authentication: both proofs are HMAC-SHA256 under the token's session secret, which
// the client got from its backend beside the token and the relay decrypts from the token
// (protocol/join_token.h). The Connect proof covers the client's nonce, the cookie, the relay
// part of the token and the client's public key; the Accept proof covers the Connect proof
// and everything the Accept says (relay key, connection id, player id, timers). A man in the
// middle that substitutes either public key cannot make the other side's check pass.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "edgephys/schema/control_generated.h"
#include "protocol/datagram_socket.h"
#include "protocol/join_token.h"
#include "protocol/packet.h"
#include "protocol/status.h"

namespace edgephys {

inline constexpr size_t kCookieSize = 24;  // u64 issue time (ms) + 16 bytes of HMAC
inline constexpr double kCookieLifetimeS = 10.0;

// Issues and checks stateless challenge cookies: HMAC-SHA256 (truncated to 16 bytes) under a
// random per-process key over the client's address, port, nonce and the issue time.
// Jars built from the same Key issue and accept the same cookies (relay shards share one).
// Thread-safety: const methods are thread-safe.
class CookieJar {
 public:
  using Key = std::array<uint8_t, 32>;
  CookieJar();  // draws a random 32-byte key from OpenSSL's RNG
  explicit CookieJar(const Key& key) : key_(key) {}
  // A fresh random key from OpenSSL's RNG (aborts if the RNG fails, as CookieJar() does).
  static Key RandomKey();
  using Cookie = std::array<uint8_t, kCookieSize>;
  Cookie Issue(const Endpoint& from, uint64_t client_nonce, double now) const;
  // True if `cookie` was issued by this jar to `from`/`client_nonce` at most
  // kCookieLifetimeS before `now`.
  bool Verify(std::span<const uint8_t> cookie, const Endpoint& from, uint64_t client_nonce,
              double now) const;

 private:
  void Mac(const Endpoint& from, uint64_t nonce, uint64_t issued_ms, uint8_t out[16]) const;
  Key key_;
};

// Builds a handshake datagram: packet prefix (connection id 0) followed by `message`.
// `pad_to` zero-pads the datagram to that size (used for Hello).
std::vector<uint8_t> BuildHandshakePacket(PacketType type, const flatbuffers::FlatBufferBuilder& message,
                                          size_t pad_to = 0);

// Verifies that `payload` holds a ControlMessage (identifier "EPCM") with a body of type
// `expected` (NONE: any). Returns nullptr when it does not. Trailing padding is allowed.
// The result points into `payload` when it is 8-byte aligned, else into a thread-local
// aligned copy that the next call on this thread overwrites: use it before verifying another.
// Cost: O(size) verification (plus a copy when misaligned).
const schema::ControlMessage* VerifyControlMessage(std::span<const uint8_t> payload,
                                                   schema::Body expected = schema::Body::NONE);

// Finishes `fbb` with `body` as a ControlMessage with the "EPCM" identifier.
template <typename T>
void FinishControl(flatbuffers::FlatBufferBuilder& fbb, flatbuffers::Offset<T> body) {
  auto msg = schema::CreateControlMessage(fbb, schema::BodyTraits<T>::enum_value, body.Union());
  schema::FinishControlMessageBuffer(fbb, msg);
}

// Random 64-bit value from OpenSSL's CSPRNG (nonces, connection ids).
uint64_t SecureRandom64();

// The handshake version a Connect carries (schema Connect.version). A relay answers any other
// (an older SDK's Connect has none: 0) with Reject{BadVersion}.
inline constexpr uint8_t kHandshakeVersion = 2;
inline constexpr size_t kHandshakeProofSize = 32;
using HandshakeProof = std::array<uint8_t, kHandshakeProofSize>;

// What the Connect proof covers (docs/protocol.md §2, "Proofs"):
//   HMAC-SHA256(session secret, "EPCP" | u8 version | u64 client_nonce | u16 len | cookie
//               | u16 len | relay token | u16 len | client_key)        (integers little-endian)
struct ConnectTranscript {
  uint64_t client_nonce = 0;
  std::span<const uint8_t> cookie;
  std::span<const uint8_t> token;       // the relay part, exactly as sent
  std::span<const uint8_t> client_key;  // empty if none was sent
};
HandshakeProof ConnectProof(const SessionSecret& secret, const ConnectTranscript& t);

// What the Accept proof covers:
//   HMAC-SHA256(session secret, "EPAP" | u8 version | connect proof (32) | u16 len | relay_key
//               | u32 connection_id | u32 player_id | u32 keepalive_ms | u32 timeout_ms)
struct AcceptTranscript {
  HandshakeProof connect_proof{};
  std::span<const uint8_t> relay_key;  // empty if the Accept carries none
  uint32_t connection_id = 0;
  uint32_t player_id = 0;
  uint32_t keepalive_ms = 0;
  uint32_t timeout_ms = 0;
};
HandshakeProof AcceptProof(const SessionSecret& secret, const AcceptTranscript& t);

// True if `received` (untrusted, any size) is exactly `expected`; constant time in the content.
bool ProofMatches(const flatbuffers::Vector<uint8_t>* received, const HandshakeProof& expected);

// The Connect datagram of this handshake version: `transcript`'s fields, version, and the proof
// under `secret` (also stored in `*proof` if not null, for checking the Accept).
std::vector<uint8_t> BuildConnectPacket(const ConnectTranscript& transcript,
                                        const SessionSecret& secret,
                                        HandshakeProof* proof = nullptr);

}  // namespace edgephys
