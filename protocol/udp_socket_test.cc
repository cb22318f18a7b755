#include "protocol/udp_socket.h"

#include "protocol/endpoint.h"

#include <gtest/gtest.h>
#include <time.h>

#include <array>
#include <chrono>
#include <ostream>
#include <string>
#include <thread>
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

// Two senders batch 32 datagrams each (distinct sizes and contents) to one receiver, which
// batch-receives all 64 with their sources.
void BatchRoundTrip(const char* loopback) {
  auto a = UdpSocket::Open(At(loopback, 0));
  auto b = UdpSocket::Open(At(loopback, 0));
  auto r = UdpSocket::Open(At(loopback, 0));
  ASSERT_TRUE(a.ok() && b.ok() && r.ok());
  constexpr size_t kCount = 64;
  std::vector<std::vector<uint8_t>> payloads(kCount);
  std::vector<UdpSocket::Outgoing> from_a, from_b;
  for (size_t i = 0; i < kCount; ++i) {
    payloads[i].resize(8 + i * 17);
    for (size_t k = 0; k < payloads[i].size(); ++k)
      payloads[i][k] = static_cast<uint8_t>(i + k * 3);
    payloads[i][0] = static_cast<uint8_t>(i);  // index, to match it on arrival
    (i % 2 == 0 ? from_a : from_b).push_back({(*r)->LocalEndpoint(), payloads[i]});
  }
  UdpSocket::BatchSendResult sa = (*a)->SendBatch(from_a);
  UdpSocket::BatchSendResult sb = (*b)->SendBatch(from_b);
  EXPECT_EQ(sa.sent + sb.sent, kCount);
  EXPECT_EQ(sa.refused + sb.refused, 0u);
  size_t expected_bytes = 0;
  for (const auto& p : payloads) expected_bytes += p.size();
  EXPECT_EQ(sa.bytes_sent + sb.bytes_sent, expected_bytes);

  std::vector<std::array<uint8_t, 1500>> storage(kCount);
  std::vector<UdpSocket::ReceiveSlot> slots(kCount);
  for (size_t i = 0; i < kCount; ++i) slots[i].buffer = storage[i];
  std::vector<bool> seen(kCount, false);
  size_t received = 0;
  for (int round = 0; round < 100 && received < kCount; ++round) {
    size_t n = (*r)->ReceiveBatch(slots);
    if (n == 0) {
      (*r)->WaitReadable(0.05);
      continue;
    }
    for (size_t k = 0; k < n; ++k) {
      const size_t i = slots[k].buffer[0];
      ASSERT_LT(i, kCount);
      EXPECT_FALSE(seen[i]) << "datagram " << i << " twice";
      seen[i] = true;
      ASSERT_EQ(slots[k].size, payloads[i].size());
      EXPECT_TRUE(std::equal(payloads[i].begin(), payloads[i].end(), slots[k].buffer.begin()));
      EXPECT_EQ(slots[k].from, i % 2 == 0 ? (*a)->LocalEndpoint() : (*b)->LocalEndpoint());
      ++received;
    }
  }
  EXPECT_EQ(received, kCount);
  EXPECT_EQ((*r)->ReceiveBatch(slots), 0u);  // nothing left, and no blocking
}

// The round trips over each address family's loopback; IPv6 is skipped on a machine without
// it, IPv4 never.
struct Family {
  const char* name;
  const char* loopback;
  bool optional;
};
void PrintTo(const Family& family, std::ostream* os) { *os << family.name; }

class UdpSocketFamily : public ::testing::TestWithParam<Family> {
 protected:
  void SetUp() override {
    if (GetParam().optional && !UdpSocket::Open(At(GetParam().loopback, 0)).ok()) {
      GTEST_SKIP() << GetParam().name << " loopback unavailable";
    }
  }
};

TEST_P(UdpSocketFamily, LoopbackRoundTrip) { RoundTrip(GetParam().loopback); }

TEST_P(UdpSocketFamily, BatchSendAndReceive) { BatchRoundTrip(GetParam().loopback); }

INSTANTIATE_TEST_SUITE_P(Loopback, UdpSocketFamily,
                         ::testing::Values(Family{"IPv4", "127.0.0.1", false},
                                           Family{"IPv6", "::1", true}),
                         [](const ::testing::TestParamInfo<Family>& param_info) {
                           return std::string(param_info.param.name);
                         });

