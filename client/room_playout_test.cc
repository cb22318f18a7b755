// PlayoutConfigForRoom, SampleOptionsForStateFormat and InterpolatorForStateFormat: what a
// receiver's jitter buffer and sampler do in a room, given the room's state format and
// Joined.max_send_interval_s (client/interpolation.h).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "client/interpolation.h"
#include "client/snapshot_buffer.h"
#include "protocol/velocity.h"

namespace edgephys {
namespace {

constexpr uint8_t kFixed = 9, kVelocity = 12, kKeySamples = 13, kKeySamplesTimed = 14;

TEST(RoomPlayoutTest, FixedRateRoomsKeepTheAdaptiveDelay) {
  const SnapshotBufferConfig base{.capacity = 7};
  for (uint8_t format : {uint8_t{0}, uint8_t{2}, kFixed, kKeySamples}) {
    for (double none : {0.0, -1.0, std::numeric_limits<double>::quiet_NaN(),
                        std::numeric_limits<double>::infinity()}) {
      const SnapshotBufferConfig c = PlayoutConfigForRoom(format, none, base);
      EXPECT_EQ(c.capacity, 7u);
      EXPECT_EQ(c.interval_multiplier, base.interval_multiplier) << int(format) << " " << none;
      EXPECT_EQ(c.min_delay_s, base.min_delay_s) << int(format) << " " << none;
      EXPECT_EQ(c.max_delay_s, base.max_delay_s) << int(format) << " " << none;
    }
  }
  EXPECT_EQ(SampleOptionsForStateFormat(kFixed).max_extrapolation_s, SampleOptions{}.max_extrapolation_s);
}

TEST(RoomPlayoutTest, AMaxSendIntervalSetsTheDelayAndVelocitiesExtrapolate) {
  const SnapshotBufferConfig base{.capacity = 7};
  for (uint8_t format : {kKeySamples, kKeySamplesTimed, kVelocity}) {
    const SnapshotBufferConfig quarter = PlayoutConfigForRoom(format, 0.25, base);
    EXPECT_EQ(quarter.capacity, 7u);
    EXPECT_EQ(quarter.interval_multiplier, 0.0);
    EXPECT_DOUBLE_EQ(quarter.min_delay_s, 0.25 + kPlayoutMarginS);
    EXPECT_DOUBLE_EQ(quarter.max_delay_s, base.max_delay_s);  // 0.3 already covers 0.27
    const SnapshotBufferConfig second = PlayoutConfigForRoom(format, 1.0, base);
    EXPECT_DOUBLE_EQ(second.min_delay_s, 1.0 + kPlayoutMarginS);
    EXPECT_DOUBLE_EQ(second.max_delay_s, 1.0 + kPlayoutMarginS);
  }
  // Dead reckoning (format 12, no interval): jitter only, and extrapolate with the velocities.
  const SnapshotBufferConfig dr = PlayoutConfigForRoom(kVelocity, 0, base);
  EXPECT_EQ(dr.interval_multiplier, 0.0);
  EXPECT_DOUBLE_EQ(dr.min_delay_s, kPlayoutMarginS);
  EXPECT_EQ(SampleOptionsForStateFormat(kVelocity).max_extrapolation_s, kVelocityExtrapolationLimitS);
  EXPECT_GT(SampleOptionsForStateFormat(kVelocity).max_gap_s, kVelocityExtrapolationLimitS);
}

// A key-sample stream: checks at 30 Hz, a sample at every check while the body turns, else one
// per max interval (0.25 s). Played out for the room, the render time never passes the newest
// state held (nothing is extrapolated) once the clock has settled; at the adaptive delay alone
// (1.5 median intervals, what the SDK did before it learnt the interval) it often does, on the
// long straight segments, and the line drawn there is one the relay never checked.
TEST(RoomPlayoutTest, KeySampleStreamIsNeverExtrapolatedAtTheRoomsPlayout) {
  auto frames_past_newest = [](const SnapshotBufferConfig& config) {
    SnapshotBuffer b(config);
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> jitter(0.0, 0.004);
    std::bernoulli_distribution turns(0.6);
    std::vector<double> sent;  // sender times of the samples, in order
    double last = -1;
    for (int tick = 0; tick < 30 * 30; ++tick) {
      const double t = tick / 30.0;
      const bool turning = std::fmod(t, 2.0) < 1.2 && turns(rng);
      if (turning || t - last >= 0.25 - 1e-9) {
        sent.push_back(t);
        last = t;
      }
    }
    size_t next = 0;
    int past = 0;
    for (int frame = 0; frame < 30 * 90; ++frame) {
      const double now = frame / 90.0;
      while (next < sent.size() && sent[next] + 0.05 <= now) {
        b.Insert({.sender_time_s = sent[next]}, sent[next] + 0.05 + jitter(rng));
        ++next;
      }
      const double render = b.RenderTime(now);
      if (now > 5 && render > b.newest().sender_time_s + 1e-9) ++past;
    }
    return past;
  };
  EXPECT_EQ(frames_past_newest(PlayoutConfigForRoom(kKeySamples, 0.25)), 0);
  EXPECT_GT(frames_past_newest(SnapshotBufferConfig{}), 100);
}

TEST(RoomPlayoutTest, APlayoutLimitLowersBothBoundsAndNothingElse) {
  const SnapshotBufferConfig room = PlayoutConfigForRoom(kKeySamples, 1.0, {.capacity = 7});
  const SnapshotBufferConfig capped = CapPlayoutDelay(room, 0.1);
  EXPECT_EQ(capped.capacity, 7u);
  EXPECT_EQ(capped.interval_multiplier, room.interval_multiplier);
  EXPECT_DOUBLE_EQ(capped.min_delay_s, 0.1);
  EXPECT_DOUBLE_EQ(capped.max_delay_s, 0.1);
  // A limit above the room's bounds changes nothing; so do "no limit" values.
  const SnapshotBufferConfig loose = CapPlayoutDelay(room, 3.0);
  EXPECT_DOUBLE_EQ(loose.min_delay_s, room.min_delay_s);
  EXPECT_DOUBLE_EQ(loose.max_delay_s, room.max_delay_s);
  for (double none : {0.0, -0.5, std::numeric_limits<double>::quiet_NaN(),
                      std::numeric_limits<double>::infinity()}) {
    const SnapshotBufferConfig c = CapPlayoutDelay(room, none);
    EXPECT_EQ(c.min_delay_s, room.min_delay_s) << none;
    EXPECT_EQ(c.max_delay_s, room.max_delay_s) << none;
  }
  // The adaptive delay (fixed rates) keeps its floor under a limit above it.
  const SnapshotBufferConfig fixed = CapPlayoutDelay(SnapshotBufferConfig{}, 0.05);
  EXPECT_DOUBLE_EQ(fixed.min_delay_s, SnapshotBufferConfig{}.min_delay_s);
  EXPECT_DOUBLE_EQ(fixed.max_delay_s, 0.05);
}

// Reconfigure on a playing buffer: the snapshots and estimates stay, the target follows the new
// bounds at once, and the playout clock slews to it (10 % of real time) instead of jumping.
TEST(RoomPlayoutTest, ReconfiguringAPlayingBufferSlewsToTheNewDelay) {
  SnapshotBuffer b(PlayoutConfigForRoom(kKeySamples, 0.5, {.capacity = 16}));
  double sent = 0;
  auto run = [&](double from, double to) {
    for (double now = from; now < to; now += 1.0 / 90) {
      while (sent + 0.03 <= now) {
        b.Insert({.sender_time_s = sent}, sent + 0.03);
        sent += 0.1;
      }
      (void)b.RenderTime(now);
    }
  };
  run(0, 4);
  const double room_delay = 0.5 + kPlayoutMarginS;  // behind the estimated sender clock
  ASSERT_NEAR(b.current_delay_s(), room_delay, 0.005);
  const size_t held = b.size();
  b.Reconfigure(CapPlayoutDelay(b.config(), 0.1));
  EXPECT_EQ(b.size(), held);
  EXPECT_EQ(b.capacity(), 16u);
  EXPECT_DOUBLE_EQ(b.target_delay_s(), 0.1);
  run(4, 4.5);  // 0.5 s at 10 % slew: at most 0.05 s closer
  EXPECT_GT(b.current_delay_s(), room_delay - 0.055);
  EXPECT_LT(b.current_delay_s(), room_delay - 0.04);
  run(4.5, 10);
  EXPECT_NEAR(b.current_delay_s(), 0.1, 0.005);
}

}  // namespace
}  // namespace edgephys
