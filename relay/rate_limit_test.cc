#include "relay/rate_limit.h"

#include <gtest/gtest.h>

namespace edgephys {
namespace {

Endpoint At(const char* address, uint16_t port = 4000) {
  return Endpoint(asio::ip::make_address(address), port);
}

int Allowed(AddressRateLimiter& limiter, const Endpoint& from, int attempts, double now) {
  int n = 0;
  for (int i = 0; i < attempts; ++i) n += limiter.Allow(from, now);
  return n;
}

// Finding 4 of issue 14: 127.0.16.1 draining its bucket stopped 127.0.0.1 (same slot of a
// 4096-entry table keyed by address mod 4096).
TEST(AddressRateLimiter, AnAddressNeverSharesABucketWithAnother) {
  AddressRateLimiter limiter(20, 40);
  EXPECT_EQ(Allowed(limiter, At("127.0.16.1"), 1000, 1.0), 40);
  EXPECT_EQ(Allowed(limiter, At("127.0.0.1"), 40, 1.0), 40);
  for (uint32_t i = 2; i < 64; ++i) {  // every address a multiple of 4096 apart
    const auto a = asio::ip::address_v4(0x7f000001u + i * 4096u);
    EXPECT_EQ(Allowed(limiter, Endpoint(a, 9), 40, 1.0), 40) << a.to_string();
  }
}

TEST(AddressRateLimiter, PortsShareTheAddressAndIpv6SharesItsSlash64) {
  AddressRateLimiter limiter(20, 40);
  for (uint16_t port = 1; port <= 40; ++port) EXPECT_TRUE(limiter.Allow(At("10.0.0.1", port), 0));
  EXPECT_FALSE(limiter.Allow(At("10.0.0.1", 41), 0));
  EXPECT_EQ(Allowed(limiter, At("2001:db8:1:2::1"), 30, 0), 30);
  EXPECT_EQ(Allowed(limiter, At("2001:db8:1:2:ffff::9"), 30, 0), 10);  // same /64
  EXPECT_EQ(Allowed(limiter, At("2001:db8:1:3::1"), 40, 0), 40);       // another /64
  EXPECT_EQ(Allowed(limiter, At("::ffff:10.0.0.2"), 40, 0), 40);
  EXPECT_FALSE(limiter.Allow(At("10.0.0.2"), 0));  // the mapped form is the same address
  EXPECT_TRUE(limiter.Allow(At("10.0.0.1"), 2.0));  // refilled
}

// A flood from more spoofed sources than the table holds evicts entries but never limits an
// honest address, and memory stays bounded (fixed table).
TEST(AddressRateLimiter, SpoofedSourceFloodNeverBlocksAnHonestAddress) {
  AddressRateLimiter limiter(20, 40);
  const Endpoint honest = At("192.168.1.7");
  int honest_allowed = 0;
  for (uint32_t i = 0; i < 200000; ++i) {
    (void)limiter.Allow(Endpoint(asio::ip::address_v4(0x0a000000u + i), 1), 0.001 * i / 100);
    if (i % 5000 == 0) honest_allowed += limiter.Allow(honest, 0.001 * i / 100);
  }
  EXPECT_EQ(honest_allowed, 40);
  EXPECT_GT(limiter.evictions(), 100000u);
}

}  // namespace
}  // namespace edgephys
