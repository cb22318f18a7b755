#include "protocol/connection.h"

#include <gtest/gtest.h>

#include <random>
#include <set>

#include "protocol/testing/connection_test_util.h"

namespace edgephys {
namespace {

using testing::Bytes;
using testing::CapturingWriter;
using testing::kTestConnectionId;
using testing::Link;
using testing::PacketBuilder;
using testing::RandomBytes;
using testing::RecordingHandler;

// The impairment every end-to-end test below must survive.
NetworkConditions Harsh(uint64_t seed) {
  return {.loss = 0.2, .duplicate = 0.05, .reorder = 0.1, .latency_s = 0.05,
          .jitter_s = 0.02, .seed = seed};
}

// Message `index`: varied sizes (mostly small, some spanning several units), content derived
// from the index so corruption or reordering is detected.
Bytes TestMessage(uint32_t index, std::mt19937& rng) {
  uint32_t pick = rng() % 100;
  size_t size = pick < 70 ? 4 + rng() % 200 : pick < 90 ? 200 + rng() % 1300 : 1500 + rng() % 4000;
  Bytes message(size);
  StoreU32LE(message.data(), index);
  for (size_t i = 4; i < size; ++i) message[i] = static_cast<uint8_t>(index * 31 + i * 7);
  return message;
}

// Both ends send one unreliable byte at every one of `steps` steps of `link` (a 1, b 2), so
// each has packets to acknowledge and to be acknowledged. Fails fatally on a refused send.
void ExchangeUnreliable(Link& link, int steps) {
  for (int i = 0; i < steps; ++i) {
    ASSERT_TRUE(link.a.connection->SendUnreliable(Bytes{1}, link.now(), link.a).ok());
    ASSERT_TRUE(link.b.connection->SendUnreliable(Bytes{2}, link.now(), link.b).ok());
    link.Step();
  }
}

TEST(ConnectionTest, ThousandReliableMessagesArriveOnceInOrderUnderLoss) {
  Link link(Harsh(11));
  std::mt19937 rng(5);
  std::vector<Bytes> a_to_b, b_to_a;
  for (uint32_t i = 0; i < 1000; ++i) {
    a_to_b.push_back(TestMessage(i, rng));
    ASSERT_TRUE(link.a.connection->SendReliable(a_to_b.back()).ok());
  }
  for (uint32_t i = 0; i < 100; ++i) {
    b_to_a.push_back(TestMessage(i, rng));
    ASSERT_TRUE(link.b.connection->SendReliable(b_to_a.back()).ok());
  }
  ASSERT_TRUE(link.RunUntil(
      [&] {
        return link.b.handler.reliable.size() >= a_to_b.size() &&
               link.a.handler.reliable.size() >= b_to_a.size();
      },
      300.0));
  ASSERT_EQ(link.b.handler.reliable.size(), a_to_b.size());
  for (size_t i = 0; i < a_to_b.size(); ++i) {
    ASSERT_EQ(link.b.handler.reliable[i], a_to_b[i]) << i;
  }
  EXPECT_EQ(link.a.handler.reliable, b_to_a);
  EXPECT_EQ(link.b.connection->stats().reliable_delivered, 1000u);

  // Nothing more arrives later, and every byte is eventually acknowledged.
  link.Run(5.0);
  EXPECT_EQ(link.b.handler.reliable.size(), a_to_b.size());
  EXPECT_EQ(link.a.connection->stats().pending_reliable_bytes, 0u);
  EXPECT_TRUE(link.a.connection->connected());
  EXPECT_TRUE(link.b.connection->connected());
  // The impairment really happened and was handled.
  EXPECT_GT(link.a.sim.stats().dropped, 0u);
  EXPECT_GT(link.a.sim.stats().duplicated, 0u);
  EXPECT_GT(link.a.sim.stats().delayed, 0u);
  EXPECT_GT(link.a.connection->stats().reliable_resends, 0u);
  EXPECT_GT(link.b.connection->stats().duplicates_dropped, 0u);
}

// reliable_acked_end() passes the position a message was queued at only once the peer has
// received it and everything before it (what the relay relies on before sending a member
// states): checked after every step of a lossy, reordering link.
TEST(ConnectionTest, ReliableAckedEndPassesAMessageOnlyAfterItIsDelivered) {
  Link link(Harsh(21));
  std::mt19937 rng(9);
  std::vector<uint64_t> ends;
  for (uint32_t i = 0; i < 200; ++i) {
    EXPECT_EQ(link.a.connection->reliable_queued_end(),
              i == 0 ? 0u : ends.back());
    ASSERT_TRUE(link.a.connection->SendReliable(TestMessage(i, rng)).ok());
    ends.push_back(link.a.connection->reliable_queued_end());
  }
  EXPECT_EQ(link.a.connection->reliable_acked_end(), 0u);
  bool ok = true;
  ASSERT_TRUE(link.RunUntil(
      [&] {
        const uint64_t acked = link.a.connection->reliable_acked_end();
        const size_t delivered = link.b.handler.reliable.size();
        for (size_t i = 0; i < ends.size(); ++i) {
          if (acked >= ends[i] && delivered <= i) ok = false;  // acked before delivered
        }
        return acked == ends.back();
      },
      300.0));
  EXPECT_TRUE(ok);
  EXPECT_EQ(link.b.handler.reliable.size(), ends.size());
  EXPECT_EQ(link.a.connection->stats().pending_reliable_bytes, 0u);
}

TEST(ConnectionTest, LargeReliableMessageArrivesIntactUnderLoss) {
  Link link(Harsh(12));
  Bytes big = RandomBytes(200 * 1024, 1);
  Bytes small = {1, 2, 3};
  ASSERT_TRUE(link.a.connection->SendReliable(big).ok());
  ASSERT_TRUE(link.a.connection->SendReliable(small).ok());
  ASSERT_TRUE(link.RunUntil([&] { return link.b.handler.reliable.size() >= 2; }, 120.0));
  ASSERT_EQ(link.b.handler.reliable.size(), 2u);
  EXPECT_TRUE(link.b.handler.reliable[0] == big);
  EXPECT_EQ(link.b.handler.reliable[1], small);
}

TEST(ConnectionTest, MaxSizeMessageArrivesIntact) {
  NetworkConditions mild;
  mild.loss = 0.05;
  mild.latency_s = 0.02;
  Link link(mild);
  Bytes big = RandomBytes(ConnectionConfig{}.max_message_size, 2);
  ASSERT_TRUE(link.a.connection->SendReliable(big).ok());
  ASSERT_TRUE(link.RunUntil([&] { return !link.b.handler.reliable.empty(); }, 120.0));
  EXPECT_TRUE(link.b.handler.reliable[0] == big);
}

// A link that reorders heavily: 5 % loss, 30 % reordering, 10 % duplication.
NetworkConditions Reordering(uint64_t seed) {
  NetworkConditions c = Harsh(seed);
  c.loss = 0.05;
  c.reorder = 0.3;
  c.duplicate = 0.1;
  return c;
}

// An unreliable payload: first byte `format` (which decides sequenced or not), then `counter`.
Bytes CounterPayload(uint8_t format, uint32_t counter) {
  Bytes payload(8);
  payload[0] = format;
  StoreU32LE(payload.data() + 1, counter);
  return payload;
}

TEST(ConnectionTest, UnreliableNeverDeliversOlderPayloads) {
  Link link(Reordering(13));
  std::map<uint16_t, uint32_t> sent_counter;  // sequence -> counter in that payload
  for (uint32_t i = 0; i < 3000; ++i) {
    const Bytes payload = CounterPayload(1, i);  // a state format: sequenced
    auto sequence = link.a.connection->SendUnreliable(payload, link.now(), link.a);
    ASSERT_TRUE(sequence.ok());
    sent_counter[*sequence] = i;
    link.Step();
  }
  link.Run(1.0);
  const RecordingHandler& h = link.b.handler;
  ASSERT_GT(h.unreliable.size(), 1200u);
  uint32_t previous = 0;
  for (size_t i = 0; i < h.unreliable.size(); ++i) {
    uint32_t counter = LoadU32LE(h.unreliable[i].data() + 1);
    EXPECT_EQ(counter, sent_counter[h.unreliable_sequences[i]]);
    if (i > 0) {
      EXPECT_GT(counter, previous);
    }
    previous = counter;
  }
  EXPECT_GT(link.b.connection->stats().stale_dropped, 0u);
  EXPECT_GT(link.b.connection->stats().duplicates_dropped, 0u);
  EXPECT_GT(link.b.statuses[StatusCode::kAlreadyExists], 0);
}

// Application messages (first byte kUnorderedPayloadFormat) interleaved with state payloads
// under reordering: every message whose packet arrives is delivered once, even when a newer
// state payload came first, and a late message never makes the next state payload stale.
TEST(ConnectionTest, UnorderedPayloadsSkipTheStaleCheckAndLeaveStatesSequenced) {
  Link link(Reordering(17));
  std::set<uint32_t> messages_sent;
  for (uint32_t i = 0; i < 3000; ++i) {
    const Bytes payload = CounterPayload(i % 2 == 0 ? kUnorderedPayloadFormat : 1, i);
    ASSERT_TRUE(link.a.connection->SendUnreliable(payload, link.now(), link.a).ok());
    if (i % 2 == 0) messages_sent.insert(i);
    link.Step();
  }
  link.Run(1.0);
  std::set<uint32_t> messages_got;
  uint32_t previous_state = 0;
  size_t states = 0;
  bool message_after_newer_state = false;
  for (const Bytes& p : link.b.handler.unreliable) {
    const uint32_t counter = LoadU32LE(p.data() + 1);
    if (p[0] == kUnorderedPayloadFormat) {
      EXPECT_TRUE(messages_got.insert(counter).second) << "message " << counter << " twice";
      if (counter < previous_state) message_after_newer_state = true;
      continue;
    }
    if (states++ > 0) {
      EXPECT_GT(counter, previous_state);
    }
    previous_state = counter;
  }
  // 5 % loss: about 1,425 of 1,500 messages arrive; the stale check would have dropped the
  // ~30 % that came after a newer packet.
  EXPECT_GT(messages_got.size(), 1350u);
  EXPECT_TRUE(message_after_newer_state);
  for (uint32_t m : messages_got) EXPECT_TRUE(messages_sent.count(m));
  EXPECT_GT(states, 1000u);
}

TEST(ConnectionTest, OversizedPeerMessageIsAProtocolError) {
  ConnectionConfig small;
  small.max_message_size = 16 * 1024;
  NetworkConditions c;
  c.latency_s = 0.01;
  Link link(c, ConnectionConfig{}, small);
  ASSERT_TRUE(link.a.connection->SendReliable(RandomBytes(100 * 1024, 3)).ok());
  link.Run(1.0);
  EXPECT_EQ(link.b.connection->disconnect_reason(), DisconnectReason::kProtocolError);
  EXPECT_EQ(link.b.statuses[StatusCode::kTooLarge], 1);
  EXPECT_TRUE(link.b.handler.reliable.empty());
  // The broken peer is told why.
  EXPECT_EQ(link.a.connection->disconnect_reason(), DisconnectReason::kProtocolError);
}

TEST(ConnectionTest, ReassemblyStopsAtMaxMessageSize) {
  ConnectionConfig config;
  config.max_message_size = 4096;
  Connection c(kTestConnectionId, config, 0);
  RecordingHandler h;
  Bytes unit(1024, 7);
  for (uint16_t id = 0; id < 4; ++id) {
    EXPECT_TRUE(
        c.ProcessPacket(PacketBuilder(PacketType::kData, id).Unit(id, false, unit).Build(), 0, h)
            .ok());
  }
  Status status =
      c.ProcessPacket(PacketBuilder(PacketType::kData, 4).Unit(4, false, unit).Build(), 0, h);
  EXPECT_EQ(status.code(), StatusCode::kTooLarge);
  EXPECT_EQ(c.disconnect_reason(), DisconnectReason::kProtocolError);
  EXPECT_EQ(
      c.ProcessPacket(PacketBuilder(PacketType::kData, 5).Unit(5, true, unit).Build(), 0, h).code(),
      StatusCode::kNotConnected);
  // The peer is told: the next Update() sends the disconnect packets.
  CapturingWriter out;
  c.Update(0.01, out);
  ASSERT_EQ(out.packets.size(), 3u);
  EXPECT_EQ(out.packets[0][5], static_cast<uint8_t>(PacketType::kDisconnect));
  EXPECT_EQ(out.packets[0].back(), static_cast<uint8_t>(DisconnectReason::kProtocolError));
  EXPECT_TRUE(h.reliable.empty());
}

TEST(ConnectionTest, UnitsOutsideTheWindowAreAProtocolError) {
  ConnectionConfig config;
  config.max_held_reliable_bytes = 4 << 20;  // the window, not the memory bound, is under test
  Connection c(kTestConnectionId, config, 0);
  RecordingHandler h;
  Bytes unit(1024, 1);
  // Fill the whole window except the first unit: buffered, bounded, never delivered.
  uint16_t sequence = 0;
  for (uint16_t id = 1; id < kReliableWindow; ++id) {
    ASSERT_TRUE(
        c.ProcessPacket(PacketBuilder(PacketType::kData, sequence++).Unit(id, false, unit).Build(),
                        0, h)
            .ok());
  }
  // Repeats are duplicates.
  uint64_t duplicates = c.stats().duplicates_dropped;
  ASSERT_TRUE(c.ProcessPacket(
                   PacketBuilder(PacketType::kData, sequence++).Unit(5, false, unit).Build(), 0, h)
                  .ok());
  EXPECT_EQ(c.stats().duplicates_dropped, duplicates + 1);
  EXPECT_TRUE(c.connected());
  Status status = c.ProcessPacket(
      PacketBuilder(PacketType::kData, sequence++).Unit(kReliableWindow, true, unit).Build(), 0, h);
  EXPECT_EQ(status.code(), StatusCode::kResourceExhausted);
  EXPECT_EQ(c.disconnect_reason(), DisconnectReason::kProtocolError);
  EXPECT_TRUE(h.reliable.empty());
}

TEST(ConnectionTest, CompletesBufferedMessagesWhenTheGapFills) {
  Connection c(kTestConnectionId, ConnectionConfig{}, 0);
  RecordingHandler h;
  Bytes x = {1}, y = {2}, z = {3};
  ASSERT_TRUE(
      c.ProcessPacket(PacketBuilder(PacketType::kData, 0).Unit(2, true, z).Build(), 0, h).ok());
  ASSERT_TRUE(
      c.ProcessPacket(PacketBuilder(PacketType::kData, 1).Unit(1, false, y).Build(), 0, h).ok());
  EXPECT_TRUE(h.reliable.empty());
  ASSERT_TRUE(
      c.ProcessPacket(
           PacketBuilder(PacketType::kData, 2).Unit(0, true, x).Unit(1, false, y).Build(), 0, h)
          .ok());
  ASSERT_EQ(h.reliable.size(), 2u);
  EXPECT_EQ(h.reliable[0], x);
  EXPECT_EQ(h.reliable[1], (Bytes{2, 3}));
  EXPECT_EQ(c.stats().reliable_delivered, 2u);
  EXPECT_EQ(c.stats().duplicates_dropped, 1u);  // unit 1 twice
}

TEST(ConnectionTest, KeepAlivesHoldAnIdleConnectionAndSilenceTimesOut) {
  NetworkConditions c;
  c.latency_s = 0.02;
  Link link(c);
  link.Run(3.0);
  EXPECT_TRUE(link.a.connection->connected());
  EXPECT_TRUE(link.b.connection->connected());
  // keepalive_interval_s = 0.1: about 30 packets in 3 s, none of them carrying chunks.
  EXPECT_GE(link.a.connection->stats().packets_sent, 25u);
  EXPECT_LE(link.a.connection->stats().packets_sent, 35u);
  EXPECT_GE(link.b.connection->stats().packets_received, 25u);

  // b goes silent: a times out after timeout_s (5 s) of silence, not before.
  link.b.mute = true;
  double silent_since = link.now();
  ASSERT_TRUE(link.RunUntil([&] { return !link.a.connection->connected(); }, 10.0));
  EXPECT_EQ(link.a.connection->disconnect_reason(), DisconnectReason::kTimeout);
  EXPECT_GE(link.now() - silent_since, 4.9);
  EXPECT_LE(link.now() - silent_since, 5.2);
  EXPECT_TRUE(link.b.connection->connected());  // a sends nothing when it times out
}

TEST(ConnectionTest, AcksArePromptAndReportedOnceForEveryPacket) {
  Connection a(kTestConnectionId, ConnectionConfig{}, 0),
      b(kTestConnectionId, ConnectionConfig{}, 0);
  RecordingHandler ha, hb;
  CapturingWriter a_out(&ha), b_out(&hb);
  auto sequence = a.SendUnreliable(Bytes{1, 2, 3}, 0.001, a_out);
  ASSERT_TRUE(sequence.ok());
  ASSERT_TRUE(b.ProcessPacket(a_out.packets.back(), 0.002, hb).ok());
  b.Update(0.003, b_out);  // owes an ack: sends one packet with no chunks
  ASSERT_EQ(b_out.packets.size(), 1u);
  EXPECT_EQ(b_out.packets[0].size(), kConnectionHeaderSize);
  b.Update(0.004, b_out);  // nothing owed, keep-alive not due
  EXPECT_EQ(b_out.packets.size(), 1u);
  ASSERT_TRUE(a.ProcessPacket(b_out.packets[0], 0.005, ha).ok());
  EXPECT_TRUE(ha.acked[*sequence]);
  EXPECT_EQ(ha.acked_count, 1u);
  EXPECT_NEAR(a.stats().rtt_s, 0.004, 1e-9);
  // Replaying the ack packet is a duplicate, never a second report.
  EXPECT_EQ(a.ProcessPacket(b_out.packets[0], 0.006, ha).code(), StatusCode::kAlreadyExists);
  EXPECT_EQ(ha.acked_count, 1u);
  // An ack-only packet does not itself ask for an ack.
  a.Update(0.007, a_out);
  EXPECT_EQ(a_out.packets.size(), 1u);
}

TEST(ConnectionTest, EveryPacketIncludingUpdatesIsAckedExactlyOnce) {
  NetworkConditions c;
  c.latency_s = 0.015;
  Link link(c);
  for (int i = 0; i < 300; ++i) {
    if (i % 5 == 0) {
      ASSERT_TRUE(link.a.connection->SendReliable(RandomBytes(2000, i)).ok());
    }
    if (i % 2 == 0) {
      ASSERT_TRUE(link.a.connection->SendUnreliable(Bytes{1}, link.now(), link.a).ok());
    }
    link.Step();
  }
  link.Run(1.0);
  // Lossless: every packet a sent except the last keep-alive or two is acknowledged.
  EXPECT_GE(link.a.handler.acked_count + 3, link.a.connection->stats().packets_sent);
  EXPECT_EQ(link.a.connection->stats().reliable_resends, 0u);
  EXPECT_NEAR(link.a.connection->stats().loss, 0.0, 1e-9);
}

TEST(ConnectionTest, RttTracksSimulatedLatency) {
  NetworkConditions c;
  c.latency_s = 0.05;
  Link link(c);
  ASSERT_NO_FATAL_FAILURE(ExchangeUnreliable(link, 300));
  // 100 ms round trip plus at most one 10 ms step before the ack leaves.
  EXPECT_GE(link.a.connection->stats().rtt_s, 0.095);
  EXPECT_LE(link.a.connection->stats().rtt_s, 0.115);
  EXPECT_LE(link.a.connection->stats().rtt_var_s, 0.02);
  EXPECT_NEAR(link.a.connection->stats().loss, 0.0, 1e-9);
}

TEST(ConnectionTest, RttAndLossUnderJitterAndLoss) {
  Link link(Harsh(14));
  ASSERT_NO_FATAL_FAILURE(ExchangeUnreliable(link, 1500));
  EXPECT_GE(link.a.connection->stats().rtt_s, 0.075);
  EXPECT_LE(link.a.connection->stats().rtt_s, 0.15);
  // "Loss" is the share of our packets the peer did not take: lost ones, and reordered ones
  // whose unreliable payload arrived stale (dropped, so deliberately not acknowledged).
  EXPECT_GE(link.a.connection->stats().loss, 0.1);
  EXPECT_LE(link.a.connection->stats().loss, 0.5);
  EXPECT_GT(link.b.connection->stats().stale_dropped, 0u);
}

TEST(ConnectionTest, DisconnectReachesThePeer) {
  NetworkConditions c;
  c.latency_s = 0.01;
  c.loss = 0.3;  // three copies: at least one arrives with this seed
  Link link(c);
  link.Run(0.2);
  link.a.connection->Disconnect(DisconnectReason::kKicked, link.a);
  EXPECT_EQ(link.a.connection->disconnect_reason(), DisconnectReason::kKicked);
  uint64_t sent = link.a.connection->stats().packets_sent;
  link.a.connection->Disconnect(DisconnectReason::kServerShutdown, link.a);  // idempotent
  EXPECT_EQ(link.a.connection->stats().packets_sent, sent);
  EXPECT_EQ(link.a.connection->disconnect_reason(), DisconnectReason::kKicked);
  link.Run(0.2);
  EXPECT_EQ(link.b.connection->disconnect_reason(), DisconnectReason::kKicked);
  EXPECT_EQ(link.a.connection->SendReliable(Bytes{1}).code(), StatusCode::kNotConnected);
  EXPECT_EQ(link.a.connection->SendUnreliable(Bytes{1}, link.now(), link.a).status().code(),
            StatusCode::kNotConnected);
}

TEST(ConnectionTest, DisconnectSendsThreeCopies) {
  Connection a(kTestConnectionId, ConnectionConfig{}, 0);
  CapturingWriter out;
  a.Disconnect(DisconnectReason::kClientLeft, out);
  ASSERT_EQ(out.packets.size(), 3u);
  for (const Bytes& p : out.packets) {
    EXPECT_EQ(p.size(), kConnectionHeaderSize + 1);
    EXPECT_EQ(p.back(), static_cast<uint8_t>(DisconnectReason::kClientLeft));
  }
  Connection b(kTestConnectionId, ConnectionConfig{}, 0);
  RecordingHandler h;
  EXPECT_TRUE(b.ProcessPacket(out.packets[1], 0, h).ok());
  EXPECT_EQ(b.disconnect_reason(), DisconnectReason::kClientLeft);
}

TEST(ConnectionTest, SendErrors) {
  ConnectionConfig config;
  config.max_message_size = 5000;
  config.max_pending_reliable_bytes = 10000;
  Connection c(kTestConnectionId, config, 0);
  CapturingWriter out;
  EXPECT_EQ(c.SendReliable(Bytes{}).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(c.SendReliable(Bytes(5001)).code(), StatusCode::kTooLarge);
  EXPECT_TRUE(c.SendReliable(Bytes(5000)).ok());
  EXPECT_TRUE(c.SendReliable(Bytes(5000)).ok());
  EXPECT_EQ(c.SendReliable(Bytes(1)).code(), StatusCode::kQueueFull);
  EXPECT_EQ(c.stats().pending_reliable_bytes, 10000u);
  EXPECT_EQ(c.SendUnreliable(Bytes(kMaxUnreliablePayload + 1), 0, out).status().code(),
            StatusCode::kTooLarge);
  EXPECT_EQ(c.SendUnreliable(Bytes{}, 0, out).status().code(), StatusCode::kInvalidArgument);
  auto ok = c.SendUnreliable(Bytes(kMaxUnreliablePayload), 0, out);
  ASSERT_TRUE(ok.ok());
  EXPECT_EQ(out.packets.back().size(), kMaxPacketSize);
}

TEST(ConnectionTest, PacketsAreFilledWithDueUnits) {
  Connection c(kTestConnectionId, ConnectionConfig{}, 0);
  CapturingWriter out;
  for (int i = 0; i < 100; ++i) {
    ASSERT_TRUE(c.SendReliable(Bytes(10, 1)).ok());
  }
  c.Update(0.01, out);
  // 100 chunks of 16 bytes: 73 fit after the 18-byte header, the rest go in a second packet.
  ASSERT_EQ(out.packets.size(), 2u);
  EXPECT_EQ(out.packets[0].size(), kConnectionHeaderSize + 73 * 16);
  EXPECT_EQ(out.packets[1].size(), kConnectionHeaderSize + 27 * 16);
  // Nothing is due again before the resend timeout.
  c.Update(0.02, out);
  EXPECT_EQ(out.packets.size(), 2u);
  c.Update(1.02, out);  // no RTT sample yet: resend after max_resend_s
  EXPECT_EQ(out.packets.size(), 4u);
  EXPECT_EQ(c.stats().reliable_resends, 100u);
}

TEST(ConnectionTest, ReliableUnitsRideOnAnUnreliablePayloadsPacket) {
  Connection c(kTestConnectionId, ConnectionConfig{}, 0);
  CapturingWriter out;
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(c.SendReliable(Bytes(10, 1)).ok());
  ASSERT_TRUE(c.SendUnreliable(Bytes(100, 2), 0.01, out).ok());
  // One packet: the payload (3-byte chunk header) and the three 16-byte unit chunks.
  ASSERT_EQ(out.packets.size(), 1u);
  EXPECT_EQ(out.packets[0].size(), kConnectionHeaderSize + 3 + 100 + 3 * 16);
  c.Update(0.012, out);  // nothing left to send: the units left with the payload
  EXPECT_EQ(out.packets.size(), 1u);
  // A payload that leaves no room for a unit: the unit waits for Update().
  ASSERT_TRUE(c.SendReliable(Bytes(10, 3)).ok());
  ASSERT_TRUE(c.SendUnreliable(Bytes(kMaxUnreliablePayload, 4), 0.02, out).ok());
  ASSERT_EQ(out.packets.size(), 2u);
  EXPECT_EQ(out.packets[1].size(), kMaxPacketSize);
  c.Update(0.021, out);
  ASSERT_EQ(out.packets.size(), 3u);
  EXPECT_EQ(out.packets[2].size(), kConnectionHeaderSize + 16);
}

TEST(ConnectionTest, AnAckedPacketWithUnitsDeliveredItsPayloadUnderReordering) {
  // Reliable messages ride on unreliable payloads; a reordered packet whose payload is stale
  // is dropped whole (not acknowledged), so an ack still means the payload was delivered, and
  // the units it carried still arrive (resent).
  NetworkConditions c = Harsh(21);
  c.reorder = 0.3;
  Link link(c);
  std::vector<bool> carried_payload(65536);
  std::mt19937 rng(3);
  std::vector<Bytes> messages;
  for (uint32_t i = 0; i < 2000; ++i) {
    if (i % 3 == 0) {
      messages.push_back(TestMessage(static_cast<uint32_t>(messages.size()), rng));
      ASSERT_TRUE(link.a.connection->SendReliable(messages.back()).ok());
    }
    Bytes payload(8);
    StoreU32LE(payload.data(), i);
    auto sequence = link.a.connection->SendUnreliable(payload, link.now(), link.a);
    ASSERT_TRUE(sequence.ok());
    carried_payload[*sequence] = true;
    link.Step();
  }
  ASSERT_TRUE(link.RunUntil([&] { return link.b.handler.reliable.size() >= messages.size(); }, 30));
  for (size_t i = 0; i < messages.size(); ++i) ASSERT_EQ(link.b.handler.reliable[i], messages[i]);
  std::vector<bool> delivered(65536);
  for (uint16_t seq : link.b.handler.unreliable_sequences) delivered[seq] = true;
  uint64_t acked_payloads = 0;
  for (size_t seq = 0; seq < 65536; ++seq) {
    if (!link.a.handler.acked[seq] || !carried_payload[seq]) continue;
    ++acked_payloads;
    EXPECT_TRUE(delivered[seq]) << "packet " << seq << " acknowledged but its payload dropped";
  }
  EXPECT_GT(acked_payloads, 1000u);
  EXPECT_GT(link.b.connection->stats().stale_dropped, 0u);
}

TEST(ConnectionTest, AckDelayWaitsForAPacketOfOursButNotForReliableUnits) {
  ConnectionConfig delayed;
  delayed.max_ack_delay_s = 0.02;
  Connection a(kTestConnectionId, ConnectionConfig{}, 0);
  Connection b(kTestConnectionId, delayed, 0);
  CapturingWriter a_out, b_out;
  RecordingHandler bh;
  ASSERT_TRUE(a.SendUnreliable(Bytes(10, 1), 0.0, a_out).ok());
  ASSERT_TRUE(b.ProcessPacket(a_out.packets.back(), 0.0, bh).ok());
  b.Update(0.01, b_out);  // owed for 10 ms only
  EXPECT_TRUE(b_out.packets.empty());
  ASSERT_TRUE(b.SendUnreliable(Bytes(5, 2), 0.015, b_out).ok());  // carries the ack
  b.Update(0.03, b_out);
  EXPECT_EQ(b_out.packets.size(), 1u);
  ASSERT_TRUE(a.SendUnreliable(Bytes(10, 3), 0.04, a_out).ok());
  ASSERT_TRUE(b.ProcessPacket(a_out.packets.back(), 0.04, bh).ok());
  b.Update(0.05, b_out);
  EXPECT_EQ(b_out.packets.size(), 1u);
  b.Update(0.061, b_out);  // 21 ms: an ack-only packet
  EXPECT_EQ(b_out.packets.size(), 2u);
  // Reliable units are acknowledged by the next Update().
  ASSERT_TRUE(a.SendReliable(Bytes(4, 5)).ok());
  a.Update(0.07, a_out);
  ASSERT_TRUE(b.ProcessPacket(a_out.packets.back(), 0.07, bh).ok());
  b.Update(0.071, b_out);
  EXPECT_EQ(b_out.packets.size(), 3u);
}

TEST(ConnectionTest, SequencesAndUnitIdsWrapAround) {
  const NetworkConditions c{.loss = 0.05, .duplicate = 0.02, .reorder = 0.05, .latency_s = 0.02,
                            .jitter_s = 0.005, .seed = 15};
  Link link(c);
  link.b.handler.keep_payloads = false;
  constexpr uint32_t kSteps = 75000;  // > 65536 packets and > 65536 reliable units
  for (uint32_t i = 0; i < kSteps; ++i) {
    Bytes message(4);
    StoreU32LE(message.data(), i);
    ASSERT_TRUE(link.a.connection->SendReliable(message).ok());
    ASSERT_TRUE(link.a.connection->SendUnreliable(message, link.now(), link.a).ok());
    link.Step();
  }
  ASSERT_TRUE(link.RunUntil([&] { return link.b.handler.reliable.size() >= kSteps; }, 30.0));
  for (uint32_t i = 0; i < kSteps; ++i) {
    ASSERT_EQ(LoadU32LE(link.b.handler.reliable[i].data()), i) << i;
  }
  EXPECT_GT(link.a.connection->stats().packets_sent, 70000u);
  EXPECT_GT(link.b.handler.unreliable_sequences.size(), 60000u);  // monotonic: checked inside
  EXPECT_GT(link.a.handler.acked_count, 60000u);
  EXPECT_TRUE(link.a.connection->connected());
  EXPECT_TRUE(link.b.connection->connected());
  EXPECT_LT(link.a.connection->stats().loss, 0.15);
}

}  // namespace
}  // namespace edgephys
