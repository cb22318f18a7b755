// Test harness: a relay and clients in one thread, on real loopback UDP (real clock) or on an
// InMemoryNetwork with a NetworkSimulator (fake clock, deterministic).
#pragma once

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <functional>
#include <initializer_list>
#include <memory>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "client/client.h"
#include "client/client_endpoint.h"
#include "protocol/container_builder.h"
#include "protocol/handshake.h"
#include "protocol/join_token.h"
#include "protocol/udp_socket.h"
#include "relay/relay.h"

namespace edgephys::testing {

inline constexpr char kSecret[] = "test-secret";

inline uint64_t UnixNow() {
  return static_cast<uint64_t>(std::chrono::duration_cast<std::chrono::seconds>(
                                   std::chrono::system_clock::now().time_since_epoch())
                                   .count());
}

inline std::vector<uint8_t> MintToken(const std::string& room, uint32_t player,
                                      int64_t ttl_s = 3600, uint32_t permissions = kDefaultPermissions,
                                      const std::string& secret = kSecret) {
  JoinToken t;
  t.room = room;
  t.player_id = player;
  t.permissions = permissions;
  t.expiry_unix_s = static_cast<uint64_t>(static_cast<int64_t>(UnixNow()) + ttl_s);
  t.nonce = SecureRandom64();
  return *SignJoinToken(t, secret);
}

// The relay part of a client token (what a Connect carries; the SDK splits it the same way).
// Bytes that are not a client token come back unchanged (tests send garbage on purpose).
inline std::vector<uint8_t> RelayPart(std::span<const uint8_t> client_token) {
  auto split = SplitClientToken(client_token);
  if (!split.ok()) return {client_token.begin(), client_token.end()};
  return {split->relay_token.begin(), split->relay_token.end()};
}
// The session secret of a client token (all zero if it is not one).
inline SessionSecret SecretOf(std::span<const uint8_t> client_token) {
  auto split = SplitClientToken(client_token);
  return split.ok() ? split->session_secret : SessionSecret{};
}

// The pumping loops of a test world (CRTP): Derived has Now() (seconds on its clock, real or
// fake) and Step() (one pump of the relay(s) and clients).
template <typename Derived>
class Pumped {
 public:
  // Pumps until `done` returns true or `timeout_s` passes; returns done().
  bool RunUntil(const std::function<bool()>& done, double timeout_s) {
    const double deadline = self().Now() + timeout_s;
    while (self().Now() < deadline) {
      self().Step();
      if (done()) return true;
    }
    return done();
  }

  // Pumps for `seconds`, calling `each(now)` (if given) before every step.
  void RunFor(double seconds, const std::function<void(double)>& each = nullptr) {
    const double end = self().Now() + seconds;
    while (self().Now() < end) {
      if (each) each(self().Now());
      self().Step();
    }
  }

 private:
  Derived& self() { return static_cast<Derived&>(*this); }
};

// Seconds of the real monotonic clock since construction (or the last Restart()).
class WallClock {
 public:
  double Now() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }
  void Restart() { start_ = std::chrono::steady_clock::now(); }

 private:
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
};

// Clients on loopback UDP sockets of their own, pumped from the test thread.
class LoopbackClients {
 public:
  // A client with `config` on a socket bound to an ephemeral port of `bind`, connecting to
  // `relay` with `token` at `now`.
  Client& Add(const ClientConfig& config, ClientListener* listener, const asio::ip::address& bind,
              const RelayAddress& relay, const std::vector<uint8_t>& token, double now) {
    auto opened = UdpSocket::Open(Endpoint(bind, 0));
    EXPECT_TRUE(opened.ok()) << bind.to_string();
    sockets_.push_back(std::move(*opened));
    clients_.push_back(std::make_unique<Client>(config, sockets_.back().get(), listener));
    (void)clients_.back()->Connect(relay, token, now);
    return *clients_.back();
  }

  void Update(double now) {
    for (auto& c : clients_) c->Update(now);
  }

  UdpSocket& socket(size_t i) { return *sockets_[i]; }
  const std::vector<std::unique_ptr<Client>>& all() const { return clients_; }

 private:
  std::vector<std::unique_ptr<UdpSocket>> sockets_;
  std::vector<std::unique_ptr<Client>> clients_;
};

// What the loopback worlds (LoopbackWorld, the sharded relay's) share: the relay's socket on an
// ephemeral loopback port and its counters, clients on sockets of their own, and the real
// clock. The derived world starts its relay on socket_ and counters_, then RestartClock().
class LoopbackWorldBase {
 public:
  double Now() const { return clock_.Now(); }
  RelayCounters& counters() { return counters_; }
  Endpoint relay_endpoint() const { return socket_->LocalEndpoint(); }
  UdpSocket& client_socket(size_t i) { return clients_.socket(i); }

 protected:
  explicit LoopbackWorldBase(const asio::ip::address& address)
      : socket_(std::move(*UdpSocket::Open(Endpoint(address, 0)))) {}

  // A client with `config` on a socket bound to `bind`, connecting to the relay with `token`.
  Client& Connect(const ClientConfig& config, ClientListener* listener,
                  const asio::ip::address& bind, const std::vector<uint8_t>& token) {
    return clients_.Add(config, listener, bind, ToRelayAddress(relay_endpoint()), token, Now());
  }
  void UpdateClients(double now) { clients_.Update(now); }
  void RestartClock() { clock_.Restart(); }

  RelayCounters counters_;
  std::unique_ptr<UdpSocket> socket_;

