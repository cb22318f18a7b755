#include "protocol/replication_tracker.h"

#include <gtest/gtest.h>

namespace edgephys {
namespace {

TEST(ReplicationTracker, SendsUntilAckedAndResendsPresumedLost) {
  ReplicationTracker t;
  EXPECT_TRUE(t.NeedsSend(5, 1, 0.0, 0.1));
  t.OnSent(10, 5, 1, 0.0);
  EXPECT_FALSE(t.NeedsSend(5, 1, 0.05, 0.1));  // in flight
  EXPECT_TRUE(t.NeedsSend(5, 1, 0.11, 0.1));   // presumed lost: resend
  EXPECT_TRUE(t.NeedsSend(5, 2, 0.05, 0.1));   // a newer version goes at once
  t.OnAcked(10);
  EXPECT_EQ(t.AckedVersion(5), 1u);
  EXPECT_FALSE(t.NeedsSend(5, 1, 1.0, 0.1));
  t.OnSent(11, 5, 2, 1.0);
  t.OnSent(12, 5, 3, 1.1);
  t.OnAcked(12);
  t.OnAcked(11);  // a late ack of an older version never lowers what was acked
  EXPECT_EQ(t.AckedVersion(5), 3u);
  t.OnAcked(999);  // unknown sequence: ignored
  t.Forget(5);
  EXPECT_EQ(t.AckedVersion(5), 0u);
}

TEST(ReplicationTracker, MarkAckedSuppressesVersionsThePeerHasAlready) {
  ReplicationTracker t;
  t.MarkAcked(9, 1);
  EXPECT_FALSE(t.NeedsSend(9, 1, 0.0, 0.1));
  EXPECT_TRUE(t.NeedsSend(9, 2, 0.0, 0.1));
  EXPECT_EQ(t.AckedVersion(9), 1u);
}

TEST(ReplicationTracker, RecordsOfOverwrittenSlotsDoNotAckTheWrongEntity) {
  ReplicationTracker t;
  t.OnSent(1, 7, 1, 0);
  t.OnSent(static_cast<uint16_t>(1 + ReplicationTracker::kPacketRecords), 8, 1, 0);
  t.OnAcked(1);  // slot now holds a different sequence
  EXPECT_EQ(t.AckedVersion(7), 0u);
  EXPECT_EQ(t.AckedVersion(8), 0u);
}

}  // namespace
}  // namespace edgephys
