// Issue 35 item 1: 200 slow admin sockets and 50 slow /metrics sockets (one header byte every
// 2 s, reconnecting 100 ms after being cut off), first all from 127.0.0.1 (the prober's own
// address), then from 127.0.0.2..127.0.0.201: /healthz answers 200 in under 1 s throughout,
// /metrics scrapes succeed, and a room's update rate on the same relay holds.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <httplib.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <map>
#include <mutex>
#include <thread>

#include "metrics/metrics_exporter.h"
#include "relay/relay_metrics.h"
#include "relay/admin/admin_http.h"
#include "relay/admin/relay_admin.h"
#include "relay/admin/testing/loopback_admin.h"
#include "tests/integration/harness.h"

namespace edgephys::testing {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

int ConnectFrom(const std::string& from, uint16_t port) {
  int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in local{};
  local.sin_family = AF_INET;
  inet_pton(AF_INET, from.c_str(), &local.sin_addr);
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_port = htons(port);
  inet_pton(AF_INET, "127.0.0.1", &to.sin_addr);
  if (::bind(fd, reinterpret_cast<sockaddr*>(&local), sizeof(local)) != 0 ||
      ::connect(fd, reinterpret_cast<sockaddr*>(&to), sizeof(to)) != 0) {
    ::close(fd);
    return -1;
  }
  return fd;
}

// Keeps `count` slow sockets open against each target until stopped.
class Slowloris {
 public:
  struct Target {
    uint16_t port;
    int count;
    const char* path;
  };
  Slowloris(std::vector<Target> targets, bool many_addresses)
      : targets_(std::move(targets)), many_(many_addresses), thread_([this] { Run(); }) {}
  ~Slowloris() {
    stop_ = true;
    thread_.join();
  }
  uint64_t reconnects() const { return reconnects_; }
  int open() const { return open_; }

