#include "protocol/redirect.h"

#include <gtest/gtest.h>

#include "protocol/handshake.h"
#include "protocol/join_token.h"
#include "protocol/packet.h"

namespace edgephys {
namespace {

std::vector<uint8_t> Token(uint64_t nonce, const std::string& room = "arena") {
  JoinToken t;
  t.room = room;
  t.player_id = 7;
  t.expiry_unix_s = 2000;
  t.nonce = nonce;
  const std::vector<uint8_t> client = *SignJoinToken(t, "secret");
  auto relay_part = SplitClientToken(client)->relay_token;  // what a Connect carries
  return {relay_part.begin(), relay_part.end()};
}

TEST(Redirect, SignedRedirectVerifiesAndSurvivesTheWire) {
  auto token = Token(1);
  auto t = SignRedirect(token, "127.0.0.1:7001", 1030);
  ASSERT_TRUE(t.ok());
  EXPECT_EQ(t->room, "arena");
  EXPECT_TRUE(VerifyRedirect(*t, token, 1000).ok());
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
  EXPECT_TRUE(VerifyRedirect(*parsed, token, 1000).ok());
}

TEST(Redirect, ForgedRedirectsAreRefused) {
  auto token = Token(1);
  auto good = *SignRedirect(token, "127.0.0.1:7001", 1030);
  auto other_address = good;
  other_address.address = "10.0.0.66:7001";  // an attacker's relay
  EXPECT_FALSE(VerifyRedirect(other_address, token, 1000).ok());
  auto flipped = good;
  flipped.mac[5] ^= 1;
  EXPECT_FALSE(VerifyRedirect(flipped, token, 1000).ok());
  auto later = good;
  later.expiry_unix_s += 3600;  // extended by a forger
  EXPECT_FALSE(VerifyRedirect(later, token, 1000).ok());
  // Signed for another token (another nonce or room): not for this one.
  EXPECT_FALSE(VerifyRedirect(*SignRedirect(Token(2), "127.0.0.1:7001", 1030), token, 1000).ok());
  EXPECT_FALSE(
      VerifyRedirect(*SignRedirect(Token(1, "lobby"), "127.0.0.1:7001", 1030), token, 1000).ok());
  // Someone without the token cannot sign: a MAC keyed by a guessed key fails.
  std::vector<uint8_t> guessed = token;
  std::fill(guessed.end() - 32, guessed.end(), 0);
  EXPECT_FALSE(VerifyRedirect(*SignRedirect(guessed, "10.0.0.66:7001", 1030), token, 1000).ok());
  // Garbage token or address.
  EXPECT_FALSE(SignRedirect(std::vector<uint8_t>{1, 2, 3}, "a:1", 5).ok());
  EXPECT_FALSE(SignRedirect(token, "", 5).ok());
}

TEST(Redirect, ExpiredRedirectIsRefused) {
  auto token = Token(1);
  auto t = *SignRedirect(token, "127.0.0.1:7001", 1030);
  EXPECT_TRUE(VerifyRedirect(t, token, 1029).ok());
  Status st = VerifyRedirect(t, token, 1030);
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
