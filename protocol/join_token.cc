#include "protocol/join_token.h"

#include <openssl/crypto.h>
#include <openssl/evp.h>
#include <openssl/hmac.h>

#include <array>
#include <string>

#include "protocol/byte_io.h"

namespace edgephys {
namespace {

constexpr uint8_t kTokenVersion = 1;
constexpr size_t kFixedSize = 1 + 4 + 4 + 8 + 8 + 1;
// VerifyJoinToken's two failure messages; IsExpiredToken tells them apart.
constexpr std::string_view kBadTokenMessage = "bad token";
constexpr std::string_view kExpiredTokenMessage = "expired token";

std::array<uint8_t, kJoinTokenMacSize> Mac(std::string_view secret,
                                           std::span<const uint8_t> data) {
  std::array<uint8_t, kJoinTokenMacSize> mac{};
  unsigned int len = 0;
  HMAC(EVP_sha256(), secret.data(), static_cast<int>(secret.size()), data.data(), data.size(),
       mac.data(), &len);
  return mac;
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
  std::vector<uint8_t> out(kFixedSize + token.room.size() + kJoinTokenMacSize);
  uint8_t* p = out.data();
  p[0] = kTokenVersion;
  StoreU32LE(p + 1, token.player_id);
  StoreU32LE(p + 5, token.permissions);
  StoreU64LE(p + 9, token.expiry_unix_s);
  StoreU64LE(p + 17, token.nonce);
  p[25] = static_cast<uint8_t>(token.room.size());
  std::copy(token.room.begin(), token.room.end(), p + kFixedSize);
  size_t body = kFixedSize + token.room.size();
  auto mac = Mac(secret, std::span<const uint8_t>(out.data(), body));
  std::copy(mac.begin(), mac.end(), p + body);
  return out;
}

Result<JoinToken> VerifyJoinToken(std::span<const uint8_t> bytes, std::string_view secret,
                                  uint64_t now_unix_s) {
  const Status bad = Status::Unauthenticated(kBadTokenMessage);
  if (secret.empty() || bytes.size() < kFixedSize + 1 + kJoinTokenMacSize ||
      bytes.size() > kMaxJoinTokenSize || bytes[0] != kTokenVersion) {
    return bad;
  }
  size_t room_size = bytes[25];
  if (room_size == 0 || room_size > kMaxRoomNameSize ||
      bytes.size() != kFixedSize + room_size + kJoinTokenMacSize) {
    return bad;
  }
  size_t body = kFixedSize + room_size;
  auto mac = Mac(secret, bytes.first(body));
  if (CRYPTO_memcmp(mac.data(), bytes.data() + body, kJoinTokenMacSize) != 0) return bad;

  JoinToken token;
  token.player_id = LoadU32LE(bytes.data() + 1);
  token.permissions = LoadU32LE(bytes.data() + 5);
  token.expiry_unix_s = LoadU64LE(bytes.data() + 9);
  token.nonce = LoadU64LE(bytes.data() + 17);
  token.room.assign(reinterpret_cast<const char*>(bytes.data() + kFixedSize), room_size);
  if (token.player_id == 0) return bad;
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
  // The same layout checks as VerifyJoinToken, in the same order.
  if (bytes.size() < kFixedSize + 1 + kJoinTokenMacSize || bytes.size() > kMaxJoinTokenSize ||
      bytes[0] != kTokenVersion) {
    return false;
  }
  size_t room_size = bytes[25];
  if (room_size == 0 || room_size > kMaxRoomNameSize ||
      bytes.size() != kFixedSize + room_size + kJoinTokenMacSize) {
    return false;
  }
  route->permissions = LoadU32LE(bytes.data() + 5);
  route->nonce = LoadU64LE(bytes.data() + 17);
  route->room =
      std::string_view(reinterpret_cast<const char*>(bytes.data() + kFixedSize), room_size);
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
