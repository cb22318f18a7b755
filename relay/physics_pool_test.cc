#include "relay/physics_pool.h"

#include <gtest/gtest.h>

#include <atomic>
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

}  // namespace
}  // namespace edgephys
