// soak_driver: --bots SDK clients churning through rooms on a real relay, for scripts/soak.sh.
//
//   soak_driver --relay 127.0.0.1:7777 --secret S --bots 200 --rooms 40 --seconds 600
//
// Each bot connects with a fresh join token (a token grants one room), joins a random room,
// spawns 4 kinematic entities, moves them every frame, and after a random 5-30 s leaves,
// disconnects and reconnects (new socket, new player id) to another random room.
//
// Reliable-loss check: before a bot leaves (and once more at the end) the driver, which sees
// every bot, lists the other bots in the same room whose 4 spawns were sent at least --grace
// seconds ago while this bot had been in the room at least --grace seconds; each of those
// entities must have been reported by this bot's OnEntitySpawned exactly once (keyed by owner
// player id and entity id, so slot reuse is not a duplicate). expected - seen = lost.
// At --seconds every bot leaves and disconnects; one JSON summary line goes to stdout.
// Exit status: 0 when nothing was lost or duplicated and no session dropped unexpectedly.
#include <CLI/CLI.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <string>
#include <thread>
#include <unordered_map>
#include <vector>

#include "client/client.h"
#include "client/client_endpoint.h"
#include "protocol/endpoint.h"
#include "protocol/handshake.h"
#include "protocol/join_token.h"
#include "protocol/udp_socket.h"

namespace {

using namespace edgephys;

constexpr int kEntitiesPerBot = 4;

uint64_t UnixNow() {
  return static_cast<uint64_t>(std::chrono::duration_cast<std::chrono::seconds>(
                                   std::chrono::system_clock::now().time_since_epoch())
                                   .count());
}

uint64_t Key(uint32_t owner, uint32_t id) { return (uint64_t{owner} << 32) | id; }

struct Totals {
  uint64_t sessions = 0, expected = 0, seen = 0, lost = 0, duplicates = 0;
  uint64_t unexpected_disconnects = 0, failed_connects = 0, relay_errors = 0, spawns_sent = 0;
};

struct Bot : ClientListener {
  int index = 0;
  Totals* totals = nullptr;
  std::unique_ptr<UdpSocket> socket;
  std::unique_ptr<Client> client;
  uint32_t player = 0;
  std::string room;
  bool join_sent = false, joined = false, leaving = false;
  double connect_at = 0;       // when to (re)connect; < 0 while a client exists
  double joined_at = 0, spawned_at = -1, leave_at = 0;
  std::vector<uint32_t> owned;
  std::unordered_map<uint64_t, int> spawned;  // (owner, id) -> OnEntitySpawned count, this session

