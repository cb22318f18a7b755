// Key samples (ReplicationConfig::key_sample_threshold_m): when an untouched PhyS body is sent.
// The room (RoomHost::ApplyPhysics) is fed scripted PhyS outputs, as an asynchronous world hands
// them over: each step's states a computation late and unevenly, sometimes several steps at once
// (one state, the last). One receiver's ClientReplicator ticks at 60 Hz over the room's frame;
// every datagram it writes is one send of the box.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "protocol/byte_io.h"
#include "relay/replication.h"
#include "relay/room_host_testing.h"

namespace edgephys::room_host_testing {
namespace {

constexpr double kStep = 1.0 / 60;  // PhyS's fixed step
constexpr double kTick = 1.0 / 60;  // the room's replication tick

struct Sends final : PacketWriter {
  std::vector<std::vector<uint8_t>> packets;
  void WritePacket(std::span<const uint8_t> p) override { packets.emplace_back(p.begin(), p.end()); }
};

// A box's trajectory: position at simulated time t.
using Trajectory = Vec3f (*)(double t);

Vec3f Straight(double t) { return {static_cast<float>(0.5 * t), 0.5f, 0}; }  // 0.5 m/s

// 1 m/s along x between walls 0.7 m apart (a bounce every 0.7 s), 0.3 m/s along z.
constexpr double kBounceEvery = 0.7;
Vec3f Bouncing(double t) {
  const double phase = std::fmod(t, 2 * kBounceEvery);
  const double x = phase < kBounceEvery ? phase : 2 * kBounceEvery - phase;
  return {static_cast<float>(x), 0.5f, static_cast<float>(0.3 * t)};
}

class KeySampleTest : public RoomHostTest {
 protected:
  KeySampleTest() {
    config_.tick_rate_hz = 60;
    config_.replication.key_sample_threshold_m = 0.01f;
    config_.replication.key_sample_rotation_deg = 5;
    config_.replication.key_sample_max_interval_s = 0.5;
    host_ = std::make_unique<RoomHost>("r", config_, RoomHostEnv{&limits_, &counters_, &placement_},
                                       0.0);
  }

  struct Sent {
    double at;            // relay time of the tick
    uint32_t payload_ms;  // the time the receiver is told the state holds at
    double state_time;    // Entity::state_time of what was sent
    uint32_t record_ms;   // the time the record holds (format 14: its own; else payload_ms)
    Vec3f position;       // what the receiver decodes
  };

  // Runs 1 + `seconds` of relay time from 10 s (the box is ambient by then): PhyS steps every
  // kStep of simulated time; every `steps_per_output` steps one output (the last step's state)
  // arrives `latency` plus up to `jitter` (deterministic, uneven) after the end of its last
  // step. Returns the box's sends to one receiver after the first second (the box at rest since
  // its spawn starting to move is a kink of its own), and counts in strayed_ the sends of those
  // found due because the line strayed.
  std::vector<Sent> Run(Trajectory path, double seconds, int steps_per_output, double latency,
                        double jitter) {
    RecordingMember owner(1);
    EXPECT_TRUE(host_->Join(owner, 0));
    box_ = Base(owner) + 1;
    EntitySpec s = DynamicBox(box_, path(0), {0.05f, 0.05f, 0.05f}, 1.0f);
    s.owner = 1;
    s.flags = kOffloaded;
    Spawn(owner, s);
    EXPECT_NE(Find(box_), nullptr);
    EXPECT_EQ(Find(box_)->physics, PhysicsRole::kSimulated);

    ClientReplicator replicator(config_.replication);
    Connection connection(7, ConnectionConfig{}, 0.0);
    Sends writer;
    std::vector<MemberLink*> receivers;
    std::vector<Sent> sent;
    // Nothing is acknowledged, so every record is a keyframe: each datagram decodes alone.
    auto params = MakeQuantizationParams(QuantizationOf(config_.replication));
    EXPECT_TRUE(params.ok());
    DeltaDecoder decoder(*params);
    StateBatch batch;
    const double start = 10.0, measure_from = start + 1.0, end = measure_from + seconds;
    uint64_t strayed_before = 0;
    bool measuring = false;
    double next_tick = start;
    int64_t step = 0;        // steps simulated from `start`
    double next_arrival = start + steps_per_output * kStep + latency;
    uint32_t lcg = 12345;
    for (double now = start; now < end; now += 0.001) {  // the relay's updates, every 1 ms
      while (now >= next_arrival) {
        step += steps_per_output;
        const double t = start + static_cast<double>(step) * kStep;  // end of the last step
        PhysicsLink::StepOutput out;
        out.steps = steps_per_output;
        out.state_time = t;
        out.moved.push_back({{box_, path(t - start), {0, 0, 0, 1}}, {}, {}});
        host_->ApplyPhysics(out, now);
        lcg = lcg * 1103515245u + 12345u;
        const double wobble = jitter * static_cast<double>((lcg >> 16) % 1000) / 1000.0;
        next_arrival = t + steps_per_output * kStep + latency + wobble;
      }
      if (now + 1e-9 >= next_tick) {
        next_tick += kTick;
        if (!measuring && now >= measure_from) {
          measuring = true;
          strayed_before = counters_.key_samples_strayed.load();
        }
        receivers.clear();
        host_->BeginTick(now, &receivers);
        const size_t before = writer.packets.size();
        replicator.Tick(host_->room().frame(), /*self=*/2, now, connection, writer, counters_);
        if (writer.packets.size() > before) {
          EXPECT_EQ(writer.packets.size(), before + 1) << "one box: one datagram";
          // Connection header, unreliable chunk header (type, length), then format 2's header:
          // format byte, time (ms).
          const uint8_t* packet = writer.packets.back().data();
          const uint8_t* p = packet + kConnectionHeaderSize + 3;
          Sent record{now, LoadU32LE(p + 1), Find(box_)->state_time, LoadU32LE(p + 1), {}};
          batch.states.clear();
          batch.times_ms.clear();
          const uint16_t size = LoadU16LE(p - 2);
          EXPECT_TRUE(decoder.Decode(std::span<const uint8_t>(p, size), &batch).ok());
          if (!batch.states.empty()) record.position = batch.states.back().position;
          if (!batch.times_ms.empty()) record.record_ms = batch.times_ms.back();
          if (measuring) sent.push_back(record);
          // ack_: the receiver acknowledges at once (the encoder then codes deltas).
          if (ack_) replicator.OnPacketAcked(LoadU16LE(packet + kPacketPrefixSize));
        }
      }
    }
    strayed_ = counters_.key_samples_strayed.load() - strayed_before;
    return sent;
  }

