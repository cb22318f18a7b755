#include "client/snapshot_buffer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <deque>
#include <limits>
#include <random>
#include <vector>

namespace edgephys {
namespace {

Snapshot At(double t, float x = 0) { return {.sender_time_s = t, .position = {x, 0, 0}}; }

TEST(SnapshotBufferTest, StartsEmpty) {
  SnapshotBuffer b;
  EXPECT_TRUE(b.empty());
  EXPECT_EQ(b.capacity(), 32u);
  EXPECT_EQ(b.clock_offset_s(), 0.0);
  EXPECT_EQ(b.RenderTime(10.0), 0.0);
  EXPECT_EQ(b.UpperBound(1.0), 0u);
}

TEST(SnapshotBufferTest, KeepsSenderTimeOrderForLateArrivals) {
  SnapshotBuffer b;
  for (double t : {0.3, 0.1, 0.5, 0.2, 0.4, 0.0}) {
    EXPECT_EQ(b.Insert(At(t, static_cast<float>(t)), 1.0), InsertResult::kInserted);
  }
  ASSERT_EQ(b.size(), 6u);
  for (size_t i = 0; i < b.size(); ++i) {
    EXPECT_DOUBLE_EQ(b[i].sender_time_s, 0.1 * static_cast<double>(i));
    EXPECT_FLOAT_EQ(b[i].position.x, 0.1f * static_cast<float>(i));
  }
  EXPECT_EQ(b.UpperBound(0.25), 3u);
  EXPECT_EQ(b.UpperBound(0.2), 3u);
  EXPECT_EQ(b.UpperBound(-1), 0u);
  EXPECT_EQ(b.UpperBound(9), 6u);
}

TEST(SnapshotBufferTest, IgnoresDuplicates) {
  SnapshotBuffer b;
  EXPECT_EQ(b.Insert(At(1.0, 1), 1.0), InsertResult::kInserted);
  EXPECT_EQ(b.Insert(At(1.0, 2), 1.1), InsertResult::kDuplicate);
  EXPECT_EQ(b.Insert(At(1.0 + 1e-9, 3), 1.1), InsertResult::kDuplicate);
  EXPECT_EQ(b.size(), 1u);
  EXPECT_EQ(b.newest().position.x, 1.0f);  // the first copy is kept
}

TEST(SnapshotBufferTest, EvictsOldestWhenFullAndRejectsOlderThanEverything) {
  SnapshotBuffer b(SnapshotBufferConfig{.capacity = 4});
  for (int i = 1; i <= 6; ++i) EXPECT_EQ(b.Insert(At(i), i), InsertResult::kInserted);
  ASSERT_EQ(b.size(), 4u);
  EXPECT_EQ(b.oldest().sender_time_s, 3.0);
  EXPECT_EQ(b.newest().sender_time_s, 6.0);
  EXPECT_EQ(b.Insert(At(2.5), 7), InsertResult::kTooOld);
  // A late one inside the kept range replaces the oldest.
  EXPECT_EQ(b.Insert(At(4.5), 7), InsertResult::kInserted);
  ASSERT_EQ(b.size(), 4u);
  EXPECT_EQ(b[0].sender_time_s, 4.0);
  EXPECT_EQ(b[1].sender_time_s, 4.5);
  EXPECT_EQ(b[3].sender_time_s, 6.0);
}

TEST(SnapshotBufferTest, RejectsNonFiniteAndNormalisesRotation) {
  SnapshotBuffer b;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(b.Insert(At(std::nan("")), 0), InsertResult::kInvalid);
  EXPECT_EQ(b.Insert({.sender_time_s = 1, .position = {nan, 0, 0}}, 0), InsertResult::kInvalid);
  EXPECT_EQ(b.Insert({.sender_time_s = 1, .rotation = {0, 0, 0, 0}}, 0), InsertResult::kInvalid);
  EXPECT_EQ(b.Insert({.sender_time_s = 1,
                      .has_linear_velocity = true,
                      .linear_velocity = {0, std::numeric_limits<float>::infinity(), 0}},
                     0),
            InsertResult::kInvalid);
  EXPECT_EQ(b.Insert(At(1), std::nan("")), InsertResult::kInvalid);
  EXPECT_TRUE(b.empty());
  EXPECT_EQ(b.Insert({.sender_time_s = 1, .rotation = {0, 0, 0, 2}}, 0), InsertResult::kInserted);
  EXPECT_FLOAT_EQ(b.newest().rotation.w, 1.0f);
}

TEST(SnapshotBufferTest, ClockOffsetIsTheMinimumDelay) {
  // Sender clock 500 s behind the local one, 40 ms base latency, 0..30 ms queueing.
  SnapshotBuffer b;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> queue(0.0, 0.030);
  double min_queue = 1;
  for (int i = 0; i < 200; ++i) {
    const double sent = i / 30.0;
    const double q = queue(rng);
    min_queue = std::min(min_queue, q);
    b.Insert(At(sent), sent + 500.0 + 0.040 + q);
  }
  // The min over the last window is within a few ms of the true base.
  EXPECT_NEAR(b.clock_offset_s(), 500.040, 0.003);
  EXPECT_GE(b.clock_offset_s(), 500.040);
  EXPECT_NEAR(b.EstimateSenderTime(1000.0), 1000.0 - b.clock_offset_s(), 1e-12);
}

TEST(SnapshotBufferTest, ClockOffsetFollowsARouteChangeWithinTwoWindows) {
  SnapshotBuffer b(SnapshotBufferConfig{.offset_window_s = 2.0});
  double sent = 0;
  for (; sent < 5; sent += 0.05) b.Insert(At(sent), sent + 0.020);
  EXPECT_NEAR(b.clock_offset_s(), 0.020, 1e-9);
  // Latency rises to 120 ms (or the clocks drift): the min-filter forgets the old minimum.
  for (; sent < 10; sent += 0.05) b.Insert(At(sent), sent + 0.120);
  EXPECT_NEAR(b.clock_offset_s(), 0.120, 1e-9);
}

TEST(SnapshotBufferTest, SendIntervalIsRobustToLoss) {
  SnapshotBuffer b;
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int i = 0; i < 300; ++i) {
    if (unit(rng) < 0.2) continue;
    b.Insert(At(i / 30.0), i / 30.0 + 0.05);
  }
  EXPECT_NEAR(b.send_interval_s(), 1.0 / 30, 1e-9);
}

TEST(SnapshotBufferTest, PlayoutDelayAdaptsToJitter) {
  const SnapshotBufferConfig config{
      .interval_multiplier = 1.5, .min_delay_s = 0.010, .max_delay_s = 0.300};
  // No jitter: delay = 1.5 * 33.3 ms.
  SnapshotBuffer steady(config);
  for (int i = 0; i < 200; ++i) steady.Insert(At(i / 30.0), i / 30.0 + 0.05);
  EXPECT_NEAR(steady.jitter_p95_s(), 0.0, 1e-9);
  EXPECT_NEAR(steady.target_delay_s(), 0.050, 1e-6);

  // +-20 ms uniform jitter: p95 of the queueing delay is about 38 ms above the minimum.
  SnapshotBuffer jittery(config);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> jitter(-0.020, 0.020);
  for (int i = 0; i < 200; ++i) jittery.Insert(At(i / 30.0), i / 30.0 + 0.05 + jitter(rng));
  EXPECT_GT(jittery.jitter_p95_s(), 0.030);
  EXPECT_LT(jittery.jitter_p95_s(), 0.040);
  EXPECT_NEAR(jittery.target_delay_s(), 0.050 + jittery.jitter_p95_s(), 1e-9);

  // Clamped at both ends.
  SnapshotBuffer slow(config);
  for (int i = 0; i < 20; ++i) slow.Insert(At(i * 1.0), i * 1.0);
  EXPECT_DOUBLE_EQ(slow.target_delay_s(), 0.300);
  SnapshotBuffer fast(config);
  for (int i = 0; i < 20; ++i) fast.Insert(At(i * 0.001), i * 0.001);
  EXPECT_DOUBLE_EQ(fast.target_delay_s(), 0.010);
}

// The estimates are maintained incrementally (sorted sliding windows); they must equal a full
// recomputation over the same windows — the median of the last kIntervalWindow gaps appended
// at the newest end and the nearest-rank p95 of the last kJitterWindow raw delays (inserted or
// too old) minus the clock offset — after every insert, for arrival streams with jitter, loss,
// reordering, duplicates, too-old snapshots, interval changes and clears.
TEST(SnapshotBufferTest, IncrementalEstimatesEqualAFullRecomputation) {
  for (uint32_t seed = 1; seed <= 8; ++seed) {
    const SnapshotBufferConfig config{.capacity = seed % 2 == 0 ? 32u : 6u};
    SnapshotBuffer b(config);
    std::deque<double> gaps, raws;
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    double interval = 1.0 / 30, jitter = 0.02, sent = 0, base_delay = 0.05;
    for (int i = 0; i < 3000; ++i) {
      if (unit(rng) < 0.01) interval = 0.005 + 0.1 * unit(rng);   // sender changes its rate
      if (unit(rng) < 0.01) jitter = 0.05 * unit(rng);            // the path changes
      if (unit(rng) < 0.003) base_delay = 0.3 * unit(rng) - 0.1;  // route / clock step
      if (unit(rng) < 0.002) {
        b.Clear();
        gaps.clear();
        raws.clear();
      }
      sent += interval;
      double t = sent;
      const double r = unit(rng);
      if (r < 0.05) t -= interval * (1 + std::floor(10 * unit(rng)));  // late or duplicate
      if (r > 0.97) t = std::round(t * 1000) / 1000;                   // coarse (ms) times
      const double received = sent + base_delay + jitter * unit(rng);
      const InsertResult result = b.Insert(At(t), received);
      if (result == InsertResult::kInserted || result == InsertResult::kTooOld) {
        raws.push_back(received - t);
        if (raws.size() > SnapshotBuffer::kJitterWindow) raws.pop_front();
      }
      if (result == InsertResult::kInserted && b.size() >= 2 && b.newest().sender_time_s == t) {
        gaps.push_back(t - b[b.size() - 2].sender_time_s);
        if (gaps.size() > SnapshotBuffer::kIntervalWindow) gaps.pop_front();
      }

      double interval_ref = config.initial_send_interval_s;
      if (!gaps.empty()) {
        std::vector<double> sorted(gaps.begin(), gaps.end());
        std::sort(sorted.begin(), sorted.end());
        interval_ref = sorted[sorted.size() / 2];
      }
      double jitter_ref = 0;
      if (!raws.empty()) {
        std::vector<double> sorted(raws.begin(), raws.end());
        std::sort(sorted.begin(), sorted.end());
        const size_t rank = (sorted.size() * 95 + 99) / 100;
        jitter_ref = std::max(0.0, sorted[rank - 1] - b.clock_offset_s());
      }
      ASSERT_EQ(b.send_interval_s(), interval_ref) << "seed " << seed << " insert " << i;
      ASSERT_EQ(b.jitter_p95_s(), jitter_ref) << "seed " << seed << " insert " << i;
      ASSERT_EQ(b.target_delay_s(),
                std::clamp(config.interval_multiplier * interval_ref + jitter_ref,
                           config.min_delay_s, config.max_delay_s))
          << "seed " << seed << " insert " << i;
      for (size_t k = 1; k < b.size(); ++k) ASSERT_LT(b[k - 1].sender_time_s, b[k].sender_time_s);
    }
  }
}

// The estimates follow a change of the sender's rate and of the path's jitter within their
// windows, in both directions, whatever the random draw.
TEST(SnapshotBufferTest, EstimatesTrackAChangedSendIntervalAndJitter) {
  for (uint32_t seed = 1; seed <= 20; ++seed) {
    SnapshotBuffer b;
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    double sent = 0;
    auto run = [&](int n, double interval, double jitter) {
      for (int i = 0; i < n; ++i) {
        sent += interval;
        if (unit(rng) < 0.1) continue;  // loss
        b.Insert(At(sent), sent + 0.04 + jitter * unit(rng));
      }
    };
    run(200, 1.0 / 30, 0.0);
    EXPECT_NEAR(b.send_interval_s(), 1.0 / 30, 1e-9);
    EXPECT_NEAR(b.jitter_p95_s(), 0.0, 1e-9);
    // 60 Hz with 0..30 ms of queueing: after a full window of both, the median gap is the new
    // interval (losses make a minority of double gaps) and the p95 sits in the top of 0..30 ms.
    run(100, 1.0 / 60, 0.030);
    EXPECT_NEAR(b.send_interval_s(), 1.0 / 60, 1e-9) << "seed " << seed;
    EXPECT_GT(b.jitter_p95_s(), 0.022) << "seed " << seed;
    EXPECT_LE(b.jitter_p95_s(), 0.030 + 1e-9) << "seed " << seed;
    EXPECT_NEAR(b.target_delay_s(), 1.5 / 60 + b.jitter_p95_s(), 1e-9);
    // Back to a quiet 20 Hz: the jitter leaves the window within kJitterWindow arrivals.
    run(100, 0.05, 0.0);
    EXPECT_NEAR(b.send_interval_s(), 0.05, 1e-9) << "seed " << seed;
    EXPECT_LT(b.jitter_p95_s(), 1e-9) << "seed " << seed;
  }
}

TEST(SnapshotBufferTest, RenderTimeIsMonotonicSlewLimitedAndConverges) {
  SnapshotBuffer b(SnapshotBufferConfig{.max_slew = 0.1});
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> jitter(-0.020, 0.020);
  int next = 0;
  double last_render = 0, last_now = 0;
  bool started = false;
  for (double now = 0; now < 20; now += 1.0 / 90) {
    // Jitter only during the middle 8 seconds: the delay must grow, then shrink again.
    const bool jittery = now > 6 && now < 14;
    while ((next / 30.0) + 0.05 <= now) {
      b.Insert(At(next / 30.0), next / 30.0 + 0.05 + (jittery ? jitter(rng) + 0.02 : 0));
      ++next;
    }
    const double render = b.RenderTime(now);
    if (started) {
      const double dt = now - last_now;
      ASSERT_GE(render, last_render);
      EXPECT_GE(render - last_render, 0.9 * dt - 1e-9);
      EXPECT_LE(render - last_render, 1.1 * dt + 1e-9);
    }
    if (now > 4 && now < 6) {
      EXPECT_NEAR(b.current_delay_s(), b.target_delay_s(), 1e-6);
    }
    started = !b.empty();
    last_render = render;
    last_now = now;
  }
  EXPECT_NEAR(b.current_delay_s(), b.target_delay_s(), 1e-6);
}

TEST(SnapshotBufferTest, RenderTimeJumpsForwardOnlyAfterALongStall) {
  SnapshotBuffer b;
  b.Insert(At(0), 0.05);
  const double r0 = b.RenderTime(0.05);
  // The sender goes quiet; the next packet is 10 s later, and frames are 10 s apart.
  b.Insert(At(10), 10.05);
  const double r1 = b.RenderTime(10.05);
  EXPECT_GT(r1, r0);
  EXPECT_NEAR(10.05 - b.clock_offset_s() - r1, b.target_delay_s(), 1e-9);
}

TEST(SnapshotBufferTest, ClearForgetsEverything) {
  SnapshotBuffer b;
  b.Insert(At(1), 2);
  b.RenderTime(2);
  b.Clear();
  EXPECT_TRUE(b.empty());
  EXPECT_EQ(b.clock_offset_s(), 0.0);
  EXPECT_EQ(b.RenderTime(3), 0.0);
  EXPECT_EQ(b.Insert(At(0.5), 3), InsertResult::kInserted);
}

}  // namespace
}  // namespace edgephys
