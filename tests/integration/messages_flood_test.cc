// A hostile player floods its room with application messages (reliable and unreliable) and
// property writes as fast as its thread can call the SDK; honest players in another room keep
// their update rate (within 10 % of their rate before the flood), and the flood is refused and
// counted by the relay. Real loopback UDP: the relay runs on its own thread (as the relay
// binary does), the flooder on another, the honest clients on the test thread. Every loop is
// bounded in time; no assertion on speed, only on the honest room's rate against itself.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cmath>
#include <map>
#include <thread>

#include "tests/integration/harness.h"

namespace edgephys::testing {
namespace {

using Clock = std::chrono::steady_clock;

struct UpdateCounter : ClientListener {
  std::map<uint32_t, uint64_t> updates;
  void OnEntityUpdated(const RemoteEntity& e) override { ++updates[e.id]; }
};

class ThreadedRelay {
 public:
  explicit ThreadedRelay(const RelayConfig& config) {
    socket_ = std::move(*UdpSocket::Open(Endpoint(asio::ip::make_address("127.0.0.1"), 0)));
    relay_ = std::make_unique<Relay>(config, socket_.get(), &counters_);
    thread_ = std::thread([this] {
      while (!stop_.load()) {
        relay_->Update(Now(), UnixNow());
        std::this_thread::sleep_for(std::chrono::microseconds(200));
      }
    });
  }
  ~ThreadedRelay() {
    stop_.store(true);
    thread_.join();
  }
  double Now() const { return std::chrono::duration<double>(Clock::now() - start_).count(); }
  RelayAddress address() const { return ToRelayAddress(socket_->LocalEndpoint()); }
  const RelayCounters& counters() const { return counters_; }

