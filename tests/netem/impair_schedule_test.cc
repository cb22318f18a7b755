// The impairment model of udp_impair (impair_schedule.h): measured rates over many datagrams,
// delay bounds, queue order and bounds, determinism; and udp_impair itself on loopback UDP.
#include "tests/netem/impair_schedule.h"

#include <gtest/gtest.h>

#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include "protocol/udp_socket.h"

extern char** environ;

namespace edgephys::netem {
namespace {

const ImpairParams kNetemArgs{.loss = 0.10, .duplicate = 0.02, .reorder = 0.05,
                              .delay_s = 0.030, .jitter_s = 0.010};

TEST(ImpairSchedule, RatesAndDelaysMatchTheNetemArguments) {
  ImpairSchedule schedule(kNetemArgs, 7);
  constexpr int kDatagrams = 200000;
  int lost = 0, duplicated = 0, copies = 0, reordered = 0;
  double min_delay = 1, max_delay = 0, sum_delay = 0;
  int delayed = 0;
  for (int i = 0; i < kDatagrams; ++i) {
    Fate f = schedule.Decide();
    ASSERT_GE(f.copies, 0);
    ASSERT_LE(f.copies, 2);
    lost += f.copies == 0;
    duplicated += f.copies == 2;
    for (int c = 0; c < f.copies; ++c) {
      ++copies;
      if (f.reordered[c]) {
        ++reordered;
        EXPECT_EQ(f.delay_s[c], 0.0);  // sent at once: overtakes the queue
        continue;
      }
      ASSERT_GE(f.delay_s[c], 0.020 - 1e-12);
      ASSERT_LE(f.delay_s[c], 0.040 + 1e-12);
      min_delay = std::min(min_delay, f.delay_s[c]);
      max_delay = std::max(max_delay, f.delay_s[c]);
      sum_delay += f.delay_s[c];
      ++delayed;
    }
  }
  const double loss_rate = static_cast<double>(lost) / kDatagrams;
  const double dup_rate = static_cast<double>(duplicated) / (kDatagrams - lost);
  const double reorder_rate = static_cast<double>(reordered) / copies;
  // Bounds are > 5 standard deviations wide (binomial), so the test is not flaky for any seed.
  EXPECT_NEAR(loss_rate, 0.10, 0.004) << loss_rate;
  EXPECT_NEAR(dup_rate, 0.02, 0.002) << dup_rate;
  EXPECT_NEAR(reorder_rate, 0.05, 0.003) << reorder_rate;
  EXPECT_NEAR(sum_delay / delayed, 0.030, 0.0003);  // uniform around 30 ms
  EXPECT_LT(min_delay, 0.0201);                     // the whole jitter range is used
  EXPECT_GT(max_delay, 0.0399);
}

TEST(ImpairSchedule, NoImpairmentIsOneCopyAtOnce) {
  ImpairSchedule schedule(ImpairParams{}, 1);
  for (int i = 0; i < 1000; ++i) {
    Fate f = schedule.Decide();
    ASSERT_EQ(f.copies, 1);
    ASSERT_EQ(f.delay_s[0], 0.0);
    ASSERT_FALSE(f.reordered[0]);
  }
}

TEST(ImpairSchedule, JitterLargerThanDelayClampsAtZero) {
  ImpairSchedule schedule(ImpairParams{.delay_s = 0.005, .jitter_s = 0.010}, 3);
  int zero = 0;
  for (int i = 0; i < 10000; ++i) {
    Fate f = schedule.Decide();
    ASSERT_GE(f.delay_s[0], 0.0);
    ASSERT_LE(f.delay_s[0], 0.015 + 1e-12);
    zero += f.delay_s[0] == 0.0;
  }
  EXPECT_GT(zero, 2000);  // a quarter of the range is below 0
}

TEST(ImpairSchedule, SameSeedSameFates) {
  ImpairSchedule a(kNetemArgs, 42), b(kNetemArgs, 42), c(kNetemArgs, 43);
  int differ = 0;
  for (int i = 0; i < 1000; ++i) {
    Fate x = a.Decide(), y = b.Decide(), z = c.Decide();
    ASSERT_EQ(x.copies, y.copies);
    ASSERT_EQ(x.delay_s[0], y.delay_s[0]);
    ASSERT_EQ(x.delay_s[1], y.delay_s[1]);
    differ += x.delay_s[0] != z.delay_s[0];
  }
  EXPECT_GT(differ, 900);
}

// Datagrams arriving every millisecond through schedule + queue, as udp_impair does: each
// leaves within its delay bounds, reordering happens (jitter and reorder), and the measured
// end-to-end loss and duplication are those asked for.
TEST(DelayQueue, ReleasesInDueOrderWithinTheDelayBounds) {
  ImpairSchedule schedule(kNetemArgs, 11);
  DelayQueue queue(100000, 64u << 20);
  constexpr uint32_t kDatagrams = 50000;
  std::map<uint32_t, int> delivered;
  uint64_t out_of_order = 0, released = 0;
  uint32_t last = 0;
  double last_due = -1;
  auto pop = [&](double now) {
    queue.PopDue(now, [&](uint64_t tag, std::span<const uint8_t> data, double due) {
      ASSERT_EQ(data.size(), 4u);
      uint32_t i;
      std::memcpy(&i, data.data(), 4);
      ASSERT_EQ(tag, i);
      ASSERT_LE(due, now);
      ASSERT_GE(due, last_due);  // due order
      last_due = due;
      const double sent = i * 0.001;
      ASSERT_GE(due - sent, -1e-9);
      ASSERT_LE(due - sent, 0.040 + 1e-9);
      out_of_order += released > 0 && i < last;
      last = i;
      ++released;
      ++delivered[i];
    });
  };
  for (uint32_t i = 0; i < kDatagrams; ++i) {
    const double now = i * 0.001;
    pop(now);
    Fate f = schedule.Decide();
    uint8_t bytes[4];
    std::memcpy(bytes, &i, 4);
    for (int c = 0; c < f.copies; ++c) ASSERT_TRUE(queue.Push(now + f.delay_s[c], i, bytes));
  }
  pop(1e9);
  EXPECT_TRUE(queue.empty());
  EXPECT_EQ(queue.bytes(), 0u);
  const double loss = 1.0 - static_cast<double>(delivered.size()) / kDatagrams;
  int twice = 0;
  for (const auto& [i, n] : delivered) twice += n == 2;
  EXPECT_NEAR(loss, 0.10, 0.008);
  EXPECT_NEAR(static_cast<double>(twice) / delivered.size(), 0.02, 0.004);
  EXPECT_GT(out_of_order, kDatagrams / 20);  // 20 ms of jitter at 1 datagram/ms reorders a lot
}

TEST(DelayQueue, TiesKeepPushOrderAndBoundsAreEnforced) {
  DelayQueue queue(3, 65536);
  const uint8_t b[1] = {0};
  EXPECT_TRUE(queue.Push(1.0, 1, b));
  EXPECT_TRUE(queue.Push(1.0, 2, b));
  EXPECT_TRUE(queue.Push(0.5, 3, b));
  EXPECT_FALSE(queue.Push(0.1, 4, b));  // 3 items at most
  std::vector<uint64_t> order;
  EXPECT_EQ(queue.PopDue(0.9, [&](uint64_t t, auto, double) { order.push_back(t); }), 1u);
  EXPECT_EQ(queue.PopDue(2.0, [&](uint64_t t, auto, double) { order.push_back(t); }), 2u);
  EXPECT_EQ(order, (std::vector<uint64_t>{3, 1, 2}));

  DelayQueue small(100, 65536);
  std::vector<uint8_t> big(40000);
  EXPECT_TRUE(small.Push(0, 1, big));
  EXPECT_FALSE(small.Push(0, 2, big));  // 80000 bytes > 65536
  EXPECT_EQ(small.bytes(), 40000u);
}

#ifdef EDGEPHYS_UDP_IMPAIR_BINARY
// The real tool on loopback: an echo "upstream", one client sending numbered datagrams. Checks
// that replies come back to the client from the proxy's address, and the round-trip rates
// (two impaired passes: 0.9^2 survive, duplicates from either pass).
TEST(UdpImpair, ForwardsAndImpairsBothDirectionsOnLoopback) {
  auto any = Endpoint(asio::ip::make_address("127.0.0.1"), 0);
  auto echo = UdpSocket::Open(any);
  auto client = UdpSocket::Open(any);
  ASSERT_TRUE(echo.ok() && client.ok());
  // Find a free port for the proxy: bind, note, close (a small race, loopback only).
  uint16_t port;
  {
    auto probe = UdpSocket::Open(any);
    ASSERT_TRUE(probe.ok());
    port = (*probe)->LocalEndpoint().port();
  }
  const std::string listen = "127.0.0.1:" + std::to_string(port);
  const std::string upstream = "127.0.0.1:" + std::to_string((*echo)->LocalEndpoint().port());
  std::vector<std::string> args = {EDGEPHYS_UDP_IMPAIR_BINARY, "--listen", listen, "--upstream",
                                   upstream, "--loss", "0.1", "--delay-ms", "30", "--jitter-ms",
                                   "10", "--duplicate", "0.02", "--reorder", "0.05", "--seed",
                                   "5", "--max-seconds", "30"};
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid;
  ASSERT_EQ(posix_spawn(&pid, argv[0], nullptr, nullptr, argv.data(), environ), 0);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));

