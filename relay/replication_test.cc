// ClientReplicator over a real RoomHost: what a receiver is sent, datagram by datagram.
#include <gtest/gtest.h>

#include <algorithm>
#include <vector>

#include "protocol/byte_io.h"
#include "relay/replication.h"
#include "relay/room_host_testing.h"

namespace edgephys::room_host_testing {
namespace {

struct Sends final : PacketWriter {
  std::vector<std::vector<uint8_t>> packets;
  void WritePacket(std::span<const uint8_t> p) override { packets.emplace_back(p.begin(), p.end()); }
};

// ---- Acknowledgements reach the encoder, in every edgephys format -----------------------------
// A player's box publishes one state and then stays still. Its receiver acknowledges every
// datagram it gets (or none): acknowledged, the box is sent once and never again; without
// acknowledgements it is resent. Fails if an acknowledgement stops short of the format's
// encoder (the box would then be resent as if every datagram had been lost).
class AckedStateTest : public RoomHostTest, public ::testing::WithParamInterface<bool> {
 protected:
  AckedStateTest() {
    config_.tick_rate_hz = 60;
    config_.replication.mode = ReplicationMode::kEdgephys;
    config_.replication.shared_encoding = GetParam();
    host_ = std::make_unique<RoomHost>("r", config_, RoomHostEnv{&limits_, &counters_, &placement_},
                                       0.0);
  }

  // Sends of the box to one receiver over 3 s of 60 Hz ticks, acknowledging each if `ack`.
  size_t SendsOverThreeSeconds(bool ack) {
    RecordingMember owner(1);
    EXPECT_TRUE(host_->Join(owner, 0));
    const uint32_t box = Base(owner) + 1;
    Spawn(owner, LocalBox(box, 1));
    host_->ApplyStates(owner, StatePayload({{box, {0.25f, 1.5f, -2}, {0, 0, 0, 1}}}), 1.0);
    ClientReplicator replicator(config_.replication);
    Connection connection(7, ConnectionConfig{}, 0.0);
    Sends writer;
    std::vector<MemberLink*> receivers;
    for (double now = 1.0; now < 4.0; now += 1.0 / 60) {
      receivers.clear();
      host_->BeginTick(now, &receivers);
      const size_t before = writer.packets.size();
      replicator.Tick(host_->room().frame(), /*self=*/2, now, connection, writer, counters_);
      if (!ack) continue;
      for (size_t i = before; i < writer.packets.size(); ++i) {
        replicator.OnPacketAcked(LoadU16LE(writer.packets[i].data() + kPacketPrefixSize));
      }
    }
    return writer.packets.size();
  }
};

TEST_P(AckedStateTest, AnAcknowledgedStateIsSentOnceAndAnUnacknowledgedOneAgain) {
  const size_t acked = SendsOverThreeSeconds(true);
  EXPECT_EQ(acked, 1u);
  host_ = std::make_unique<RoomHost>("r", config_, RoomHostEnv{&limits_, &counters_, &placement_},
                                     0.0);
  EXPECT_GE(SendsOverThreeSeconds(false), 3u);
}

INSTANTIATE_TEST_SUITE_P(Formats, AckedStateTest, ::testing::Bool(),
                         [](const auto& param_info) { return param_info.param ? "format9" : "format2"; });

// ---- Key samples ---------------------------------------------------------------------------
// A PhyS box slides at 1 m/s on the ambient schedule (6 Hz, every 10th tick at 60 Hz). With a
// wall halfway between two scheduled sends it bounces back at once: the receiver gets the box in
// the tick of the bounce, off the schedule, and then on the schedule again; a box that keeps
// its line gets only its scheduled sends. Fails if the bounce waits for the schedule (the
// receiver would interpolate across the wall) or if straight motion is sent off schedule.
class KeySampleTest : public RoomHostTest {
 protected:
  KeySampleTest() {
    config_.tick_rate_hz = 60;
    host_ = std::make_unique<RoomHost>("r", config_, RoomHostEnv{&limits_, &counters_, &placement_},
                                       0.0);
  }

  // The ticks (0..119, 2 s from t = 1 s) in which the receiver was sent a datagram; `bounce`:
  // the box turns back at tick `bounce_tick` (-1: never).
  std::vector<int> SendTicks(int bounce_tick, uint32_t* box_out) {
    RecordingMember owner(1), receiver(2);
    EXPECT_TRUE(host_->Join(owner, 0));
    EXPECT_TRUE(host_->Join(receiver, 0));
    const uint32_t box = Base(owner) + 1;
    *box_out = box;
    EntitySpec spec = DynamicBox(box, {0, 1, 0}, {0.1f, 0.1f, 0.1f}, 1.0f);
    spec.owner = 1;
    spec.flags = kOffloaded;
    Spawn(owner, spec);
    EXPECT_EQ(Find(box)->physics, PhysicsRole::kSimulated);
    ClientReplicator replicator(config_.replication);
    Connection connection(7, ConnectionConfig{}, 0.0);
    Sends writer;
    std::vector<MemberLink*> receivers;
    std::vector<int> ticks;
    float x = 0, v = 1;
    for (int k = 0; k < 120; ++k) {
      const double now = 1.0 + k / 60.0;
      if (k == bounce_tick) v = -v;
      x += v / 60.0f;
      PhysicsLink::StepOutput out;
      out.moved.push_back({EntityState{box, {x, 1, 0}, {0, 0, 0, 1}}, {v, 0, 0}, {0, 0, 0}});
      out.state_time = now;
      host_->ApplyPhysics(out, now);
      receivers.clear();
      host_->BeginTick(now, &receivers);
      const size_t before = writer.packets.size();
      replicator.Tick(host_->room().frame(), /*self=*/2, now, connection, writer, counters_);
      if (writer.packets.size() > before) ticks.push_back(k);
      for (size_t i = before; i < writer.packets.size(); ++i) {
        replicator.OnPacketAcked(LoadU16LE(writer.packets[i].data() + kPacketPrefixSize));
      }
    }
    return ticks;
  }
};

TEST_F(KeySampleTest, ABounceIsSentAtOnceAndAStraightLineOnlyOnSchedule) {
  uint32_t box = 0;
  const std::vector<int> straight = SendTicks(-1, &box);
  ASSERT_GE(straight.size(), 10u);
  for (size_t i = 2; i < straight.size(); ++i) {  // every 10th tick (6 Hz at 60 Hz ticks)
    EXPECT_EQ(straight[i] - straight[i - 1], 10) << "tick " << straight[i];
  }
  // The bounce: halfway between two scheduled sends.
  const int bounce = straight[straight.size() / 2] + 5;
  host_ = std::make_unique<RoomHost>("r", config_, RoomHostEnv{&limits_, &counters_, &placement_},
                                     0.0);
  uint32_t box2 = 0;
  const std::vector<int> bounced = SendTicks(bounce, &box2);
  ASSERT_EQ(box2, box);  // the same id: the same schedule
  EXPECT_NE(std::find(bounced.begin(), bounced.end(), bounce), bounced.end())
      << "the bounce waited for the schedule";
  EXPECT_EQ(bounced.size(), straight.size() + 1);  // one key sample, the schedule otherwise
  for (int k : straight) EXPECT_NE(std::find(bounced.begin(), bounced.end(), k), bounced.end()) << k;
}

}  // namespace
}  // namespace edgephys::room_host_testing
