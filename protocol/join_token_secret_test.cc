// The session secret a join token carries: sealed for relays in the relay part, in clear in the
// client token's tail (protocol/join_token.h). Refusals name their cause.
#include <openssl/hmac.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <string>

#include "protocol/join_token.h"

namespace edgephys {
namespace {

constexpr char kSecret[] = "operator-secret";

JoinToken Sample(uint8_t secret_byte = 0) {
  JoinToken t;
  t.room = "yard";
  t.player_id = 41;
  t.expiry_unix_s = 2'000'000'000;
  t.nonce = 0xabcdef;
  if (secret_byte != 0) t.session_secret.fill(secret_byte);
  return t;
}

std::vector<uint8_t> Relay(const std::vector<uint8_t>& client) {
  auto split = SplitClientToken(client);
  EXPECT_TRUE(split.ok()) << split.status().ToString();
  return {split->relay_token.begin(), split->relay_token.end()};
}

// The detail of VerifyJoinToken's refusal ("" if it verified).
std::string Cause(std::span<const uint8_t> bytes, std::string_view secret = kSecret) {
  auto t = VerifyJoinToken(bytes, secret, 1'000);
  if (t.ok()) return "";
  EXPECT_TRUE(t.status().IsUnauthenticated());
  EXPECT_FALSE(IsExpiredToken(t.status()));
  return std::string(t.status().detail());
}

bool Has(const std::string& text, std::string_view part) {
  return text.find(part) != std::string::npos;
}

// Re-signs the relay part's HMAC with the operator secret: what lets a test reach the checks
// behind the MAC (an attacker cannot do this without the secret).
void Resign(std::vector<uint8_t>& relay) {
  const size_t body = relay.size() - kJoinTokenMacSize;
  unsigned int len = 0;
  HMAC(EVP_sha256(), kSecret, static_cast<int>(sizeof(kSecret) - 1), relay.data(), body,
       relay.data() + body, &len);
}

TEST(JoinTokenSecret, ClientAndRelayGetTheSameSecretAndTheRelayPartHidesIt) {
  auto client = *SignJoinToken(Sample(), kSecret);
  ASSERT_EQ(client.size(), JoinTokenSize(4) + kSessionSecretSize);
  auto split = *SplitClientToken(client);
  EXPECT_EQ(split.relay_token.size(), JoinTokenSize(4));
  EXPECT_NE(split.session_secret, SessionSecret{});  // drawn at random
  auto verified = VerifyJoinToken(split.relay_token, kSecret, 1'000);
  ASSERT_TRUE(verified.ok()) << verified.status().ToString();
  EXPECT_EQ(verified->session_secret, split.session_secret);
  EXPECT_EQ(verified->room, "yard");
  // An observer of the relay part (it travels in clear) does not see the secret in it, not
  // even 8 bytes of it in a row.
  for (size_t i = 0; i + 8 <= kSessionSecretSize; ++i) {
    auto piece = std::span(split.session_secret).subspan(i, 8);
    EXPECT_EQ(std::search(split.relay_token.begin(), split.relay_token.end(), piece.begin(),
                          piece.end()),
              split.relay_token.end());
  }
  // Every minting draws a new secret.
  auto again = *SplitClientToken(*SignJoinToken(Sample(), kSecret));
  EXPECT_NE(again.session_secret, split.session_secret);
}

TEST(JoinTokenSecret, AGivenSecretIsSealedAsGivenAndDeterministically) {
  auto a = *SignJoinToken(Sample(7), kSecret);
  auto b = *SignJoinToken(Sample(7), kSecret);
  EXPECT_EQ(a, b);
  auto split = *SplitClientToken(a);
  EXPECT_EQ(split.session_secret, Sample(7).session_secret);
  EXPECT_EQ(VerifyJoinToken(split.relay_token, kSecret, 1'000)->session_secret,
            Sample(7).session_secret);
  // Another secret: another seal nonce (bytes 30..42 for a 4-byte room) and ciphertext.
  auto c = *SignJoinToken(Sample(8), kSecret);
  const size_t nonce_at = kJoinTokenFieldsSize + 4;
  EXPECT_FALSE(std::equal(a.begin() + nonce_at, a.begin() + nonce_at + kTokenSealNonceSize,
                          c.begin() + nonce_at));
}

TEST(JoinTokenSecret, AWrongOperatorSecretIsRefusedAsAMacMismatch) {
  auto relay = Relay(*SignJoinToken(Sample(), kSecret));
  std::mt19937 rng(11);
  for (int i = 0; i < 200; ++i) {
    std::string other(1 + rng() % 40, ' ');
    for (char& ch : other) ch = static_cast<char>(33 + rng() % 90);
    if (other == kSecret) continue;
    EXPECT_TRUE(Has(Cause(relay, other), "MAC mismatch")) << other;
  }
  EXPECT_TRUE(Has(Cause(relay, ""), "no operator secret"));
}

TEST(JoinTokenSecret, ATamperedSealedSecretIsRefusedWithOrWithoutAValidMac) {
  auto relay = Relay(*SignJoinToken(Sample(), kSecret));
  const size_t sealed_at = kJoinTokenFieldsSize + 4;
  for (size_t byte = sealed_at; byte < sealed_at + kTokenSealedSecretSize; ++byte) {
    for (int bit = 0; bit < 8; bit += 3) {
      auto t = relay;
      t[byte] ^= static_cast<uint8_t>(1u << bit);
      // An attacker without the operator secret: the MAC gives it away.
      EXPECT_TRUE(Has(Cause(t), "MAC mismatch")) << byte;
      // Even behind a valid MAC, the AEAD refuses a changed nonce, ciphertext or tag.
      Resign(t);
      EXPECT_TRUE(Has(Cause(t), "session secret does not decrypt")) << byte;
    }
  }
  // The public fields are bound to the sealed secret as well (its AAD): a token whose fields
  // were changed and re-signed does not decrypt either.
  for (size_t byte = 1; byte < sealed_at; ++byte) {
    auto t = relay;
    t[byte] ^= 0x01;
    if (byte == kJoinTokenFieldsSize - 1) continue;  // room length: a layout error instead
    Resign(t);
    EXPECT_TRUE(Has(Cause(t), "session secret does not decrypt")) << byte;
  }
}

TEST(JoinTokenSecret, TruncatedExtendedAndOldTokensAreRefusedNamingTheCause) {
  auto client = *SignJoinToken(Sample(), kSecret);
  auto relay = Relay(client);
  for (size_t n = 0; n < relay.size(); ++n) {
    EXPECT_TRUE(Has(Cause(std::span(relay).first(n)), "truncated")) << n;
  }
  // The whole client token sent to a relay: its tail is not for relays.
  EXPECT_TRUE(Has(Cause(client), "client token sent whole"));
  auto old = relay;
  old[0] = 1;
  EXPECT_TRUE(Has(Cause(old), "version 1, expected 2"));
  auto room = relay;
  room[kJoinTokenFieldsSize - 1] = 0;
  EXPECT_TRUE(Has(Cause(room), "room length 0"));
}

TEST(JoinTokenSecret, RandomInputsAreRefusedWithANamedCauseNeverACrash) {
  auto relay = Relay(*SignJoinToken(Sample(), kSecret));
  std::mt19937 rng(5);
  for (int i = 0; i < 20000; ++i) {
    std::vector<uint8_t> bytes;
    switch (i % 3) {
      case 0:  // pure noise of any length
        bytes.resize(rng() % (kMaxClientTokenSize + 20));
        for (auto& b : bytes) b = static_cast<uint8_t>(rng());
        break;
      case 1:  // a plausible layout: version 2, a valid room length, the exact size
        bytes.resize(JoinTokenSize(1 + rng() % kMaxRoomNameSize));
        for (auto& b : bytes) b = static_cast<uint8_t>(rng());
        bytes[0] = kJoinTokenVersion;
        bytes[kJoinTokenFieldsSize - 1] = static_cast<uint8_t>(bytes.size() - JoinTokenSize(0));
        break;
      default:  // the real token with a few random bytes changed
        bytes = relay;
        for (int k = 0; k < 1 + static_cast<int>(rng() % 4); ++k) {
          bytes[rng() % bytes.size()] ^= static_cast<uint8_t>(1 + rng() % 255);
        }
        break;
    }
    const std::string cause = Cause(bytes);
    ASSERT_FALSE(cause.empty()) << "random bytes verified, case " << i % 3;
    EXPECT_TRUE(Has(cause, "truncated") || Has(cause, "extended") || Has(cause, "version") ||
                Has(cause, "room length") || Has(cause, "MAC mismatch"))
        << cause;
    // The split that an SDK does never crashes either, and never yields a verified token.
    auto split = SplitClientToken(bytes);
    if (split.ok()) {
      EXPECT_FALSE(VerifyJoinToken(split->relay_token, kSecret, 1'000).ok());
    }
  }
}

TEST(JoinTokenSecret, SplitRefusesAnythingButAWholeClientToken) {
  auto client = *SignJoinToken(Sample(), kSecret);
  auto relay = Relay(client);
  auto alone = SplitClientToken(relay);
  ASSERT_FALSE(alone.ok());
  EXPECT_TRUE(alone.status().IsMalformed());
  EXPECT_TRUE(Has(std::string(alone.status().detail()), "without its session secret"));
  for (size_t n = 0; n < client.size(); ++n) {
    EXPECT_FALSE(SplitClientToken(std::span(client).first(n)).ok()) << n;
  }
  auto longer = client;
  longer.push_back(0);
  EXPECT_FALSE(SplitClientToken(longer).ok());
  auto old = client;
  old[0] = 1;
  EXPECT_TRUE(Has(std::string(SplitClientToken(old).status().detail()), "version 1"));
}

}  // namespace
}  // namespace edgephys
