// A small in-process ccu over several rooms: what it measures is each receiver's own room-mates.
#include "loadgen/ccu.h"

#include <gtest/gtest.h>
#include <spdlog/spdlog.h>

namespace edgephys::loadgen {
namespace {

CcuResult SmallRun(uint32_t users, uint32_t rooms, double impaired = 0) {
  spdlog::set_level(spdlog::level::warn);  // the in-process relay logs every join at info
  CcuOptions o;
  o.users = {users};
  o.rooms = rooms;
  o.ramp_s = 1.5;
  o.duration_s = 3;
  o.progress = false;
  o.impaired_fraction = impaired;
  std::vector<CcuResult> r = RunCcu(o);
  EXPECT_EQ(r.size(), 1u);
  return r.empty() ? CcuResult{} : r[0];
}

// Rooms reuse entity ids (slot blocks), so bots in one slot of different rooms own the same
// hand and box ids. Every measured hand pose must be matched to its own publisher's publish,
// and no sample may be timed against another room's bot.
TEST(Ccu, ManyRoomsMatchEveryPoseToItsOwnPublisher) {
  const CcuResult r = SmallRun(16, 4);
  EXPECT_EQ(r.connected, 16u);
  EXPECT_EQ(r.reliable_lost, 0u);
  ASSERT_GT(r.hand_updates_measured, 200u);  // 4 rooms x 4 bots x 3 watchers x 30 Hz x 3 s
  EXPECT_LE(r.hand_unmatched, r.hand_updates_measured / 100)
      << "of " << r.hand_updates_measured << " measured hand poses";
  EXPECT_EQ(r.cross_room_samples, 0u);
  EXPECT_GT(r.latency_ms_p50, 0);
}

// The control: one room, where ids are unique.
TEST(Ccu, OneRoomMatchesEveryPose) {
  const CcuResult r = SmallRun(6, 1);
  EXPECT_EQ(r.connected, 6u);
  ASSERT_GT(r.hand_updates_measured, 200u);
  EXPECT_LE(r.hand_unmatched, r.hand_updates_measured / 100);
  EXPECT_EQ(r.cross_room_samples, 0u);
}

// --impaired: a quarter of the bots on a 10 % loss, 30 ms link. The links really drop both
// ways, and reliable spawns and grab events still reach every room-mate once.
TEST(Ccu, ImpairedBotsLoseDatagramsButNoReliableMessage) {
  const CcuResult r = SmallRun(8, 2, 0.25);
  EXPECT_EQ(r.connected, 8u);
  EXPECT_EQ(r.impaired_users, 2u);
  EXPECT_GT(r.impaired_dropped_up, 10u);
  EXPECT_GT(r.impaired_dropped_down, 10u);
  EXPECT_EQ(r.reliable_lost, 0u);
  EXPECT_GT(r.hand_updates_measured, 100u);
}

}  // namespace
}  // namespace edgephys::loadgen
