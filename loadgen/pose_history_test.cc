#include "loadgen/pose_history.h"

#include <gtest/gtest.h>

#include <cmath>

namespace edgephys::loadgen {
namespace {

// What a receiver decodes: the published position on the relay's 1 mm lattice.
Vec3f OnLattice(const Vec3f& p) {
  auto q = [](float v) { return std::round(v * 1000.f) / 1000.f; };
  return {q(p.x), q(p.y), q(p.z)};
}

Vec3f Path(int k) { return {0.2f + 0.009f * k, 1.1f, -0.3f + 0.004f * k}; }  // ~1 cm a publish

TEST(PoseHistory, MatchesTheLatticeRoundedPublish) {
  PoseHistory h;
  for (int k = 0; k < 10; ++k) h.Add({.t = k * 0.033, .unix_s = 100 + k * 0.033, .position = Path(k)});
  const PoseHistory::Publish* p = h.Match(OnLattice(Path(4)));
  ASSERT_NE(p, nullptr);
  EXPECT_DOUBLE_EQ(p->t, 4 * 0.033);
  EXPECT_DOUBLE_EQ(p->unix_s, 100 + 4 * 0.033);
}

TEST(PoseHistory, UnknownOrEmptyMatchesNothing) {
  PoseHistory h;
  EXPECT_EQ(h.Match(Path(0)), nullptr);
  h.Add({.t = 0, .position = Path(0)});
  EXPECT_EQ(h.Match({Path(0).x + 0.002f, Path(0).y, Path(0).z}), nullptr);  // 2 mm off
  EXPECT_EQ(h.Match({NAN, NAN, NAN}), nullptr);
}

TEST(PoseHistory, NewestPublishOfAPositionWins) {
  // The hand passes the same point twice within the ring: the receiver's pose is the newer one.
  PoseHistory h;
  h.Add({.t = 1.0, .position = Path(0)});
  h.Add({.t = 1.033, .position = Path(1)});
  h.Add({.t = 2.0, .position = Path(0)});
  const PoseHistory::Publish* p = h.Match(OnLattice(Path(0)));
  ASSERT_NE(p, nullptr);
  EXPECT_DOUBLE_EQ(p->t, 2.0);
}

TEST(PoseHistory, ARestingHandCountsFromItsFirstPublish) {
  // The same position published again and again (a hand held over a box) is sent once by the
  // relay; its latency counts from the first publish, not from a later copy.
  PoseHistory h;
  h.Add({.t = 0.9, .position = Path(1)});
  for (int k = 0; k < 100; ++k) h.Add({.t = 1.0 + k * 0.033, .position = Path(0)});
  EXPECT_EQ(h.size(), 2u);
  const PoseHistory::Publish* p = h.Match(OnLattice(Path(0)));
  ASSERT_NE(p, nullptr);
  EXPECT_DOUBLE_EQ(p->t, 1.0);
  ASSERT_NE(h.Match(OnLattice(Path(1))), nullptr);  // the run did not push older poses out
}

TEST(PoseHistory, ForgetsBeyondItsCapacity) {
  PoseHistory h;
  const int n = static_cast<int>(PoseHistory::kCapacity) + 5;
  for (int k = 0; k < n; ++k) h.Add({.t = k * 0.033, .position = Path(k)});
  EXPECT_EQ(h.size(), PoseHistory::kCapacity);
  EXPECT_EQ(h.Match(OnLattice(Path(0))), nullptr);
  EXPECT_EQ(h.Match(OnLattice(Path(4))), nullptr);
  ASSERT_NE(h.Match(OnLattice(Path(5))), nullptr);
  ASSERT_NE(h.Match(OnLattice(Path(n - 1))), nullptr);
  EXPECT_DOUBLE_EQ(h.Match(OnLattice(Path(n - 1)))->t, (n - 1) * 0.033);
}

TEST(RoomEntityKey, SameIdInTwoRoomsIsTwoKeys) {
  // Slot 1 of every room spawns ids from kEntityIdBlock: the id alone does not name the entity.
  const uint32_t id = kEntityIdBlock + 3;
  EXPECT_NE(RoomEntityKey(0, id), RoomEntityKey(1, id));
  EXPECT_NE(RoomEntityKey(1, 0), RoomEntityKey(0, 1));
  EXPECT_EQ(RoomEntityKey(7, id), RoomEntityKey(7, id));
}

}  // namespace
}  // namespace edgephys::loadgen
