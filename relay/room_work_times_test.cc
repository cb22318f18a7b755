#include "relay/room_work_times.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

namespace edgephys {
namespace {

double Seconds(const RoomWorkTimes& t, const std::string& label) {
  for (const auto& s : t.Snapshot()) {
    if (s.label == label) return s.seconds;
  }
  return -1;
}

TEST(RoomWorkTimes, AddsPerRoomAndRemovesClosedRooms) {
  RoomWorkTimes t;
  t.Add("lobby", 0.25);
  t.Add("arena", 1.0);
  t.Add("lobby", 0.5);
  auto snap = t.Snapshot();
  ASSERT_EQ(snap.size(), 2u);
  EXPECT_EQ(snap[0].label, "arena");  // ordered by label
  EXPECT_DOUBLE_EQ(Seconds(t, "lobby"), 0.75);
  t.Remove("lobby");
  EXPECT_EQ(Seconds(t, "lobby"), -1);
  t.Remove("never-seen");  // no-op
  t.Add("lobby", 0.125);   // reopened: starts again
  EXPECT_DOUBLE_EQ(Seconds(t, "lobby"), 0.125);
}

TEST(RoomWorkTimes, RoomsPastTheCapShareOtherAndFreedSlotsAreReused) {
  RoomWorkTimes t(2);
  t.Add("r1", 1);
  t.Add("r2", 2);
  EXPECT_EQ(Seconds(t, std::string(RoomWorkTimes::kOtherLabel)), -1);  // no overflow yet
  t.Add("r3", 3);
  t.Add("r4", 4);
  t.Add("r1", 1);  // tracked rooms stay tracked
  EXPECT_EQ(t.Snapshot().size(), 3u);
  EXPECT_DOUBLE_EQ(Seconds(t, "r1"), 2);
  EXPECT_DOUBLE_EQ(Seconds(t, "~other"), 7);
  EXPECT_EQ(t.Snapshot().back().label, "~other");
  t.Remove("r2");
  t.Add("r5", 5);  // a freed slot: a series of its own
  EXPECT_DOUBLE_EQ(Seconds(t, "r5"), 5);
  EXPECT_DOUBLE_EQ(Seconds(t, "~other"), 7);  // only grows
  t.Remove("r3");  // in "~other": nothing to remove
  EXPECT_DOUBLE_EQ(Seconds(t, "~other"), 7);
}

TEST(RoomWorkTimes, IgnoresBadAmounts) {
  RoomWorkTimes t;
  t.Add("r", std::numeric_limits<double>::quiet_NaN());
  t.Add("r", -1);
  t.Add("r", std::numeric_limits<double>::infinity());
  EXPECT_TRUE(t.Snapshot().empty());
  t.Add("r", 0.5);
  EXPECT_DOUBLE_EQ(Seconds(t, "r"), 0.5);
}

TEST(RoomWorkTimes, LabelsArePrintableAsciiAndNeverOther) {
  EXPECT_EQ(RoomWorkTimes::Label("caf\xc3\xa9\n\x01"), "caf????");
  EXPECT_EQ(RoomWorkTimes::Label("~other"), "?other");
  EXPECT_EQ(RoomWorkTimes::Label("a \"quoted\" \\ name"), "a \"quoted\" \\ name");
  RoomWorkTimes t;
  t.Add("x\xff", 1);
  t.Add("x\xfe", 2);  // same label: one series, the sum
  auto snap = t.Snapshot();
  ASSERT_EQ(snap.size(), 1u);
  EXPECT_EQ(snap[0].label, "x?");
  EXPECT_DOUBLE_EQ(snap[0].seconds, 3);
}

TEST(RoomWorkLedger, PublishesAtMostEveryIntervalAndForgets) {
  RoomWorkTimes t;
  RoomWorkLedger ledger;
  const std::string a = "a", b = "b";
  int ka = 0, kb = 0;  // keys
  ledger.Charge(&ka, &a, 0.25);
  ledger.Charge(&kb, &b, 0.5);
  ledger.Charge(nullptr, &a, 9);  // no room: not charged
  ledger.Publish(&t, 10.0);
  EXPECT_DOUBLE_EQ(Seconds(t, "a"), 0.25);
  ledger.Charge(&ka, &a, 0.25);
  ledger.Publish(&t, 10.0 + RoomWorkLedger::kPublishIntervalS / 2);  // too soon
  EXPECT_DOUBLE_EQ(Seconds(t, "a"), 0.25);
  ledger.Publish(&t, 10.0 + 1.5 * RoomWorkLedger::kPublishIntervalS);
  EXPECT_DOUBLE_EQ(Seconds(t, "a"), 0.5);
  ledger.Charge(&kb, &b, 1);
  ledger.Forget(&kb, b, &t);  // unpublished work of a closed room is dropped with its series
  ledger.Publish(&t, 20.0, /*force=*/true);
  EXPECT_EQ(Seconds(t, "b"), -1);
  EXPECT_DOUBLE_EQ(Seconds(t, "a"), 0.5);
}

}  // namespace
}  // namespace edgephys
