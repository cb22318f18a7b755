// Handshake helpers shared by the relay and the client SDK (docs/protocol.md, "Handshake").
//
//   client                                   relay
//   Hello{nonce, padding} (>= 1000 bytes) -->
//                                         <-- Challenge{cookie}          (stateless, < hello)
//   Connect{cookie, token, nonce}         -->
//                                         <-- Accept{connection id} | Reject{reason}
//
// The relay keeps no state for an address until a Connect carries a cookie it issued to that
// address and nonce within kCookieLifetimeS, and never answers an unverified address with
// more bytes than the datagram that provoked the answer.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "edgephys/schema/control_generated.h"
#include "protocol/datagram_socket.h"
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

}  // namespace edgephys
