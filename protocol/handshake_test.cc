#include "protocol/handshake.h"

#include <gtest/gtest.h>

namespace edgephys {
namespace {

Endpoint Ep(const char* a, uint16_t port) { return Endpoint(asio::ip::make_address(a), port); }

TEST(CookieJar, VerifiesOnlyForTheSameAddressNonceAndWithinLifetime) {
  CookieJar jar;
  auto cookie = jar.Issue(Ep("127.0.0.1", 5000), 99, 100.0);
  EXPECT_TRUE(jar.Verify(cookie, Ep("127.0.0.1", 5000), 99, 100.5));
  EXPECT_TRUE(jar.Verify(cookie, Ep("127.0.0.1", 5000), 99, 100.0 + kCookieLifetimeS - 0.01));
  EXPECT_FALSE(jar.Verify(cookie, Ep("127.0.0.1", 5000), 99, 100.0 + kCookieLifetimeS + 0.5));
  EXPECT_FALSE(jar.Verify(cookie, Ep("127.0.0.1", 5001), 99, 100.5));
  EXPECT_FALSE(jar.Verify(cookie, Ep("127.0.0.2", 5000), 99, 100.5));
  EXPECT_FALSE(jar.Verify(cookie, Ep("::1", 5000), 99, 100.5));
  EXPECT_FALSE(jar.Verify(cookie, Ep("127.0.0.1", 5000), 98, 100.5));
  CookieJar other;
  EXPECT_FALSE(other.Verify(cookie, Ep("127.0.0.1", 5000), 99, 100.5));
  for (size_t i = 0; i < cookie.size(); ++i) {
    auto c = cookie;
    c[i] ^= 0x10;
    EXPECT_FALSE(jar.Verify(c, Ep("127.0.0.1", 5000), 99, 100.5)) << "byte " << i;
  }
  EXPECT_FALSE(jar.Verify(std::span(cookie).first(10), Ep("127.0.0.1", 5000), 99, 100.5));
}

TEST(CookieJar, JarsWithTheSameKeyAcceptEachOthersCookies) {
  const CookieJar::Key key = CookieJar::RandomKey();
  CookieJar a(key), b(key), c(CookieJar::RandomKey());
  auto cookie = a.Issue(Ep("127.0.0.1", 5000), 7, 10.0);
  EXPECT_TRUE(b.Verify(cookie, Ep("127.0.0.1", 5000), 7, 10.5));
  EXPECT_FALSE(c.Verify(cookie, Ep("127.0.0.1", 5000), 7, 10.5));
  EXPECT_FALSE(b.Verify(cookie, Ep("127.0.0.1", 5001), 7, 10.5));
}

TEST(Handshake, HelloIsPaddedAndChallengeIsSmaller) {
  flatbuffers::FlatBufferBuilder hello;
  FinishControl(hello, schema::CreateHello(hello, 1));
  auto hello_packet = BuildHandshakePacket(PacketType::kHello, hello, kMinHelloPacketSize);
  EXPECT_EQ(hello_packet.size(), kMinHelloPacketSize);
  ASSERT_NE(VerifyControlMessage(std::span(hello_packet).subspan(kPacketPrefixSize),
                                 schema::Body::Hello),
            nullptr);

  CookieJar jar;
  auto cookie = jar.Issue(Ep("127.0.0.1", 1), 1, 0);
  flatbuffers::FlatBufferBuilder challenge;
  FinishControl(challenge, schema::CreateChallenge(challenge, challenge.CreateVector(cookie.data(), cookie.size())));
  auto challenge_packet = BuildHandshakePacket(PacketType::kChallenge, challenge);
  EXPECT_LT(challenge_packet.size(), kMinHelloPacketSize);
}

TEST(Handshake, VerifierRejectsGarbageAndWrongBodies) {
  std::vector<uint8_t> garbage(100, 0xab);
  EXPECT_EQ(VerifyControlMessage(garbage), nullptr);
  EXPECT_EQ(VerifyControlMessage({}), nullptr);
  flatbuffers::FlatBufferBuilder fbb;
  FinishControl(fbb, schema::CreateLeaveRoom(fbb));
  std::span<const uint8_t> msg(fbb.GetBufferPointer(), fbb.GetSize());
  EXPECT_NE(VerifyControlMessage(msg), nullptr);
  EXPECT_EQ(VerifyControlMessage(msg, schema::Body::Hello), nullptr);
  // Every truncation fails cleanly.
  for (size_t n = 0; n < msg.size(); ++n) EXPECT_EQ(VerifyControlMessage(msg.first(n)), nullptr);
}

}  // namespace
}  // namespace edgephys
