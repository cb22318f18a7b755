#include "relay/bulk_tick_scheduler.h"

#include <gtest/gtest.h>

#include <limits>

namespace edgephys {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kInterval = 1.0 / 60;

TEST(BulkTickScheduler, WaitsOnlyForALightTickDueWithinTheLead) {
  BulkTickScheduler s;
  EXPECT_DOUBLE_EQ(s.lead(), BulkTickScheduler::kMinLeadS);
  EXPECT_TRUE(s.ShouldWait(10.0, 10.0, kInterval, 10.001));   // light due in 1 ms
  EXPECT_FALSE(s.ShouldWait(10.0, 10.0, kInterval, 10.005));  // 5 ms: time enough
  EXPECT_FALSE(s.ShouldWait(10.0, 10.0, kInterval, kInf));    // no light room
  EXPECT_FALSE(s.ShouldWait(10.0, 10.0, kInterval, 10.0));    // light room not in the future
  EXPECT_FALSE(s.ShouldWait(10.0, 10.0, kInterval, std::numeric_limits<double>::quiet_NaN()));
}

TEST(BulkTickScheduler, LeadFollowsTheBulkPassAndLatenessIsBounded) {
  BulkTickScheduler s;
  s.RecordPass(0.006);
  EXPECT_NEAR(s.lead(), 0.009, 1e-12);
  s.RecordPass(-1);  // ignored
  s.RecordPass(std::numeric_limits<double>::quiet_NaN());
  EXPECT_NEAR(s.lead(), 0.009, 1e-12);
  EXPECT_TRUE(s.ShouldWait(10.0, 10.0, kInterval, 10.008));
  // Due since 4 ms: waiting 8 ms more would make it 12 ms late, over half of 16.7 ms.
  EXPECT_FALSE(s.ShouldWait(10.0, 9.996, kInterval, 10.008));
  EXPECT_TRUE(s.ShouldWait(10.0, 10.0, kInterval, 10.008));  // 8 ms late at most
}

}  // namespace
}  // namespace edgephys
