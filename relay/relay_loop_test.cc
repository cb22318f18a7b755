// The relay driven as edgephys-relay's loop drives it (relay/main.cc): Update() runs only when
// Relay::NextDeadline() (capped by the loop's longest sleep) has come, never because a datagram
// arrived, and the socket is drained in recvmmsg batches. Handshakes, joins, poses and reliable
// events must still flow, with poses no later than the room's next tick and events no later
// than that tick or the connections' reliable hold.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "protocol/batched_socket.h"
#include "tests/integration/harness.h"

namespace edgephys {
namespace {

using schema::EntityFlags;
using testing::MintToken;

constexpr char kRoom[] = "loop";
constexpr double kMaxSleep = 0.02;  // the loop's cap in these tests (edgephys-relay: 10 ms)
constexpr double kTick = 1.0 / 60;

class SleepingLoopWorld {
 public:
  SleepingLoopWorld() {
    RelayConfig config = testing::LoopbackWorld::DefaultConfig();
    config.room_defaults.tick_rate_hz = 60;
    config.physics_threads = 1;
    config.connection.max_reliable_delay_s = 0.02;  // --reliable-delay 0.02 (off by default)
    socket_ = std::move(*UdpSocket::Open(Endpoint(asio::ip::make_address("127.0.0.1"), 0)));
    batched_ = std::make_unique<BatchedSocket>(socket_.get(), /*batch_sends=*/false);
    relay_ = std::make_unique<Relay>(config, batched_.get(), &counters_);
    start_ = std::chrono::steady_clock::now();
  }

  double Now() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }

  Client& AddClient(uint32_t player) {
    sockets_.push_back(std::move(*UdpSocket::Open(Endpoint(asio::ip::make_address("127.0.0.1"), 0))));
    clients_.push_back(std::make_unique<Client>(ClientConfig{}, sockets_.back().get()));
    (void)clients_.back()->Connect(ToRelayAddress(socket_->LocalEndpoint()),
                                   MintToken(kRoom, player), Now());
    return *clients_.back();
  }

  // The clients are pumped every 0.5 ms; the relay only at its deadline, as main.cc sleeps.
  void Step() {
    const double now = Now();
    if (now >= next_wake_) {
      relay_->Update(now, testing::UnixNow());
      ++relay_updates_;
      next_wake_ = std::min(relay_->NextDeadline(), now + kMaxSleep);
      EXPECT_GT(next_wake_, now - 1.0);  // a deadline in the distant past would spin the loop
    }
    for (auto& c : clients_) c->Update(now);
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }

  bool RunUntil(const std::function<bool()>& done, double timeout_s) {
    const double deadline = Now() + timeout_s;
    while (Now() < deadline) {
      Step();
      if (done()) return true;
    }
    return done();
  }

  uint64_t relay_updates() const { return relay_updates_; }
  const RelayCounters& counters() const { return counters_; }

