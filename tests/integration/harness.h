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

// A relay on an ephemeral loopback UDP port plus clients, all pumped from the test thread with
// the real monotonic clock.
class LoopbackWorld {
 public:
  explicit LoopbackWorld(RelayConfig config = DefaultConfig(), const char* host = "127.0.0.1") {
    auto address = asio::ip::make_address(host);
    relay_socket_ = std::move(*UdpSocket::Open(Endpoint(address, 0)));
    relay_ = std::make_unique<Relay>(config, relay_socket_.get(), &counters_);
    client_config_.require_packet_auth = config.packet_auth;  // a relay without it: accept that
    start_ = std::chrono::steady_clock::now();
  }

  static RelayConfig DefaultConfig() {
    RelayConfig c;
    c.secret = kSecret;
    c.room_defaults.tick_rate_hz = 30;
    return c;
  }

  double Now() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }

  // A client with its own loopback socket, connecting with `token`.
  Client& AddClient(const std::vector<uint8_t>& token, ClientListener* listener = nullptr) {
    auto address = relay_socket_->LocalEndpoint().address();
    sockets_.push_back(std::move(*UdpSocket::Open(Endpoint(address, 0))));
    clients_.push_back(std::make_unique<Client>(client_config_, sockets_.back().get(), listener));
    (void)clients_.back()->Connect(ToRelayAddress(relay_socket_->LocalEndpoint()), token, Now());
    return *clients_.back();
  }

  void Step() {
    double now = Now();
    relay_->Update(now, UnixNow());
    for (auto& c : clients_) c->Update(now);
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }

  // Pumps until `done` returns true or `timeout_s` passes; returns done().
  bool RunUntil(const std::function<bool()>& done, double timeout_s) {
    double deadline = Now() + timeout_s;
    while (Now() < deadline) {
      Step();
      if (done()) return true;
    }
    return done();
  }

  void RunFor(double seconds, const std::function<void(double)>& each = nullptr) {
    double end = Now() + seconds;
    while (Now() < end) {
      if (each) each(Now());
      Step();
    }
  }

  Relay& relay() { return *relay_; }
  RelayCounters& counters() { return counters_; }
  Endpoint relay_endpoint() const { return relay_socket_->LocalEndpoint(); }

 private:
  RelayCounters counters_;
  std::unique_ptr<UdpSocket> relay_socket_;
  std::unique_ptr<Relay> relay_;
  ClientConfig client_config_;  // AddClient's
  std::vector<std::unique_ptr<UdpSocket>> sockets_;
  std::vector<std::unique_ptr<Client>> clients_;
  std::chrono::steady_clock::time_point start_;
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

}  // namespace edgephys::testing
