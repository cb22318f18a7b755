// edgephys-relay: the relay server process, and `edgephys-relay token` to mint join tokens.
//
//   edgephys-relay                         # UDP 0.0.0.0:7777, metrics on 0.0.0.0:9464
//   edgephys-relay --config relay.toml     # any flag below as a key in a TOML/INI file
//   edgephys-relay token --room lobby --player 7 --ttl 3600
#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <iostream>
#include <thread>

#include "metrics/metrics_exporter.h"
#include "relay/admin/admin_http.h"
#include "relay/admin/relay_admin.h"
#include "protocol/batched_socket.h"
#include "protocol/endpoint.h"
#include "protocol/handshake.h"
#include "protocol/join_token.h"
#include "protocol/udp_socket.h"
#include "relay/cluster_hook.h"
#include "relay/relay.h"
#include "relay/relay_shards.h"

namespace {

std::atomic<bool> g_stop{false};
void OnSignal(int) { g_stop.store(true); }

uint64_t UnixNow() {
  return static_cast<uint64_t>(std::chrono::duration_cast<std::chrono::seconds>(
                                   std::chrono::system_clock::now().time_since_epoch())
                                   .count());
}

std::string AdminKeyFromEnv(const std::string& flag) {
  if (!flag.empty()) return flag;
  const char* env = std::getenv("EDGEPHYS_ADMIN_KEY");
  return env != nullptr ? env : "";
}

std::string SecretFromEnv(const std::string& flag) {
  if (!flag.empty()) return flag;
  const char* env = std::getenv("EDGEPHYS_SECRET");
  return env != nullptr ? env : edgephys::kDevelopmentSecret;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace edgephys;
  CLI::App app{"edgephys-relay: UDP relay for collaborative XR and multiplayer rooms"};
  app.set_config("--config", "", "Read flags from a TOML/INI config file");
  RelayConfig config;
  std::string bind = "0.0.0.0:7777";
  std::string metrics = "0.0.0.0:9464";
  std::string secret;
  std::string log_level = "info";
  double run_for_s = 0;
  app.add_option("--bind", bind, "UDP address:port to serve")->capture_default_str();
  app.add_option("--metrics", metrics, "Prometheus address:port ('off' to disable)")
      ->capture_default_str();
  std::string admin_addr = "127.0.0.1:9465";
  std::string admin_key;
  auto* admin_addr_opt =
      app.add_option("--admin-addr", admin_addr,
                     "Admin HTTP API and /monitor address:port ('off' to disable; a non-loopback "
                     "address needs a key)")
          ->capture_default_str();
  app.add_option("--admin-key", admin_key,
                 "Admin API bearer key (default: $EDGEPHYS_ADMIN_KEY; none: loopback only)");
  app.add_option("--secret", secret,
                 "Join token secret (default: $EDGEPHYS_SECRET, else a development secret)");
  app.add_option("--max-clients", config.max_clients, "Connections at once")->capture_default_str();
  app.add_option("--room-capacity", config.room_defaults.capacity, "Players per room")
      ->capture_default_str();
  app.add_option("--room-ttl", config.room_defaults.idle_ttl_s, "Seconds an empty room is kept")
      ->capture_default_str();
  app.add_option("--tick-rate", config.room_defaults.tick_rate_hz, "Room ticks per second")
      ->capture_default_str()
      ->check(CLI::Range(1.0, 1000.0));
  app.add_option("--max-entities-per-player", config.room_defaults.max_entities_per_player,
                 "Entities one player may own in a room")
      ->capture_default_str();
  RoomBudgets& budget = config.room_defaults.budgets;  // docs/operations.md, "Room budgets"
  app.add_option("--max-room-entities", budget.max_entities, "Entities in one room (0: off)")
      ->capture_default_str();
  app.add_option("--max-player-bytes", budget.max_bytes_per_player,
                 "Stored spawn bytes per player in a room")->capture_default_str();
  app.add_option("--max-room-bytes", budget.max_bytes, "Stored spawn bytes in one room")
      ->capture_default_str();
  app.add_option("--max-player-bodies", budget.max_bodies_per_player, "PhyS bodies per player")
      ->capture_default_str();
  app.add_option("--max-room-bodies", budget.max_bodies, "PhyS bodies in one room")
      ->capture_default_str();
  app.add_option("--max-player-particles", budget.max_particles_per_player,
                 "Soft-body particles per player")->capture_default_str();
  app.add_option("--max-room-particles", budget.max_particles, "Soft-body particles in one room")
      ->capture_default_str();
  app.add_option("--max-player-joints", budget.max_joints_per_player, "PhyS joints per player")
      ->capture_default_str();
  app.add_option("--max-room-joints", budget.max_joints, "PhyS joints in one room")
      ->capture_default_str();
  app.add_option("--max-name-bytes", budget.max_name_bytes, "Longest entity name (bytes)")
      ->capture_default_str();
  std::string replication_mode = "edgephys";
  app.add_option("--replication-mode", replication_mode,
                 "State encoding: edgephys (quantized delta), float, photon or paper (emulations)")
      ->capture_default_str();
  ReplicationConfig& rep = config.room_defaults.replication;
  app.add_flag("--shared-encoding,!--no-shared-encoding", rep.shared_encoding,
               "edgephys mode: state format 9 (shared delta: each entity delta encoded once per "
               "room tick for every receiver on the same baseline; the default); "
               "--no-shared-encoding sends format 2. --velocities and --key-samples send their "
               "own formats either way");
  app.add_flag("--shared-lockstep", rep.shared_lockstep,
               "With --shared-encoding and no bandwidth budget: receivers that acknowledge the "
               "room's canonical payloads within --lockstep-ack-ticks are sent copies of them "
               "instead of being walked entity by entity; off by default");
  app.add_option("--lockstep-ack-ticks", rep.lockstep_ack_ticks,
                 "Lockstep rooms: room ticks after which an acknowledgement counts as a baseline "
                 "(and by which a lockstep receiver must have acknowledged)")
      ->capture_default_str()->check(CLI::Range(1, 32));
  app.add_flag("--velocities", rep.velocities,
               "edgephys mode: state format 12 (format 2 plus velocities): receivers extrapolate "
               "and PhyS bodies are sent only when that strays beyond the extrapolation "
               "thresholds (dead reckoning); off by default");
  app.add_option("--extrapolation-threshold", rep.extrapolation_position_threshold_m,
                 "Dead reckoning: position error (m) that makes a PhyS body be sent")
      ->capture_default_str()->check(CLI::Range(1e-4, 1.0));
  app.add_option("--extrapolation-rotation-threshold", rep.extrapolation_rotation_threshold_deg,
                 "Dead reckoning: rotation error (deg) that makes a PhyS body be sent")
      ->capture_default_str()->check(CLI::Range(0.01, 90.0));
  app.add_option("--extrapolation-max-hz", rep.extrapolation_max_hz,
                 "Dead reckoning: how often a PhyS body is checked (and at most sent)")
      ->capture_default_str()->check(CLI::Range(1.0, 240.0));
  app.add_option("--position-step", rep.position_step_m, "Position quantisation step (m)")
      ->capture_default_str()->check(CLI::Range(1e-5, 1.0));
  app.add_option("--rotation-bound", rep.rotation_bound_deg, "Rotation error bound (deg)")
      ->capture_default_str()->check(CLI::Range(0.001, 10.0));
  app.add_option("--critical-hz", rep.critical_hz, "Send rate of avatars, hands, grabbed objects")
      ->capture_default_str()->check(CLI::Range(1.0, 240.0));
  app.add_option("--normal-hz", rep.normal_hz, "Send rate of other moving entities")
      ->capture_default_str()->check(CLI::Range(1.0, 240.0));
  app.add_option("--soft-touched-hz", rep.soft_touched_hz,
                 "Send rate of a soft body while a hand touches it (format 11)")
      ->capture_default_str()->check(CLI::Range(1.0, 240.0));
  app.add_option("--ambient-hz", rep.ambient_hz,
                 "Send rate of PhyS-simulated entities no user interacts with")
      ->capture_default_str()->check(CLI::Range(1.0, 240.0));
  app.add_option("--key-samples", rep.key_sample_threshold_m,
                 "Format 2 only: send an untouched PhyS body when the straight line receivers "
                 "interpolate strays from PhyS's states by more than this (m) instead of at "
                 "--ambient-hz (0: off; docs/benchmarks.md, \"Key samples\")")
      ->capture_default_str()->check(CLI::Range(0.0, 10.0));
  app.add_option("--key-samples-rotation", rep.key_sample_rotation_deg,
                 "With --key-samples: the same for rotation (deg)")
      ->capture_default_str()->check(CLI::Range(0.1, 180.0));
  app.add_option("--key-samples-max-interval", rep.key_sample_max_interval_s,
                 "With --key-samples: longest time (s) a moving body goes unsent; receivers play "
                 "out this far behind")
      ->capture_default_str()->check(CLI::Range(0.02, 10.0));
  app.add_option("--key-samples-check-hz", rep.key_sample_check_hz,
                 "With --key-samples: how often untouched bodies are checked, so that their "
                 "samples share datagrams (0: every tick)")
      ->capture_default_str()->check(CLI::Range(0.0, 1000.0));
  app.add_flag("--key-samples-at-kink", rep.key_sample_at_kink,
               "With --key-samples: send the state at the kink, with its own time (state format "
               "14), instead of the present state when a line strays");
  app.add_flag("--key-samples-arrival-stamp", rep.key_sample_arrival_stamp,
               "With --key-samples: stamp PhyS bodies with their state's time plus the running "
               "mean of how far PhyS's newest state trails the tick");
  app.add_flag("--stamp-state-time", rep.stamp_state_time,
               "Format 2: stamp PhyS bodies with the time their states hold, not the tick's");
  app.add_option("--interaction-linger", rep.interaction_linger_s,
                 "Seconds an entity stays out of the ambient class after a grab, release or event")
      ->capture_default_str()->check(CLI::Range(0.0, 3600.0));
  app.add_option("--client-budget", rep.bandwidth_budget_bytes_per_s,
                 "Per-client bandwidth budget in bytes/s (0: unlimited)")
      ->capture_default_str();
  AbuseLimits& lim = config.limits;
  app.add_option("--max-packets-per-s", lim.packets_per_s, "Per-connection packet rate limit (0: off)")
      ->capture_default_str();
  app.add_option("--max-bytes-per-s", lim.bytes_per_s, "Per-connection byte rate limit (0: off)")
      ->capture_default_str();
  app.add_option("--max-spawns-per-s", lim.spawns_per_s, "Per-connection spawn rate limit")
      ->capture_default_str();
  app.add_option("--max-spawn-bytes", lim.max_spawn_bytes, "Largest accepted container (bytes)")
      ->capture_default_str();
  app.add_option("--max-handshakes-per-s", lim.handshakes_per_s, "Hello/Connect per source address")
      ->capture_default_str();
  app.add_option("--max-connections-per-address", lim.max_sessions_per_address,
                 "Live connections from one IP address")
      ->capture_default_str();
  app.add_option("--join-timeout", lim.join_timeout_s, "Seconds a connection may stay without a room")
      ->capture_default_str();
  app.add_option("--physics-threads", config.physics_threads,
                 "Threads for embedded PhyS, the relay's included (1: PhyS on the relay's "
                 "thread; N > 1: N-1 physics threads off the relay loop)")
      ->capture_default_str();
  app.add_option("--physics-nice", config.physics_nice,
                 "Niceness the physics threads add to their priority (0..19; 0: none), so the "
                 "relay loop goes first when every core is busy")
      ->check(CLI::Range(0, 19))
      ->capture_default_str();
  app.add_flag("--physics-idle", config.physics_idle,
               "Physics threads run under SCHED_IDLE, only on cores nothing else wants (overrides "
               "--physics-nice; on a machine that is always busy, PhyS rooms then stall)");
  size_t io_threads = 1;
  app.add_option("--io-threads", io_threads,
                 "Relay shards, each on its own thread, rooms spread over them (1: one thread, "
                 "as before; N>1 adds a receive thread; see docs/operations.md)")
      ->capture_default_str()
      ->check(CLI::Range(size_t{1}, RelayShards::kMaxShards));
  app.add_option("--packet-auth", config.packet_auth,
                 "Seal every packet after the handshake (ChaCha20-Poly1305; 'false' only to "
                 "measure its cost)")
      ->capture_default_str();
  bool batching = false;
  app.add_flag("--batching", batching,
               "One thread: receive and send with recvmmsg/sendmmsg batches, flushed once per "
               "update (experimental: measured no faster in `ceiling` on 2 cores, see "
               "docs/benchmarks.md)");
  bool sleep_to_deadline = false;
  app.add_flag("--sleep-to-deadline,!--no-sleep-to-deadline", sleep_to_deadline,
               "One thread: sleep until the next room tick, PhyS step or connection timer and "
               "drain the socket in recvmmsg batches, instead of waking on every arriving "
               "datagram (at least every 2 ms) and receiving one per call as by default "
               "(--no-sleep-to-deadline); opt-in, see docs/operations.md");
  double max_sleep_s = 0.01;
  app.add_option("--max-sleep", max_sleep_s,
                 "One thread: longest sleep of the relay loop (s); bounds how long a handshake "
                 "or an admin request waits while no room ticks")
      ->capture_default_str()
      ->check(CLI::Range(0.0005, 0.1));
  app.add_option("--reliable-delay", config.connection.max_reliable_delay_s,
                 "Seconds a reliable event queued between room ticks may wait for its "
                 "receiver's next state datagram before leaving on its own (0: at once)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 0.1));
  app.add_option("--timeout", config.connection.timeout_s, "Seconds of silence before a client is dropped")
      ->capture_default_str();
  app.add_option("--ack-delay", config.connection.max_ack_delay_s,
                 "Seconds an ack owed for a client's unreliable payloads may wait for its next "
                 "state datagram before leaving on its own (0: at once)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 0.1));
  app.add_option("--log-level", log_level, "trace|debug|info|warn|error|off")->capture_default_str();
  app.add_option("--run-for", run_for_s, "Exit after this many seconds (0: until a signal)");
  // Cluster (docs/operations.md, "Scale-out and failover"): off unless --redis is given.
  std::string redis;
  ClusterOptions cluster;
  double cluster_snapshot_ms = 500, cluster_heartbeat_ms = 200, cluster_ttl_ms = 1000;
  app.add_option("--redis", redis,
                 "Join a cluster of relays over this Redis (host:port); off: run alone");
  app.add_option("--relay-id", cluster.directory.relay_id,
                 "Unique id of this relay in the cluster (default: host-port of --public-address)");
  app.add_option("--public-address", cluster.directory.public_address,
                 "host:port clients reach this relay at, sent in redirects (default: --bind, "
                 "which must then not be a wildcard address)");
  app.add_option("--cluster-snapshot-ms", cluster_snapshot_ms,
                 "Rooms' state written to Redis at most this often (bounds what a failover loses)")
      ->capture_default_str()->check(CLI::Range(20.0, 60000.0));
  app.add_option("--cluster-heartbeat-ms", cluster_heartbeat_ms, "Registration refreshed this often")
      ->capture_default_str()->check(CLI::Range(10.0, 60000.0));
  app.add_option("--cluster-ttl-ms", cluster_ttl_ms,
                 "A relay silent this long is dead and its rooms fail over")
      ->capture_default_str()->check(CLI::Range(50.0, 600000.0));

  auto* token_cmd = app.add_subcommand("token", "Mint a join token (printed as base64url)");
  JoinToken token;
  double ttl_s = 3600;
  token.room = "lobby";
  token_cmd->add_option("--room", token.room, "Room the token grants")->capture_default_str();
  token_cmd->add_option("--player", token.player_id, "Player id (non-zero)")->required();
  token_cmd->add_option("--ttl", ttl_s, "Seconds until the token expires")->capture_default_str();
  token_cmd->add_option("--permissions", token.permissions, "Permission bits (1: spawn)")
      ->capture_default_str();
  token_cmd->add_option("--secret", secret, "Secret (default: $EDGEPHYS_SECRET)");
  CLI11_PARSE(app, argc, argv);

  config.secret = SecretFromEnv(secret);
  if (*token_cmd) {
    token.expiry_unix_s = UnixNow() + static_cast<uint64_t>(ttl_s);
    token.nonce = SecureRandom64();
    auto bytes = SignJoinToken(token, config.secret);
    if (!bytes.ok()) {
      std::fprintf(stderr, "token: %s\n", std::string(bytes.status().message()).c_str());
      return 2;
    }
    std::cout << Base64UrlEncode(*bytes) << "\n";
    return 0;
  }

  spdlog::set_level(spdlog::level::from_str(log_level));
  if (!ParseReplicationMode(replication_mode, &rep.mode)) {
    spdlog::error("--replication-mode: unknown mode '{}'", replication_mode);
    return 2;
  }
  if (config.secret == kDevelopmentSecret) {
    spdlog::warn("using the built-in development secret: anyone can mint tokens. "
                 "Set --secret or EDGEPHYS_SECRET in production.");
  }
  auto endpoint = ParseEndpoint(bind);
  if (!endpoint.ok()) {
    spdlog::error("--bind {}: {}", bind, endpoint.status().message());
    return 2;
  }
  auto socket = UdpSocket::Open(*endpoint);
  if (!socket.ok()) {
    spdlog::error("cannot bind UDP {}: {}", bind, socket.status().message());
    return 1;
  }
  RelayCounters counters;
  std::unique_ptr<MetricsExporter> exporter;
  if (metrics != "off") {
    auto started = MetricsExporter::Start(metrics, &counters);
    if (!started.ok()) {
      spdlog::error("cannot serve metrics on {}: {}", metrics, started.status().message());
      return 1;
    }
    exporter = std::move(*started);
    // The port actually bound (an ephemeral one for port 0), so scripts can bind :0 and read it.
    const size_t colon = metrics.rfind(':');
    const std::string host = colon == std::string::npos ? "0.0.0.0" : metrics.substr(0, colon);
    spdlog::info("metrics on http://{}:{}/metrics", host, exporter->port());
  }
  if (io_threads > 1 && !redis.empty()) {
    spdlog::error("--redis is not supported with --io-threads > 1");
    return 2;
  }
  if (io_threads > 1) {
    if (admin_addr != "off") spdlog::warn("the admin API needs --io-threads 1; disabled");
    std::signal(SIGINT, OnSignal);
    std::signal(SIGTERM, OnSignal);
    RelayShardsOptions options;
    options.shards = io_threads;
    auto shards = RelayShards::Start(config, socket->get(), &counters, options);
    if (!shards.ok()) {
      spdlog::error("cannot start {} relay shards: {}", io_threads, shards.status().message());
      return 1;
    }
    spdlog::info("edgephys-relay listening on udp {} ({} shards)",
                 FormatEndpoint((*socket)->LocalEndpoint()), io_threads);
    const auto start = std::chrono::steady_clock::now();
    while (!g_stop.load()) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      double now = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      if (run_for_s > 0 && now >= run_for_s) break;
    }
    spdlog::info("shutting down");
    (*shards)->Stop();
    return 0;
  }
  const bool wake_on_datagram = !sleep_to_deadline;
  // --sleep-to-deadline: the loop sleeps until the relay's next deadline and drains what arrived in recvmmsg
  // batches; with --batching, sends leave in sendmmsg batches too (flushed at the end of every
  // Update). --wake-on-datagram: one datagram per call, unless --batching.
  BatchedSocket batched(socket->get(), /*batch_sends=*/batching);
  DatagramSocket* relay_socket = batching || !wake_on_datagram
                                     ? static_cast<DatagramSocket*>(&batched)
                                     : socket->get();
  Relay relay(config, relay_socket, &counters);
  if (!redis.empty()) {
    auto redis_endpoint = ParseEndpoint(redis);
    if (!redis_endpoint.ok()) {
      spdlog::error("--redis {}: {}", redis, redis_endpoint.status().message());
      return 2;
    }
    cluster::DirectoryOptions& d = cluster.directory;
    d.redis_host = redis_endpoint->address().to_string();
    d.redis_port = redis_endpoint->port();
    if (d.public_address.empty()) {
      Endpoint local = (*socket)->LocalEndpoint();
      if (local.address().is_unspecified()) {
        spdlog::error("--redis needs --public-address when --bind is a wildcard address");
        return 2;
      }
      d.public_address = FormatEndpoint(local);
    }
    if (d.relay_id.empty()) {
      d.relay_id = d.public_address;
      for (char& c : d.relay_id) c = (c == ':' || c == ' ') ? '-' : c;
    }
    d.heartbeat_s = cluster_heartbeat_ms / 1000.0;
    d.ttl_s = cluster_ttl_ms / 1000.0;
    d.refresh_s = d.heartbeat_s;
    d.redis_timeout_s = std::min(0.5, d.ttl_s / 2);
    cluster.snapshot_interval_s = cluster_snapshot_ms / 1000.0;
    Status joined = relay.EnableCluster(cluster);
    if (!joined.ok()) {
      spdlog::error("cannot join the cluster: {}", joined.ToString());
      return 2;
    }
    spdlog::info("cluster: relay '{}' at {} on redis {}", d.relay_id, d.public_address, redis);
  }
  spdlog::info("edgephys-relay listening on udp {}", FormatEndpoint((*socket)->LocalEndpoint()));
  // The admin API (docs/admin-api.md): its HTTP threads reach the relay only through
  // RelayAdmin's command queue, which the loop below drains.
  admin::RelayAdmin admin_backend(&relay, config.room_defaults);
  std::unique_ptr<admin::AdminHttpServer> admin_http;
  if (admin_addr != "off") {
    admin::AdminHttpOptions options;
    options.address = admin_addr;
    options.key = AdminKeyFromEnv(admin_key);
    auto started = admin::AdminHttpServer::Start(options, &admin_backend);
    if (started.ok()) {
      admin_http = std::move(*started);
      spdlog::info("admin API on http://{}/v1 (monitor: http://{}/monitor){}", admin_http->address(),
                   admin_http->address(), options.key.empty() ? ", no key" : "");
    } else if (admin_addr_opt->count() == 0 && started.status().code() == StatusCode::kIoError) {
      // The default address is taken (another relay on this host): run without the API.
      spdlog::warn("admin API disabled: {} ({}); pass --admin-addr", started.status().ToString(),
                   admin_addr);
    } else {
      spdlog::error("admin API: {}", started.status().ToString());
      return 2;
    }
  }

  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);
  const auto start = std::chrono::steady_clock::now();
  auto clock = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  while (!g_stop.load()) {
    if (wake_on_datagram) (*socket)->WaitReadable(0.002);
    double now = clock();
    relay.Update(now, UnixNow());
    admin_backend.Tick(now);
    if (admin_backend.ShouldExit()) break;  // a drain finished
    if (run_for_s > 0 && now >= run_for_s) break;
    if (wake_on_datagram) continue;
    // Sleep until the next room tick, PhyS step or connection timer (capped): datagrams that
    // arrive meanwhile wait in the socket's buffer (4 MiB) for the next Update's batches.
    const double wait = std::min(relay.NextDeadline(), now + max_sleep_s) - clock();
    if (wait > 0) std::this_thread::sleep_for(std::chrono::duration<double>(wait));
  }
  spdlog::info("shutting down");
  admin_backend.Close();  // requests waiting for the loop get 503 now, so Stop() is quick
  if (admin_http) admin_http->Stop();
  relay.Shutdown();
  return 0;
}