  uint32_t box_ = 0;
  uint64_t strayed_ = 0;
  bool ack_ = false;  // acknowledge every datagram (deltas) instead of none (keyframes)
};

// Moving straight at constant velocity: sent only at the max interval (0.5 s; checked one
// key_sample_check_hz period early, as checks come only every other tick at 30 Hz), although
// its states arrive 8-14 ms late and unevenly; and every send is stamped with the time its state
// holds (what the receiver interpolates with), not the tick's.
TEST_F(KeySampleTest, AStraightLineIsSentOnlyAtTheMaxInterval) {
  const std::vector<Sent> sent = Run(Straight, 4.0, 1, 0.008, 0.006);
  EXPECT_GE(sent.size(), 7u);   // 4 s / 0.5 s
  EXPECT_LE(sent.size(), 9u);   // and the first
  EXPECT_EQ(strayed_, 0u);
  for (size_t i = 1; i < sent.size(); ++i) {
    const double early = 1.0 / config_.replication.key_sample_check_hz;
    EXPECT_GE(sent[i].at - sent[i - 1].at, 0.5 - early - 0.002) << "send " << i;
    EXPECT_LE(sent[i].at - sent[i - 1].at, 0.5 + kTick + 0.002) << "send " << i;
  }
  for (const Sent& s : sent) {
    EXPECT_EQ(s.payload_ms, static_cast<uint32_t>(static_cast<uint64_t>(s.state_time * 1000.0)));
    EXPECT_LT(s.state_time, s.at);
  }
}

// Several steps collected into one output (one state, stamped with its last step's time)
// arriving in bursts: no extra samples.
TEST_F(KeySampleTest, StatesArrivingInBurstsAddNoSamples) {
  const std::vector<Sent> sent = Run(Straight, 4.0, 3, 0.004, 0.030);
  EXPECT_GE(sent.size(), 7u);
  EXPECT_LE(sent.size(), 9u);
  EXPECT_EQ(strayed_, 0u);
}

// A bounce (a kink in the path) is sent within two ticks of the first state after it reaching
// the relay; between bounces only the max interval sends.
TEST_F(KeySampleTest, ABounceIsSentWithinTwoTicks) {
  const double latency = 0.008, jitter = 0.006;
  const std::vector<Sent> sent = Run(Bouncing, 4.0, 1, latency, jitter);
  int bounces = 0;
  for (double b = 2 * kBounceEvery; b < 5.0 - 0.1; b += kBounceEvery, ++bounces) {
    const double bounce = 10.0 + b;  // from 11.4 s, inside the measured window
    // The first state past the bounce is the step after it; it arrives at most
    // latency + jitter after that step.
    const double seen_by = bounce + kStep + latency + jitter;
    bool found = false;
    for (const Sent& s : sent) found = found || (s.at > bounce && s.at <= seen_by + 2 * kTick + 1e-6);
    EXPECT_TRUE(found) << "bounce at " << b << " s";
  }
  EXPECT_EQ(bounces, 5);
  EXPECT_GE(strayed_, 5u);
  // Each bounce costs a sample or two more than the max interval's 8 or 9.
  EXPECT_LE(sent.size(), 9u + 2u * 5u);
}

// At the kink (key_sample_at_kink, format 14): the record sent for a bounce is PhyS's state at
// the bounce, with the time it holds, not the present one: its time within a step of the bounce
// and its position within 17 mm (1 m/s x a step) of the wall. Fails with the present state sent
// (the record's time is then the payload's, a step or more after the bounce's first state).
TEST_F(KeySampleTest, AtTheKinkTheBounceStateIsSentAtItsOwnTime) {
  config_.replication.key_sample_at_kink = true;
  host_ = std::make_unique<RoomHost>("r", config_, RoomHostEnv{&limits_, &counters_, &placement_},
                                     0.0);
  const std::vector<Sent> sent = Run(Bouncing, 4.0, 1, 0.008, 0.006);
  int bounces = 0, timed = 0;
  for (double b = 2 * kBounceEvery; b < 5.0 - 0.1; b += kBounceEvery, ++bounces) {
    const double bounce = 10.0 + b;
    const float wall = std::fmod(b, 2 * kBounceEvery) < 1e-6 ? 0.0f : static_cast<float>(kBounceEvery);
    bool found = false;
    for (const Sent& s : sent) {
      const double t = s.record_ms / 1000.0;
      if (std::fabs(t - bounce) <= kStep + 0.002 && std::fabs(s.position.x - wall) <= 0.0175f) {
        found = true;
        timed += s.record_ms < s.payload_ms ? 1 : 0;
      }
    }
    EXPECT_TRUE(found) << "bounce at " << b << " s";
  }
  EXPECT_EQ(bounces, 5);
  EXPECT_GE(timed, 4);  // sent after the fact, at their own (earlier) times
  EXPECT_LE(sent.size(), 9u + 2u * 5u);
  for (const Sent& s : sent) EXPECT_LE(s.record_ms, s.payload_ms);
}

// At the kink with every datagram acknowledged (delta records, "previous" references and record
// times together): every state the receiver decodes is the box's pose at the time its record
// holds, within the lattice (0.87 mm) plus the millisecond the time is rounded to (1.04 m/s).
TEST_F(KeySampleTest, AtTheKinkEveryDecodedStateIsThePoseAtItsTime) {
  config_.replication.key_sample_at_kink = true;
  host_ = std::make_unique<RoomHost>("r", config_, RoomHostEnv{&limits_, &counters_, &placement_},
                                     0.0);
  ack_ = true;
  const std::vector<Sent> sent = Run(Bouncing, 4.0, 1, 0.008, 0.006);
  ASSERT_GE(sent.size(), 10u);
  int timed = 0;
  for (const Sent& s : sent) {
    // Run's states: the pose at (state time - 10 s), the state time the end of a step.
    const Vec3f want = Bouncing(s.record_ms / 1000.0 - 10.0);
    const float dx = s.position.x - want.x, dy = s.position.y - want.y, dz = s.position.z - want.z;
    EXPECT_LE(std::sqrt(dx * dx + dy * dy + dz * dz), 0.0019f) << "record at " << s.record_ms;
    timed += s.record_ms < s.payload_ms ? 1 : 0;
  }
  EXPECT_GE(timed, 4);
}

// key_sample_arrival_stamp: payloads are stamped the running mean of PhyS's lag (here 8-14 ms)
// later than the times the states hold, and no straight line looks kinked.
TEST_F(KeySampleTest, ArrivalStampShiftsTheTimesByTheMeanLag) {
  config_.replication.key_sample_arrival_stamp = true;
  host_ = std::make_unique<RoomHost>("r", config_, RoomHostEnv{&limits_, &counters_, &placement_},
                                     0.0);
  const std::vector<Sent> sent = Run(Straight, 4.0, 1, 0.008, 0.006);
  EXPECT_GE(sent.size(), 7u);
  EXPECT_LE(sent.size(), 9u);
  EXPECT_EQ(strayed_, 0u);
  for (const Sent& s : sent) {
    const double shift = s.payload_ms / 1000.0 - s.state_time;
    EXPECT_GE(shift, 0.007) << s.at;  // less a ms of rounding
    EXPECT_LE(shift, 0.0155) << s.at;
  }
}

// stamp_state_time without key samples: the fixed rate's payloads hold PhyS's state time.
TEST_F(KeySampleTest, FixedRateStampedWithTheStateTime) {
  config_.replication.key_sample_threshold_m = 0;
  config_.replication.stamp_state_time = true;
  host_ = std::make_unique<RoomHost>("r", config_, RoomHostEnv{&limits_, &counters_, &placement_},
                                     0.0);
  const std::vector<Sent> sent = Run(Straight, 2.0, 1, 0.008, 0.006);
  EXPECT_GE(sent.size(), 10u);  // the ambient rate (6 Hz) over 2 s
  for (const Sent& s : sent) {
    EXPECT_EQ(s.payload_ms, static_cast<uint32_t>(static_cast<uint64_t>(s.state_time * 1000.0)));
    EXPECT_LT(s.state_time, s.at);
  }
}

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

}  // namespace
}  // namespace edgephys::room_host_testing
