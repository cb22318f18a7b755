#include "protocol/batched_socket.h"

#include <gtest/gtest.h>

#include <array>
#include <vector>

namespace edgephys {
namespace {

Endpoint Loopback() { return Endpoint(asio::ip::make_address("127.0.0.1"), 0); }

// Datagram i: its length and bytes encode i, so order and content can be checked.
std::vector<uint8_t> Datagram(size_t i) {
  std::vector<uint8_t> d(20 + i % 900);
  for (size_t k = 0; k < d.size(); ++k) d[k] = static_cast<uint8_t>(i * 31 + k);
  return d;
}

// Reads through `socket` until `count` datagrams arrived or ~5 s passed (a stall guard).
std::vector<std::vector<uint8_t>> ReceiveAll(BatchedSocket& socket, UdpSocket& raw, size_t count) {
  std::vector<std::vector<uint8_t>> got;
  std::array<uint8_t, 4096> buffer{};
  for (int wait = 0; got.size() < count && wait < 50;) {
    Endpoint from;
    size_t n = socket.ReceiveFrom(&from, buffer);
    if (n == 0) {
      raw.WaitReadable(0.1);
      ++wait;
      continue;
    }
    got.emplace_back(buffer.begin(), buffer.begin() + std::min(n, buffer.size()));
  }
  return got;
}

TEST(BatchedSocket, QueuedSendsLeaveInOrderOnFlushWithFewSystemCalls) {
  auto a = UdpSocket::Open(Loopback());
  auto b = UdpSocket::Open(Loopback());
  ASSERT_TRUE(a.ok() && b.ok());
  BatchedSocket sender(a->get()), receiver(b->get());
  constexpr size_t kCount = 300;  // more than the queue: one automatic flush on the way
  for (size_t i = 0; i < kCount; ++i) {
    ASSERT_TRUE(sender.SendTo((*b)->LocalEndpoint(), Datagram(i)).ok());
  }
  EXPECT_EQ(sender.Flush(), 0u);
  EXPECT_EQ(sender.Flush(), 0u);  // nothing left: no call
  // 256 queued (4 calls of 64) + 44 (1 call).
  EXPECT_EQ(sender.send_calls(), 5u);

  auto got = ReceiveAll(receiver, **b, kCount);
  ASSERT_EQ(got.size(), kCount);
  for (size_t i = 0; i < kCount; ++i) EXPECT_EQ(got[i], Datagram(i)) << i;
  // At most kMaxBatch datagrams per receive call, plus the empty polls while waiting.
  EXPECT_LT(receiver.receive_calls(), kCount / 4);
}

TEST(BatchedSocket, WithoutSendBatchingSendsLeaveAtOnceAndReceivesStillComeInBatches) {
  auto a = UdpSocket::Open(Loopback());
  auto b = UdpSocket::Open(Loopback());
  ASSERT_TRUE(a.ok() && b.ok());
  BatchedSocket sender(a->get(), /*batch_sends=*/false), receiver(b->get(), false);
  constexpr size_t kCount = 200;
  for (size_t i = 0; i < kCount; ++i) {
    ASSERT_TRUE(sender.SendTo((*b)->LocalEndpoint(), Datagram(i)).ok());
  }
  EXPECT_EQ(sender.send_calls(), kCount);  // one sendto each, before any Flush()
  EXPECT_EQ(sender.Flush(), 0u);
  EXPECT_EQ(sender.send_calls(), kCount);
  auto got = ReceiveAll(receiver, **b, kCount);
  ASSERT_EQ(got.size(), kCount);
  for (size_t i = 0; i < kCount; ++i) EXPECT_EQ(got[i], Datagram(i)) << i;
  EXPECT_LT(receiver.receive_calls(), kCount / 4);
}

TEST(BatchedSocket, NothingLeavesBeforeFlush) {
  auto a = UdpSocket::Open(Loopback());
  auto b = UdpSocket::Open(Loopback());
  ASSERT_TRUE(a.ok() && b.ok());
  BatchedSocket sender(a->get());
  ASSERT_TRUE(sender.SendTo((*b)->LocalEndpoint(), Datagram(1)).ok());
  EXPECT_FALSE((*b)->WaitReadable(0.05));
  EXPECT_EQ(sender.Flush(), 0u);
  EXPECT_TRUE((*b)->WaitReadable(5.0));
}

TEST(BatchedSocket, LargeDatagramsKeepTheirOrderAndReportTheirFullSize) {
  auto a = UdpSocket::Open(Loopback());
  auto b = UdpSocket::Open(Loopback());
  ASSERT_TRUE(a.ok() && b.ok());
  BatchedSocket sender(a->get()), receiver(b->get());
  std::vector<uint8_t> big(3000, 0xab);  // beyond a slot: sent alone, after what was queued
  ASSERT_TRUE(sender.SendTo((*b)->LocalEndpoint(), Datagram(1)).ok());
  ASSERT_TRUE(sender.SendTo((*b)->LocalEndpoint(), big).ok());
  ASSERT_TRUE(sender.SendTo((*b)->LocalEndpoint(), Datagram(2)).ok());
  EXPECT_EQ(sender.Flush(), 0u);

  std::array<uint8_t, 4096> buffer{};
  std::vector<size_t> sizes;
  for (int wait = 0; sizes.size() < 3 && wait < 50;) {
    Endpoint from;
    size_t n = receiver.ReceiveFrom(&from, buffer);
    if (n == 0) {
      (*b)->WaitReadable(0.1);
      ++wait;
      continue;
    }
    sizes.push_back(n);
    if (n <= BatchedSocket::kSlotBytes) {
      EXPECT_EQ(from, (*a)->LocalEndpoint());
    }
  }
  // The big one arrives truncated to a slot but is reported with its full size, so a caller
  // drops it as too large, as with UdpSocket::ReceiveFrom.
  EXPECT_EQ(sizes, (std::vector<size_t>{Datagram(1).size(), big.size(), Datagram(2).size()}));
}

TEST(BatchedSocket, AnInvalidDestinationIsRefusedAtFlushAndTheRestStillLeave) {
  auto a = UdpSocket::Open(Loopback());
  auto b = UdpSocket::Open(Loopback());
  ASSERT_TRUE(a.ok() && b.ok());
  BatchedSocket sender(a->get()), receiver(b->get());
  ASSERT_TRUE(sender.SendTo((*b)->LocalEndpoint(), Datagram(1)).ok());
  // An IPv6 destination from an IPv4 socket: the OS path refuses it.
  (void)sender.SendTo(Endpoint(asio::ip::make_address("::1"), 9), Datagram(2));
  ASSERT_TRUE(sender.SendTo((*b)->LocalEndpoint(), Datagram(3)).ok());
  EXPECT_EQ(sender.Flush(), 1u);
  auto got = ReceiveAll(receiver, **b, 2);
  ASSERT_EQ(got.size(), 2u);
  EXPECT_EQ(got[0], Datagram(1));
  EXPECT_EQ(got[1], Datagram(3));
}

}  // namespace
}  // namespace edgephys
