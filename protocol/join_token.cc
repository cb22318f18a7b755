#include "protocol/join_token.h"

#include <openssl/crypto.h>
#include <openssl/evp.h>
#include <openssl/hmac.h>
#include <openssl/rand.h>

#include <algorithm>
#include <array>
#include <cstdlib>
#include <cstring>
#include <string>

#include "protocol/byte_io.h"
#include "protocol/hkdf.h"

namespace edgephys {
namespace {

constexpr size_t kFixedSize = kJoinTokenFieldsSize;
constexpr std::string_view kTokenKeyInfo = "edgephys token key";
// VerifyJoinToken's two failure messages; IsExpiredToken tells them apart.
constexpr std::string_view kBadTokenMessage = "bad token";
constexpr std::string_view kExpiredTokenMessage = "expired token";

std::array<uint8_t, kJoinTokenMacSize> Mac(std::span<const uint8_t> key,
                                           std::span<const uint8_t> data) {
  std::array<uint8_t, kJoinTokenMacSize> mac{};
  unsigned int len = 0;
  HMAC(EVP_sha256(), key.data(), static_cast<int>(key.size()), data.data(), data.size(),
       mac.data(), &len);
  return mac;
}

std::span<const uint8_t> Bytes(std::string_view s) {
  return {reinterpret_cast<const uint8_t*>(s.data()), s.size()};
}

// The keys that seal a token's session secret, derived from the operator's secret:
// HKDF-SHA256(ikm = secret, no salt, info = "edgephys token key") -> 64 bytes: the
// ChaCha20-Poly1305 key, then the key of the synthetic seal nonce.
struct TokenKeys {
  std::array<uint8_t, 32> seal{};
  std::array<uint8_t, 32> nonce{};
};

bool DeriveTokenKeys(std::string_view secret, TokenKeys* keys) {
  std::array<uint8_t, 64> okm{};
  const bool ok = HkdfSha256({}, Bytes(secret), Bytes(kTokenKeyInfo), okm);
  std::memcpy(keys->seal.data(), okm.data(), 32);
  std::memcpy(keys->nonce.data(), okm.data() + 32, 32);
  OPENSSL_cleanse(okm.data(), okm.size());
  return ok;
}

// ChaCha20-Poly1305 of one session secret. `aad` is authenticated, `in` (32 bytes) encrypted
// into `out` (32 bytes) with its tag in `tag`; decrypting checks `tag` instead. False if
// OpenSSL fails or (decrypting) the tag does not verify.
bool SealSecret(bool encrypt, const std::array<uint8_t, 32>& key, const uint8_t* nonce,
                std::span<const uint8_t> aad, const uint8_t* in, uint8_t* out, uint8_t* tag) {
  EVP_CIPHER_CTX* ctx = EVP_CIPHER_CTX_new();
  if (ctx == nullptr) return false;
  int len = 0;
  bool ok = EVP_CipherInit_ex(ctx, EVP_chacha20_poly1305(), nullptr, nullptr, nullptr,
                              encrypt ? 1 : 0) == 1 &&
            EVP_CIPHER_CTX_ctrl(ctx, EVP_CTRL_AEAD_SET_IVLEN, kTokenSealNonceSize, nullptr) == 1 &&
            EVP_CipherInit_ex(ctx, nullptr, nullptr, key.data(), nonce, encrypt ? 1 : 0) == 1 &&
            EVP_CipherUpdate(ctx, nullptr, &len, aad.data(), static_cast<int>(aad.size())) == 1 &&
            EVP_CipherUpdate(ctx, out, &len, in, kSessionSecretSize) == 1;
  if (ok && !encrypt) {
    ok = EVP_CIPHER_CTX_ctrl(ctx, EVP_CTRL_AEAD_SET_TAG, kTokenSealTagSize, tag) == 1;
  }
  ok = ok && EVP_CipherFinal_ex(ctx, out + len, &len) == 1;
  if (ok && encrypt) {
    ok = EVP_CIPHER_CTX_ctrl(ctx, EVP_CTRL_AEAD_GET_TAG, kTokenSealTagSize, tag) == 1;
  }
  EVP_CIPHER_CTX_free(ctx);
  return ok;
}

// The layout checks shared by VerifyJoinToken, PeekJoinToken and SplitClientToken, in this
// order. kOk sets `*room_size`.
enum class Layout { kOk, kTruncated, kBadVersion, kBadRoomLength, kExtended };

Layout CheckLayout(std::span<const uint8_t> bytes, size_t* room_size) {
  if (bytes.empty()) return Layout::kTruncated;
  if (bytes[0] != kJoinTokenVersion) return Layout::kBadVersion;
  if (bytes.size() < kMinJoinTokenSize) return Layout::kTruncated;
  size_t room = bytes[kFixedSize - 1];
  if (room == 0 || room > kMaxRoomNameSize) return Layout::kBadRoomLength;
  if (bytes.size() < JoinTokenSize(room)) return Layout::kTruncated;
  if (bytes.size() > JoinTokenSize(room)) return Layout::kExtended;
  *room_size = room;
  return Layout::kOk;
}

std::string LayoutDetail(Layout layout, std::span<const uint8_t> bytes) {
  const std::string n = std::to_string(bytes.size()) + " bytes";
  switch (layout) {
    case Layout::kOk: return {};
    case Layout::kTruncated:
      return "truncated: " + n + (bytes.size() < kMinJoinTokenSize || bytes.empty()
                                      ? ", the smallest token is " + std::to_string(kMinJoinTokenSize)
                                      : ", a token for a room of " + std::to_string(bytes[kFixedSize - 1]) +
                                            " bytes is " + std::to_string(JoinTokenSize(bytes[kFixedSize - 1])));
    case Layout::kBadVersion:
      return "version " + std::to_string(bytes[0]) + ", expected " + std::to_string(kJoinTokenVersion) +
             " (a token from an older token tool?)";
    case Layout::kBadRoomLength:
      return "room length " + std::to_string(bytes[kFixedSize - 1]) + " outside 1.." +
             std::to_string(kMaxRoomNameSize);
    case Layout::kExtended:
      return "extended: " + n + ", a token for a room of " + std::to_string(bytes[kFixedSize - 1]) +
             " bytes is " + std::to_string(JoinTokenSize(bytes[kFixedSize - 1])) +
             " (a client token sent whole? only its relay part goes to a relay)";
  }
  return {};
}

constexpr char kAlphabet[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789-_";

int DecodeChar(char c) {
  if (c >= 'A' && c <= 'Z') return c - 'A';
  if (c >= 'a' && c <= 'z') return c - 'a' + 26;
  if (c >= '0' && c <= '9') return c - '0' + 52;
  if (c == '-') return 62;
  if (c == '_') return 63;
  return -1;
}

}  // namespace

Result<std::vector<uint8_t>> SignJoinToken(const JoinToken& token, std::string_view secret) {
  if (secret.empty()) return Status::InvalidArgument("empty secret");
  if (token.player_id == 0) return Status::InvalidArgument("player id 0");
  if (token.room.empty() || token.room.size() > kMaxRoomNameSize) {
    return Status::InvalidArgument("room name must be 1..64 bytes");
  }
  SessionSecret session = token.session_secret;
  if (session == SessionSecret{} &&
      RAND_bytes(session.data(), static_cast<int>(session.size())) != 1) {
    std::abort();  // the CSPRNG failing is not recoverable for a minter of secrets
  }
  TokenKeys keys;
  if (!DeriveTokenKeys(secret, &keys)) {
    return Status::ResourceExhausted("token key derivation failed (OpenSSL)");
  }

  const size_t room = token.room.size();
  const size_t relay_size = JoinTokenSize(room);
  std::vector<uint8_t> out(relay_size + kSessionSecretSize);
  uint8_t* p = out.data();
  p[0] = kJoinTokenVersion;
  StoreU32LE(p + 1, token.player_id);
  StoreU32LE(p + 5, token.permissions);
  StoreU64LE(p + 9, token.expiry_unix_s);
  StoreU64LE(p + 17, token.nonce);
  p[25] = static_cast<uint8_t>(room);
  std::copy(token.room.begin(), token.room.end(), p + kFixedSize);
  // Synthetic nonce: the first 12 bytes of HMAC(nonce key, fields | room | session secret).
  // Distinct tokens get distinct nonces without trusting an RNG per token; the same inputs
  // give the same token, which reveals nothing new.
  const size_t fields = kFixedSize + room;
  uint8_t* seal_nonce = p + fields;
  std::copy(session.begin(), session.end(), seal_nonce);  // scratch: fields | session secret
  auto nonce_mac = Mac(keys.nonce, std::span<const uint8_t>(p, fields + kSessionSecretSize));
  std::copy_n(nonce_mac.begin(), kTokenSealNonceSize, seal_nonce);
  uint8_t* cipher = seal_nonce + kTokenSealNonceSize;
  uint8_t* tag = cipher + kSessionSecretSize;
  if (!SealSecret(true, keys.seal, seal_nonce,
                  std::span<const uint8_t>(p, fields + kTokenSealNonceSize), session.data(),
                  cipher, tag)) {
    return Status::ResourceExhausted("sealing the session secret failed (OpenSSL)");
  }
  const size_t body = relay_size - kJoinTokenMacSize;
  auto mac = Mac(Bytes(secret), std::span<const uint8_t>(p, body));
  std::copy(mac.begin(), mac.end(), p + body);
  std::copy(session.begin(), session.end(), p + relay_size);
  OPENSSL_cleanse(&keys, sizeof(keys));
  return out;
}

Result<ClientToken> SplitClientToken(std::span<const uint8_t> client_token) {
  if (client_token.empty()) return Status::Malformed("empty client token");
  if (client_token[0] != kJoinTokenVersion) {
    return Status::Malformed("not a client token",
                             "version " + std::to_string(client_token[0]) + ", expected " +
                                 std::to_string(kJoinTokenVersion));
  }
  if (client_token.size() < kFixedSize) {
    return Status::Malformed("not a client token",
                             "truncated: " + std::to_string(client_token.size()) + " bytes");
  }
  const size_t room = client_token[kFixedSize - 1];
  if (room == 0 || room > kMaxRoomNameSize) {
    return Status::Malformed("not a client token",
                             "room length " + std::to_string(room) + " outside 1..64");
  }
  const size_t relay_size = JoinTokenSize(room);
  if (client_token.size() == relay_size) {
    return Status::Malformed("not a client token",
                             "a relay part without its session secret (mint tokens with this "
                             "release's token tool and pass the whole client token)");
  }
  if (client_token.size() != relay_size + kSessionSecretSize) {
    return Status::Malformed("not a client token",
                             std::to_string(client_token.size()) + " bytes; a client token for a room of " +
                                 std::to_string(room) + " bytes is " +
                                 std::to_string(relay_size + kSessionSecretSize));
  }
  ClientToken out;
  out.relay_token = client_token.first(relay_size);
  std::copy_n(client_token.data() + relay_size, kSessionSecretSize, out.session_secret.begin());
  return out;
}

Result<JoinToken> VerifyJoinToken(std::span<const uint8_t> bytes, std::string_view secret,
                                  uint64_t now_unix_s) {
  if (secret.empty()) return Status::Unauthenticated(kBadTokenMessage, "no operator secret");
  size_t room = 0;
  if (Layout layout = CheckLayout(bytes, &room); layout != Layout::kOk) {
    return Status::Unauthenticated(kBadTokenMessage, LayoutDetail(layout, bytes));
  }
  const size_t fields = kFixedSize + room;
  const size_t body = JoinTokenSize(room) - kJoinTokenMacSize;
  auto mac = Mac(Bytes(secret), bytes.first(body));
  if (CRYPTO_memcmp(mac.data(), bytes.data() + body, kJoinTokenMacSize) != 0) {
    return Status::Unauthenticated(kBadTokenMessage,
                                   "MAC mismatch (signed with another operator secret, or altered)");
  }
  JoinToken token;
  TokenKeys keys;
  const uint8_t* seal_nonce = bytes.data() + fields;
  const uint8_t* cipher = seal_nonce + kTokenSealNonceSize;
  std::array<uint8_t, kTokenSealTagSize> tag{};
  std::copy_n(cipher + kSessionSecretSize, kTokenSealTagSize, tag.begin());
  const bool opened =
      DeriveTokenKeys(secret, &keys) &&
      SealSecret(false, keys.seal, seal_nonce, bytes.first(fields + kTokenSealNonceSize), cipher,
                 token.session_secret.data(), tag.data());
  OPENSSL_cleanse(&keys, sizeof(keys));
  if (!opened) {
    return Status::Unauthenticated(
        kBadTokenMessage,
        "the session secret does not decrypt (altered, or sealed under another operator secret)");
  }
  token.player_id = LoadU32LE(bytes.data() + 1);
  token.permissions = LoadU32LE(bytes.data() + 5);
  token.expiry_unix_s = LoadU64LE(bytes.data() + 9);
  token.nonce = LoadU64LE(bytes.data() + 17);
  token.room.assign(reinterpret_cast<const char*>(bytes.data() + kFixedSize), room);
  if (token.player_id == 0) return Status::Unauthenticated(kBadTokenMessage, "player id 0");
  if (token.expiry_unix_s <= now_unix_s) {
    return Status::Unauthenticated(kExpiredTokenMessage,
                                   "expiry " + std::to_string(token.expiry_unix_s) +
                                       " <= now " + std::to_string(now_unix_s) + " (unix s)");
  }
  return token;
}

bool IsExpiredToken(const Status& status) {
  return status.IsUnauthenticated() && status.message() == kExpiredTokenMessage;
}

Result<JoinToken> VerifyJoinToken(std::span<const uint8_t> bytes, std::string_view secret,
                                  uint64_t now_unix_s, TokenError* error) {
  Result<JoinToken> token = VerifyJoinToken(bytes, secret, now_unix_s);
  *error = token.ok() ? TokenError::kNone
                      : (IsExpiredToken(token.status()) ? TokenError::kExpired : TokenError::kBad);
  return token;
}

bool PeekJoinToken(std::span<const uint8_t> bytes, JoinTokenRoute* route) {
  size_t room = 0;
  if (CheckLayout(bytes, &room) != Layout::kOk) return false;  // VerifyJoinToken's checks
  route->permissions = LoadU32LE(bytes.data() + 5);
  route->nonce = LoadU64LE(bytes.data() + 17);
  route->room = std::string_view(reinterpret_cast<const char*>(bytes.data() + kFixedSize), room);
  return true;
}

std::string Base64UrlEncode(std::span<const uint8_t> bytes) {
  std::string out;
  out.reserve((bytes.size() * 4 + 2) / 3);
  size_t i = 0;
  for (; i + 3 <= bytes.size(); i += 3) {
    uint32_t v = (bytes[i] << 16) | (bytes[i + 1] << 8) | bytes[i + 2];
    for (int s = 18; s >= 0; s -= 6) out.push_back(kAlphabet[(v >> s) & 63]);
  }
  size_t rest = bytes.size() - i;
  if (rest == 1) {
    uint32_t v = bytes[i] << 16;
    out.push_back(kAlphabet[(v >> 18) & 63]);
    out.push_back(kAlphabet[(v >> 12) & 63]);
  } else if (rest == 2) {
    uint32_t v = (bytes[i] << 16) | (bytes[i + 1] << 8);
    out.push_back(kAlphabet[(v >> 18) & 63]);
    out.push_back(kAlphabet[(v >> 12) & 63]);
    out.push_back(kAlphabet[(v >> 6) & 63]);
  }
  return out;
}

Result<std::vector<uint8_t>> Base64UrlDecode(std::string_view text) {
  while (!text.empty() && text.back() == '=') text.remove_suffix(1);
  if (text.size() % 4 == 1) return Status::Malformed("bad base64url length");
  std::vector<uint8_t> out;
  out.reserve(text.size() * 3 / 4);
  uint32_t acc = 0;
  int bits = 0;
  for (char c : text) {
    int v = DecodeChar(c);
    if (v < 0) return Status::Malformed("bad base64url character");
    acc = (acc << 6) | static_cast<uint32_t>(v);
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      out.push_back(static_cast<uint8_t>(acc >> bits));
    }
  }
  return out;
}

Status ReplayGuard::Admit(uint64_t nonce, uint64_t expiry_unix_s, uint64_t now_unix_s) {
  if (now_unix_s >= last_prune_s_ + 10 || seen_.size() >= capacity_) Prune(now_unix_s);
  if (seen_.count(nonce) != 0) return Status::AlreadyExists("replayed token");
  if (seen_.size() >= capacity_) {
    return Status::ResourceExhausted("replay guard full");
  }
  seen_.emplace(nonce, expiry_unix_s);
  return Status::Ok();
}

void ReplayGuard::Prune(uint64_t now_unix_s) {
  last_prune_s_ = now_unix_s;
  std::erase_if(seen_, [now_unix_s](const auto& kv) { return kv.second <= now_unix_s; });
}

}  // namespace edgephys