  void OnJoined(std::string_view, uint32_t) override { joined = true; }
  void OnEntitySpawned(const RemoteEntity& e) override {
    if (++spawned[Key(e.owner, e.id)] == 2) ++totals->duplicates;
  }
  void OnEntityDespawned(uint32_t id) override {
    // The owner left: forget every key with this id (any owner); a reused id may spawn again.
    for (auto it = spawned.begin(); it != spawned.end();) {
      it = (static_cast<uint32_t>(it->first) == id) ? spawned.erase(it) : std::next(it);
    }
  }
  void OnDisconnected(DisconnectReason reason) override {
    if (!leaving) {
      ++totals->unexpected_disconnects;
      std::fprintf(stderr, "soak: bot %d (player %u) dropped, reason %d\n", index, player,
                   static_cast<int>(reason));
    }
  }
  void OnError(uint16_t reason, uint32_t entity_id, std::string_view detail) override {
    ++totals->relay_errors;
    std::fprintf(stderr, "soak: bot %d relay error %u entity %u: %.*s\n", index, reason, entity_id,
                 static_cast<int>(detail.size()), detail.data());
  }
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"soak_driver: bots churning through rooms on an edgephys relay"};
  std::string relay = "127.0.0.1:7777", secret = "edgephys-dev-secret", bind_host = "127.0.0.1";
  int bots = 200, rooms = 40;
  double seconds = 600, min_stay = 5, max_stay = 30, grace = 2.0;
  uint32_t seed = 1;
  app.add_option("--relay", relay, "Relay UDP ip:port")->capture_default_str();
  app.add_option("--secret", secret, "The relay's token secret");
  app.add_option("--bots", bots, "Concurrent bots")->capture_default_str();
  app.add_option("--rooms", rooms, "Distinct room names to churn through")->capture_default_str();
  app.add_option("--seconds", seconds, "Run time before everyone leaves")->capture_default_str();
  app.add_option("--min-stay", min_stay, "Shortest stay in a room (s)")->capture_default_str();
  app.add_option("--max-stay", max_stay, "Longest stay in a room (s)")->capture_default_str();
  app.add_option("--grace", grace, "Age (s) after which a spawn must have arrived")->capture_default_str();
  app.add_option("--seed", seed, "Random seed")->capture_default_str();
  app.add_option("--bind-host", bind_host, "Local address of the bots' sockets")->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  auto server = ParseEndpoint(relay);
  if (!server.ok()) {
    std::fprintf(stderr, "--relay %s: %s\n", relay.c_str(), std::string(server.status().message()).c_str());
    return 2;
  }
  const auto bind_address = asio::ip::make_address(bind_host);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> stay(min_stay, max_stay);
  std::uniform_int_distribution<int> pick_room(0, rooms - 1);
  Totals totals;
  std::vector<std::unique_ptr<Bot>> all;
  for (int i = 0; i < bots; ++i) {
    auto b = std::make_unique<Bot>();
    b->index = i;
    b->totals = &totals;
    b->connect_at = 5.0 * i / bots;  // ramp up over 5 s
    all.push_back(std::move(b));
  }
  uint32_t generation = 0;
  const auto t0 = std::chrono::steady_clock::now();
  auto mono = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };

  // Verifies that `b` saw every spawn it should have, from bots in its room.
  auto check = [&](Bot& b, double now) {
    if (!b.joined || now - b.joined_at < grace) return;
    for (auto& o : all) {
      if (o.get() == &b || !o->joined || o->leaving || o->room != b.room || o->spawned_at < 0 ||
          now - o->spawned_at < grace) {
        continue;
      }
      for (uint32_t id : o->owned) {
        ++totals.expected;
        auto it = b.spawned.find(Key(o->player, id));
        if (it != b.spawned.end()) {
          ++totals.seen;
        } else {
          ++totals.lost;
          std::fprintf(stderr, "soak: bot %d (player %u, room %s) never saw entity %u of player %u\n",
                       b.index, b.player, b.room.c_str(), id, o->player);
        }
      }
    }
  };
  auto leave = [&](Bot& b) {
    b.leaving = true;
    if (b.client->joined()) (void)b.client->LeaveRoom();
    b.client->Disconnect();
  };
  auto drop = [&](Bot& b, double now, double pause) {
    b.client.reset();
    b.socket.reset();
    b.joined = b.join_sent = b.leaving = false;
    b.owned.clear();
    b.spawned.clear();
    b.spawned_at = -1;
    b.connect_at = now + pause;
  };

  double next_report = 10;
  bool ok_start = true;
  while (true) {
    const double now = mono();
    if (now >= seconds) break;
    for (auto& bp : all) {
      Bot& b = *bp;
      if (!b.client) {
        if (now < b.connect_at) continue;
        auto socket = UdpSocket::Open(Endpoint(bind_address, 0));
        if (!socket.ok()) {
          std::fprintf(stderr, "soak: cannot open a socket: %s\n", std::string(socket.status().message()).c_str());
          ok_start = false;
          break;
        }
        b.socket = std::move(*socket);
        b.player = ++generation;  // unique per connection
        b.room = "soak-" + std::to_string(pick_room(rng));
        JoinToken t;
        t.room = b.room;
        t.player_id = b.player;
        t.expiry_unix_s = UnixNow() + 120;
        t.nonce = SecureRandom64();
        ClientConfig cc;
        b.client = std::make_unique<Client>(cc, b.socket.get(), &b);
        (void)b.client->Connect(ToRelayAddress(*server), *SignJoinToken(t, secret), now);
        ++totals.sessions;
      }
      b.client->Update(now);
      const ClientState st = b.client->state();
      if (st == ClientState::kRejected || st == ClientState::kFailed) {
        ++totals.failed_connects;
        std::fprintf(stderr, "soak: bot %d could not connect (state %d, reject %u)\n", b.index,
                     static_cast<int>(st), b.client->reject_reason());
        drop(b, now, 1.0);
        continue;
      }
      if (st == ClientState::kDisconnected) {  // counted in OnDisconnected
        drop(b, now, 0.5);
        continue;
      }
      if (st != ClientState::kConnected) continue;
      if (!b.join_sent) {
        (void)b.client->JoinRoom(b.room);
        b.join_sent = true;
      }
      if (b.joined && b.spawned_at < 0) {
        b.joined_at = now;
        for (int k = 0; k < kEntitiesPerBot; ++k) {
          SpawnDesc d;
          d.position = {static_cast<float>(k), 1, static_cast<float>(b.index % 10)};
          auto id = b.client->Spawn(d);
          if (id.ok()) {
            b.owned.push_back(*id);
            ++totals.spawns_sent;
          }
        }
        b.spawned_at = now;
        b.leave_at = now + stay(rng);
      }
      if (b.spawned_at >= 0) {
        for (size_t k = 0; k < b.owned.size(); ++k) {
          double a = now * 1.5 + static_cast<double>(k);
          (void)b.client->PublishTransform(
              b.owned[k],
              {static_cast<float>(k + std::cos(a)), 1.0f, static_cast<float>(b.index % 10 + std::sin(a))},
              Quatf{});
        }
        if (now >= b.leave_at) {
          check(b, now);
          leave(b);
          b.client->Update(now);
          drop(b, now, 0.05);
        }
      }
    }
    if (!ok_start) break;
    if (now >= next_report) {
      next_report += 10;
      int connected = 0, in_room = 0;
      for (auto& b : all) {
        connected += b->client && b->client->state() == ClientState::kConnected;
        in_room += b->joined;
      }
      std::fprintf(stderr,
                   "soak: t=%.0f connected=%d in_room=%d sessions=%llu expected=%llu lost=%llu dup=%llu "
                   "drops=%llu\n",
                   now, connected, in_room, static_cast<unsigned long long>(totals.sessions),
                   static_cast<unsigned long long>(totals.expected),
                   static_cast<unsigned long long>(totals.lost),
                   static_cast<unsigned long long>(totals.duplicates),
                   static_cast<unsigned long long>(totals.unexpected_disconnects));
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }

  // The end: a last check for everyone still in a room, then all leave.
  const double end = mono();
  for (auto& b : all) {
    if (b->client) check(*b, end);
  }
  for (auto& b : all) {
    if (b->client) leave(*b);
  }
  while (mono() < end + 1.0) {  // flush the LeaveRoom / Disconnect packets
    for (auto& b : all) {
      if (b->client) b->client->Update(mono());
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  all.clear();

  const bool pass = ok_start && totals.lost == 0 && totals.duplicates == 0 &&
                    totals.unexpected_disconnects == 0 && totals.expected > 0;
  std::printf(
      "{\"bots\":%d,\"seconds\":%.0f,\"sessions\":%llu,\"spawns_sent\":%llu,\"expected\":%llu,\"seen\":%llu,"
      "\"lost\":%llu,\"duplicates\":%llu,\"unexpected_disconnects\":%llu,\"failed_connects\":%llu,"
      "\"relay_errors\":%llu,\"pass\":%s}\n",
      bots, seconds, static_cast<unsigned long long>(totals.sessions),
      static_cast<unsigned long long>(totals.spawns_sent), static_cast<unsigned long long>(totals.expected),
      static_cast<unsigned long long>(totals.seen), static_cast<unsigned long long>(totals.lost),
      static_cast<unsigned long long>(totals.duplicates),
      static_cast<unsigned long long>(totals.unexpected_disconnects),
      static_cast<unsigned long long>(totals.failed_connects),
      static_cast<unsigned long long>(totals.relay_errors), pass ? "true" : "false");
  return pass ? 0 : 1;
}
