#include "protocol/packet_seal.h"

#include <openssl/crypto.h>
#include <openssl/evp.h>
#include <openssl/sha.h>

#include <cstring>
#include <string_view>
#include <vector>

#include "protocol/byte_io.h"
#include "protocol/hkdf.h"

namespace edgephys {
namespace {

constexpr size_t kAadSize = kPacketPrefixSize + kSealSequenceSize;
constexpr std::string_view kKeyInfo = "edgephys v2 packet keys";

EVP_CIPHER_CTX* NewCipher(const PacketKey& key, bool encrypt) {
  EVP_CIPHER_CTX* ctx = EVP_CIPHER_CTX_new();
  if (ctx == nullptr) return nullptr;
  const int ok = encrypt ? EVP_EncryptInit_ex(ctx, EVP_chacha20_poly1305(), nullptr, key.data(), nullptr)
                         : EVP_DecryptInit_ex(ctx, EVP_chacha20_poly1305(), nullptr, key.data(), nullptr);
  if (ok != 1) {
    EVP_CIPHER_CTX_free(ctx);
    return nullptr;
  }
  return ctx;
}

void PutNonce(uint32_t direction, uint64_t sequence, uint8_t nonce[12]) {
  for (int i = 0; i < 4; ++i) nonce[i] = static_cast<uint8_t>(direction >> (8 * i));
  for (int i = 0; i < 8; ++i) nonce[4 + i] = static_cast<uint8_t>(sequence >> (8 * i));
}

}  // namespace

// --- KeyExchange --------------------------------------------------------------------------

Result<KeyExchange> KeyExchange::Generate() {
  KeyExchange kx;
  EVP_PKEY_CTX* ctx = EVP_PKEY_CTX_new_id(EVP_PKEY_X25519, nullptr);
  EVP_PKEY* pkey = nullptr;
  const bool ok = ctx != nullptr && EVP_PKEY_keygen_init(ctx) == 1 && EVP_PKEY_keygen(ctx, &pkey) == 1;
  EVP_PKEY_CTX_free(ctx);
  if (!ok) return Status::Unauthenticated("X25519 key generation failed");
  kx.pkey_ = pkey;
  size_t len = kx.public_.size();
  if (EVP_PKEY_get_raw_public_key(pkey, kx.public_.data(), &len) != 1 || len != kx.public_.size()) {
    return Status::Unauthenticated("X25519 public key unavailable");
  }
  return kx;
}

KeyExchange::KeyExchange(KeyExchange&& o) noexcept : pkey_(o.pkey_), public_(o.public_) {
  o.pkey_ = nullptr;
}

KeyExchange& KeyExchange::operator=(KeyExchange&& o) noexcept {
  if (this != &o) {
    EVP_PKEY_free(static_cast<EVP_PKEY*>(pkey_));
    pkey_ = o.pkey_;
    public_ = o.public_;
    o.pkey_ = nullptr;
  }
  return *this;
}

KeyExchange::~KeyExchange() { EVP_PKEY_free(static_cast<EVP_PKEY*>(pkey_)); }

Result<ConnectionKeys> KeyExchange::Derive(std::span<const uint8_t> peer_public, bool own_is_client,
                                           std::span<const uint8_t> token,
                                           const SessionSecret& session_secret,
                                           uint64_t client_nonce, uint32_t connection_id) const {
  if (peer_public.size() != kKeyExchangePublicSize || pkey_ == nullptr) {
    return Status::InvalidArgument("key exchange: a public key is 32 bytes");
  }
  EVP_PKEY* peer = EVP_PKEY_new_raw_public_key(EVP_PKEY_X25519, nullptr, peer_public.data(),
                                               peer_public.size());
  if (peer == nullptr) return Status::InvalidArgument("key exchange: bad public key");
  // ikm = X25519 shared secret | session secret.
  std::array<uint8_t, 32 + kSessionSecretSize> shared{};
  size_t shared_len = 32;
  EVP_PKEY_CTX* dctx = EVP_PKEY_CTX_new(static_cast<EVP_PKEY*>(pkey_), nullptr);
  const bool derived = dctx != nullptr && EVP_PKEY_derive_init(dctx) == 1 &&
                       EVP_PKEY_derive_set_peer(dctx, peer) == 1 &&
                       EVP_PKEY_derive(dctx, shared.data(), &shared_len) == 1 && shared_len == 32;
  EVP_PKEY_CTX_free(dctx);
  EVP_PKEY_free(peer);
  // An all-zero secret means a small-order peer point (RFC 7748 §6.1): refuse it.
  bool zero = true;
  for (size_t i = 0; i < 32; ++i) zero &= shared[i] == 0;
  if (!derived || zero) return Status::InvalidArgument("key exchange: derivation refused");
  std::memcpy(shared.data() + 32, session_secret.data(), kSessionSecretSize);

  std::array<uint8_t, SHA256_DIGEST_LENGTH> salt{};
  SHA256(token.data(), token.size(), salt.data());
  std::vector<uint8_t> info(kKeyInfo.begin(), kKeyInfo.end());
  const KeyExchangePublic& client = own_is_client ? public_ : *reinterpret_cast<const KeyExchangePublic*>(peer_public.data());
  const uint8_t* relay = own_is_client ? peer_public.data() : public_.data();
  info.insert(info.end(), client.begin(), client.end());
  info.insert(info.end(), relay, relay + kKeyExchangePublicSize);
  for (int i = 0; i < 8; ++i) info.push_back(static_cast<uint8_t>(client_nonce >> (8 * i)));
  for (int i = 0; i < 4; ++i) info.push_back(static_cast<uint8_t>(connection_id >> (8 * i)));

  std::array<uint8_t, 64> okm{};
  const bool expanded = HkdfSha256(salt, shared, info, okm);
  OPENSSL_cleanse(shared.data(), shared.size());
  if (!expanded) return Status::Unauthenticated("key exchange: HKDF failed");
  ConnectionKeys keys;
  std::memcpy(keys.client_to_relay.data(), okm.data(), 32);
  std::memcpy(keys.relay_to_client.data(), okm.data() + 32, 32);
  return keys;
}

// --- PacketSeal ---------------------------------------------------------------------------

PacketSeal::PacketSeal(const ConnectionKeys& keys, Side side)
    : send_direction_(side == Side::kClient ? 0 : 1), receive_direction_(side == Side::kClient ? 1 : 0) {
  const PacketKey& send = side == Side::kClient ? keys.client_to_relay : keys.relay_to_client;
  const PacketKey& receive = side == Side::kClient ? keys.relay_to_client : keys.client_to_relay;
  send_ctx_ = NewCipher(send, /*encrypt=*/true);
  receive_ctx_ = NewCipher(receive, /*encrypt=*/false);
}

PacketSeal::~PacketSeal() {
  EVP_CIPHER_CTX_free(static_cast<EVP_CIPHER_CTX*>(send_ctx_));
  EVP_CIPHER_CTX_free(static_cast<EVP_CIPHER_CTX*>(receive_ctx_));
}

size_t PacketSeal::Seal(std::span<const uint8_t> packet, std::span<uint8_t> out) {
  auto* ctx = static_cast<EVP_CIPHER_CTX*>(send_ctx_);
  if (ctx == nullptr || packet.size() < kPacketPrefixSize || packet.size() > kMaxPacketSize ||
      out.size() < packet.size() + kSealOverhead) {
    return 0;
  }
  const uint64_t sequence = send_sequence_++;
  std::memcpy(out.data(), packet.data(), kPacketPrefixSize);
  for (int i = 0; i < 8; ++i) out[kPacketPrefixSize + i] = static_cast<uint8_t>(sequence >> (8 * i));
  uint8_t nonce[12];
  PutNonce(send_direction_, sequence, nonce);
  int len = 0;
  const int body = static_cast<int>(packet.size() - kPacketPrefixSize);
  uint8_t* cipher = out.data() + kAadSize;
  if (EVP_EncryptInit_ex(ctx, nullptr, nullptr, nullptr, nonce) != 1 ||
      EVP_EncryptUpdate(ctx, nullptr, &len, out.data(), static_cast<int>(kAadSize)) != 1 ||
      EVP_EncryptUpdate(ctx, cipher, &len, packet.data() + kPacketPrefixSize, body) != 1 ||
      EVP_EncryptFinal_ex(ctx, cipher + len, &len) != 1 ||
      EVP_CIPHER_CTX_ctrl(ctx, EVP_CTRL_AEAD_GET_TAG, static_cast<int>(kSealTagSize),
                          cipher + body) != 1) {
    return 0;
  }
  return packet.size() + kSealOverhead;
}

size_t PacketSeal::Open(std::span<const uint8_t> datagram, std::span<uint8_t> out,
                        DropReason* reason) {
  auto* ctx = static_cast<EVP_CIPHER_CTX*>(receive_ctx_);
  if (datagram.size() < kAadSize + kSealTagSize || datagram.size() > kMaxDatagramSize ||
      out.size() < datagram.size() - kSealOverhead) {
    *reason = DropReason::kBadAuth;  // no room for a seal: not an authenticated packet
    return 0;
  }
  uint64_t sequence = 0;
  for (int i = 7; i >= 0; --i) sequence = sequence << 8 | datagram[kPacketPrefixSize + i];
  // Replay check before the (costlier) decryption; the window moves only once verified.
  if (sequence == UINT64_MAX || (newest_ > kReplayWindow && sequence + kReplayWindow < newest_) ||
      window_[sequence % kReplayWindow] == sequence + 1) {
    *reason = DropReason::kReplayed;
    return 0;
  }
  const size_t body = datagram.size() - kAadSize - kSealTagSize;
  uint8_t nonce[12];
  PutNonce(receive_direction_, sequence, nonce);
  int len = 0;
  uint8_t tag[kSealTagSize];
  std::memcpy(tag, datagram.data() + kAadSize + body, kSealTagSize);
  uint8_t* plain = out.data() + kPacketPrefixSize;
  const bool ok =
      ctx != nullptr && EVP_DecryptInit_ex(ctx, nullptr, nullptr, nullptr, nonce) == 1 &&
      EVP_DecryptUpdate(ctx, nullptr, &len, datagram.data(), static_cast<int>(kAadSize)) == 1 &&
      EVP_DecryptUpdate(ctx, plain, &len, datagram.data() + kAadSize, static_cast<int>(body)) == 1 &&
      EVP_CIPHER_CTX_ctrl(ctx, EVP_CTRL_AEAD_SET_TAG, static_cast<int>(kSealTagSize), tag) == 1 &&
      EVP_DecryptFinal_ex(ctx, plain + len, &len) == 1;
  if (!ok) {
    *reason = DropReason::kBadAuth;
    return 0;
  }
  std::memcpy(out.data(), datagram.data(), kPacketPrefixSize);
  window_[sequence % kReplayWindow] = sequence + 1;
  if (sequence + 1 > newest_) newest_ = sequence + 1;
  return kPacketPrefixSize + body;
}

}  // namespace edgephys
