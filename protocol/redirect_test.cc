#include "protocol/redirect.h"

#include <gtest/gtest.h>

#include <algorithm>

#include "protocol/handshake.h"
#include "protocol/join_token.h"
#include "protocol/packet.h"

namespace edgephys {
namespace {

// A client token split: the relay part (what a Connect carries) and its session secret.
struct Split {
  std::vector<uint8_t> relay;
  SessionSecret secret;
};

Split Token(uint64_t nonce, const std::string& room = "arena") {
  JoinToken t;
  t.room = room;
  t.player_id = 7;
  t.expiry_unix_s = 2000;
  t.nonce = nonce;
  const std::vector<uint8_t> client = *SignJoinToken(t, "secret");
  auto split = *SplitClientToken(client);
  return {{split.relay_token.begin(), split.relay_token.end()}, split.session_secret};
}

TEST(Redirect, SignedRedirectVerifiesAndSurvivesTheWire) {
  auto [token, secret] = Token(1);
  auto t = SignRedirect(token, secret, "127.0.0.1:7001", 1030);
  ASSERT_TRUE(t.ok());
  EXPECT_EQ(t->room, "arena");
  EXPECT_TRUE(VerifyRedirect(*t, token, secret, 1000).ok());
  auto packet = BuildRedirectPacket(*t);
  PacketPrefix prefix{};
  DropReason reason{};
  ASSERT_TRUE(ParsePacketPrefix(packet, &prefix, &reason));
  EXPECT_EQ(prefix.type, PacketType::kReject);
  const auto* msg = VerifyControlMessage(std::span<const uint8_t>(packet).subspan(kPacketPrefixSize),
                                         schema::Body::Redirect);
  ASSERT_NE(msg, nullptr);
  auto parsed = ParseRedirect(*msg->body_as_Redirect());
  ASSERT_TRUE(parsed.ok());
  EXPECT_EQ(parsed->address, "127.0.0.1:7001");
  EXPECT_TRUE(VerifyRedirect(*parsed, token, secret, 1000).ok());
}

TEST(Redirect, ForgedRedirectsAreRefused) {
  auto [token, secret] = Token(1);
  auto good = *SignRedirect(token, secret, "127.0.0.1:7001", 1030);
  auto other_address = good;
  other_address.address = "10.0.0.66:7001";  // an attacker's relay
  EXPECT_FALSE(VerifyRedirect(other_address, token, secret, 1000).ok());
  auto flipped = good;
  flipped.mac[5] ^= 1;
  EXPECT_FALSE(VerifyRedirect(flipped, token, secret, 1000).ok());
  auto later = good;
  later.expiry_unix_s += 3600;  // extended by a forger
  EXPECT_FALSE(VerifyRedirect(later, token, secret, 1000).ok());
  // Signed for another token (another nonce or room): not for this one.
  const Split other = Token(2), lobby = Token(1, "lobby");
  EXPECT_FALSE(VerifyRedirect(*SignRedirect(other.relay, other.secret, "127.0.0.1:7001", 1030),
                              token, secret, 1000).ok());
  EXPECT_FALSE(VerifyRedirect(*SignRedirect(lobby.relay, lobby.secret, "127.0.0.1:7001", 1030),
                              token, secret, 1000).ok());
  // An observer who saw this token in a Connect (the relay part, its MAC included) but not the
  // session secret cannot sign: a MAC under a guessed secret fails, and the token's MAC is no
  // key any more.
  SessionSecret guessed{};
  EXPECT_FALSE(
      VerifyRedirect(*SignRedirect(token, guessed, "10.0.0.66:7001", 1030), token, secret, 1000)
          .ok());
  SessionSecret token_mac{};
  std::copy(token.end() - 32, token.end(), token_mac.begin());
  EXPECT_FALSE(
      VerifyRedirect(*SignRedirect(token, token_mac, "10.0.0.66:7001", 1030), token, secret, 1000)
          .ok());
  // Garbage token or address.
  EXPECT_FALSE(SignRedirect(std::vector<uint8_t>{1, 2, 3}, secret, "a:1", 5).ok());
  EXPECT_FALSE(SignRedirect(token, secret, "", 5).ok());
}

TEST(Redirect, ExpiredRedirectIsRefused) {
  auto [token, secret] = Token(1);
  auto t = *SignRedirect(token, secret, "127.0.0.1:7001", 1030);
  EXPECT_TRUE(VerifyRedirect(t, token, secret, 1029).ok());
  Status st = VerifyRedirect(t, token, secret, 1030);
  EXPECT_TRUE(st.IsUnauthenticated());
  EXPECT_EQ(st.message(), "expired redirect");
}

TEST(Redirect, MalformedMessageIsRefused) {
  flatbuffers::FlatBufferBuilder fbb;
  std::vector<uint8_t> short_mac(16, 0);
  FinishControl(fbb, schema::CreateRedirect(fbb, fbb.CreateString("a:1"), fbb.CreateString("r"),
                                            1, 2, fbb.CreateVector(short_mac)));
  const auto* msg = schema::GetControlMessage(fbb.GetBufferPointer());
  EXPECT_FALSE(ParseRedirect(*msg->body_as_Redirect()).ok());
  fbb.Clear();
  FinishControl(fbb, schema::CreateRedirect(fbb));
  msg = schema::GetControlMessage(fbb.GetBufferPointer());
  EXPECT_FALSE(ParseRedirect(*msg->body_as_Redirect()).ok());
}

}  // namespace
}  // namespace edgephys
