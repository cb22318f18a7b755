#include "relay/physics_pool.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <thread>
#include <vector>

namespace edgephys {
namespace {

TEST(PhysicsPool, RunsEveryIndexExactlyOnceAcrossManyRuns) {
  for (size_t threads : {1u, 2u, 4u}) {
    PhysicsPool pool(threads);
    EXPECT_EQ(pool.threads(), threads);
    for (size_t n : {0u, 1u, 2u, 7u, 100u}) {
      for (int run = 0; run < 50; ++run) {
        std::vector<std::atomic<int>> hits(n);
        pool.Run(n, [&](size_t i) { hits[i].fetch_add(1); });
        for (size_t i = 0; i < n; ++i) ASSERT_EQ(hits[i].load(), 1) << threads << " " << n;
      }
    }
  }
}

TEST(PhysicsPool, UsesMoreThanOneThreadWhenAsked) {
  PhysicsPool pool(2);
  std::atomic<int> concurrent{0}, peak{0};
  pool.Run(64, [&](size_t) {
    int c = concurrent.fetch_add(1) + 1;
    int p = peak.load();
    while (c > p && !peak.compare_exchange_weak(p, c)) {
    }
    std::atomic<int> spin{0};  // work the optimiser cannot remove
    while (spin.fetch_add(1, std::memory_order_relaxed) < 200000) {
    }
    concurrent.fetch_sub(1);
  });
  EXPECT_GE(peak.load(), 1);
  EXPECT_LE(peak.load(), 2);
}

// A worker that is woken but not running (its core busy with PhyS or another process) must not
// hold up the caller: the caller runs every index itself and returns. The worker here is held
// in its wake hook until the test releases it; a watchdog releases it after 10 s, which only a
// Run() that waits for the worker needs (the test then fails instead of hanging).
TEST(PhysicsPool, RunDoesNotWaitForAWorkerThatHasNotJoinedYet) {
  PhysicsPool pool(2);
  std::mutex mu;
  std::condition_variable cv;
  bool released = false, released_by_watchdog = false, hook_entered = false;
  pool.SetWorkerWakeHookForTesting([&] {
    std::unique_lock<std::mutex> lock(mu);
    if (released) return;
    hook_entered = true;
    cv.notify_all();
    cv.wait(lock, [&] { return released; });
  });
  std::thread watchdog([&] {
    std::unique_lock<std::mutex> lock(mu);
    if (!cv.wait_for(lock, std::chrono::seconds(10), [&] { return released; })) {
      released = released_by_watchdog = true;
      cv.notify_all();
    }
  });
  const std::thread::id caller = std::this_thread::get_id();
  std::vector<std::atomic<int>> hits(16);
  std::atomic<int> off_caller{0};
  pool.Run(hits.size(), [&](size_t i) {
    {  // hold every index until the worker is parked in its hook (at most 10 s)
      std::unique_lock<std::mutex> lock(mu);
      cv.wait(lock, [&] { return hook_entered || released; });
    }
    hits[i].fetch_add(1);
    if (std::this_thread::get_id() != caller) off_caller.fetch_add(1);
  });
  bool watchdog_fired;
  {
    std::lock_guard<std::mutex> lock(mu);
    watchdog_fired = released_by_watchdog;
    released = true;
  }
  cv.notify_all();
  watchdog.join();
  EXPECT_FALSE(watchdog_fired) << "Run() waited for a worker that had not joined";
  EXPECT_EQ(off_caller.load(), 0);
  for (auto& h : hits) EXPECT_EQ(h.load(), 1);
  // The released worker finds the run closed; it is counted and the pool still works.
  for (int i = 0; i < 500 && pool.late_wakeups() == 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  EXPECT_EQ(pool.late_wakeups(), 1u);
  EXPECT_EQ(pool.joined(), 0u);
  std::vector<std::atomic<int>> again(100);
  for (int run = 0; run < 20; ++run) {
    for (auto& h : again) h.store(0);
    pool.Run(again.size(), [&](size_t i) { again[i].fetch_add(1); });
    for (auto& h : again) ASSERT_EQ(h.load(), 1);
  }
}

}  // namespace
}  // namespace edgephys
