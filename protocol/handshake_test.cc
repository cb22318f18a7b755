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

// Each field a proof covers changes it; only the exact 32 bytes match.
TEST(HandshakeProof, CoversEveryTranscriptFieldAndTheSecret) {
  const SessionSecret secret{1, 2, 3};
  const std::vector<uint8_t> cookie(kCookieSize, 9), token(130, 4), key(32, 5), relay_key(32, 6);
  const ConnectTranscript base{77, cookie, token, key};
  const HandshakeProof connect = ConnectProof(secret, base);
  EXPECT_EQ(ConnectProof(secret, base), connect);
  EXPECT_NE(ConnectProof(SessionSecret{1, 2, 4}, base), connect);
  EXPECT_NE(ConnectProof(secret, {78, cookie, token, key}), connect);
  std::vector<uint8_t> other_key = key;
  other_key[31] ^= 1;  // a substituted client key
  EXPECT_NE(ConnectProof(secret, {77, cookie, token, other_key}), connect);
  EXPECT_NE(ConnectProof(secret, {77, cookie, token, {}}), connect);  // key stripped
  EXPECT_NE(ConnectProof(secret, {77, std::span(cookie).first(23), token, key}), connect);
  EXPECT_NE(ConnectProof(secret, {77, cookie, std::span(token).first(129), key}), connect);
  // Field boundaries are length-prefixed: moving a byte from one field to the next changes it.
  std::vector<uint8_t> joined(cookie);
  joined.insert(joined.end(), token.begin(), token.end());
  EXPECT_NE(ConnectProof(secret, {77, std::span(joined).first(kCookieSize + 1),
                                  std::span(joined).subspan(kCookieSize + 1), key}),
            connect);

  const AcceptTranscript accept{connect, relay_key, 5, 6, 100, 5000};
  const HandshakeProof proof = AcceptProof(secret, accept);
  EXPECT_EQ(AcceptProof(secret, accept), proof);
  EXPECT_NE(proof, connect);
  auto changed = [&](auto edit) {
    AcceptTranscript t = accept;
    std::vector<uint8_t> k = relay_key;
    t.relay_key = k;
    edit(t, k);
    return AcceptProof(secret, t) != proof;
  };
  EXPECT_TRUE(changed([](AcceptTranscript& t, auto&) { t.connect_proof[0] ^= 1; }));
  EXPECT_TRUE(changed([](AcceptTranscript&, auto& k) { k[0] ^= 1; }));  // substituted relay key
  EXPECT_TRUE(changed([](AcceptTranscript& t, auto&) { t.relay_key = {}; }));
  EXPECT_TRUE(changed([](AcceptTranscript& t, auto&) { t.connection_id++; }));
  EXPECT_TRUE(changed([](AcceptTranscript& t, auto&) { t.player_id++; }));
  EXPECT_TRUE(changed([](AcceptTranscript& t, auto&) { t.keepalive_ms++; }));
  EXPECT_TRUE(changed([](AcceptTranscript& t, auto&) { t.timeout_ms++; }));
  EXPECT_NE(AcceptProof(SessionSecret{}, accept), proof);
}

TEST(HandshakeProof, TheBuiltConnectCarriesVersionAndAProofThatMatchesOnlyExactly) {
  const SessionSecret secret{7};
  const std::vector<uint8_t> cookie(kCookieSize, 1), token(140, 2), key(32, 3);
  HandshakeProof proof{};
  auto packet = BuildConnectPacket({42, cookie, token, key}, secret, &proof);
  const auto* msg = VerifyControlMessage(std::span(packet).subspan(kPacketPrefixSize),
                                         schema::Body::Connect);
  ASSERT_NE(msg, nullptr);
  const auto* c = msg->body_as_Connect();
  EXPECT_EQ(c->version(), kHandshakeVersion);
  EXPECT_EQ(c->client_nonce(), 42u);
  EXPECT_TRUE(ProofMatches(c->proof(), proof));
  EXPECT_TRUE(ProofMatches(c->proof(), ConnectProof(secret, {42, cookie, token, key})));
  HandshakeProof off = proof;
  off[31] ^= 0x80;
  EXPECT_FALSE(ProofMatches(c->proof(), off));
  EXPECT_FALSE(ProofMatches(nullptr, proof));
  flatbuffers::FlatBufferBuilder fbb;
  auto short_proof = fbb.CreateVector(proof.data(), 31);
  fbb.Finish(short_proof);
  EXPECT_FALSE(ProofMatches(flatbuffers::GetRoot<flatbuffers::Vector<uint8_t>>(fbb.GetBufferPointer()),
                            proof));
  // No client key: the field is absent, and the proof covers its absence.
  auto keyless = BuildConnectPacket({42, cookie, token, {}}, secret);
  const auto* k = VerifyControlMessage(std::span(keyless).subspan(kPacketPrefixSize),
                                       schema::Body::Connect);
  ASSERT_NE(k, nullptr);
  EXPECT_EQ(k->body_as_Connect()->client_key(), nullptr);
  EXPECT_FALSE(ProofMatches(k->body_as_Connect()->proof(), proof));
}

}  // namespace
}  // namespace edgephys
