// Packet authentication after the handshake (docs/protocol.md §3a): an ephemeral X25519 key
// exchange, mixed with the session secret that only the client (from its backend) and the
// relays (sealed in the join token) know, yields one ChaCha20-Poly1305 key per direction; every Data
// and Disconnect packet is then sealed (AEAD: the prefix and a 64-bit per-direction sequence
// authenticated in clear, the rest encrypted) and opened with a replay window.
//
//   sealed datagram = prefix (10, clear) | seal sequence u64 LE (8, clear)
//                     | ChaCha20-Poly1305(packet[10..]) | tag (16)
//   nonce (12)      = direction u32 LE (0: client -> relay, 1: relay -> client) | sequence u64 LE
//   AAD             = the first 18 bytes
//
// Keys: ikm = X25519(own private, peer public) | session secret (32);
// salt = SHA-256(join token relay part, as sent in Connect);
// info = "edgephys v2 packet keys" | client public (32) | relay public (32) | client nonce u64 LE
// | connection id u32 LE; HKDF-SHA256 -> 64 bytes: client->relay key, relay->client key.
// Without the session secret, a man in the middle that substituted both public keys cannot
// derive either side's keys.
//
// Thread-safety: a PacketSeal may be used by one thread at a time (one per connection). Cost:
// O(packet) per Seal/Open, no allocation after construction. Failure modes: Open() refuses a
// datagram whose tag does not verify (kBadAuth: forged, corrupted, wrong key) or whose sequence
// was already accepted or is older than the window (kReplayed); the window moves only on a
// verified datagram, so forgeries cannot poison it.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>

#include "protocol/join_token.h"
#include "protocol/packet.h"
#include "protocol/status.h"

namespace edgephys {

inline constexpr size_t kSealSequenceSize = 8;
inline constexpr size_t kSealTagSize = 16;
inline constexpr size_t kSealOverhead = kSealSequenceSize + kSealTagSize;
// Largest datagram on the wire: a full packet, sealed (1224 <= 1232, IPv6's minimum MTU less
// its headers).
inline constexpr size_t kMaxDatagramSize = kMaxPacketSize + kSealOverhead;
inline constexpr size_t kKeyExchangePublicSize = 32;
inline constexpr size_t kReplayWindow = 256;  // sequences

using PacketKey = std::array<uint8_t, 32>;
using KeyExchangePublic = std::array<uint8_t, kKeyExchangePublicSize>;

struct ConnectionKeys {
  PacketKey client_to_relay{};
  PacketKey relay_to_client{};
};

// One side's ephemeral X25519 key pair. Move-only; the private key never leaves it.
class KeyExchange {
 public:
  // Errors: kInternal (OpenSSL failed).
  static Result<KeyExchange> Generate();
  KeyExchange(KeyExchange&&) noexcept;
  KeyExchange& operator=(KeyExchange&&) noexcept;
  ~KeyExchange();
  const KeyExchangePublic& public_key() const { return public_; }
  // The connection's keys given the peer's public key and the handshake transcript (see the top
  // of this file). `own_is_client` says which public key is whose. Errors: kInvalidArgument
  // (a peer key of the wrong size or a degenerate point), kInternal.
  // `token` is the relay part sent in Connect; `session_secret` the token's session secret.
  Result<ConnectionKeys> Derive(std::span<const uint8_t> peer_public, bool own_is_client,
                                std::span<const uint8_t> token,
                                const SessionSecret& session_secret, uint64_t client_nonce,
                                uint32_t connection_id) const;

 private:
  KeyExchange() = default;
  void* pkey_ = nullptr;  // EVP_PKEY*
  KeyExchangePublic public_{};
};

class PacketSeal {
 public:
  enum class Side : uint8_t { kClient, kRelay };
  PacketSeal(const ConnectionKeys& keys, Side side);
  ~PacketSeal();
  PacketSeal(const PacketSeal&) = delete;
  PacketSeal& operator=(const PacketSeal&) = delete;

  // Seals `packet` (a whole plaintext packet, prefix first, kPacketPrefixSize..kMaxPacketSize
  // bytes) into `out` (at least packet.size() + kSealOverhead bytes); returns the datagram's
  // size, 0 if the packet does not fit or OpenSSL failed.
  size_t Seal(std::span<const uint8_t> packet, std::span<uint8_t> out);
  // Opens a sealed datagram into `out` (at least datagram.size() - kSealOverhead bytes): the
  // plaintext packet, prefix first. Returns its size, or 0 with `*reason` set: kBadAuth (also
  // for a datagram too short or too long to be sealed), kReplayed.
  size_t Open(std::span<const uint8_t> datagram, std::span<uint8_t> out, DropReason* reason);
  uint64_t sealed() const { return send_sequence_; }

 private:
  void* send_ctx_ = nullptr;     // EVP_CIPHER_CTX*
  void* receive_ctx_ = nullptr;  // EVP_CIPHER_CTX*
  uint32_t send_direction_;
  uint32_t receive_direction_;
  uint64_t send_sequence_ = 0;
  // Replay window: the newest accepted sequence + 1 (0: none yet), and per slot the sequence
  // + 1 accepted there.
  uint64_t newest_ = 0;
  std::array<uint64_t, kReplayWindow> window_{};
};

}  // namespace edgephys
