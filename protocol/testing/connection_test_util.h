// Test helpers for connection_test.cc and connection_malformed_test.cc: a recording handler, a packet builder for hand-made
// (and broken) packets, and a Link that pumps two Connections through an InMemoryNetwork with
// a NetworkSimulator on each side, with injected time in fixed steps.
#pragma once

#include <gtest/gtest.h>

#include <array>
#include <map>
#include <memory>
#include <random>
#include <vector>

#include "protocol/byte_io.h"
#include "protocol/connection.h"
#include "protocol/testing/in_memory_network.h"
#include "protocol/network_simulator.h"
#include "protocol/sequence.h"

namespace edgephys::testing {

using Bytes = std::vector<uint8_t>;

inline constexpr uint32_t kTestConnectionId = 42;

// `size` bytes from a generator seeded with `seed` (the same bytes for the same seed).
inline Bytes RandomBytes(size_t size, uint32_t seed) {
  std::mt19937 rng(seed);
  Bytes bytes(size);
  for (uint8_t& b : bytes) b = static_cast<uint8_t>(rng());
  return bytes;
}

// Records deliveries and checks the handler contracts as they happen: unreliable sequences
// strictly increase, and each of our packets is acknowledged at most once and only if sent.
class RecordingHandler : public ConnectionHandler {
 public:
  void OnReliableMessage(std::span<const uint8_t> message) override {
    reliable.emplace_back(message.begin(), message.end());
  }
  void OnUnreliablePayload(uint16_t sequence, std::span<const uint8_t> payload) override {
    // Payloads starting with kUnorderedPayloadFormat may come in any order (connection.h).
    if (payload.empty() || payload[0] != kUnorderedPayloadFormat) {
      if (have_ordered_) {
        EXPECT_TRUE(SequenceGreater(sequence, last_ordered_))
            << sequence << " after " << last_ordered_;
      }
      have_ordered_ = true;
      last_ordered_ = sequence;
    }
    unreliable_sequences.push_back(sequence);
    if (keep_payloads) unreliable.emplace_back(payload.begin(), payload.end());
  }
  void OnPacketAcked(uint16_t sequence) override {
    EXPECT_TRUE(sent[sequence]) << "ack for unsent packet " << sequence;
    EXPECT_FALSE(acked[sequence]) << "second ack for packet " << sequence;
    acked[sequence] = true;
    ++acked_count;
  }
  // Called by the writer for every packet we send (the sequence follows the prefix).
  void NoteSent(std::span<const uint8_t> packet) {
    uint16_t sequence = LoadU16LE(packet.data() + kPacketPrefixSize);
    sent[sequence] = true;
    acked[sequence] = false;
  }

  bool keep_payloads = true;
  std::vector<Bytes> reliable;
  std::vector<uint16_t> unreliable_sequences;
  std::vector<Bytes> unreliable;
  std::vector<bool> sent = std::vector<bool>(65536);
  std::vector<bool> acked = std::vector<bool>(65536);
  uint64_t acked_count = 0;
 private:
  bool have_ordered_ = false;
  uint16_t last_ordered_ = 0;
};

// Collects the packets a Connection writes.
class CapturingWriter : public PacketWriter {
 public:
  explicit CapturingWriter(RecordingHandler* sender = nullptr) : sender_(sender) {}
  void WritePacket(std::span<const uint8_t> packet) override {
    EXPECT_LE(packet.size(), kMaxPacketSize);
    if (sender_ != nullptr) sender_->NoteSent(packet);
    packets.emplace_back(packet.begin(), packet.end());
  }
  std::vector<Bytes> packets;

