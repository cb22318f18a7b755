#include "protocol/join_token.h"

#include <gtest/gtest.h>

#include <random>

namespace edgephys {
namespace {

JoinToken Sample() {
  JoinToken t;
  t.room = "lobby";
  t.player_id = 77;
  t.permissions = kPermissionSpawn;
  t.expiry_unix_s = 2'000'000'000;
  t.nonce = 0x1122334455667788ull;
  return t;
}

// The relay part of a freshly minted client token (what a Connect carries).
std::vector<uint8_t> RelayPart(const JoinToken& t, std::string_view secret) {
  auto client = SignJoinToken(t, secret);
  EXPECT_TRUE(client.ok());
  auto split = SplitClientToken(*client);
  EXPECT_TRUE(split.ok());
  return {split->relay_token.begin(), split->relay_token.end()};
}

TEST(JoinToken, SignVerifyRoundTrip) {
  auto bytes = RelayPart(Sample(), "s3cret");
  TokenError err;
  auto t = VerifyJoinToken(bytes, "s3cret", 1'900'000'000, &err);
  ASSERT_TRUE(t.ok());
  EXPECT_EQ(err, TokenError::kNone);
  EXPECT_EQ(t->room, "lobby");
  EXPECT_EQ(t->player_id, 77u);
  EXPECT_EQ(t->permissions, kPermissionSpawn);
  EXPECT_EQ(t->expiry_unix_s, 2'000'000'000u);
  EXPECT_EQ(t->nonce, 0x1122334455667788ull);
}

TEST(JoinToken, PeekReadsRoutingFieldsOfEveryTokenThatVerifies) {
  JoinToken sample = Sample();
  sample.permissions = kPermissionWorker;
  auto bytes = RelayPart(sample, "s3cret");
  JoinTokenRoute route;
  ASSERT_TRUE(PeekJoinToken(bytes, &route));
  EXPECT_EQ(route.room, "lobby");
  EXPECT_EQ(route.permissions, kPermissionWorker);
  EXPECT_EQ(route.nonce, sample.nonce);
  // Truncated, extended, or a wrong room length: no route (and no verification either).
  for (size_t n = 0; n < bytes.size(); ++n) {
    EXPECT_FALSE(PeekJoinToken(std::span(bytes).first(n), &route)) << n;
  }
  auto longer = bytes;
  longer.push_back(0);
  EXPECT_FALSE(PeekJoinToken(longer, &route));
  auto bad_length = bytes;
  bad_length[25] = 0;
  EXPECT_FALSE(PeekJoinToken(bad_length, &route));
  bad_length[25] = 200;
  EXPECT_FALSE(PeekJoinToken(bad_length, &route));
  // Random bytes never crash; whenever they verify they also peek.
  std::mt19937 rng(3);
  for (int i = 0; i < 2000; ++i) {
    std::vector<uint8_t> junk(rng() % 240);
    for (auto& b : junk) b = static_cast<uint8_t>(rng());
    TokenError err;
    bool verified = VerifyJoinToken(junk, "s3cret", 0, &err).ok();
    bool peeked = PeekJoinToken(junk, &route);
    EXPECT_TRUE(!verified || peeked);
  }
}

TEST(JoinToken, WrongSecretExpiryAndEveryFlippedBitAreRejected) {
  auto bytes = RelayPart(Sample(), "s3cret");
  TokenError err;
  EXPECT_FALSE(VerifyJoinToken(bytes, "other", 0, &err).ok());
  EXPECT_EQ(err, TokenError::kBad);
  EXPECT_FALSE(VerifyJoinToken(bytes, "s3cret", 2'000'000'000, &err).ok());
  EXPECT_EQ(err, TokenError::kExpired);
  for (size_t i = 0; i < bytes.size() * 8; ++i) {
    auto t = bytes;
    t[i / 8] ^= static_cast<uint8_t>(1u << (i % 8));
    EXPECT_FALSE(VerifyJoinToken(t, "s3cret", 0, &err).ok()) << "bit " << i;
  }
  for (size_t n = 0; n < bytes.size(); ++n) {
    EXPECT_FALSE(VerifyJoinToken(std::span(bytes).first(n), "s3cret", 0, &err).ok());
  }
}

TEST(JoinToken, StatusTellsExpiredFromBadTokens) {
  auto bytes = RelayPart(Sample(), "s3cret");
  auto ok = VerifyJoinToken(bytes, "s3cret", 1'900'000'000);
  ASSERT_TRUE(ok.ok());
  EXPECT_FALSE(IsExpiredToken(ok.status()));

  auto expired = VerifyJoinToken(bytes, "s3cret", 2'000'000'000);
  ASSERT_FALSE(expired.ok());
  EXPECT_TRUE(expired.status().IsUnauthenticated());
  EXPECT_TRUE(IsExpiredToken(expired.status()));
  EXPECT_NE(expired.status().detail().find("2000000000"), std::string_view::npos);

  auto bad = VerifyJoinToken(bytes, "other", 0);
  ASSERT_FALSE(bad.ok());
  EXPECT_TRUE(bad.status().IsUnauthenticated());
  EXPECT_FALSE(IsExpiredToken(bad.status()));
  // An expired token signed with another secret is bad, not expired: the MAC is checked first.
  EXPECT_FALSE(IsExpiredToken(VerifyJoinToken(bytes, "other", 2'000'000'000).status()));

  // The TokenError form agrees with the Status form.
  for (uint64_t now : {uint64_t{0}, uint64_t{2'000'000'000}}) {
    for (std::string_view secret : {"s3cret", "other"}) {
      TokenError err = TokenError::kNone;
      auto with_error = VerifyJoinToken(bytes, secret, now, &err);
      auto plain = VerifyJoinToken(bytes, secret, now);
      EXPECT_EQ(with_error.ok(), plain.ok());
      EXPECT_EQ(err, plain.ok() ? TokenError::kNone
                                : IsExpiredToken(plain.status()) ? TokenError::kExpired
                                                                 : TokenError::kBad);
    }
  }
}

TEST(JoinToken, RefusesToSignInvalidTokens) {
  JoinToken t = Sample();
  EXPECT_FALSE(SignJoinToken(t, "").ok());
  t.player_id = 0;
  EXPECT_FALSE(SignJoinToken(t, "k").ok());
  t = Sample();
  t.room = std::string(kMaxRoomNameSize + 1, 'x');
  EXPECT_FALSE(SignJoinToken(t, "k").ok());
  t.room = "";
  EXPECT_FALSE(SignJoinToken(t, "k").ok());
}

TEST(JoinToken, Base64UrlRoundTripsRandomBytes) {
  std::mt19937 rng(1);
  for (int n = 0; n < 200; ++n) {
    std::vector<uint8_t> bytes(n);
    for (auto& b : bytes) b = static_cast<uint8_t>(rng());
    std::string text = Base64UrlEncode(bytes);
    EXPECT_EQ(text.find_first_of("+/="), std::string::npos);
    auto back = Base64UrlDecode(text);
    ASSERT_TRUE(back.ok());
    EXPECT_EQ(*back, bytes);
  }
  EXPECT_FALSE(Base64UrlDecode("ab$d").ok());
  EXPECT_FALSE(Base64UrlDecode("abcde").ok());
}

TEST(ReplayGuard, AdmitsEachNonceOnceUntilExpiry) {
  ReplayGuard guard(3);
  EXPECT_TRUE(guard.Admit(1, 100, 10).ok());
  EXPECT_EQ(guard.Admit(1, 100, 11).code(), StatusCode::kAlreadyExists);
  EXPECT_TRUE(guard.Admit(2, 50, 12).ok());
  EXPECT_TRUE(guard.Admit(3, 100, 13).ok());
  // Full: refuses rather than forgetting a live nonce.
  EXPECT_EQ(guard.Admit(4, 100, 14).code(), StatusCode::kResourceExhausted);
  // Once nonce 2 expired, room frees up; an expired nonce's token is refused by expiry anyway.
  EXPECT_TRUE(guard.Admit(4, 100, 60).ok());
  EXPECT_EQ(guard.Admit(1, 100, 61).code(), StatusCode::kAlreadyExists);
}

}  // namespace
}  // namespace edgephys
