// Reassembly memory of a Connection (protocol/connection.h): what a peer can make the receiver
// hold for partial reliable messages stays under ConnectionConfig::max_held_reliable_bytes plus
// kReliableHeldSlack whatever the peer sends, refusals are counted, and an honest peer still
// delivers every message (slower) when the bound is tight.
#include <gtest/gtest.h>

#include <algorithm>

#include "protocol/connection.h"
#include "protocol/reliable_channel.h"
#include "protocol/testing/connection_test_util.h"

namespace edgephys {
namespace {

using testing::Bytes;
using testing::kTestConnectionId;
using testing::Link;
using testing::PacketBuilder;
using testing::RandomBytes;
using testing::RecordingHandler;

// A peer hand-feeding one receiver unit packets, tracking the most it ever held.
class Feeder {
 public:
  explicit Feeder(const ConnectionConfig& config = {})
      : config_(config), connection_(kTestConnectionId, config, 0.0) {}

  Status Send(uint16_t unit, bool last, size_t size = kMaxReliableUnitSize) {
    Bytes packet = PacketBuilder(PacketType::kData, sequence_++)
                       .Unit(unit, last, RandomBytes(size, unit))
                       .Build();
    Status status = connection_.ProcessPacket(packet, 0.0, handler_);
    peak_ = std::max(peak_, connection_.reliable_held_bytes());
    return status;
  }
  size_t bound() const { return config_.max_held_reliable_bytes + kReliableHeldSlack; }
  size_t peak() const { return peak_; }
  Connection& connection() { return connection_; }
  RecordingHandler& handler() { return handler_; }

