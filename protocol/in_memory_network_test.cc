#include "protocol/testing/in_memory_network.h"

#include <gtest/gtest.h>

#include <array>
#include <vector>

namespace edgephys {
namespace {

Endpoint At(const char* address, uint16_t port) {
  return Endpoint(asio::ip::make_address(address), port);
}

TEST(InMemoryNetworkTest, DeliversBetweenSockets) {
  InMemoryNetwork network;
  auto a = network.CreateSocket(At("10.0.0.1", 1));
  auto b = network.CreateSocket(At("10.0.0.2", 2));
  ASSERT_TRUE(a && b);
  std::vector<uint8_t> hello = {1, 2, 3};
  ASSERT_TRUE(a->SendTo(b->LocalEndpoint(), hello).ok());
  ASSERT_TRUE(a->SendTo(b->LocalEndpoint(), std::vector<uint8_t>{4}).ok());
  std::array<uint8_t, 16> buffer{};
  Endpoint from;
  ASSERT_EQ(b->ReceiveFrom(&from, buffer), 3u);
  EXPECT_EQ(from, a->LocalEndpoint());
  EXPECT_EQ(buffer[2], 3);
  ASSERT_EQ(b->ReceiveFrom(&from, buffer), 1u);
  EXPECT_EQ(buffer[0], 4);
  EXPECT_EQ(b->ReceiveFrom(&from, buffer), 0u);
  EXPECT_EQ(a->ReceiveFrom(&from, buffer), 0u);
  EXPECT_EQ(network.stats().delivered, 2u);
}

TEST(InMemoryNetworkTest, UnknownDestinationVanishes) {
  InMemoryNetwork network;
  auto a = network.CreateSocket(At("10.0.0.1", 1));
  EXPECT_TRUE(a->SendTo(At("10.0.0.9", 9), std::vector<uint8_t>{1}).ok());
  EXPECT_EQ(network.stats().no_destination, 1u);
}

TEST(InMemoryNetworkTest, WildcardBindReceivesAndEphemeralPortsAreUnique) {
  InMemoryNetwork network;
  auto server = network.CreateSocket(At("0.0.0.0", 7777));
  auto c1 = network.CreateSocket(At("127.0.0.1", 0));
  auto c2 = network.CreateSocket(At("127.0.0.1", 0));
  ASSERT_TRUE(server && c1 && c2);
  EXPECT_NE(c1->LocalEndpoint().port(), 0);
  EXPECT_NE(c1->LocalEndpoint(), c2->LocalEndpoint());
  ASSERT_TRUE(c1->SendTo(At("127.0.0.1", 7777), std::vector<uint8_t>{5}).ok());
  std::array<uint8_t, 4> buffer{};
  Endpoint from;
  ASSERT_EQ(server->ReceiveFrom(&from, buffer), 1u);
  EXPECT_EQ(from, c1->LocalEndpoint());
  EXPECT_EQ(network.CreateSocket(At("0.0.0.0", 7777)), nullptr);  // already bound
}

TEST(InMemoryNetworkTest, ReportsFullSizeOfTruncatedDatagram) {
  InMemoryNetwork network;
  auto a = network.CreateSocket(At("10.0.0.1", 1));
  auto b = network.CreateSocket(At("10.0.0.2", 2));
  ASSERT_TRUE(a->SendTo(b->LocalEndpoint(), std::vector<uint8_t>(100, 9)).ok());
  std::array<uint8_t, 10> buffer{};
  Endpoint from;
  EXPECT_EQ(b->ReceiveFrom(&from, buffer), 100u);
  EXPECT_EQ(buffer[9], 9);
}

TEST(InMemoryNetworkTest, BoundedQueues) {
  InMemoryNetwork network(/*max_queued_per_socket=*/4);
  auto a = network.CreateSocket(At("10.0.0.1", 1));
  auto b = network.CreateSocket(At("10.0.0.2", 2));
  for (int i = 0; i < 6; ++i) {
    ASSERT_TRUE(a->SendTo(b->LocalEndpoint(), std::vector<uint8_t>{1}).ok());
  }
  EXPECT_EQ(network.stats().queue_full, 2u);
}

TEST(InMemoryNetworkTest, SocketsAndNetworkMayDieInAnyOrder) {
  auto network = std::make_unique<InMemoryNetwork>();
  auto a = network->CreateSocket(At("10.0.0.1", 1));
  {
    auto b = network->CreateSocket(At("10.0.0.2", 2));
    ASSERT_TRUE(a->SendTo(b->LocalEndpoint(), std::vector<uint8_t>{1}).ok());
  }
  // b is gone: its address is free again and datagrams to it vanish.
  EXPECT_TRUE(a->SendTo(At("10.0.0.2", 2), std::vector<uint8_t>{1}).ok());
  EXPECT_EQ(network->stats().no_destination, 1u);
  auto b2 = network->CreateSocket(At("10.0.0.2", 2));
  ASSERT_NE(b2, nullptr);
  network.reset();
  EXPECT_TRUE(a->SendTo(b2->LocalEndpoint(), std::vector<uint8_t>{7}).ok());
  std::array<uint8_t, 4> buffer{};
  Endpoint from;
  EXPECT_EQ(b2->ReceiveFrom(&from, buffer), 1u);
}

}  // namespace
}  // namespace edgephys
