#include "relay/relay_flags.h"

#include "relay/relay_shards.h"

namespace edgephys {
namespace {

constexpr char kNetwork[] = "Network";
constexpr char kAccess[] = "Access";
constexpr char kRooms[] = "Rooms and limits";
constexpr char kReplication[] = "Replication";
constexpr char kPhysics[] = "Physics";
constexpr char kCluster[] = "Cluster (Redis)";
constexpr char kAdmin[] = "Admin API and metrics";
constexpr char kLogging[] = "Logging and process";
// Tuning: read from the command line and the config file, not listed by --help
// (docs/operations.md, "Tuning options").
constexpr char kTuning[] = "";

// CLI::Range, with the option's name in the error (CLI11 leaves it out for config-file keys).
template <typename T>
CLI::Validator InRange(const char* option, T lo, T hi) {
  CLI::Range range(lo, hi);
  CLI::Validator named(
      [option, range](std::string& value) mutable {
        std::string error = range(value);
        return error.empty() ? error : std::string(option) + ": " + error;
      },
      range.get_description());
  return named;
}

void AddNetwork(CLI::App& app, RelayFlags* f) {
  RelayConfig& c = f->config;
  app.add_option("--bind", f->bind, "UDP address:port to serve")
      ->group(kNetwork)->capture_default_str();
  app.add_option("--io-threads", f->io_threads,
                 "Relay shards, each on its own thread, rooms spread over them")
      ->group(kNetwork)->capture_default_str()
      ->check(InRange("--io-threads", size_t{1}, RelayShards::kMaxShards));
  app.add_option("--max-clients", c.max_clients, "Connections at once")
      ->group(kNetwork)->capture_default_str();
  app.add_option("--timeout", c.connection.timeout_s,
                 "Seconds of silence before a client is dropped")
      ->group(kNetwork)->capture_default_str();
  app.add_option("--packet-auth", c.packet_auth,
                 "Seal every packet after the handshake (ChaCha20-Poly1305)")
      ->group(kTuning)->capture_default_str();
  app.add_option("--ack-delay", c.connection.max_ack_delay_s,
                 "Seconds an ack for unreliable payloads may wait for the next state datagram")
      ->group(kTuning)->capture_default_str()->check(InRange("--ack-delay", 0.0, 0.1));
}

void AddAccess(CLI::App& app, RelayFlags* f) {
  app.add_option("--secret", f->secret,
                 "Join token secret (default: $EDGEPHYS_SECRET, else a development secret)")
      ->group(kAccess);
}

void AddRooms(CLI::App& app, RelayFlags* f) {
  RoomConfig& room = f->config.room_defaults;
  RoomBudgets& budget = room.budgets;
  AbuseLimits& lim = f->config.limits;
  auto visible = [&](const char* name, auto& field, const char* help) {
    app.add_option(name, field, help)->group(kRooms)->capture_default_str();
  };
  auto tuning = [&](const char* name, auto& field, const char* help) {
    app.add_option(name, field, help)->group(kTuning)->capture_default_str();
  };
  visible("--room-capacity", room.capacity, "Players per room");
  visible("--room-ttl", room.idle_ttl_s, "Seconds an empty room is kept");
  app.add_option("--tick-rate", room.tick_rate_hz, "Room ticks per second")
      ->group(kRooms)->capture_default_str()->check(InRange("--tick-rate", 1.0, 1000.0));
  visible("--max-entities-per-player", room.max_entities_per_player,
          "Entities one player may own in a room");
  visible("--max-room-entities", budget.max_entities, "Entities in one room (0: off)");
  visible("--max-room-bodies", budget.max_bodies, "PhyS bodies in one room");
  visible("--max-room-particles", budget.max_particles, "Soft-body particles in one room");
  visible("--max-spawn-bytes", lim.max_spawn_bytes, "Largest accepted container (bytes)");
  visible("--max-packets-per-s", lim.packets_per_s, "Per-connection packet rate (0: off)");
  visible("--max-bytes-per-s", lim.bytes_per_s, "Per-connection byte rate (0: off)");
  visible("--max-connections-per-address", lim.max_sessions_per_address,
          "Live connections from one IP address");
  tuning("--max-player-bytes", budget.max_bytes_per_player, "Stored spawn bytes per player");
  tuning("--max-room-bytes", budget.max_bytes, "Stored spawn bytes in one room");
  tuning("--max-player-bodies", budget.max_bodies_per_player, "PhyS bodies per player");
  tuning("--max-player-particles", budget.max_particles_per_player,
         "Soft-body particles per player");
  tuning("--max-player-joints", budget.max_joints_per_player, "PhyS joints per player");
  tuning("--max-room-joints", budget.max_joints, "PhyS joints in one room");
  tuning("--max-name-bytes", budget.max_name_bytes, "Longest entity name (bytes)");
  tuning("--max-spawns-per-s", lim.spawns_per_s, "Per-connection spawn rate");
  tuning("--max-handshakes-per-s", lim.handshakes_per_s, "Hello/Connect per source address");
  tuning("--join-timeout", lim.join_timeout_s, "Seconds a connection may stay without a room");
  tuning("--max-reassembly-bytes", lim.max_reassembly_bytes,
         "Bytes of partial reliable messages all connections may hold (0: no cap)");
}

void AddReplication(CLI::App& app, RelayFlags* f) {
  ReplicationConfig& rep = f->config.room_defaults.replication;
  auto rate = [&](const char* name, double& field, const char* help, const char* group) {
    app.add_option(name, field, help)->group(group)->capture_default_str()
        ->check(InRange(name, 1.0, 240.0));
  };
  rate("--critical-hz", rep.critical_hz, "Send rate of avatars, hands, grabbed objects",
       kReplication);
  rate("--normal-hz", rep.normal_hz, "Send rate of other moving entities", kReplication);
  rate("--ambient-hz", rep.ambient_hz, "Send rate of PhyS bodies nobody interacts with",
       kReplication);
  rate("--soft-touched-hz", rep.soft_touched_hz, "Send rate of a soft body a hand touches",
       kTuning);
  app.add_option("--position-step", rep.position_step_m, "Position quantisation step (m)")
      ->group(kReplication)->capture_default_str()->check(InRange("--position-step", 1e-5, 1.0));
  app.add_option("--rotation-bound", rep.rotation_bound_deg, "Rotation error bound (deg)")
      ->group(kReplication)->capture_default_str()->check(InRange("--rotation-bound", 0.001, 10.0));
  app.add_option("--client-budget", rep.bandwidth_budget_bytes_per_s,
                 "Per-client bandwidth budget (bytes/s; 0: unlimited)")
      ->group(kReplication)->capture_default_str();
  app.add_option("--interaction-linger", rep.interaction_linger_s,
                 "Seconds an entity stays out of the ambient class after an interaction")
      ->group(kTuning)->capture_default_str()->check(InRange("--interaction-linger", 0.0, 3600.0));
  app.add_flag("--shared-encoding,!--no-shared-encoding", rep.shared_encoding,
               "Encode each entity delta once per room tick for all receivers (format 9; "
               "default: on)")
      ->group(kTuning);
}

void AddPhysics(CLI::App& app, RelayFlags* f) {
  RelayConfig& c = f->config;
  app.add_option("--physics-threads", c.physics_threads,
                 "Threads for embedded PhyS, the relay's included (1: on the relay's thread)")
      ->group(kPhysics)->capture_default_str();
  app.add_option("--physics-nice", c.physics_nice,
                 "Niceness added to the physics threads (0..19), so the relay loop goes first")
      ->group(kPhysics)->capture_default_str()->check(InRange("--physics-nice", 0, 19));
  app.add_flag("--physics-idle", c.physics_idle,
               "Physics threads under SCHED_IDLE (overrides --physics-nice; default: off)")
      ->group(kTuning);
}

void AddCluster(CLI::App& app, RelayFlags* f) {
  app.add_option("--redis", f->redis, "Join a cluster of relays over this Redis (host:port)")
      ->group(kCluster);
  app.add_option("--relay-id", f->cluster.directory.relay_id,
                 "Unique id of this relay (default: from --public-address)")
      ->group(kCluster);
  app.add_option("--public-address", f->cluster.directory.public_address,
                 "host:port clients reach this relay at, sent in redirects (default: --bind)")
      ->group(kCluster);
  app.add_option("--cluster-snapshot-ms", f->cluster_snapshot_ms,
                 "Rooms' state written to Redis at most this often")
      ->group(kTuning)->capture_default_str()->check(InRange("--cluster-snapshot-ms", 20.0, 60000.0));
  app.add_option("--cluster-heartbeat-ms", f->cluster_heartbeat_ms,
                 "Registration refreshed this often")
      ->group(kTuning)->capture_default_str()->check(InRange("--cluster-heartbeat-ms", 10.0, 60000.0));
  app.add_option("--cluster-ttl-ms", f->cluster_ttl_ms,
                 "A relay silent this long is dead and its rooms fail over")
      ->group(kTuning)->capture_default_str()->check(InRange("--cluster-ttl-ms", 50.0, 600000.0));
}

void AddAdmin(CLI::App& app, RelayFlags* f) {
  app.add_option("--metrics", f->metrics, "Prometheus address:port ('off' to disable)")
      ->group(kAdmin)->capture_default_str();
  f->admin_addr_opt =
      app.add_option("--admin-addr", f->admin_addr,
                     "Admin API and /monitor address:port ('off'; non-loopback needs a key)")
          ->group(kAdmin)->capture_default_str();
  app.add_option("--admin-key", f->admin_key,
                 "Admin API bearer key (default: $EDGEPHYS_ADMIN_KEY; none: loopback only)")
      ->group(kAdmin);
}

void AddLogging(CLI::App& app, RelayFlags* f) {
  app.add_option("--log-level", f->log_level, "trace|debug|info|warn|error|off")
      ->group(kLogging)->capture_default_str()
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error", "critical", "off"}));
  app.add_option("--run-for", f->run_for_s, "Exit after this many seconds (0: until a signal)")
      ->group(kLogging)->capture_default_str();
}

void AddToken(CLI::App& app, RelayFlags* f) {
  f->token_cmd = app.add_subcommand("token", "Mint a client join token (base64url: the relay part and the player's session secret; hand it to the player over a secure channel)");
  f->token.room = "lobby";
  f->token_cmd->add_option("--room", f->token.room, "Room the token grants")
      ->capture_default_str();
  f->token_cmd->add_option("--player", f->token.player_id, "Player id (non-zero)")->required();
  f->token_cmd->add_option("--ttl", f->token_ttl_s, "Seconds until the token expires")
      ->capture_default_str();
  f->token_cmd->add_option("--permissions", f->token.permissions, "Permission bits (1: spawn)")
      ->capture_default_str();
  f->token_cmd->add_option("--secret", f->secret, "The relay's secret (default: $EDGEPHYS_SECRET)");
  f->token_cmd->add_flag("--dev-secret", f->token_dev_secret,
                         "Sign with the built-in development secret (a relay run without one)");
}

}  // namespace

void AddRelayFlags(CLI::App& app, RelayFlags* flags) {
  AddNetwork(app, flags);
  AddAccess(app, flags);
  AddRooms(app, flags);
  AddReplication(app, flags);
  AddPhysics(app, flags);
  AddCluster(app, flags);
  AddAdmin(app, flags);
  AddLogging(app, flags);
  app.set_config("--config", "", "Read options from a TOML/INI config file")->group(kLogging);
  AddToken(app, flags);
}

Status FinishRelayFlags(RelayFlags* flags) {
  flags->admin_addr_given = flags->admin_addr_opt != nullptr && flags->admin_addr_opt->count() > 0;
  const ReplicationConfig& rep = flags->config.room_defaults.replication;
  if (Result<QuantizationParams> q = MakeQuantizationParams(QuantizationOf(rep)); !q.ok()) {
    return Status::InvalidArgument("--position-step / --rotation-bound: not a usable quantisation",
                                   std::string(q.status().message()));
  }
  return Status::Ok();
}

}  // namespace edgephys
