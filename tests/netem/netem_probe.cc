// netem_probe: one real SDK client for tests/netem/netem_test.sh (faults on a real network path).
//
//   netem_probe --role owner    --relay 10.0.0.1:7777 --secret S --room R --player 1
//               --entities 8 --seconds 36 --start-at <unix ms>
//   netem_probe --role observer --relay 10.0.0.1:7777 --secret S --room R --player 2
//               --entities 8 --seconds 36 --start-at <unix ms>
//
// Both roles follow one schedule on the shared wall clock (every network namespace shares the
// kernel's CLOCK_REALTIME): time is cut into cycles of --period seconds starting at --start-at.
// In the first half of cycle c the owner moves its entities (entity k circles around (k,2,3+c));
// in the second half it holds entity k at exactly (k, 2, 3 + c), identity rotation. The owner
// spawns its --entities kinematic entities first (local ids 1..N, so
// entity id % kEntityIdBlock == k), then, with --physics (default), an Offloaded static ground
// and an Offloaded ball resting on it, which put the room on PhyS (a remote edgephys-phys
// worker when one is attached).
//
// The observer checks every hold: it has converged when all N owner entities are within
// --tolerance metres of (k, 2, 3 + c) before the hold ends. At the end each role prints one
// JSON line on stdout (progress goes to stderr). The observer's line:
//   {"role":"observer","entities_seen":10,"owner_entities":8,"room_entities":2,"spawns":10,
//    "duplicate_spawns":0,"despawns":0,"cycles":[1,1,0,...],"converge_ms":[140,...,-1],
//    "converged_final":true,"session_survived":true,...}
// cycles[c] is 1 when hold c converged (-1 in converge_ms when it did not). "spawns" counts
// OnEntitySpawned calls (reliable Spawn messages); each entity must be spawned exactly once.
// Exit status: 0 when the session survived to the end (both roles), else 1; 2 on bad flags.
#include <CLI/CLI.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "client/client.h"
#include "client/client_endpoint.h"
#include "protocol/container_builder.h"
#include "protocol/endpoint.h"
#include "protocol/handshake.h"
#include "protocol/join_token.h"
#include "protocol/udp_socket.h"

namespace {

using namespace edgephys;

double UnixNowS() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

constexpr double kPi = 3.14159265358979323846;

struct Schedule {
  double start_s = 0;   // unix seconds
  double period_s = 6;
  int Cycle(double t) const { return static_cast<int>(std::floor((t - start_s) / period_s)); }
  double Phase(double t) const { return (t - start_s) - Cycle(t) * period_s; }
  bool Holding(double t) const { return Phase(t) >= period_s / 2; }
  static Vec3f HoldPose(uint32_t k, int cycle) {
    return {static_cast<float>(k), 2.0f, 3.0f + static_cast<float>(cycle)};
  }
  // The owner's pose for entity k at time t.
  Vec3f Pose(uint32_t k, double t, Quatf* rotation) const {
    int c = std::max(0, Cycle(t));
    Vec3f hold = HoldPose(k, c);
    *rotation = Quatf{};
    if (t < start_s || Holding(t)) return hold;
    double a = 2 * kPi * Phase(t) / (period_s / 2) + 0.3 * k;
    *rotation = Quatf{0, static_cast<float>(std::sin(a / 2)), 0, static_cast<float>(std::cos(a / 2))};
    return {hold.x + 0.5f * static_cast<float>(std::cos(a)), hold.y,
            hold.z + 0.5f * static_cast<float>(std::sin(a))};
  }
};

struct Probe : ClientListener {
  std::map<uint32_t, int> spawn_count;  // entity id -> OnEntitySpawned calls
  int spawns = 0;
  int despawns = 0;
  int updates = 0;  // OnEntityUpdated calls (states received), for the progress line
  int errors = 0;
  int disconnects = 0;
  bool joined = false;
  uint32_t base = 0;
  void OnJoined(std::string_view, uint32_t entity_id_base) override {
    joined = true;
    base = entity_id_base;
  }
  void OnEntitySpawned(const RemoteEntity& e) override {
    ++spawns;
    ++spawn_count[e.id];
  }
  void OnEntityUpdated(const RemoteEntity&) override { ++updates; }
  void OnEntityDespawned(uint32_t) override { ++despawns; }
  void OnDisconnected(DisconnectReason reason) override {
    ++disconnects;
    std::fprintf(stderr, "probe: disconnected (reason %d)\n", static_cast<int>(reason));
  }
  void OnError(uint16_t reason, uint32_t entity_id, std::string_view detail) override {
    ++errors;
    std::fprintf(stderr, "probe: relay error %u on entity %u: %.*s\n", reason, entity_id,
                 static_cast<int>(detail.size()), detail.data());
  }
};

const char* StateName(ClientState s) {
  switch (s) {
    case ClientState::kIdle: return "idle";
    case ClientState::kHandshaking: return "handshaking";
    case ClientState::kConnected: return "connected";
    case ClientState::kRejected: return "rejected";
    case ClientState::kDisconnected: return "disconnected";
    case ClientState::kFailed: return "failed";
  }
  return "?";
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"netem_probe: owner/observer client for the netem fault tests"};
  std::string role, relay, secret = "edgephys-dev-secret", room = "netem";
  uint32_t player = 0, entities = 8;
  double seconds = 36, period = 6, tolerance = 0.005, start_at_ms = 0, connect_timeout = 20;
  bool physics = true;
  app.add_option("--role", role, "owner | observer")->required()->check(CLI::IsMember({"owner", "observer"}));
  app.add_option("--relay", relay, "Relay UDP ip:port")->required();
  app.add_option("--secret", secret, "The relay's token secret");
  app.add_option("--room", room, "Room name")->capture_default_str();
  app.add_option("--player", player, "Player id (non-zero)")->required();
  app.add_option("--entities", entities, "Kinematic entities the owner spawns")->capture_default_str();
  app.add_option("--seconds", seconds, "Run this long after --start-at")->capture_default_str();
  app.add_option("--period", period, "Schedule cycle (s): half moving, half holding")->capture_default_str();
  app.add_option("--start-at", start_at_ms, "Schedule origin, unix ms (default: now + 2 s)");
  app.add_option("--tolerance", tolerance, "Convergence tolerance (m)")->capture_default_str();
  app.add_option("--connect-timeout", connect_timeout, "Give up joining after this long (s)")
      ->capture_default_str();
  app.add_flag("!--no-physics", physics, "Owner: no Offloaded ground and ball");
  CLI11_PARSE(app, argc, argv);
  const bool owner = role == "owner";

