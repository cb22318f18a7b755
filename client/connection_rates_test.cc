#include "client/connection_rates.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace edgephys {
namespace {

ConnectionRates::Totals At(double t, double send_bps, double recv_bps, double send_pps,
                           double recv_pps) {
  return {static_cast<uint64_t>(std::floor(send_bps * t)),
          static_cast<uint64_t>(std::floor(recv_bps * t)),
          static_cast<uint64_t>(std::floor(send_pps * t)),
          static_cast<uint64_t>(std::floor(recv_pps * t))};
}

TEST(ConnectionRates, ZeroUntilTwoSamplesApart) {
  ConnectionRates r;
  EXPECT_EQ(r.Get().send_bytes_per_s, 0);
  r.Sample(5.0, {100, 100, 1, 1});
  EXPECT_EQ(r.Get().send_bytes_per_s, 0);
  r.Sample(5.0001, {200, 200, 2, 2});  // under 1 ms apart: no rate yet
  EXPECT_EQ(r.Get().send_bytes_per_s, 0);
}

TEST(ConnectionRates, SteadyTrafficAtAFrameRate) {
  ConnectionRates r(1.0);
  for (int i = 0; i <= 180; ++i) {
    const double t = 10.0 + i / 60.0;
    r.Sample(t, At(t, 60000, 6000, 60, 30));
  }
  const auto g = r.Get();
  EXPECT_NEAR(g.send_bytes_per_s, 60000, 60000 * 0.01);
  EXPECT_NEAR(g.receive_bytes_per_s, 6000, 6000 * 0.01);
  EXPECT_NEAR(g.send_packets_per_s, 60, 2);
  EXPECT_NEAR(g.receive_packets_per_s, 30, 2);
}

TEST(ConnectionRates, FollowsAChangeWithinOneWindow) {
  ConnectionRates r(1.0);
  double t = 0;
  ConnectionRates::Totals totals;
  for (; t < 3.0; t += 1.0 / 60) {
    totals = At(t, 60000, 0, 60, 0);
    r.Sample(t, totals);
  }
  EXPECT_NEAR(r.Get().send_bytes_per_s, 60000, 1000);
  const double stop = t;
  for (; t < stop + 0.5; t += 1.0 / 60) r.Sample(t, totals);  // nothing more sent
  const double half = r.Get().send_bytes_per_s;
  EXPECT_GT(half, 60000 * 0.2);
  EXPECT_LT(half, 60000 * 0.8);
  for (; t < stop + 1.2; t += 1.0 / 60) r.Sample(t, totals);
  EXPECT_EQ(r.Get().send_bytes_per_s, 0);
}

TEST(ConnectionRates, APauseInSamplingIsAveragedOverNotDividedByAFrame) {
  ConnectionRates r(1.0);
  for (int i = 0; i <= 120; ++i) r.Sample(i / 60.0, At(i / 60.0, 1000, 0, 10, 0));
  // The game loop stalls for 3 s while 3,000 bytes go out (e.g. a background thread updates).
  r.Sample(5.0, At(5.0, 1000, 0, 10, 0));
  EXPECT_NEAR(r.Get().send_bytes_per_s, 1000, 10);  // the mean over the pause, not 3000 / 16 ms
  r.Sample(5.0 + 1.0 / 60, At(5.0 + 1.0 / 60, 1000, 0, 10, 0));
  EXPECT_NEAR(r.Get().send_bytes_per_s, 1000, 10);
}

TEST(ConnectionRates, ANewConnectionOrTimeGoingBackRestartsTheWindow) {
  ConnectionRates r(1.0);
  for (int i = 0; i <= 60; ++i) r.Sample(i / 60.0, At(i / 60.0, 50000, 0, 50, 0));
  EXPECT_GT(r.Get().send_bytes_per_s, 40000);
  r.Sample(1.1, {10, 0, 1, 0});  // counters went down: a new connection
  EXPECT_EQ(r.Get().send_bytes_per_s, 0);
  r.Sample(1.6, {510, 0, 2, 0});
  EXPECT_NEAR(r.Get().send_bytes_per_s, 1000, 1);
  r.Sample(1.2, {600, 0, 3, 0});  // time went back
  EXPECT_EQ(r.Get().send_bytes_per_s, 0);
  r.Sample(NAN, {700, 0, 4, 0});  // ignored
  r.Sample(1.7, {1100, 0, 5, 0});
  EXPECT_NEAR(r.Get().send_bytes_per_s, 1000, 1);
}

TEST(ConnectionRates, RandomFrameTimesMeasureAConstantRate) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 200; ++trial) {
    std::uniform_real_distribution<double> rate(10, 1e6), dt(0.0005, 0.25), window(0.2, 3.0);
    const double bps = rate(rng), w = window(rng);
    ConnectionRates r(w);
    double t = std::uniform_real_distribution<double>(0, 1e5)(rng);
    const double start = t;
    while (t < start + 3 * w + 1.0) {
      r.Sample(t, At(t - start, bps, bps / 2, 0, 0));
      t += dt(rng);
      const auto g = r.Get();
      ASSERT_TRUE(std::isfinite(g.send_bytes_per_s));
      ASSERT_GE(g.send_bytes_per_s, 0);
    }
    // The span is at least half a window (more than 0.1 s), so flooring the counters moves the
    // rate by at most 1 / 0.1 bytes per second.
    EXPECT_NEAR(r.Get().send_bytes_per_s, bps, 10.0 + 1e-9 * bps) << "trial " << trial;
    EXPECT_NEAR(r.Get().receive_bytes_per_s, bps / 2, 10.0 + 1e-9 * bps) << "trial " << trial;
  }
}

}  // namespace
}  // namespace edgephys
