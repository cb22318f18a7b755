#include "protocol/network_simulator.h"

#include <gtest/gtest.h>

#include <deque>
#include <map>
#include <vector>

#include "protocol/byte_io.h"

namespace edgephys {
namespace {

// Inner socket that records what reaches it and when.
class RecordingSocket final : public DatagramSocket {
 public:
  struct Sent {
    double time;
    Endpoint to;
    std::vector<uint8_t> data;
  };
  Status SendTo(const Endpoint& to, std::span<const uint8_t> data) override {
    sent.push_back({now, to, std::vector<uint8_t>(data.begin(), data.end())});
    return Status::Ok();
  }
  size_t ReceiveFrom(Endpoint* from, std::span<uint8_t> buffer) override {
    *from = LocalEndpoint();
    buffer[0] = 42;
    return 1;
  }
  Endpoint LocalEndpoint() const override {
    return Endpoint(asio::ip::make_address("192.0.2.1"), 4242);
  }
  double now = 0;
  std::vector<Sent> sent;
};

const Endpoint kTo(asio::ip::make_address("192.0.2.2"), 1);

std::vector<uint8_t> Numbered(uint32_t i) {
  std::vector<uint8_t> data(4);
  StoreU32LE(data.data(), i);
  return data;
}

// Sends `count` numbered datagrams, one per 1 ms tick, then drains; returns what arrived.
std::vector<RecordingSocket::Sent> Pump(const NetworkConditions& c, uint32_t count) {
  RecordingSocket inner;
  NetworkSimulator sim(&inner, c);
  double now = 0;
  for (uint32_t i = 0; i < count; ++i) {
    EXPECT_TRUE(sim.SendTo(kTo, Numbered(i)).ok());
    now += 0.001;
    inner.now = now;
    sim.Update(now);
  }
  inner.now = now + 100;
  sim.Update(now + 100);
  EXPECT_EQ(sim.queued(), 0u);
  return inner.sent;
}

TEST(NetworkSimulatorTest, PerfectNetworkForwardsAtNextUpdate) {
  RecordingSocket inner;
  NetworkSimulator sim(&inner);
  ASSERT_TRUE(sim.SendTo(kTo, Numbered(7)).ok());
  EXPECT_TRUE(inner.sent.empty());
  sim.Update(0);
  ASSERT_EQ(inner.sent.size(), 1u);
  EXPECT_EQ(inner.sent[0].to, kTo);
  EXPECT_EQ(inner.sent[0].data, Numbered(7));
  EXPECT_EQ(sim.stats().forwarded, 1u);
}

TEST(NetworkSimulatorTest, LatencyHoldsUntilDue) {
  RecordingSocket inner;
  NetworkConditions c;
  c.latency_s = 0.05;
  NetworkSimulator sim(&inner, c);
  sim.Update(1.0);
  ASSERT_TRUE(sim.SendTo(kTo, Numbered(1)).ok());  // stamped 1.0, due 1.05
  sim.Update(1.04);
  EXPECT_TRUE(inner.sent.empty());
  EXPECT_EQ(sim.queued(), 1u);
  sim.Update(1.06);
  EXPECT_EQ(inner.sent.size(), 1u);
}

TEST(NetworkSimulatorTest, LossRateMatches) {
  NetworkConditions c;
  c.loss = 0.2;
  c.seed = 3;
  auto arrived = Pump(c, 20000);
  double rate = 1.0 - arrived.size() / 20000.0;
  EXPECT_NEAR(rate, 0.2, 0.02);
}

TEST(NetworkSimulatorTest, DuplicatesAreExtraCopies) {
  NetworkConditions c;
  c.duplicate = 0.1;
  auto arrived = Pump(c, 10000);
  EXPECT_NEAR(arrived.size() / 10000.0, 1.1, 0.02);
}

TEST(NetworkSimulatorTest, JitterStaysWithinBounds) {
  RecordingSocket inner;
  NetworkConditions c;
  c.latency_s = 0.05;
  c.jitter_s = 0.02;
  NetworkSimulator sim(&inner, c);
  std::vector<double> sent_at;
  double now = 0;
  for (uint32_t i = 0; i < 2000; ++i) {
    ASSERT_TRUE(sim.SendTo(kTo, Numbered(i)).ok());
    sent_at.push_back(now);
    now += 0.001;
    inner.now = now;
    sim.Update(now);
  }
  for (int i = 0; i < 200; ++i) {
    now += 0.001;
    inner.now = now;
    sim.Update(now);
  }
  ASSERT_EQ(inner.sent.size(), 2000u);
  double min_delay = 1, max_delay = 0;
  for (const auto& s : inner.sent) {
    double delay = s.time - sent_at[LoadU32LE(s.data.data())];
    min_delay = std::min(min_delay, delay);
    max_delay = std::max(max_delay, delay);
  }
  EXPECT_GE(min_delay, 0.03 - 1e-9);
  EXPECT_LE(max_delay, 0.07 + 0.001 + 1e-9);  // one tick of Update granularity
  EXPECT_LT(min_delay, 0.035);
  EXPECT_GT(max_delay, 0.065);
}

TEST(NetworkSimulatorTest, ReorderLetsLaterDatagramsOvertake) {
  NetworkConditions c;
  c.reorder = 0.2;
  c.latency_s = 0.01;
  auto arrived = Pump(c, 5000);
  ASSERT_EQ(arrived.size(), 5000u);
  int inversions = 0;
  for (size_t i = 1; i < arrived.size(); ++i) {
    if (LoadU32LE(arrived[i].data.data()) < LoadU32LE(arrived[i - 1].data.data())) ++inversions;
  }
  EXPECT_GT(inversions, 100);
  // Without reordering (and without jitter) the order is kept.
  c.reorder = 0;
  auto ordered = Pump(c, 1000);
  for (size_t i = 0; i < ordered.size(); ++i) {
    EXPECT_EQ(LoadU32LE(ordered[i].data.data()), i);
  }
}

TEST(NetworkSimulatorTest, DeterministicForASeed) {
  NetworkConditions c{.loss = 0.1, .duplicate = 0.1, .reorder = 0.1, .latency_s = 0.02,
                      .jitter_s = 0.01, .seed = 77};
  auto first = Pump(c, 3000);
  auto second = Pump(c, 3000);
  ASSERT_EQ(first.size(), second.size());
  for (size_t i = 0; i < first.size(); ++i) {
    EXPECT_EQ(first[i].data, second[i].data);
    EXPECT_EQ(first[i].time, second[i].time);
  }
  c.seed = 78;
  auto other = Pump(c, 3000);
  bool differs = other.size() != first.size();
  for (size_t i = 0; !differs && i < first.size(); ++i) differs = other[i].data != first[i].data;
  EXPECT_TRUE(differs);
}

TEST(NetworkSimulatorTest, BoundedQueueDropsAndCounts) {
  RecordingSocket inner;
  NetworkConditions c;
  c.latency_s = 1.0;
  NetworkSimulator sim(&inner, c, /*max_queued=*/10);
  for (uint32_t i = 0; i < 15; ++i) {
    EXPECT_TRUE(sim.SendTo(kTo, Numbered(i)).ok());
  }
  EXPECT_EQ(sim.queued(), 10u);
  EXPECT_EQ(sim.stats().queue_full, 5u);
  sim.Update(2.0);
  EXPECT_EQ(inner.sent.size(), 10u);
  EXPECT_EQ(sim.queued(), 0u);
}

TEST(NetworkSimulatorTest, ReceiveAndAddressPassThrough) {
  RecordingSocket inner;
  NetworkSimulator sim(&inner);
  EXPECT_EQ(sim.LocalEndpoint(), inner.LocalEndpoint());
  uint8_t buffer[4] = {};
  Endpoint from;
  EXPECT_EQ(sim.ReceiveFrom(&from, buffer), 1u);
  EXPECT_EQ(buffer[0], 42);
  EXPECT_EQ(from, inner.LocalEndpoint());
}

TEST(NetworkSimulatorTest, SetConditionsAppliesToLaterSends) {
  RecordingSocket inner;
  NetworkSimulator sim(&inner);
  NetworkConditions all_lost;
  all_lost.loss = 1.0;
  sim.SetConditions(all_lost);
  EXPECT_EQ(sim.conditions().loss, 1.0);
  for (uint32_t i = 0; i < 100; ++i) {
    ASSERT_TRUE(sim.SendTo(kTo, Numbered(i)).ok());
  }
  sim.Update(1);
  EXPECT_TRUE(inner.sent.empty());
  EXPECT_EQ(sim.stats().dropped, 100u);
  sim.SetConditions(NetworkConditions{});
  ASSERT_TRUE(sim.SendTo(kTo, Numbered(1)).ok());
  sim.Update(1);
  EXPECT_EQ(inner.sent.size(), 1u);
}

// Inner socket with datagrams waiting to be read (fed by the test) and a record of sends.
class FeedSocket final : public DatagramSocket {
 public:
  Status SendTo(const Endpoint& to, std::span<const uint8_t> data) override {
    sent.push_back({0, to, std::vector<uint8_t>(data.begin(), data.end())});
    return Status::Ok();
  }
  size_t ReceiveFrom(Endpoint* from, std::span<uint8_t> buffer) override {
    if (pending.empty()) return 0;
    *from = kTo;
    const std::vector<uint8_t> d = std::move(pending.front());
    pending.pop_front();
    std::copy_n(d.begin(), std::min(d.size(), buffer.size()), buffer.begin());
    return d.size();
  }
  Endpoint LocalEndpoint() const override {
    return Endpoint(asio::ip::make_address("192.0.2.1"), 4242);
  }
  std::deque<std::vector<uint8_t>> pending;
  std::vector<RecordingSocket::Sent> sent;
};

// Both directions of one socket, each with its own conditions: arrivals lose their share and
// wait their delay, sends are impaired apart from them.
TEST(ImpairedSocketTest, ArrivalsAreLostAndDelayedApartFromSends) {
  FeedSocket inner;
  NetworkConditions up;
  up.loss = 0.5;
  up.seed = 11;
  NetworkConditions down;
  down.loss = 0.1;
  down.latency_s = 0.030;
  down.seed = 12;
  ImpairedSocket socket(&inner, up, down);
  EXPECT_EQ(socket.LocalEndpoint(), inner.LocalEndpoint());
  constexpr uint32_t kCount = 20000;
  std::map<uint32_t, double> fed_at, read_at;
  double now = 0;
  uint8_t buffer[16];
  for (uint32_t i = 0; i < kCount + 100; ++i) {
    if (i < kCount) {
      inner.pending.push_back(Numbered(i));
      fed_at[i] = now;
      ASSERT_TRUE(socket.SendTo(kTo, Numbered(i)).ok());
    }
    now += 0.001;
    socket.Update(now);
    Endpoint from;
    while (size_t n = socket.ReceiveFrom(&from, buffer)) {
      ASSERT_EQ(n, 4u);
      EXPECT_EQ(from, kTo);
      const uint32_t id = LoadU32LE(buffer);
      EXPECT_TRUE(read_at.emplace(id, now).second) << "delivered twice: " << id;
    }
  }
  EXPECT_NEAR(1.0 - read_at.size() / double(kCount), 0.10, 0.01);
  for (const auto& [id, t] : read_at) {
    // Fed at fed_at, taken into the simulator at the next read (one step later at most).
    EXPECT_GE(t - fed_at[id], 0.030 - 1e-9) << id;
    EXPECT_LE(t - fed_at[id], 0.030 + 0.003) << id;
  }
  EXPECT_NEAR(inner.sent.size() / double(kCount), 0.5, 0.02);
  EXPECT_EQ(socket.down_stats().dropped + read_at.size(), kCount);
  EXPECT_EQ(socket.up_stats().sent, kCount);
}

// A datagram larger than the reader's buffer is reported with its full size, as UdpSocket does.
TEST(ImpairedSocketTest, OversizedArrivalKeepsItsSize) {
  FeedSocket inner;
  ImpairedSocket socket(&inner, {}, {});
  inner.pending.push_back(std::vector<uint8_t>(3000, 7));
  socket.Update(1);
  uint8_t small[100];
  Endpoint from;
  EXPECT_EQ(socket.ReceiveFrom(&from, small), 3000u);
  EXPECT_EQ(small[99], 7);
  EXPECT_EQ(socket.ReceiveFrom(&from, small), 0u);
}

}  // namespace
}  // namespace edgephys