  Schedule schedule;
  schedule.period_s = period;
  schedule.start_s = start_at_ms > 0 ? start_at_ms / 1000.0 : UnixNowS() + 2.0;
  const double end_s = schedule.start_s + seconds;

  auto server = ParseEndpoint(relay);
  if (!server.ok()) {
    std::fprintf(stderr, "--relay %s: %s\n", relay.c_str(), std::string(server.status().message()).c_str());
    return 2;
  }
  auto socket = UdpSocket::Open(Endpoint(asio::ip::make_address("0.0.0.0"), 0));
  if (!socket.ok()) {
    std::fprintf(stderr, "cannot open a UDP socket\n");
    return 1;
  }
  JoinToken token;
  token.room = room;
  token.player_id = player;
  token.expiry_unix_s = static_cast<uint64_t>(UnixNowS()) + 3600;
  token.nonce = SecureRandom64();
  auto signed_token = SignJoinToken(token, secret);
  if (!signed_token.ok()) {
    std::fprintf(stderr, "cannot sign the token\n");
    return 2;
  }

  Probe probe;
  ClientConfig cc;
  cc.handshake_timeout_s = connect_timeout;
  Client client(cc, socket->get(), &probe);
  const auto t0 = std::chrono::steady_clock::now();
  auto mono = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };
  (void)client.Connect(ToRelayAddress(*server), *signed_token, mono());

  bool join_sent = false, spawned = false, ever_connected = false;
  double connected_at = -1;
  std::vector<uint32_t> owned;
  // Observer bookkeeping per cycle.
  const int cycles = std::max(1, static_cast<int>(std::ceil(seconds / period)));
  std::vector<int> converged(cycles, 0);
  std::vector<int> converge_ms(cycles, -1);
  double last_progress = 0;
  std::string failure;

  auto owner_entities = [&](std::vector<const RemoteEntity*>* out) {
    out->assign(entities, nullptr);
    for (const auto& [id, e] : client.entities()) {
      uint32_t k = id % kEntityIdBlock;
      if (e.owner != 0 && e.owner != player && k >= 1 && k <= entities && e.spawned) out->at(k - 1) = &e;
    }
  };
  std::vector<const RemoteEntity*> seen;

  while (UnixNowS() < end_s) {
    (*socket)->WaitReadable(0.002);
    const double now = mono();
    const double wall = UnixNowS();
    client.Update(now);
    const ClientState st = client.state();
    if (st == ClientState::kConnected) {
      if (!ever_connected) connected_at = wall;
      ever_connected = true;
      if (!join_sent) {
        (void)client.JoinRoom(room);
        join_sent = true;
      }
    } else if (st == ClientState::kRejected || st == ClientState::kFailed ||
               st == ClientState::kDisconnected) {
      failure = std::string("client ") + StateName(st);
      break;
    }
    if (owner && probe.joined && !spawned) {
      for (uint32_t k = 1; k <= entities; ++k) {
        SpawnDesc d;
        Quatf q;
        d.position = schedule.Pose(k, wall, &q);
        d.rotation = q;
        auto id = client.Spawn(d);
        if (!id.ok()) {
          failure = "spawn failed";
          break;
        }
        owned.push_back(*id);
      }
      if (physics) {
        const uint32_t offloaded = static_cast<uint32_t>(schema::EntityFlags::Offloaded);
        SpawnDesc ground{.position = {0, -10.5f, 0}, .flags = offloaded};
        ground.colliders.push_back(BoxCollider({20, 0.5f, 20}));
        SpawnDesc ball{.position = {0, -9.9f, 0}, .flags = offloaded};
        ball.rigid_body = RigidBodySpec{};
        ball.colliders.push_back(SphereCollider(0.1f));
        if (!client.Spawn(ground).ok() || !client.Spawn(ball).ok()) failure = "physics spawn failed";
      }
      spawned = true;
      if (!failure.empty()) break;
    }
    if (owner && spawned) {
      for (size_t i = 0; i < owned.size(); ++i) {
        Quatf q;
        Vec3f p = schedule.Pose(static_cast<uint32_t>(i + 1), wall, &q);
        (void)client.PublishTransform(owned[i], p, q);
      }
    }
    if (!owner && wall >= schedule.start_s) {
      const int c = schedule.Cycle(wall);
      if (c >= 0 && c < cycles && schedule.Holding(wall) && !converged[c]) {
        owner_entities(&seen);
        bool all = true;
        for (uint32_t k = 1; k <= entities && all; ++k) {
          const RemoteEntity* e = seen[k - 1];
          if (e == nullptr) { all = false; break; }
          Vec3f want = Schedule::HoldPose(k, c);
          double dx = e->state.position.x - want.x, dy = e->state.position.y - want.y,
                 dz = e->state.position.z - want.z;
          if (std::sqrt(dx * dx + dy * dy + dz * dz) > tolerance) all = false;
        }
        if (all) {
          converged[c] = 1;
          converge_ms[c] = static_cast<int>((schedule.Phase(wall) - period / 2) * 1000);
        }
      }
    }
    if (now - last_progress >= 2.0) {
      last_progress = now;
      const ConnectionStats* cs = client.stats();
      std::fprintf(stderr, "probe %s: t=%.1f state=%s joined=%d entities=%zu spawns=%d updates=%d"
                   " stale_dropped=%llu duplicates_dropped=%llu",
                   role.c_str(), wall - schedule.start_s, StateName(st), probe.joined ? 1 : 0,
                   client.entities().size(), probe.spawns, probe.updates,
                   static_cast<unsigned long long>(cs ? cs->stale_dropped : 0),
                   static_cast<unsigned long long>(cs ? cs->duplicates_dropped : 0));
      if (!owner) {  // where the observer sees owner entity 1, and since when (relay ms)
        owner_entities(&seen);
        if (const RemoteEntity* e = seen.empty() ? nullptr : seen[0]) {
          std::fprintf(stderr, " entity1=(%.3f,%.3f,%.3f)@%u", e->state.position.x,
                       e->state.position.y, e->state.position.z, e->state_time_ms);
        }
      }
      std::fprintf(stderr, "\n");
    }
  }

  const ClientState final_state = client.state();
  const bool survived = failure.empty() && ever_connected && final_state == ClientState::kConnected &&
                        probe.disconnects == 0 && client.joined();
  std::ostringstream js;
  js << "{\"role\":\"" << role << "\",\"player\":" << player << ",\"state\":\"" << StateName(final_state)
     << "\",\"session_survived\":" << (survived ? "true" : "false")
     << ",\"disconnects\":" << probe.disconnects << ",\"errors\":" << probe.errors
     << ",\"connected_after_s\":" << (ever_connected ? connected_at - schedule.start_s : -1);
  if (!failure.empty()) js << ",\"failure\":\"" << failure << "\"";
  if (owner) {
    js << ",\"spawned\":" << owned.size() + (physics && spawned ? 2 : 0) << ",\"entities\":" << entities;
  } else {
    owner_entities(&seen);
    int owner_seen = 0;
    for (const RemoteEntity* e : seen) owner_seen += e != nullptr;
    int room_entities = 0, seen_total = 0;
    for (const auto& [id, e] : client.entities()) {
      if (!e.spawned) continue;
      ++seen_total;
      if (e.owner == 0) ++room_entities;
    }
    int dups = 0;
    for (const auto& [id, n] : probe.spawn_count) dups += n > 1 ? n - 1 : 0;
    js << ",\"entities_seen\":" << seen_total << ",\"owner_entities\":" << owner_seen
       << ",\"room_entities\":" << room_entities << ",\"spawns\":" << probe.spawns
       << ",\"distinct_spawned\":" << probe.spawn_count.size() << ",\"duplicate_spawns\":" << dups
       << ",\"despawns\":" << probe.despawns << ",\"cycles\":[";
    for (int c = 0; c < cycles; ++c) js << (c ? "," : "") << converged[c];
    js << "],\"converge_ms\":[";
    for (int c = 0; c < cycles; ++c) js << (c ? "," : "") << converge_ms[c];
    js << "],\"converged_final\":" << (converged[cycles - 1] ? "true" : "false");
  }
  js << "}";
  std::printf("%s\n", js.str().c_str());
  std::fflush(stdout);
  client.Disconnect();
  client.Update(mono());
  return survived ? 0 : 1;
}
