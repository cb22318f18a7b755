// New reliable units held for a packet that leaves anyway (ConnectionConfig::
// max_reliable_delay_s) and Connection::NextTimer, the time a sleeping loop must wake by.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "protocol/connection.h"
#include "protocol/testing/connection_test_util.h"

namespace edgephys {
namespace {

using testing::Bytes;
using testing::CapturingWriter;
using testing::kTestConnectionId;
using testing::Link;
using testing::RecordingHandler;

constexpr size_t kUnitChunk = 6;  // a reliable chunk's header

ConnectionConfig Held(double delay_s) {
  ConnectionConfig c;
  c.max_reliable_delay_s = delay_s;
  return c;
}

Bytes Message(uint32_t index, size_t size) {
  Bytes m(size);
  StoreU32LE(m.data(), index);
  for (size_t i = 4; i < size; ++i) m[i] = static_cast<uint8_t>(index * 13 + i);
  return m;
}

TEST(ConnectionHold, NewUnitsWaitForTheNextPayloadUpToTheDelay) {
  Connection c(kTestConnectionId, Held(0.02), 0);
  CapturingWriter out;
  ASSERT_TRUE(c.SendReliable(Bytes(10, 1)).ok());  // queued as of t = 0
  c.Update(0.01, out);
  EXPECT_TRUE(out.packets.empty());
  EXPECT_DOUBLE_EQ(c.NextTimer(), 0.02);  // the hold ends
  // The next payload carries it.
  ASSERT_TRUE(c.SendUnreliable(Bytes(100, 2), 0.015, out).ok());
  ASSERT_EQ(out.packets.size(), 1u);
  EXPECT_EQ(out.packets[0].size(), kConnectionHeaderSize + 3 + 100 + kUnitChunk + 10);
  c.Update(0.03, out);
  EXPECT_EQ(out.packets.size(), 1u);
  // No payload within the delay: the unit leaves alone once it has waited that long.
  ASSERT_TRUE(c.SendReliable(Bytes(10, 3)).ok());  // as of t = 0.03, the last time given
  EXPECT_DOUBLE_EQ(c.NextTimer(), 0.05);
  c.Update(0.045, out);
  EXPECT_EQ(out.packets.size(), 1u);
  c.Update(0.05, out);
  ASSERT_EQ(out.packets.size(), 2u);
  EXPECT_EQ(out.packets[1].size(), kConnectionHeaderSize + kUnitChunk + 10);
  // Resends are not held: without an RTT sample, max_resend_s after the last send.
  EXPECT_DOUBLE_EQ(c.NextTimer(), 0.05 + 0.1);  // the keep-alive comes first
}

TEST(ConnectionHold, AHeldUnitRidesOnAKeepAliveOrAnOwedAck) {
  Connection c(kTestConnectionId, Held(0.02), 0);
  CapturingWriter out;
  c.Update(0.095, out);
  ASSERT_TRUE(out.packets.empty());
  ASSERT_TRUE(c.SendReliable(Bytes(10, 1)).ok());
  c.Update(0.1, out);  // a keep-alive is due: the unit goes in it, held only 5 ms
  ASSERT_EQ(out.packets.size(), 1u);
  EXPECT_EQ(out.packets[0].size(), kConnectionHeaderSize + kUnitChunk + 10);

  // A reliable unit from the peer is owed an ack at the next Update(): ours rides on it.
  Connection peer(kTestConnectionId, ConnectionConfig{}, 0);
  CapturingWriter peer_out;
  RecordingHandler handler;
  ASSERT_TRUE(peer.SendReliable(Bytes(4, 9)).ok());
  peer.Update(0.11, peer_out);
  ASSERT_EQ(peer_out.packets.size(), 1u);
  ASSERT_TRUE(c.ProcessPacket(peer_out.packets[0], 0.11, handler).ok());
  ASSERT_TRUE(c.SendReliable(Bytes(10, 2)).ok());
  EXPECT_DOUBLE_EQ(c.NextTimer(), 0.11);  // the owed ack: at once
  c.Update(0.112, out);
  ASSERT_EQ(out.packets.size(), 2u);
  EXPECT_EQ(out.packets[1].size(), kConnectionHeaderSize + kUnitChunk + 10);
}

TEST(ConnectionHold, NextTimerOfADisconnectingAndADisconnectedConnection) {
  Connection c(kTestConnectionId, Held(0.02), 0);
  CapturingWriter out;
  c.Update(0.5, out);  // a keep-alive
  EXPECT_DOUBLE_EQ(c.NextTimer(), 0.6);
  c.Disconnect(DisconnectReason::kClientLeft, out);  // sends its copies at once
  EXPECT_EQ(c.NextTimer(), std::numeric_limits<double>::infinity());
}

// Messages every 10 ms, payloads every 20 ms (a 50 Hz tick), 20 % loss, duplication and
// reordering: every message arrives once, in order, and fewer packets are sent than without
// the hold.
TEST(ConnectionHold, HeldMessagesArriveOnceInOrderUnderLossReorderingAndDuplication) {
  auto run = [](double delay_s, uint64_t* packets_sent) {
    NetworkConditions c;
    c.loss = 0.2;
    c.duplicate = 0.05;
    c.reorder = 0.1;
    c.latency_s = 0.03;
    c.jitter_s = 0.01;
    c.seed = 41;
    Link link(c, Held(delay_s));
    std::mt19937 rng(5);
    std::vector<Bytes> messages;
    for (uint32_t step = 0; step < 1500; ++step) {
      messages.push_back(Message(static_cast<uint32_t>(messages.size()), 4 + rng() % 300));
      EXPECT_TRUE(link.a.connection->SendReliable(messages.back()).ok());
      if (step % 2 == 0) {
        EXPECT_TRUE(link.a.connection->SendUnreliable(Bytes(40, 7), link.now(), link.a).ok());
      }
      link.Step();
    }
    EXPECT_TRUE(link.RunUntil([&] { return link.b.handler.reliable.size() >= messages.size(); }, 30));
    EXPECT_EQ(link.b.handler.reliable.size(), messages.size());
    for (size_t i = 0; i < messages.size() && i < link.b.handler.reliable.size(); ++i) {
      ASSERT_EQ(link.b.handler.reliable[i], messages[i]) << i;
    }
    EXPECT_GT(link.a.connection->stats().reliable_resends, 0u);  // the loss was felt
    *packets_sent = link.a.connection->stats().packets_sent;
  };
  uint64_t held = 0, unheld = 0;
  run(0.02, &held);
  run(0.0, &unheld);
  EXPECT_LT(static_cast<double>(held), 0.75 * static_cast<double>(unheld))
      << held << " packets held, " << unheld << " without";
}

// Without loss a message is delivered within the delay, the step granularity of both ends and
// the link's latency; with payloads every 30 ms some ride on them and some leave on their own.
TEST(ConnectionHold, LatencyIsBoundedByTheDelay) {
  NetworkConditions c;
  c.latency_s = 0.005;
  c.seed = 3;
  constexpr double kDelay = 0.02;
  Link link(c, Held(kDelay));
  std::vector<double> queued_at;
  std::vector<double> delivered_at;
  for (uint32_t step = 0; step < 600; ++step) {
    if (step % 4 == 1) {
      queued_at.push_back(link.now());
      ASSERT_TRUE(link.a.connection->SendReliable(Message(step, 20)).ok());
    }
    if (step % 3 == 0) {
      ASSERT_TRUE(link.a.connection->SendUnreliable(Bytes(40, 7), link.now(), link.a).ok());
    }
    link.Step();
    while (delivered_at.size() < link.b.handler.reliable.size()) delivered_at.push_back(link.now());
  }
  ASSERT_TRUE(link.RunUntil([&] { return link.b.handler.reliable.size() >= queued_at.size(); }, 2));
  while (delivered_at.size() < link.b.handler.reliable.size()) delivered_at.push_back(link.now());
  ASSERT_EQ(delivered_at.size(), queued_at.size());
  double worst = 0;
  for (size_t i = 0; i < queued_at.size(); ++i) worst = std::max(worst, delivered_at[i] - queued_at[i]);
  // Held at most kDelay, sent by the Update() of the step that passes it, then one step of
  // latency rounding on the way and one more until the receiver's step reads it.
  EXPECT_LE(worst, kDelay + 3 * Link::kStep + 1e-9);
  EXPECT_GE(worst, kDelay - 1e-9);  // some waited the whole delay (no payload in time)
  EXPECT_EQ(link.a.connection->stats().reliable_resends, 0u);
}

}  // namespace
}  // namespace edgephys
