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

namespace {

// Appends `bytes` with a u16 length (longer inputs are cut: no valid field comes near it).
void PutField(std::vector<uint8_t>& out, std::span<const uint8_t> bytes) {
  const size_t n = std::min<size_t>(bytes.size(), UINT16_MAX);
  out.push_back(static_cast<uint8_t>(n));
  out.push_back(static_cast<uint8_t>(n >> 8));
  out.insert(out.end(), bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(n));
}

void PutU32(std::vector<uint8_t>& out, uint32_t v) {
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<uint8_t>(v >> (8 * i)));
}

HandshakeProof Hmac(const SessionSecret& key, const std::vector<uint8_t>& data) {
  HandshakeProof out{};
  unsigned int len = 0;
  HMAC(EVP_sha256(), key.data(), static_cast<int>(key.size()), data.data(), data.size(),
       out.data(), &len);
  return out;
}

}  // namespace

HandshakeProof ConnectProof(const SessionSecret& secret, const ConnectTranscript& t) {
  std::vector<uint8_t> m = {'E', 'P', 'C', 'P', kHandshakeVersion};
  m.reserve(5 + 8 + 6 + t.cookie.size() + t.token.size() + t.client_key.size());
  for (int i = 0; i < 8; ++i) m.push_back(static_cast<uint8_t>(t.client_nonce >> (8 * i)));
  PutField(m, t.cookie);
  PutField(m, t.token);
  PutField(m, t.client_key);
  return Hmac(secret, m);
}

HandshakeProof AcceptProof(const SessionSecret& secret, const AcceptTranscript& t) {
  std::vector<uint8_t> m = {'E', 'P', 'A', 'P', kHandshakeVersion};
  m.insert(m.end(), t.connect_proof.begin(), t.connect_proof.end());
  PutField(m, t.relay_key);
  PutU32(m, t.connection_id);
  PutU32(m, t.player_id);
  PutU32(m, t.keepalive_ms);
  PutU32(m, t.timeout_ms);
  return Hmac(secret, m);
}

bool ProofMatches(const flatbuffers::Vector<uint8_t>* received, const HandshakeProof& expected) {
  return received != nullptr && received->size() == kHandshakeProofSize &&
         CRYPTO_memcmp(received->data(), expected.data(), kHandshakeProofSize) == 0;
}

std::vector<uint8_t> BuildConnectPacket(const ConnectTranscript& t, const SessionSecret& secret,
                                        HandshakeProof* proof) {
  const HandshakeProof p = ConnectProof(secret, t);
  if (proof != nullptr) *proof = p;
  flatbuffers::FlatBufferBuilder fbb(512);
  auto cookie = fbb.CreateVector(t.cookie.data(), t.cookie.size());
  auto token = fbb.CreateVector(t.token.data(), t.token.size());
  flatbuffers::Offset<flatbuffers::Vector<uint8_t>> key;
  if (!t.client_key.empty()) key = fbb.CreateVector(t.client_key.data(), t.client_key.size());
  auto proof_vector = fbb.CreateVector(p.data(), p.size());
  FinishControl(fbb, schema::CreateConnect(fbb, cookie, token, t.client_nonce, key,
                                           kHandshakeVersion, proof_vector));
  return BuildHandshakePacket(PacketType::kConnect, fbb);
}

}  // namespace edgephys
