// Configuration of one relay process. Every field has a flag of the same name in
// edgephys-relay (relay/main.cc) and a key in its config file.
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
};

// The relay's connections: an ack owed for a client's unreliable payloads waits up to 20 ms
// for the client's next state datagram (rooms tick every 1/60 s by default) instead of
// leaving in a sealed datagram of its own; acks for reliable units leave at once. Reliable
// events leave at once by default; max_reliable_delay_s = 0.02 (--reliable-delay) makes those
// queued between two ticks wait for the next tick's state datagram (PhyS worker links: always
// at once). Off by default: the gate for the default, ccu 1,000 users / 40 rooms socket p99
// under 50 ms with it and --sleep-to-deadline, was not met in issue 11 session 10 (52.5 ms;
// without them 55.5 ms in the same sitting; docs/benchmarks.md, "Session 10"). The SDK
// example failures of session 9 were the test's own angle check.
inline ConnectionConfig RelayConnectionDefaults() {
  ConnectionConfig c;
  c.max_ack_delay_s = 0.02;
  return c;
}

struct RelayConfig {
  // The operator's secret for join tokens (HMAC-SHA256). The built-in default is for local
  // development only; the relay warns loudly when it is used.
  std::string secret = "edgephys-dev-secret";
  uint32_t max_clients = 4096;     // connections at once; beyond: ServerFull
  // Every packet after the handshake authenticated and encrypted (protocol/packet_seal.h);
  // off only to measure its cost: then a Connect without a key is accepted and not sealed.
  bool packet_auth = true;
  RoomConfig room_defaults;
  ConnectionConfig connection = RelayConnectionDefaults();
  physics::PhysicsConfig physics;  // each room's embedded PhyS world
  // Threads for embedded PhyS and the parallel replication tick, the relay's own thread
  // included. 1: PhyS steps synchronously on the relay's thread (deterministic; tests). N > 1:
  // N - 1 physics threads step rooms' worlds off the relay loop (relay/async_physics.h), which
  // hands commands over and picks finished steps up without ever waiting for one.
  size_t physics_threads = std::max(1u, std::thread::hardware_concurrency());
  // Niceness the N - 1 physics threads add to their own priority (Linux; 0..19, 0: none), so
  // that on a machine whose cores are all busy the relay loop's packets go before a heavy
  // room's physics, which then simulates slower (its real-time factor, a metric) instead of
  // delaying every room's hand poses and acks (relay/async_physics.h; docs/benchmarks.md,
  // "Isolation").
  int physics_nice = 0;
  // The physics threads run under SCHED_IDLE (Linux; physics_nice is then ignored): only on
  // cores the relay loop and other normal-priority work leave idle (AsyncPhysicsPool).
  bool physics_idle = false;
  size_t max_datagrams_per_update = 4096;  // receive batch bound per Update()
  AbuseLimits limits;
};

inline constexpr char kDevelopmentSecret[] = "edgephys-dev-secret";

}  // namespace edgephys