TEST(UdpSocketTest, BatchCountsInvalidDatagramsAsRefusedAndSendsTheRest) {
  auto a = UdpSocket::Open(At("127.0.0.1", 0));
  auto r = UdpSocket::Open(At("127.0.0.1", 0));
  ASSERT_TRUE(a.ok() && r.ok());
  std::vector<uint8_t> small = {1, 2, 3}, huge(70000, 1);
  std::vector<UdpSocket::Outgoing> out = {{(*r)->LocalEndpoint(), small},
                                          {At("::1", 9), small},  // IPv6 from an IPv4 socket
                                          {(*r)->LocalEndpoint(), huge},
                                          {(*r)->LocalEndpoint(), small}};
  UdpSocket::BatchSendResult result = (*a)->SendBatch(out);
  EXPECT_EQ(result.sent, 2u);
  EXPECT_EQ(result.refused, 2u);
  EXPECT_EQ(result.bytes_sent, 6u);
  std::array<uint8_t, 64> buffer{};
  Endpoint from;
  EXPECT_EQ(ReceiveWithin(**r, &from, buffer), 3u);
  EXPECT_EQ(ReceiveWithin(**r, &from, buffer), 3u);
}

TEST(UdpSocketTest, BatchReceiveReportsTruncatedFullSize) {
  auto a = UdpSocket::Open(At("127.0.0.1", 0));
  auto r = UdpSocket::Open(At("127.0.0.1", 0));
  ASSERT_TRUE(a.ok() && r.ok());
  ASSERT_TRUE((*a)->SendTo((*r)->LocalEndpoint(), std::vector<uint8_t>(3000, 5)).ok());
  ASSERT_TRUE((*r)->WaitReadable(5.0));
  std::array<uint8_t, 1200> buffer{};
  std::array<UdpSocket::ReceiveSlot, 4> slots{};
  slots[0].buffer = buffer;
  ASSERT_EQ((*r)->ReceiveBatch(std::span<UdpSocket::ReceiveSlot>(slots.data(), 1)), 1u);
  EXPECT_EQ(slots[0].size, 3000u);
  EXPECT_EQ(slots[0].from, (*a)->LocalEndpoint());
  EXPECT_EQ(buffer[1199], 5);
}

// CLOCK_REALTIME in seconds, the clock of arrival times.
double RealtimeNow() {
  timespec now{};
  clock_gettime(CLOCK_REALTIME, &now);
  return static_cast<double>(now.tv_sec) + now.tv_nsec * 1e-9;
}

// As ReceiveWithin, through ReceiveFromTimed.
size_t ReceiveTimedWithin(UdpSocket& socket, Endpoint* from, std::span<uint8_t> buffer,
                          double* arrival_unix_s) {
  for (int i = 0; i < 50; ++i) {
    if (size_t size = socket.ReceiveFromTimed(from, buffer, arrival_unix_s)) return size;
    socket.WaitReadable(0.1);
  }
  return 0;
}

TEST(UdpSocketTest, ArrivalTimeLiesBetweenTheSendAndTheRead) {
  auto a = UdpSocket::Open(At("127.0.0.1", 0));
  auto b = UdpSocket::Open(At("127.0.0.1", 0));
  ASSERT_TRUE(a.ok() && b.ok());
  ASSERT_TRUE((*b)->EnableArrivalTimes());
  // The first socket on a host to ask turns stamping on through deferred kernel work; until it
  // has run, datagrams are stamped when read. Give it a moment.
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  std::array<uint8_t, 64> buffer{};
  for (int round = 0; round < 3; ++round) {
    const std::vector<uint8_t> ping = {1, 2, static_cast<uint8_t>(round)};
    const double sent = RealtimeNow();
    ASSERT_TRUE((*a)->SendTo((*b)->LocalEndpoint(), ping).ok());
    // Let it wait in the queue, so a read time passed off as the arrival would show.
    ASSERT_TRUE((*b)->WaitReadable(5.0));
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    Endpoint from;
    double arrival = -1;
    const size_t size = ReceiveTimedWithin(**b, &from, buffer, &arrival);
    const double read = RealtimeNow();
    ASSERT_EQ(size, ping.size());
    EXPECT_EQ(from, (*a)->LocalEndpoint());
    EXPECT_EQ(buffer[2], round);
    EXPECT_GE(arrival, sent);
    EXPECT_LE(arrival, read - 0.015);  // stamped on arrival, not when read 20 ms later
  }
}