 private:
  ConnectionConfig config_;
  Connection connection_;
  RecordingHandler handler_;
  uint16_t sequence_ = 0;
  size_t peak_ = 0;
};

// The probe's shape: every unit of a 1 MiB message but its last, then the next window of
// units with a gap. Without the bound this held ~2 MiB.
TEST(ReliableHeldTest, AllButOneUnitThenNextWindowStaysUnderBound) {
  Feeder feeder;
  for (uint16_t id = 0; id < 1023; ++id) ASSERT_TRUE(feeder.Send(id, false).ok()) << id;
  size_t refused = 0;
  for (uint16_t id = 1024; id < 1023 + kReliableWindow; ++id) {
    Status status = feeder.Send(id, false);
    if (status.code() == StatusCode::kQueueFull) ++refused;
    else ASSERT_TRUE(status.ok()) << status.message();
  }
  EXPECT_TRUE(feeder.connection().connected());
  EXPECT_GT(refused, 900u);  // nearly the whole second window
  EXPECT_EQ(feeder.connection().stats().reassembly_refused, refused);
  EXPECT_LE(feeder.peak(), feeder.bound());
  EXPECT_GE(feeder.peak(), 1023u * kMaxReliableUnitSize);  // it did hold the first message
  ::testing::Test::RecordProperty("peak_held_bytes", static_cast<int>(feeder.peak()));
}

// Half a message in order, out-of-order units beyond a gap, then the gap filled in order up
// to the message limit: the gap's bytes were counted when the out-of-order units came.
TEST(ReliableHeldTest, GapFilledAfterOutOfOrderUnitsWasCountedBeforehand) {
  Feeder feeder;
  for (uint16_t id = 0; id < 512; ++id) ASSERT_TRUE(feeder.Send(id, false).ok());
  for (uint16_t id = 1023; id >= 544; --id) (void)feeder.Send(id, false);
  for (uint16_t id = 512; id < 1024; ++id) {
    Status status = feeder.Send(id, false);
    if (!status.ok()) break;  // past max_message_size: the peer broke the protocol
  }
  EXPECT_LE(feeder.peak(), feeder.bound());
}

// A whole window of out-of-order units first, then the gap filled in order: data moved from
// the slots into the message is not held twice, and the buffers go once it is delivered.
TEST(ReliableHeldTest, OutOfOrderWindowThenGapFilledStaysUnderBound) {
  Feeder feeder;
  const uint16_t last = 899;  // the span to it (900 units) fits the 1 MiB bound
  for (uint16_t id = 100; id <= last; ++id) ASSERT_TRUE(feeder.Send(id, id == last).ok()) << id;
  for (uint16_t id = 0; id < 100; ++id) ASSERT_TRUE(feeder.Send(id, false).ok()) << id;
  EXPECT_TRUE(feeder.connection().connected());
  EXPECT_LE(feeder.peak(), feeder.bound());
  ASSERT_EQ(feeder.handler().reliable.size(), 1u);
  EXPECT_EQ(feeder.handler().reliable[0].size(), 900u * kMaxReliableUnitSize);
  // Delivered: no partial message left; what stays is the buffers kept for reuse and the slot
  // table (~65 KiB), not the burst's ~1 MiB.
  EXPECT_EQ(feeder.connection().reliable_partial_bytes(), 0u);
  EXPECT_LE(feeder.connection().reliable_held_bytes(),
            ReliableReceiver::kMaxSpareBuffers * kMaxReliableUnitSize + (34u << 10));
}

// One-byte units cost a unit buffer each (reusable for any unit), and the bound charges them
// as full units: the span the bound allows is the same whatever their size.
TEST(ReliableHeldTest, SmallOutOfOrderUnitsAreChargedAsFullUnits) {
  Feeder feeder;
  for (uint16_t id = 1; id < 900; ++id) ASSERT_TRUE(feeder.Send(id, false, 1).ok());
  EXPECT_LE(feeder.peak(), feeder.bound());
  EXPECT_EQ(feeder.connection().reliable_partial_bytes(), 899u * kMaxReliableUnitSize);
  // Past the span the bound allows, out-of-order units wait.
  EXPECT_EQ(feeder.Send(1020, false, 1).code(), StatusCode::kQueueFull);
  EXPECT_TRUE(feeder.Send(0, true, 1).ok());  // the next one always gets in
  EXPECT_EQ(feeder.handler().reliable.size(), 1u);
  // Units 1..899 drained into the next message (899 bytes, in progress); their buffers are
  // kept for reuse or freed.
  EXPECT_LT(feeder.connection().reliable_partial_bytes(), 2048u);
}

// A tight bound with an honest peer on a lossy, reordering network: every message arrives,
// intact and in order, and the receiver never held more than the bound.
TEST(ReliableHeldTest, HonestPeerDeliversEverythingUnderTightBound) {
  NetworkConditions conditions;
  conditions.loss = 0.1;
  conditions.reorder = 0.1;
  conditions.latency_s = 0.02;
  ConnectionConfig receiver;
  receiver.max_held_reliable_bytes = 256 * 1024;
  Link link(conditions, ConnectionConfig{}, receiver);
  std::vector<Bytes> sent;
  for (uint32_t i = 0; i < 6; ++i) {
    sent.push_back(RandomBytes(100 * 1024 + i * 7, 100 + i));
    ASSERT_TRUE(link.a.connection->SendReliable(sent.back()).ok());
  }
  size_t peak = 0;
  bool done = link.RunUntil(
      [&] {
        peak = std::max(peak, link.b.connection->reliable_held_bytes());
        return link.b.handler.reliable.size() == sent.size();
      },
      120.0);
  ASSERT_TRUE(done) << link.b.handler.reliable.size() << " of " << sent.size();
  EXPECT_EQ(link.b.handler.reliable, sent);
  EXPECT_TRUE(link.b.connection->connected());
  EXPECT_LE(peak, receiver.max_held_reliable_bytes + kReliableHeldSlack);
  EXPECT_GT(link.b.connection->stats().reassembly_refused, 0u);  // the bound was exercised
}

}  // namespace
}  // namespace edgephys