 private:
  RecordingHandler* sender_;
};

// Hand-made packets, well-formed or not.
class PacketBuilder {
 public:
  PacketBuilder(PacketType type, uint16_t sequence, uint16_t ack = 0xFFFF, uint32_t ack_bits = 0,
                uint32_t connection_id = kTestConnectionId)
      : bytes_(kConnectionHeaderSize) {
    WritePacketPrefix(type, connection_id, bytes_);
    StoreU16LE(bytes_.data() + kPacketPrefixSize, sequence);
    StoreU16LE(bytes_.data() + kPacketPrefixSize + 2, ack);
    StoreU32LE(bytes_.data() + kPacketPrefixSize + 4, ack_bits);
  }
  PacketBuilder& Unit(uint16_t id, bool last, const Bytes& data, uint8_t extra_flags = 0) {
    U8(0x01).U16(id).U8(static_cast<uint8_t>((last ? 1 : 0) | extra_flags));
    U16(static_cast<uint16_t>(data.size()));
    return Raw(data);
  }
  PacketBuilder& Unreliable(const Bytes& data) {
    U8(0x02).U16(static_cast<uint16_t>(data.size()));
    return Raw(data);
  }
  PacketBuilder& U8(uint8_t v) {
    bytes_.push_back(v);
    return *this;
  }
  PacketBuilder& U16(uint16_t v) {
    bytes_.push_back(static_cast<uint8_t>(v));
    bytes_.push_back(static_cast<uint8_t>(v >> 8));
    return *this;
  }
  PacketBuilder& Raw(const Bytes& data) {
    bytes_.insert(bytes_.end(), data.begin(), data.end());
    return *this;
  }
  Bytes Build() const { return bytes_; }

 private:
  Bytes bytes_;
};

// One end of a Link: socket, simulator, connection and handler.
class Peer : public PacketWriter {
 public:
  Peer(InMemoryNetwork& network, const Endpoint& self, const Endpoint& remote,
       const ConnectionConfig& config, const NetworkConditions& conditions)
      : socket_(network.CreateSocket(self)),
        remote_(remote),
        sim(socket_.get(), conditions),
        connection(std::make_unique<Connection>(kTestConnectionId, config, 0.0)) {}

  void WritePacket(std::span<const uint8_t> packet) override {
    EXPECT_LE(packet.size(), kMaxPacketSize);
    handler.NoteSent(packet);
    if (!mute) (void)sim.SendTo(remote_, packet);  // NetworkSimulator::SendTo is always Ok
  }

  void Receive(double now) {
    Endpoint from;
    while (size_t size = sim.ReceiveFrom(&from, buffer_)) {
      if (deaf) continue;
      Status status = connection->ProcessPacket(std::span(buffer_.data(), size), now, handler);
      statuses[status.code()]++;
    }
  }

  bool mute = false;    // drop everything this end sends
  bool deaf = false;    // ignore everything this end receives
  bool paused = false;  // Link does not call Update() on this end
  std::map<StatusCode, int> statuses;
  RecordingHandler handler;

 private:
  std::unique_ptr<DatagramSocket> socket_;
  Endpoint remote_;
  std::array<uint8_t, 2048> buffer_{};

 public:
  NetworkSimulator sim;
  std::unique_ptr<Connection> connection;
};

// Two Connections pumped in fixed time steps: each step advances the clock, lets both
// simulators forward what is due, delivers it, then calls Update() on both ends.
class Link {
 public:
  static constexpr double kStep = 0.01;

  explicit Link(const NetworkConditions& conditions, const ConnectionConfig& config_a = {},
                const ConnectionConfig& config_b = {})
      : a(network_, EndpointA(), EndpointB(), config_a, WithSeed(conditions, 0)),
        b(network_, EndpointB(), EndpointA(), config_b, WithSeed(conditions, 1)) {}

  static Endpoint EndpointA() { return Endpoint(asio::ip::make_address("10.0.0.1"), 1000); }
  static Endpoint EndpointB() { return Endpoint(asio::ip::make_address("10.0.0.2"), 2000); }

  double now() const { return static_cast<double>(steps_) * kStep; }

  void Step() {
    ++steps_;
    double t = now();
    a.sim.Update(t);
    b.sim.Update(t);
    a.Receive(t);
    b.Receive(t);
    if (!a.paused) a.connection->Update(t, a);
    if (!b.paused) b.connection->Update(t, b);
  }

  // Steps until `done()` or `max_seconds` of simulated time passed; returns done().
  template <typename Done>
  bool RunUntil(Done done, double max_seconds) {
    double end = now() + max_seconds;
    while (!done() && now() < end) Step();
    return done();
  }

  void Run(double seconds) {
    RunUntil([] { return false; }, seconds);
  }

 private:
  static NetworkConditions WithSeed(NetworkConditions c, uint64_t salt) {
    c.seed = c.seed * 2 + salt;
    return c;
  }

  InMemoryNetwork network_;
  uint64_t steps_ = 0;

 public:
  Peer a;
  Peer b;
};

}  // namespace edgephys::testing
