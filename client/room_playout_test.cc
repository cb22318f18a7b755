// CapPlayoutDelay and SnapshotBuffer::Reconfigure: an application's latency limit on the
// playout delay (edgephys_client_set_max_playout_delay), applied to a playing buffer.
#include <gtest/gtest.h>

#include <algorithm>
#include <limits>

#include "client/interpolation.h"
#include "client/snapshot_buffer.h"

namespace edgephys {
namespace {

// A buffer held `delay_s` behind (no adaptive part).
SnapshotBufferConfig FixedDelay(double delay_s, size_t capacity) {
  SnapshotBufferConfig c{.capacity = capacity};
  c.interval_multiplier = 0;
  c.min_delay_s = delay_s;
  c.max_delay_s = std::max(c.max_delay_s, delay_s);
  return c;
}

TEST(RoomPlayoutTest, APlayoutLimitLowersBothBoundsAndNothingElse) {
  const SnapshotBufferConfig room = FixedDelay(1.02, 7);
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
  SnapshotBuffer b(FixedDelay(0.52, 16));
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
  const double room_delay = 0.52;  // behind the estimated sender clock
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
