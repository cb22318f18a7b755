#include "protocol/handshake.h"

#include <openssl/crypto.h>
#include <openssl/evp.h>
#include <openssl/hmac.h>
#include <openssl/rand.h>

#include <cmath>
#include <cstring>

#include "protocol/byte_io.h"

namespace edgephys {

uint64_t SecureRandom64() {
  uint8_t bytes[8];
  if (RAND_bytes(bytes, sizeof(bytes)) != 1) {
    // The CSPRNG failing is not recoverable for a server handing out keys.
    std::abort();
  }
  return LoadU64LE(bytes);
}

CookieJar::CookieJar() : key_(RandomKey()) {}

CookieJar::Key CookieJar::RandomKey() {
  Key key;
  if (RAND_bytes(key.data(), static_cast<int>(key.size())) != 1) std::abort();
  return key;
}

void CookieJar::Mac(const Endpoint& from, uint64_t nonce, uint64_t issued_ms,
                    uint8_t out[16]) const {
  uint8_t msg[16 + 2 + 8 + 8] = {};
  size_t n = 0;
  if (from.address().is_v4()) {
    auto b = from.address().to_v4().to_bytes();
    std::memcpy(msg, b.data(), b.size());
    n = b.size();
  } else {
    auto b = from.address().to_v6().to_bytes();
    std::memcpy(msg, b.data(), b.size());
    n = b.size();
  }
  StoreU16LE(msg + n, from.port());
  StoreU64LE(msg + n + 2, nonce);
  StoreU64LE(msg + n + 10, issued_ms);
  uint8_t full[32];
  unsigned int len = 0;
  HMAC(EVP_sha256(), key_.data(), static_cast<int>(key_.size()), msg, n + 18, full, &len);
  std::memcpy(out, full, 16);
}

CookieJar::Cookie CookieJar::Issue(const Endpoint& from, uint64_t client_nonce,
                                   double now) const {
  Cookie cookie{};
  uint64_t issued_ms = static_cast<uint64_t>(std::max(0.0, now) * 1000.0);
  StoreU64LE(cookie.data(), issued_ms);
  Mac(from, client_nonce, issued_ms, cookie.data() + 8);
  return cookie;
}

bool CookieJar::Verify(std::span<const uint8_t> cookie, const Endpoint& from,
                       uint64_t client_nonce, double now) const {
  if (cookie.size() != kCookieSize) return false;
  uint64_t issued_ms = LoadU64LE(cookie.data());
  double age = now - static_cast<double>(issued_ms) / 1000.0;
  if (age < -1.0 || age > kCookieLifetimeS) return false;
  uint8_t expected[16];
  Mac(from, client_nonce, issued_ms, expected);
  return CRYPTO_memcmp(expected, cookie.data() + 8, 16) == 0;
}

std::vector<uint8_t> BuildHandshakePacket(PacketType type,
                                          const flatbuffers::FlatBufferBuilder& message,
                                          size_t pad_to) {
  size_t size = kPacketPrefixSize + message.GetSize();
  std::vector<uint8_t> out(std::max(size, std::min(pad_to, kMaxPacketSize)), 0);
  WritePacketPrefix(type, 0, out);
  std::memcpy(out.data() + kPacketPrefixSize, message.GetBufferPointer(), message.GetSize());
  return out;
}

const schema::ControlMessage* VerifyControlMessage(std::span<const uint8_t> payload,
                                                   schema::Body expected) {
  if (payload.size() < 8 || payload.size() > (64u << 20)) return nullptr;
  // FlatBuffers reads scalars in place: a buffer must start 8-byte aligned. Messages inside
  // datagrams rarely do, so misaligned ones are verified and read from an aligned copy.
  if (reinterpret_cast<uintptr_t>(payload.data()) % 8 != 0) {
    thread_local std::vector<uint64_t> aligned;
    aligned.resize((payload.size() + 7) / 8);
    std::memcpy(aligned.data(), payload.data(), payload.size());
    payload = std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(aligned.data()),
                                       payload.size());
  }
  flatbuffers::Verifier::Options options;
  options.max_depth = 16;
  options.max_tables = 1 << 20;
  flatbuffers::Verifier verifier(payload.data(), payload.size(), options);
  if (!schema::VerifyControlMessageBuffer(verifier)) return nullptr;
  const auto* msg = schema::GetControlMessage(payload.data());
  if (msg->body_type() == schema::Body::NONE || msg->body() == nullptr) return nullptr;
  if (expected != schema::Body::NONE && msg->body_type() != expected) return nullptr;
  return msg;
}

}  // namespace edgephys
