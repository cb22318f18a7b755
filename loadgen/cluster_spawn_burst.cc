#include "loadgen/cluster_spawn_burst.h"
#include "loadgen/relay_process.h"

#include <nlohmann/json.hpp>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <deque>
#include <fstream>
#include <set>
#include <thread>

#include "client/client.h"
#include "client/client_endpoint.h"
#include "cluster/redis_client.h"
#include "cluster/testing/redis_server.h"
#include "protocol/endpoint.h"
#include "protocol/handshake.h"
#include "protocol/join_token.h"
#include "protocol/udp_socket.h"

namespace edgephys {
namespace {

using Clock = std::chrono::steady_clock;
constexpr uint32_t kPersistent = static_cast<uint32_t>(schema::EntityFlags::Persistent);
constexpr std::string_view kLostPrefix = "lost in failover: ";
constexpr char kRoom[] = "burst";

// Collects the entities its client reported lost (OnError "lost in failover: ...").
struct LossListener : ClientListener {
  std::set<uint32_t> lost;
  int other_errors = 0;
  void OnError(uint16_t reason, uint32_t entity_id, std::string_view detail) override {
    if (detail.substr(0, kLostPrefix.size()) == kLostPrefix) {
      lost.insert(entity_id);
    } else {
      ++other_errors;
      std::fprintf(stderr, "error %u on entity %u: %.*s\n", reason, entity_id,
                   static_cast<int>(detail.size()), detail.data());
    }
  }
};

struct Player {
  std::unique_ptr<UdpSocket> socket;
  LossListener listener;
  std::unique_ptr<Client> client;
  uint32_t id = 0;
  bool spawner = false;
  bool join_sent = false;
  double next_spawn = 0;
  std::vector<uint32_t> spawned;  // every id Spawn() returned
};

}  // namespace

int RunKillDuringSpawns(const SpawnBurstOptions& o) {
  const std::string secret = "spawn-burst-secret";
  cluster::testing::RedisServer redis;
  if (!redis.Start()) {
    std::fprintf(stderr, "cannot start redis-server\n");
    return 1;
  }
  ClusterRelays cluster = StartClusterRelays(o.relays, [&](const std::string& bind) {
    return ClusterRelayArgs(o.relay_binary, bind, secret, redis.port(), o.relay_timeout_s, o.ttl_ms,
                            o.heartbeat_ms, o.snapshot_ms, 120);
  });
  std::vector<pid_t>& pids = cluster.pids;
  const std::vector<Endpoint>& endpoints = cluster.endpoints;
  const std::vector<std::string>& relay_ids = cluster.ids;
  auto stop_all = [&] { KillRelayProcesses(pids); };
  std::this_thread::sleep_for(std::chrono::milliseconds(600));  // relays register

  const auto start = Clock::now();
  auto now_s = [&] { return std::chrono::duration<double>(Clock::now() - start).count(); };
  // o.spawners players spawning, and one observer that only watches (the "other client").
  std::deque<Player> players;
  for (int i = 0; i <= o.spawners; ++i) {
    Player& p = players.emplace_back();
    p.id = 100 + i;
    p.spawner = i < o.spawners;
    p.socket = std::move(*UdpSocket::Open(*ParseEndpoint("127.0.0.1:0")));
    p.client =
        std::make_unique<Client>(ClusterClientConfig(endpoints), p.socket.get(), &p.listener);
    (void)p.client->Connect(ToRelayAddress(endpoints[i % o.relays]),
                            MintJoinToken(secret, kRoom, p.id), now_s());
  }
  Player& observer = players.back();
  bool spawning = false;
  double kill_s = 1e9;
  uint64_t spawn_refused = 0;  // Spawn() errors (kNotConnected while resuming): not spawned
  uint64_t into_dead = 0;      // spawns after the kill, before the SDK noticed it
  auto pump = [&] {
    const double t = now_s();
    for (Player& p : players) {
      p.client->Update(t);
      if (p.client->state() == ClientState::kConnected && !p.client->joined() &&
          !p.client->resuming() && !p.join_sent) {
        p.join_sent = p.client->JoinRoom(kRoom).ok();
      }
      if (spawning && p.spawner && t >= p.next_spawn) {
        p.next_spawn = t + o.spawn_period_s;
        SpawnDesc d;
        d.flags = kPersistent;
        d.position = {static_cast<float>(p.spawned.size() % 50) * 0.1f, 1, 0};
        auto id = p.client->Spawn(d);
        if (id.ok()) {
          p.spawned.push_back(*id);
          into_dead += t > kill_s && p.client->resumes() == 0;
        } else {
          ++spawn_refused;
        }
      }
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  };
  nlohmann::json out;
  bool ok = true;
  auto fail = [&](const char* why) {
    std::fprintf(stderr, "%s\n", why);
    ok = false;
  };
  // 1. Join: every player in the room (all on its owner, through redirects).
  for (double end = now_s() + 15; now_s() < end;) {
    pump();
    if (std::all_of(players.begin(), players.end(), [](const Player& p) { return p.client->joined(); })) break;
  }
  if (!std::all_of(players.begin(), players.end(), [](const Player& p) { return p.client->joined(); })) {
    fail("not every player joined");
  }
  // 2. Spawn for o.kill_after_s, then kill -9 the room's owner while the spawns go on.
  spawning = true;
  for (double end = now_s() + o.kill_after_s; now_s() < end;) pump();
  cluster::RedisClient rc("127.0.0.1", redis.port(), 1.0);
  auto owner = rc.Command({"GET", std::string("edgephys:room:") + kRoom});
  int victim = -1;
  for (int i = 0; owner.ok() && owner->is_string() && i < o.relays; ++i) {
    if (relay_ids[i] == owner->str) victim = i;
  }
  if (victim < 0) {
    fail("the room has no owner in Redis");
    stop_all();
    return 1;
  }
  kill(pids[victim], SIGKILL);
  waitpid(pids[victim], nullptr, 0);
  pids[victim] = -1;
  kill_s = now_s();
  size_t spawned_before_kill = 0;
  for (const Player& p : players) spawned_before_kill += p.spawned.size();
  // 3. Spawns go on until every player has resumed (or the deadline), and a little after.
  auto all_resumed = [&] {
    return std::all_of(players.begin(), players.end(), [](const Player& p) {
      return p.client->joined() && !p.client->resuming() && p.client->resumes() > 0;
    });
  };
  double resumed_s = -1;
  for (double end = kill_s + o.recover_timeout_s; now_s() < end;) {
    pump();
    if (all_resumed()) {
      resumed_s = now_s() - kill_s;
      break;
    }
  }
  if (resumed_s < 0) fail("not every player resumed");
  for (double end = now_s() + 0.5; now_s() < end;) pump();
  spawning = false;
  // 4. Settle: until the observer (and every other spawner) sees every entity not reported
  // lost, bounded.
  auto silent = [&](const Player& p, uint32_t id) {
    if (p.listener.lost.count(id) != 0) return false;  // reported lost: not silent
    if (p.client->OwnerOf(id) != p.id) return true;    // no longer owned, never reported
    for (const Player& other : players) {
      if (&other != &p && other.client->entities().count(id) == 0) return true;
    }
    return false;
  };
  auto silent_losses = [&] {
    size_t n = 0;
    for (const Player& p : players) {
      for (uint32_t id : p.spawned) n += silent(p, id);
    }
    return n;
  };
  for (double end = now_s() + o.settle_s; now_s() < end && silent_losses() != 0;) pump();
  size_t spawned = 0, reported_lost = 0, present = 0, respawns = 0, duplicates = 0;
  for (const Player& p : players) {
    spawned += p.spawned.size();
    reported_lost += p.listener.lost.size();
    respawns += p.client->respawns_sent();
    duplicates += p.client->respawns_duplicate();
    for (uint32_t id : p.spawned) present += observer.client->entities().count(id);
  }
  const size_t silently_lost = silent_losses();
  int other_errors = 0;
  for (const Player& p : players) other_errors += p.listener.other_errors;
  out["fault"] = "kill-during-spawns";
  out["spawners"] = o.spawners;
  out["spawned"] = spawned;
  out["spawned_before_kill"] = spawned_before_kill;
  out["spawned_into_the_dead_connection"] = into_dead;
  out["spawn_calls_refused_while_resuming"] = spawn_refused;
  out["present_at_observer"] = present;
  // Of the re-spawns sent after the resume: the ones the restored room held (its snapshot had
  // them) and the ones it lacked (spawned again; a refusal among them is in reported_lost).
  out["restored_from_snapshot"] = duplicates;
  out["respawned"] = respawns - duplicates;
  out["reported_lost"] = reported_lost;
  out["silently_lost"] = silently_lost;
  out["other_errors"] = other_errors;
  out["resumed_s"] = resumed_s;
  if (silently_lost != 0) fail("entities lost silently");
  if (other_errors != 0) fail("errors not about lost entities");
  if (spawned_before_kill == 0) fail("nothing was spawned before the kill");
  if (into_dead == 0) fail("nothing was spawned into the dead connection");
  out["ok"] = ok;
  std::printf("%s\n", out.dump(2).c_str());
  if (!o.json_path.empty()) std::ofstream(o.json_path) << out.dump(2) << "\n";
  stop_all();
  return ok ? 0 : 1;
}

}  // namespace edgephys