  const Endpoint proxy(asio::ip::make_address("127.0.0.1"), port);
  constexpr uint32_t kDatagrams = 4000;
  std::map<uint32_t, int> back;
  uint32_t reached_upstream = 0;
  Endpoint upstream_peer;
  auto drain = [&] {
    uint8_t buf[64];
    Endpoint from;
    while (size_t n = (*echo)->ReceiveFrom(&from, buf)) {
      ++reached_upstream;
      upstream_peer = from;
      (void)(*echo)->SendTo(from, std::span<const uint8_t>(buf, n));
    }
    while (size_t n = (*client)->ReceiveFrom(&from, buf)) {
      EXPECT_EQ(from, proxy);
      uint32_t i;
      ASSERT_EQ(n, 4u);
      std::memcpy(&i, buf, 4);
      ++back[i];
    }
  };
  for (uint32_t i = 0; i < kDatagrams; ++i) {
    uint8_t bytes[4];
    std::memcpy(bytes, &i, 4);
    ASSERT_TRUE((*client)->SendTo(proxy, bytes).ok());
    drain();
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
  const auto until = std::chrono::steady_clock::now() + std::chrono::milliseconds(500);
  while (std::chrono::steady_clock::now() < until) {
    drain();
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  kill(pid, SIGTERM);
  int status = 0;
  ASSERT_EQ(waitpid(pid, &status, 0), pid);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);

  EXPECT_NE(upstream_peer.port(), (*client)->LocalEndpoint().port());  // its own socket
  const double up_rate = static_cast<double>(reached_upstream) / kDatagrams;  // ~0.9 * 1.02
  EXPECT_GT(up_rate, 0.87);
  EXPECT_LT(up_rate, 0.97);
  const double round_trip = static_cast<double>(back.size()) / kDatagrams;  // ~0.81 + dup share
  EXPECT_GT(round_trip, 0.77);
  EXPECT_LT(round_trip, 0.87);
  int twice = 0;
  for (const auto& [i, n] : back) twice += n >= 2;
  EXPECT_GT(twice, 0);
}
#endif

}  // namespace
}  // namespace edgephys::netem