 private:
  struct Sock {
    int fd = -1;
    uint16_t port;
    std::string from, request;
    size_t sent = 0;
    Clock::time_point next;
  };
  void Run() {
    std::vector<Sock> socks;
    int n = 0;
    for (const Target& t : targets_) {
      for (int i = 0; i < t.count; ++i, ++n) {
        Sock s;
        s.port = t.port;
        s.from = many_ ? "127.0.0." + std::to_string(2 + n % 200) : "127.0.0.1";
        s.request = std::string("GET ") + t.path + " HTTP/1.1\r\nHost: x\r\nX-Pad: " +
                    std::string(200, 'a') + "\r\n\r\n";
        s.next = Clock::now();
        socks.push_back(std::move(s));
      }
    }
    while (!stop_) {
      int live = 0;
      for (Sock& s : socks) {
        const auto now = Clock::now();
        if (s.fd < 0) {
          if (now < s.next) continue;
          s.fd = ConnectFrom(s.from, s.port);
          s.sent = 0;
          s.next = now;
          if (s.fd < 0) {
            s.next = now + 100ms;
            continue;
          }
        }
        ++live;
        // Cut off by the server (408, eviction): reconnect after 100 ms.
        pollfd p{s.fd, POLLIN, 0};
        if (::poll(&p, 1, 0) > 0) {
          ::close(s.fd);
          s.fd = -1;
          s.next = now + 100ms;
          ++reconnects_;
          continue;
        }
        if (now >= s.next && s.sent + 3 < s.request.size()) {
          (void)::send(s.fd, &s.request[s.sent++], 1, MSG_NOSIGNAL);
          s.next = now + 2s;
        }
      }
      open_ = live;
      std::this_thread::sleep_for(10ms);
    }
    for (Sock& s : socks) {
      if (s.fd >= 0) ::close(s.fd);
    }
  }
  std::vector<Target> targets_;
  bool many_;
  std::atomic<bool> stop_{false};
  std::atomic<uint64_t> reconnects_{0};
  std::atomic<int> open_{0};
  std::thread thread_;
};

struct Counts : ClientListener {
  std::map<uint32_t, int> updates;
  void OnEntityUpdated(const RemoteEntity& e) override { ++updates[e.id]; }
};

TEST(AdminSlowloris, HealthMetricsAndRoomsSurviveSlowClients) {
  LoopbackWorld world;
  admin::RelayAdmin backend(&world.relay(), LoopbackWorld::DefaultConfig().room_defaults);
  admin::AdminHttpOptions options;
  options.key = "k";
  const std::unique_ptr<admin::AdminHttpServer> admin_http = StartLoopbackAdmin(options, &backend);
  ASSERT_NE(admin_http, nullptr);
  const uint16_t admin_port = static_cast<uint16_t>(AdminPort(*admin_http));
  auto metrics = MetricsExporter::Start("127.0.0.1:0", RelayMetrics(&world.counters()));
  ASSERT_TRUE(metrics.ok()) << metrics.status().ToString();
  const uint16_t metrics_port = (*metrics)->port();

  Counts a_log, b_log;
  Client& a = world.AddClient(MintToken("r", 1), &a_log);
  Client& b = world.AddClient(MintToken("r", 2), &b_log);
  for (Client* c : {&a, &b}) {
    ASSERT_TRUE(world.RunUntil([&] { backend.Tick(world.Now()); return c->state() == ClientState::kConnected; }, 3.0));
    ASSERT_TRUE(c->JoinRoom("r").ok());
  }
  ASSERT_TRUE(world.RunUntil([&] { return a.joined() && b.joined(); }, 3.0));
  std::vector<uint32_t> ids;
  for (int i = 0; i < 4; ++i) ids.push_back(*a.Spawn({.position = {float(i), 0, 0}}));
  ASSERT_TRUE(world.RunUntil([&] { return b.entities().size() == 4; }, 3.0));

  // Probes from 127.0.0.1 every 250 ms: /healthz on the admin port, /metrics every second.
  std::atomic<bool> probing{true};
  std::atomic<int> health_ok{0}, health_bad{0}, scrapes_ok{0}, scrapes_bad{0};
  std::atomic<int64_t> worst_health_ms{0};
  std::thread prober([&] {
    for (int i = 0; probing; ++i) {
      httplib::Client h("127.0.0.1", admin_port);
      h.set_connection_timeout(3);
      h.set_read_timeout(3);
      auto t0 = Clock::now();
      auto r = h.Get("/healthz");
      int64_t ms = std::chrono::duration_cast<std::chrono::milliseconds>(Clock::now() - t0).count();
      if (r && r->status == 200 && ms < 1000) {
        ++health_ok;
      } else {
        ++health_bad;
      }
      if (ms > worst_health_ms) worst_health_ms = ms;
      if (i % 4 == 0) {
        httplib::Client m("127.0.0.1", metrics_port);
        m.set_connection_timeout(3);
        m.set_read_timeout(3);
        auto s = m.Get("/metrics");
        if (s && s->status == 200 && s->body.find("edgephys_clients") != std::string::npos) {
          ++scrapes_ok;
        } else {
          ++scrapes_bad;
        }
      }
      std::this_thread::sleep_for(250ms);
    }
  });

  auto phase = [&](double seconds) {
    b_log.updates.clear();
    double next = world.Now();
    world.RunFor(seconds, [&](double now) {
      backend.Tick(now);
      if (now >= next) {
        next += 1.0 / 12.0;
        for (uint32_t id : ids) (void)a.PublishTransform(id, {float(now), 1, float(id % 5)}, {});
      }
    });
    int total = 0;
    for (uint32_t id : ids) total += b_log.updates[id];
    return total / seconds;
  };
  const double baseline = phase(3.0);
  EXPECT_GT(baseline, 4 * 12 * 0.9);
  for (bool many : {false, true}) {
    health_ok = health_bad = scrapes_ok = scrapes_bad = 0;
    uint64_t reconnects = 0;
    int open = 0;
    double rate = 0;
    {
      Slowloris attack({{admin_port, 200, "/healthz"}, {metrics_port, 50, "/metrics"}}, many);
      rate = phase(8.0);
      reconnects = attack.reconnects();
      open = attack.open();
    }
    SCOPED_TRACE(many ? "from 200 addresses" : "from 127.0.0.1");
    EXPECT_GT(open, 0);
    EXPECT_GT(reconnects, 0u) << "the gate never cut a slow socket off";
    EXPECT_GE(health_ok.load(), 20);
    EXPECT_EQ(health_bad.load(), 0) << "worst /healthz: " << worst_health_ms << " ms";
    EXPECT_GE(scrapes_ok.load(), 5);
    EXPECT_EQ(scrapes_bad.load(), 0);
    EXPECT_NEAR(rate, baseline, baseline * 0.10) << "the room's rate changed under the attack";
  }
  probing = false;
  prober.join();
  backend.Close();
}

}  // namespace
}  // namespace edgephys::testing