 private:
  RelayCounters counters_;
  std::unique_ptr<UdpSocket> socket_;
  std::unique_ptr<BatchedSocket> batched_;
  std::unique_ptr<Relay> relay_;
  std::vector<std::unique_ptr<UdpSocket>> sockets_;
  std::vector<std::unique_ptr<Client>> clients_;
  std::chrono::steady_clock::time_point start_;
  double next_wake_ = 0;
  uint64_t relay_updates_ = 0;
};

bool ConnectAndJoin(SleepingLoopWorld& world, Client& c) {
  if (!world.RunUntil([&] { return c.state() == ClientState::kConnected; }, 2.0)) return false;
  (void)c.JoinRoom(kRoom);
  return world.RunUntil([&] { return c.joined(); }, 2.0);
}

TEST(RelayLoop, ClientsConnectJoinAndExchangePosesWithoutAWakeUpPerDatagram) {
  SleepingLoopWorld world;
  std::vector<Client*> clients;
  for (uint32_t p = 1; p <= 6; ++p) clients.push_back(&world.AddClient(p));
  for (Client* c : clients) ASSERT_TRUE(ConnectAndJoin(world, *c));
  std::vector<uint32_t> ids;
  for (Client* c : clients) {
    SpawnDesc d;
    d.position = {0, 1, 0};
    auto id = c->Spawn(d);
    ASSERT_TRUE(id.ok());
    ids.push_back(*id);
  }
  // Everyone publishes a moving pose every client step for a second.
  const uint64_t received_before = world.counters().packets_received.load();
  const uint64_t updates_before = world.relay_updates();
  const double start = world.Now();
  float x = 0;
  world.RunUntil(
      [&] {
        x += 0.001f;
        for (size_t i = 0; i < clients.size(); ++i) {
          (void)clients[i]->PublishTransform(ids[i], {x, 1, static_cast<float>(i)}, Quatf{});
        }
        return false;
      },
      1.0);
  const double seconds = world.Now() - start;
  const double received = static_cast<double>(world.counters().packets_received.load() - received_before);
  const double updates = static_cast<double>(world.relay_updates() - updates_before);
  // The room's ticks and the connections' timers, not the datagrams, set the pace.
  EXPECT_GT(received / seconds, 300.0);
  EXPECT_LT(updates / seconds, 1.0 / kTick + 1.0 / kMaxSleep);
  EXPECT_LT(updates, 0.5 * received) << updates << " updates for " << received << " datagrams";
  // Every member has every other member's latest pose (within the 1 mm lattice).
  ASSERT_TRUE(world.RunUntil(
      [&] {
        for (size_t i = 0; i < clients.size(); ++i) {
          for (size_t j = 0; j < clients.size(); ++j) {
            if (i == j) continue;
            const RemoteEntity* e = clients[j]->FindEntity(ids[i]);
            if (e == nullptr || !e->has_state || std::fabs(e->state.position.x - x) > 0.001f) {
              return false;
            }
          }
        }
        return true;
      },
      1.0));
}

TEST(RelayLoop, PosesLeaveOnTheNextTickAndEventsWithinTheHold) {
  SleepingLoopWorld world;
  Client& a = world.AddClient(1);
  Client& b = world.AddClient(2);
  ASSERT_TRUE(ConnectAndJoin(world, a));
  ASSERT_TRUE(ConnectAndJoin(world, b));
  // A hand: the critical class (48 Hz on the room's send grid), as the ccu bots' hands.
  SpawnDesc d{.position = {0, 1, 0}, .flags = static_cast<uint32_t>(EntityFlags::Hand)};
  auto id = a.Spawn(d);
  ASSERT_TRUE(id.ok());
  ASSERT_TRUE(world.RunUntil([&] { return b.FindEntity(*id) != nullptr; }, 1.0));

  // Poses: from publish to the other member's decode. The client publishes at its send rate
  // (60 Hz); the relay drains it at its next wake, which is no later than the room's next
  // tick, and sends it on the first tick at or after the hand's next 48 Hz grid point: at most
  // one client interval, one grid interval and one tick, plus the test's 0.5 ms steps.
  double worst_pose = 0;
  for (int i = 1; i <= 20; ++i) {
    const float x = 0.05f * static_cast<float>(i);
    const double t0 = world.Now();
    (void)a.PublishTransform(*id, {x, 1, 0}, Quatf{});
    ASSERT_TRUE(world.RunUntil(
        [&] {
          const RemoteEntity* e = b.FindEntity(*id);
          return e != nullptr && e->has_state && std::fabs(e->state.position.x - x) < 0.001f;
        },
        1.0))
        << i;
    worst_pose = std::max(worst_pose, world.Now() - t0);
  }
  EXPECT_LT(worst_pose, 2 * kTick + 1.0 / 48 + 0.008) << "worst pose latency " << worst_pose;

  // Events (a Spawn broadcast): sent by the client at once, drained by the relay's next
  // wake (a tick or the cap), then held at most until the next tick's state datagram or the
  // 20 ms hold, whichever comes first.
  double worst_event = 0;
  for (int i = 0; i < 10; ++i) {
    SpawnDesc e;
    e.position = {static_cast<float>(i), 2, 0};
    const double t0 = world.Now();
    auto spawned = a.Spawn(e);
    ASSERT_TRUE(spawned.ok());
    ASSERT_TRUE(world.RunUntil([&] { return b.FindEntity(*spawned) != nullptr; }, 1.0)) << i;
    worst_event = std::max(worst_event, world.Now() - t0);
    world.RunUntil([] { return false; }, 0.013 * (i % 3));  // vary the phase against the tick
  }
  EXPECT_LT(worst_event, kTick + 0.02 + 0.012) << "worst event latency " << worst_event;
}

}  // namespace
}  // namespace edgephys
