// HKDF-SHA256 (RFC 5869, extract then expand) over OpenSSL: the one key derivation behind join
// token keys (protocol/join_token.cc) and connection keys (protocol/packet_seal.cc).
#pragma once

#include <cstdint>
#include <span>

namespace edgephys {

// Fills `out` (at most 255 * 32 bytes) with HKDF-SHA256(salt, ikm, info); an empty `salt` is
// RFC 5869's default (32 zero bytes). False if OpenSSL failed: `out` then holds no usable key.
// Thread-safe.
bool HkdfSha256(std::span<const uint8_t> salt, std::span<const uint8_t> ikm,
                std::span<const uint8_t> info, std::span<uint8_t> out);

}  // namespace edgephys