 private:
  const Clock::time_point start_ = Clock::now();
  RelayCounters counters_;
  std::unique_ptr<UdpSocket> socket_;
  std::unique_ptr<Relay> relay_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

// A client with its own socket, pumped by whichever thread owns it.
struct Peer {
  Peer(ThreadedRelay& relay, const std::vector<uint8_t>& token, ClientListener* listener) {
    socket = std::move(*UdpSocket::Open(Endpoint(asio::ip::make_address("127.0.0.1"), 0)));
    client = std::make_unique<Client>(ClientConfig{}, socket.get(), listener);
    (void)client->Connect(relay.address(), token, relay.Now());
  }
  std::unique_ptr<UdpSocket> socket;
  std::unique_ptr<Client> client;
};

TEST(MessagesFlood, HonestClientsInAnotherRoomKeepTheirUpdateRate) {
  RelayConfig config = LoopbackWorld::DefaultConfig();
  config.room_defaults.replication.fixed_rate_hz = 30;  // every moving entity at the tick rate
  ThreadedRelay relay(config);
  UpdateCounter b1_seen, b2_seen;
  Peer flooder(relay, MintToken("a", 1), nullptr);
  Peer a_honest(relay, MintToken("a", 2), nullptr);
  Peer b1(relay, MintToken("b", 11), &b1_seen);
  Peer b2(relay, MintToken("b", 12), &b2_seen);
  std::vector<Peer*> honest = {&a_honest, &b1, &b2};
  const auto pump = [&](Peer* also = nullptr) {
    const double now = relay.Now();
    for (Peer* p : honest) p->client->Update(now);
    if (also != nullptr) also->client->Update(now);
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  };
  const auto run_until = [&](const std::function<bool()>& done, double timeout_s, Peer* also) {
    const double end = relay.Now() + timeout_s;
    while (relay.Now() < end && !done()) pump(also);
    return done();
  };
  std::vector<std::pair<Peer*, const char*>> joins = {
      {&flooder, "a"}, {&a_honest, "a"}, {&b1, "b"}, {&b2, "b"}};
  ASSERT_TRUE(run_until([&] {
    for (auto [p, room] : joins) {
      if (p->client->state() != ClientState::kConnected) return false;
    }
    return true;
  }, 5.0, &flooder));
  for (auto [p, room] : joins) ASSERT_TRUE(p->client->JoinRoom(room).ok());
  ASSERT_TRUE(run_until([&] {
    for (auto [p, room] : joins) {
      if (!p->client->joined()) return false;
    }
    return true;
  }, 5.0, &flooder));

  // Room B: each honest client moves one entity, published at the SDK's 30 Hz.
  auto e1 = b1.client->Spawn(SpawnDesc{.position = {0, 1, 0}});
  auto e2 = b2.client->Spawn(SpawnDesc{.position = {1, 1, 0}});
  ASSERT_TRUE(e1.ok() && e2.ok());
  const auto move = [&](double now) {
    const float x = static_cast<float>(std::sin(now));
    (void)b1.client->PublishTransform(*e1, {x, 1, 0}, {});
    (void)b2.client->PublishTransform(*e2, {1, 1, x}, {});
  };
  // B's received updates per second over `seconds` (both directions together).
  const auto b_rate = [&](double seconds, Peer* also) {
    const uint64_t before = b1_seen.updates[*e2] + b2_seen.updates[*e1];
    const double start = relay.Now(), end = start + seconds;
    while (relay.Now() < end) {
      move(relay.Now());
      pump(also);
    }
    return static_cast<double>(b1_seen.updates[*e2] + b2_seen.updates[*e1] - before) /
           (relay.Now() - start);
  };
  (void)b_rate(0.5, &flooder);  // both entities spawned and streaming
  const double rate_before = b_rate(2.0, &flooder);
  ASSERT_GT(rate_before, 30.0);  // ~2 x 30 updates/s (not a speed check: a sanity check)

  const auto rate_limited = [&] {
    return RequestsRejected(relay.counters(), schema::RejectReason::RateLimited) +
           Rejected(relay.counters(), DropReason::kRateLimited);
  };
  const uint64_t limited_before = rate_limited();
  // The flooder, on its own thread, for 3 s: batches of unreliable and reliable messages and
  // property writes, each call repeated until the SDK refuses (a full reliable queue) or the
  // batch is done, then an Update, then the next batch at once (a 0.2 ms pause lets the
  // shared test machine's other threads run).
  std::atomic<uint64_t> sent_unreliable{0}, sent_reliable{0}, sent_properties{0};
  std::atomic<bool> flooding{true};
  const double flood_end = relay.Now() + 3.0;
  std::thread flood([&] {
    const std::vector<uint8_t> small(32, 0xab), large(1000, 0xcd);
    Client& c = *flooder.client;
    while (relay.Now() < flood_end) {
      for (int i = 0; i < 64; ++i) {
        if (c.SendMessageUnreliable(MessageTarget::kRoom, 0, i % 2 ? small : large).ok()) {
          ++sent_unreliable;
        }
      }
      for (int i = 0; i < 16; ++i) {
        if (!c.SendMessage(MessageTarget::kOthers, 0, large).ok()) break;
        ++sent_reliable;
      }
      for (int i = 0; i < 16; ++i) {
        if (!c.SetProperty(0, "flood", PropertyValue::Int64(i), PropertyAuthority::kAnyone).ok()) {
          break;
        }
        ++sent_properties;
      }
      c.Update(relay.Now());
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
    flooding.store(false);
  });
  (void)b_rate(0.3, nullptr);  // the flood under way
  const double rate_during = b_rate(2.5, nullptr);
  while (flooding.load()) pump();
  flood.join();

  EXPECT_GT(sent_unreliable.load() + sent_reliable.load(), 10000u);
  EXPECT_GT(sent_properties.load(), 1000u);
  EXPECT_GT(rate_limited() - limited_before, 5000u);  // the flood was refused and counted
  EXPECT_NEAR(rate_during, rate_before, 0.10 * rate_before)
      << "before " << rate_before << "/s, during " << rate_during << "/s";
  std::printf("honest room B: %.1f updates/s before, %.1f during the flood; flood: %llu "
              "unreliable, %llu reliable messages, %llu property writes sent, %llu refused or "
              "dropped by rate\n",
              rate_before, rate_during, static_cast<unsigned long long>(sent_unreliable.load()),
              static_cast<unsigned long long>(sent_reliable.load()),
              static_cast<unsigned long long>(sent_properties.load()),
              static_cast<unsigned long long>(rate_limited() - limited_before));
  RecordProperty("rate_before", std::to_string(rate_before));
  RecordProperty("rate_during", std::to_string(rate_during));
}

}  // namespace
}  // namespace edgephys::testing
