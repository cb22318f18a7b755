#include "protocol/redirect.h"

#include <openssl/crypto.h>
#include <openssl/evp.h>
#include <openssl/hmac.h>

#include "protocol/byte_io.h"
#include "protocol/handshake.h"
#include "protocol/join_token.h"

namespace edgephys {
namespace {

std::array<uint8_t, 32> RedirectMac(std::span<const uint8_t> key, const RedirectTicket& t) {
  std::vector<uint8_t> msg;
  msg.reserve(32 + t.room.size() + t.address.size());
  msg.insert(msg.end(), {'E', 'P', 'R', 'D', 1, static_cast<uint8_t>(t.room.size())});
  msg.insert(msg.end(), t.room.begin(), t.room.end());
  uint8_t buf[8];
  StoreU64LE(buf, t.token_nonce);
  msg.insert(msg.end(), buf, buf + 8);
  StoreU64LE(buf, t.expiry_unix_s);
  msg.insert(msg.end(), buf, buf + 8);
  msg.push_back(static_cast<uint8_t>(t.address.size() & 0xff));
  msg.push_back(static_cast<uint8_t>(t.address.size() >> 8));
  msg.insert(msg.end(), t.address.begin(), t.address.end());
  std::array<uint8_t, 32> mac{};
  unsigned int len = 0;
  HMAC(EVP_sha256(), key.data(), static_cast<int>(key.size()), msg.data(), msg.size(),
       mac.data(), &len);
  return mac;
}

// The redirect MAC key: HMAC-SHA256(session secret, "edgephys redirect key").
std::array<uint8_t, 32> RedirectKey(const SessionSecret& secret) {
  static constexpr char kLabel[] = "edgephys redirect key";
  std::array<uint8_t, 32> key{};
  unsigned int len = 0;
  HMAC(EVP_sha256(), secret.data(), static_cast<int>(secret.size()),
       reinterpret_cast<const uint8_t*>(kLabel), sizeof(kLabel) - 1, key.data(), &len);
  return key;
}

}  // namespace

Result<RedirectTicket> SignRedirect(std::span<const uint8_t> token, const SessionSecret& secret,
                                    std::string_view address, uint64_t expiry_unix_s) {
  JoinTokenRoute route;
  if (!PeekJoinToken(token, &route)) return Status::InvalidArgument("malformed token");
  if (address.empty() || address.size() > kMaxRedirectAddressSize) {
    return Status::InvalidArgument("redirect address must be 1..128 bytes");
  }
  RedirectTicket t;
  t.address = std::string(address);
  t.room = std::string(route.room);
  t.token_nonce = route.nonce;
  t.expiry_unix_s = expiry_unix_s;
  t.mac = RedirectMac(RedirectKey(secret), t);
  return t;
}

Status VerifyRedirect(const RedirectTicket& t, std::span<const uint8_t> token,
                      const SessionSecret& secret, uint64_t now_unix_s) {
  const Status forged = Status::Unauthenticated("forged redirect");
  JoinTokenRoute route;
  if (!PeekJoinToken(token, &route) || t.address.empty() ||
      t.address.size() > kMaxRedirectAddressSize || t.room != route.room ||
      t.token_nonce != route.nonce) {
    return forged;
  }
  auto mac = RedirectMac(RedirectKey(secret), t);
  if (CRYPTO_memcmp(mac.data(), t.mac.data(), mac.size()) != 0) return forged;
  if (t.expiry_unix_s <= now_unix_s) {
    return Status::Unauthenticated("expired redirect",
                                   "expiry " + std::to_string(t.expiry_unix_s) + " <= now " +
                                       std::to_string(now_unix_s));
  }
  return Status::Ok();
}

std::vector<uint8_t> BuildRedirectPacket(const RedirectTicket& t) {
  flatbuffers::FlatBufferBuilder fbb(256);
  FinishControl(fbb, schema::CreateRedirect(fbb, fbb.CreateString(t.address),
                                            fbb.CreateString(t.room), t.token_nonce,
                                            t.expiry_unix_s,
                                            fbb.CreateVector(t.mac.data(), t.mac.size())));
  return BuildHandshakePacket(PacketType::kReject, fbb);
}

Result<RedirectTicket> ParseRedirect(const schema::Redirect& m) {
  if (m.address() == nullptr || m.room() == nullptr || m.mac() == nullptr ||
      m.mac()->size() != 32 || m.address()->size() > kMaxRedirectAddressSize) {
    return Status::Malformed("bad redirect");
  }
  RedirectTicket t;
  t.address = m.address()->str();
  t.room = m.room()->str();
  t.token_nonce = m.token_nonce();
  t.expiry_unix_s = m.expiry_unix_s();
  std::copy(m.mac()->begin(), m.mac()->end(), t.mac.begin());
  return t;
}

}  // namespace edgephys