 private:
  LoopbackClients clients_;
  WallClock clock_;
};

// A relay on an ephemeral loopback UDP port plus clients, all pumped from the test thread with
// the real monotonic clock.
class LoopbackWorld : public LoopbackWorldBase, public Pumped<LoopbackWorld> {
 public:
  explicit LoopbackWorld(RelayConfig config = DefaultConfig(), const char* host = "127.0.0.1")
      : LoopbackWorldBase(asio::ip::make_address(host)) {
    relay_ = std::make_unique<Relay>(config, socket_.get(), &counters_);
    client_config_.require_packet_auth = config.packet_auth;  // a relay without it: accept that
    RestartClock();
  }

  static RelayConfig DefaultConfig() {
    RelayConfig c;
    c.secret = kSecret;
    c.room_defaults.tick_rate_hz = 30;
    return c;
  }

  // A client with its own loopback socket, connecting with `token`.
  Client& AddClient(const std::vector<uint8_t>& token, ClientListener* listener = nullptr) {
    return Connect(client_config_, listener, relay_endpoint().address(), token);
  }

  void Step() {
    double now = Now();
    relay_->Update(now, UnixNow());
    UpdateClients(now);
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }

  Relay& relay() { return *relay_; }

 private:
  std::unique_ptr<Relay> relay_;
  ClientConfig client_config_;  // AddClient's
};

// Pumps `world` (a LoopbackWorld or a SimWorld) until every client is connected, has each join
// `room`, then pumps until every one has joined; each wait is bounded by `timeout_s`. Fails
// naming the step that did not finish.
template <typename World>
::testing::AssertionResult ConnectAndJoinAll(World& world, std::initializer_list<Client*> clients,
                                             const std::string& room, double timeout_s) {
  auto all = [&](auto pred) {
    for (Client* c : clients) {
      if (!pred(*c)) return false;
    }
    return true;
  };
  auto connected = [](Client& c) { return c.state() == ClientState::kConnected; };
  if (!world.RunUntil([&] { return all(connected); }, timeout_s)) {
    return ::testing::AssertionFailure() << "handshake did not finish";
  }
  for (Client* c : clients) {
    if (!c->JoinRoom(room).ok()) {
      return ::testing::AssertionFailure() << "JoinRoom(" << room << ") failed";
    }
  }
  if (!world.RunUntil([&] { return all([](Client& c) { return c.joined(); }); }, timeout_s)) {
    return ::testing::AssertionFailure() << "join of " << room << " did not finish";
  }
  return ::testing::AssertionSuccess();
}

// The set-up of the tests where a victim client the test pumps itself and another client share
// `room`: `pump(seconds, done)` pumps both (and the relay) until done() or `seconds` pass, and
// returns done(). Waits (3 s each) until both are connected, joins both to `room`, has the
// victim spawn a box at (1, 2, 3) and waits until the other has it; its id in *id. Fails
// fatally at the first step that does not finish.
template <typename Pump>
void JoinVictimAndSpawn(Pump& pump, Client& victim, Client& other, const char* room,
                        uint32_t* id) {
  ASSERT_TRUE(pump(3.0, [&] { return victim.state() == ClientState::kConnected &&
                                     other.state() == ClientState::kConnected; }));
  ASSERT_TRUE(victim.JoinRoom(room).ok());
  ASSERT_TRUE(other.JoinRoom(room).ok());
  ASSERT_TRUE(pump(3.0, [&] { return victim.joined() && other.joined(); }));
  Result<uint32_t> spawned = victim.Spawn({.position = {1, 2, 3}});
  ASSERT_TRUE(spawned.ok());
  *id = *spawned;
  ASSERT_TRUE(pump(3.0, [&] { return other.entities().count(*id) == 1; }));
}

// True if `a` is within the default edgephys encoder's stated precision of `b`: position
// step 1 mm (Euclidean error <= sqrt(3)/2 mm) and rotation error <= 0.1 degree.
inline bool WithinPrecision(const EntityState& a, const EntityState& b) {
  double dx = a.position.x - b.position.x, dy = a.position.y - b.position.y,
         dz = a.position.z - b.position.z;
  if (std::sqrt(dx * dx + dy * dy + dz * dz) > 0.000867) return false;
  double dot = std::fabs(double(a.rotation.x) * b.rotation.x + double(a.rotation.y) * b.rotation.y +
                         double(a.rotation.z) * b.rotation.z + double(a.rotation.w) * b.rotation.w);
  return dot >= std::cos(0.1 * 3.14159265358979 / 180.0 / 2.0) - 1e-7;
}

inline uint64_t Rejected(const RelayCounters& c, DropReason r) {
  return c.packets_rejected[static_cast<size_t>(r)].load();
}
inline uint64_t UpdatesRejected(const RelayCounters& c, DropReason r) {
  return c.updates_rejected[static_cast<size_t>(r)].load();
}
inline uint64_t RequestsRejected(const RelayCounters& c, schema::RejectReason r) {
  return c.requests_rejected[static_cast<size_t>(r)].load();
}
// Expects exactly `count` requests rejected for each reason of `expected`.
inline void ExpectRequestsRejected(
    const RelayCounters& c,
    std::initializer_list<std::pair<schema::RejectReason, uint64_t>> expected) {
  for (const auto& [reason, count] : expected) {
    EXPECT_EQ(RequestsRejected(c, reason), count) << schema::EnumNameRejectReason(reason);
  }
}

}  // namespace edgephys::testing
