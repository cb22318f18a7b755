// Configuration of one relay process: one line per field (meaning, unit, default). The
// edgephys-relay command line and config file set them (relay/relay_flags.h).
#pragma once

#include <cstdint>
#include <algorithm>
#include <string>
#include <thread>

#include "protocol/connection.h"
#include "physics_backend/physics_world.h"
#include "relay/replication.h"
#include "relay/room_budget.h"

namespace edgephys {

struct RoomConfig {
  uint32_t capacity = 64;          // players at once; joins beyond get RoomFull
  double idle_ttl_s = 300.0;       // an empty room is closed after this long
  double tick_rate_hz = 60.0;      // replication ticks per second
  uint32_t max_entities_per_player = 1024;  // per player identity, also after it leaves
  RoomBudgets budgets;             // room-wide and per-player caps (relay/room_budget.h)
  // PhyS for this room: false refuses spawns with physics components (InvalidContainer).
  bool physics = true;
  ReplicationConfig replication;   // encoder, send rates by priority class, thresholds, budget
};

// Limits on what one peer may cost the relay. A packet over a session's limits is dropped
// before it is parsed (and so not acknowledged: reliable data is resent later); a spawn over
// its limits is refused with Error{RateLimited}. 0 disables a rate.
struct AbuseLimits {
  double packets_per_s = 1500;           // per session (bursts of 2 s allowed)
  double bytes_per_s = 512 * 1024;       // per session
  double spawns_per_s = 500;             // per session, burst 20x (a scene's dissection)
  size_t max_spawn_bytes = 512 * 1024;   // one container
  double handshakes_per_s = 20;          // Hello/Connect per source address, burst 40
  size_t max_sessions_per_address = 64;  // live connections from one IP address
  double join_timeout_s = 10;            // a connection that joins no room by then is dropped
  // Bytes all connections together may hold for clients' partial reliable messages
  // (reassembly and out-of-order units; each connection also stays under
  // ConnectionConfig::max_held_reliable_bytes + kReliableHeldSlack). Past it, the connection
  // holding the most is ended (kicked) and counted. 0: no relay-wide cap.
  size_t max_reassembly_bytes = size_t{128} << 20;
};

// The relay's connections: an ack owed for a client's unreliable payloads waits up to 20 ms
// for the client's next state datagram instead of leaving in a datagram of its own.
inline ConnectionConfig RelayConnectionDefaults() {
  ConnectionConfig c;
  c.max_ack_delay_s = 0.02;
  return c;
}

struct RelayConfig {
  std::string secret = "edgephys-dev-secret";  // join-token HMAC key; the default is for development
  uint32_t max_clients = 4096;       // connections at once; beyond: ServerFull
  bool packet_auth = true;           // seal every packet after the handshake; false only to measure
  RoomConfig room_defaults;          // rooms created without an explicit configuration
  ConnectionConfig connection = RelayConnectionDefaults();  // timeouts, ack delay
  physics::PhysicsConfig physics;    // each room's embedded PhyS world
  // Threads for embedded PhyS, the relay's own included. 1: PhyS steps on the relay's thread
  // (deterministic; tests). N > 1: N - 1 threads step rooms' worlds off the relay loop.
  size_t physics_threads = std::max(1u, std::thread::hardware_concurrency());
  int physics_nice = 0;              // niceness added to the physics threads (0..19)
  bool physics_idle = false;         // physics threads under SCHED_IDLE (overrides physics_nice)
  size_t max_datagrams_per_update = 4096;  // receive batch bound per Update()
  AbuseLimits limits;                // what one peer may cost the relay
};

inline constexpr char kDevelopmentSecret[] = "edgephys-dev-secret";

}  // namespace edgephys