TEST(UdpSocketTest, ArrivalTimeIsUnknownUntilEnabledAndReceiveFromIsUnchanged) {
  auto a = UdpSocket::Open(At("127.0.0.1", 0));
  auto b = UdpSocket::Open(At("127.0.0.1", 0));
  ASSERT_TRUE(a.ok() && b.ok());
  std::array<uint8_t, 2048> buffer{};
  Endpoint from;
  double arrival = -1;
  EXPECT_EQ((*b)->ReceiveFromTimed(&from, buffer, &arrival), 0u);  // nothing pending
  ASSERT_TRUE((*a)->SendTo((*b)->LocalEndpoint(), std::vector<uint8_t>{7, 7}).ok());
  ASSERT_EQ(ReceiveTimedWithin(**b, &from, buffer, &arrival), 2u);
  EXPECT_EQ(arrival, 0.0);  // not enabled: unknown
  EXPECT_EQ(from, (*a)->LocalEndpoint());

  // With timestamps on, the plain calls read as before (the control data is discarded).
  ASSERT_TRUE((*b)->EnableArrivalTimes());
  ASSERT_TRUE((*a)->SendTo((*b)->LocalEndpoint(), std::vector<uint8_t>(3000, 5)).ok());
  std::array<uint8_t, 1200> small{};
  EXPECT_EQ(ReceiveWithin(**b, &from, small), 3000u);  // full size of a truncated datagram
  EXPECT_EQ(from, (*a)->LocalEndpoint());
  EXPECT_EQ(small[1199], 5);
  ASSERT_TRUE((*a)->SendTo((*b)->LocalEndpoint(), std::vector<uint8_t>{9}).ok());
  ASSERT_TRUE((*b)->WaitReadable(5.0));
  std::array<UdpSocket::ReceiveSlot, 1> slots{};
  slots[0].buffer = buffer;
  ASSERT_EQ((*b)->ReceiveBatch(slots), 1u);
  EXPECT_EQ(slots[0].size, 1u);
  EXPECT_EQ(slots[0].from, (*a)->LocalEndpoint());
  EXPECT_EQ(buffer[0], 9);

  // And the timed read reports a truncated datagram's full size too.
  ASSERT_TRUE((*a)->SendTo((*b)->LocalEndpoint(), std::vector<uint8_t>(3000, 6)).ok());
  ASSERT_EQ(ReceiveTimedWithin(**b, &from, small, &arrival), 3000u);
  EXPECT_EQ(small[1199], 6);
  EXPECT_GT(arrival, 0.0);
}

TEST(UdpSocketTest, ArrivalTimesOverIPv6) {
  if (!UdpSocket::Open(At("::1", 0)).ok()) GTEST_SKIP() << "IPv6 loopback unavailable";
  auto a = UdpSocket::Open(At("::1", 0));
  auto b = UdpSocket::Open(At("::1", 0));
  ASSERT_TRUE(a.ok() && b.ok());
  ASSERT_TRUE((*b)->EnableArrivalTimes());
  const double sent = RealtimeNow();
  ASSERT_TRUE((*a)->SendTo((*b)->LocalEndpoint(), std::vector<uint8_t>{4}).ok());
  std::array<uint8_t, 16> buffer{};
  Endpoint from;
  double arrival = 0;
  ASSERT_EQ(ReceiveTimedWithin(**b, &from, buffer, &arrival), 1u);
  EXPECT_EQ(from, (*a)->LocalEndpoint());
  EXPECT_GE(arrival, sent);
  EXPECT_LE(arrival, RealtimeNow());
}

TEST(UdpSocket, BindErrorNamesTheAddressAndTheReason) {
  auto first = UdpSocket::Open(*ParseEndpoint("127.0.0.1:0"));
  ASSERT_TRUE(first.ok());
  const Endpoint taken = (*first)->LocalEndpoint();
  auto second = UdpSocket::Open(taken);
  ASSERT_FALSE(second.ok());
  const std::string message = second.status().ToString();
  EXPECT_NE(message.find(FormatEndpoint(taken)), std::string::npos) << message;
  EXPECT_NE(message.find("in use"), std::string::npos) << message;
}

}  // namespace
}  // namespace edgephys
