#include "protocol/udp_socket.h"

#include <gtest/gtest.h>

#include <array>
#include <vector>

namespace edgephys {
namespace {

Endpoint At(const char* address, uint16_t port) {
  return Endpoint(asio::ip::make_address(address), port);
}

// Polls for up to ~5 s (the datagram is on loopback; this only guards against a stall).
size_t ReceiveWithin(UdpSocket& socket, Endpoint* from, std::span<uint8_t> buffer) {
  for (int i = 0; i < 50; ++i) {
    if (size_t size = socket.ReceiveFrom(from, buffer)) return size;
    socket.WaitReadable(0.1);
  }
  return 0;
}

void RoundTrip(const char* loopback) {
  auto a = UdpSocket::Open(At(loopback, 0));
  auto b = UdpSocket::Open(At(loopback, 0));
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_NE((*a)->LocalEndpoint().port(), 0);
  EXPECT_EQ((*a)->LocalEndpoint().address(), asio::ip::make_address(loopback));

  std::vector<uint8_t> ping(1200);
  for (size_t i = 0; i < ping.size(); ++i) ping[i] = static_cast<uint8_t>(i * 13);
  ASSERT_TRUE((*a)->SendTo((*b)->LocalEndpoint(), ping).ok());
  std::array<uint8_t, 2048> buffer{};
  Endpoint from;
  ASSERT_EQ(ReceiveWithin(**b, &from, buffer), ping.size());
  EXPECT_EQ(from, (*a)->LocalEndpoint());
  EXPECT_TRUE(std::equal(ping.begin(), ping.end(), buffer.begin()));

  std::vector<uint8_t> pong = {9, 8, 7};
  ASSERT_TRUE((*b)->SendTo(from, pong).ok());
  ASSERT_EQ(ReceiveWithin(**a, &from, buffer), pong.size());
  EXPECT_EQ(from, (*b)->LocalEndpoint());
  EXPECT_EQ(buffer[0], 9);
}

TEST(UdpSocketTest, LoopbackRoundTripIPv4) { RoundTrip("127.0.0.1"); }

TEST(UdpSocketTest, LoopbackRoundTripIPv6) {
  if (!UdpSocket::Open(At("::1", 0)).ok()) GTEST_SKIP() << "IPv6 loopback unavailable";
  RoundTrip("::1");
}

TEST(UdpSocketTest, NothingPendingReturnsZeroWithoutBlocking) {
  auto a = UdpSocket::Open(At("127.0.0.1", 0));
  ASSERT_TRUE(a.ok());
  std::array<uint8_t, 64> buffer{};
  Endpoint from;
  EXPECT_EQ((*a)->ReceiveFrom(&from, buffer), 0u);
  EXPECT_FALSE((*a)->WaitReadable(0));
  EXPECT_FALSE((*a)->WaitReadable(0.01));
}

TEST(UdpSocketTest, WaitReadableSeesPendingDatagram) {
  auto a = UdpSocket::Open(At("127.0.0.1", 0));
  auto b = UdpSocket::Open(At("127.0.0.1", 0));
  ASSERT_TRUE(a.ok() && b.ok());
  ASSERT_TRUE((*a)->SendTo((*b)->LocalEndpoint(), std::vector<uint8_t>{1}).ok());
  EXPECT_TRUE((*b)->WaitReadable(5.0));
}

TEST(UdpSocketTest, OversizedDatagramReportsFullSize) {
  auto a = UdpSocket::Open(At("127.0.0.1", 0));
  auto b = UdpSocket::Open(At("127.0.0.1", 0));
  ASSERT_TRUE(a.ok() && b.ok());
  ASSERT_TRUE((*a)->SendTo((*b)->LocalEndpoint(), std::vector<uint8_t>(3000, 5)).ok());
  std::array<uint8_t, 1200> buffer{};
  Endpoint from;
  EXPECT_EQ(ReceiveWithin(**b, &from, buffer), 3000u);
  EXPECT_EQ(buffer[1199], 5);
}

TEST(UdpSocketTest, BindConflictIsAnError) {
  auto a = UdpSocket::Open(At("127.0.0.1", 0));
  ASSERT_TRUE(a.ok());
  auto b = UdpSocket::Open((*a)->LocalEndpoint());
  EXPECT_FALSE(b.ok());
  EXPECT_EQ(b.status().code(), StatusCode::kIoError);
}

TEST(UdpSocketTest, DualStackServesIPv4Peers) {
  auto server = UdpSocket::Open(At("::", 0));
  if (!server.ok()) GTEST_SKIP() << "IPv6 unavailable";
  auto client = UdpSocket::Open(At("127.0.0.1", 0));
  ASSERT_TRUE(client.ok());
  ASSERT_TRUE(
      (*client)
          ->SendTo(At("127.0.0.1", (*server)->LocalEndpoint().port()), std::vector<uint8_t>{1})
          .ok());
  std::array<uint8_t, 16> buffer{};
  Endpoint from;
  if (ReceiveWithin(**server, &from, buffer) == 0) GTEST_SKIP() << "IPv6 socket is v6-only here";
  EXPECT_EQ(from, (*client)->LocalEndpoint());  // plain IPv4, not ::ffff:127.0.0.1
  ASSERT_TRUE((*server)->SendTo(from, std::vector<uint8_t>{2}).ok());
  EXPECT_EQ(ReceiveWithin(**client, &from, buffer), 1u);
}

}  // namespace
}  // namespace edgephys
