#include "protocol/packet_seal.h"

#include <gtest/gtest.h>

#include <vector>

namespace edgephys {
namespace {

struct Pair {
  std::unique_ptr<PacketSeal> client, relay;
};

Pair Connect(std::vector<uint8_t> token = {1, 2, 3}) {
  auto c = KeyExchange::Generate();
  auto r = KeyExchange::Generate();
  EXPECT_TRUE(c.ok() && r.ok());
  const SessionSecret secret{9, 8, 7};
  auto ck = c->Derive(r->public_key(), true, token, secret, 77, 0x1234);
  auto rk = r->Derive(c->public_key(), false, token, secret, 77, 0x1234);
  EXPECT_TRUE(ck.ok() && rk.ok());
  EXPECT_EQ(ck->client_to_relay, rk->client_to_relay);
  EXPECT_EQ(ck->relay_to_client, rk->relay_to_client);
  EXPECT_NE(ck->client_to_relay, ck->relay_to_client);
  return {std::make_unique<PacketSeal>(*ck, PacketSeal::Side::kClient),
          std::make_unique<PacketSeal>(*rk, PacketSeal::Side::kRelay)};
}

std::vector<uint8_t> Packet(size_t size, uint8_t fill) {
  std::vector<uint8_t> p(size, fill);
  WritePacketPrefix(PacketType::kData, 0x1234, p);
  return p;
}

TEST(PacketSeal, RoundTripsBothWaysAndHidesTheBody) {
  Pair p = Connect();
  for (size_t size : {kPacketPrefixSize, size_t{18}, size_t{600}, kMaxPacketSize}) {
    auto plain = Packet(size, 0xab);
    std::vector<uint8_t> sealed(kMaxDatagramSize), opened(kMaxDatagramSize);
    size_t n = p.client->Seal(plain, sealed);
    ASSERT_EQ(n, size + kSealOverhead);
    EXPECT_EQ(std::vector<uint8_t>(sealed.begin(), sealed.begin() + kPacketPrefixSize),
              std::vector<uint8_t>(plain.begin(), plain.begin() + kPacketPrefixSize));
    if (size > 40) {
      // A cipher stream leaves a byte unchanged with chance 1/256: the body is hidden when
      // far fewer than half its bytes still read as the plaintext (expected ~size/256).
      size_t same = 0;
      const size_t body = kPacketPrefixSize + kSealSequenceSize;
      for (size_t i = body; i < body + size - kPacketPrefixSize; ++i) same += sealed[i] == 0xab;
      EXPECT_LT(same, (size - kPacketPrefixSize) / 8) << size;
    }
    DropReason why{};
    size_t m = p.relay->Open({sealed.data(), n}, opened, &why);
    ASSERT_EQ(m, size);
    EXPECT_EQ(std::vector<uint8_t>(opened.begin(), opened.begin() + m), plain);
    n = p.relay->Seal(plain, sealed);
    ASSERT_EQ(p.client->Open({sealed.data(), n}, opened, &why), size);
    // A packet sealed for the other direction never opens (direction in the nonce and key).
    n = p.client->Seal(plain, sealed);
    EXPECT_EQ(p.client->Open({sealed.data(), n}, opened, &why), 0u);
    EXPECT_EQ(why, DropReason::kBadAuth);
    ASSERT_EQ(p.relay->Open({sealed.data(), n}, opened, &why), size);
  }
}

TEST(PacketSeal, ForgedCorruptedAndOtherKeysAreRefused) {
  Pair p = Connect(), other = Connect();
  auto plain = Packet(100, 7);
  std::vector<uint8_t> sealed(kMaxDatagramSize), opened(kMaxDatagramSize);
  size_t n = p.client->Seal(plain, sealed);
  DropReason why{};
  for (size_t i = 0; i < n; ++i) {  // every single bit flip, prefix and sequence included
    auto bad = sealed;
    bad[i] ^= 0x10;
    EXPECT_EQ(p.relay->Open({bad.data(), n}, opened, &why), 0u) << i;
  }
  // The right address and connection id but no key: an unsealed packet or another key's.
  auto forged = Packet(100 + kSealOverhead, 0);
  EXPECT_EQ(p.relay->Open(forged, opened, &why), 0u);
  EXPECT_EQ(why, DropReason::kBadAuth);
  size_t m = other.client->Seal(plain, forged);
  EXPECT_EQ(p.relay->Open({forged.data(), m}, opened, &why), 0u);
  EXPECT_EQ(why, DropReason::kBadAuth);
  EXPECT_EQ(p.relay->Open({sealed.data(), n}, opened, &why), 100u);  // the real one still opens
  EXPECT_EQ(p.relay->Open({sealed.data(), 20}, opened, &why), 0u);
  EXPECT_EQ(why, DropReason::kBadAuth);
}

TEST(PacketSeal, ReplayWindowAcceptsReorderingOnceAndRefusesRepeatsAndTheTooOld) {
  Pair p = Connect();
  auto plain = Packet(50, 1);
  std::vector<std::vector<uint8_t>> sent;
  for (int i = 0; i < 600; ++i) {
    std::vector<uint8_t> d(kMaxDatagramSize);
    d.resize(p.client->Seal(plain, d));
    sent.push_back(d);
  }
  std::vector<uint8_t> out(kMaxDatagramSize);
  DropReason why{};
  EXPECT_EQ(p.relay->Open(sent[10], out, &why), 50u);
  EXPECT_EQ(p.relay->Open(sent[5], out, &why), 50u);  // reordered: fine
  EXPECT_EQ(p.relay->Open(sent[10], out, &why), 0u);
  EXPECT_EQ(why, DropReason::kReplayed);
  EXPECT_EQ(p.relay->Open(sent[5], out, &why), 0u);
  EXPECT_EQ(p.relay->Open(sent[500], out, &why), 50u);
  EXPECT_EQ(p.relay->Open(sent[200], out, &why), 0u);  // older than the window
  EXPECT_EQ(why, DropReason::kReplayed);
  EXPECT_EQ(p.relay->Open(sent[300], out, &why), 50u);  // inside it
  EXPECT_EQ(p.relay->Open(sent[300], out, &why), 0u);
}

TEST(KeyExchange, RefusesBadPeerKeysAndBindsTheTokenAndTheSessionSecret) {
  auto c = KeyExchange::Generate();
  auto r = KeyExchange::Generate();
  ASSERT_TRUE(c.ok() && r.ok());
  const SessionSecret s1{1}, s2{2};
  std::vector<uint8_t> short_key(31, 1), zero(32, 0);
  EXPECT_FALSE(c->Derive(short_key, true, {}, s1, 1, 1).ok());
  EXPECT_FALSE(c->Derive(zero, true, {}, s1, 1, 1).ok());  // small-order point
  std::vector<uint8_t> t1{1}, t2{2};
  auto a = c->Derive(r->public_key(), true, t1, s1, 1, 1);
  auto b = r->Derive(c->public_key(), false, t2, s1, 1, 1);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_NE(a->client_to_relay, b->client_to_relay);
  // Same keys and token, another session secret: other keys. A man in the middle that ran its
  // own X25519 with both sides knows each shared secret but not the session secret.
  auto same = r->Derive(c->public_key(), false, t1, s1, 1, 1);
  auto other = r->Derive(c->public_key(), false, t1, s2, 1, 1);
  ASSERT_TRUE(same.ok() && other.ok());
  EXPECT_EQ(a->client_to_relay, same->client_to_relay);
  EXPECT_NE(a->client_to_relay, other->client_to_relay);
  EXPECT_NE(a->relay_to_client, other->relay_to_client);
}

}  // namespace
}  // namespace edgephys
