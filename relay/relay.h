// Relay: the edgephys server. Admits clients through the handshake (protocol/handshake.h)
// with join tokens, hosts rooms, keeps every entity's owner and latest state, and fans state
// out to each room every tick.
//
// I/O and time are injected: the relay reads and writes datagrams only through the
// DatagramSocket it is given, and does work only inside Update(now). The process wrapper
// (main.cc) drives it from a UDP socket and a steady clock; tests drive it from an
// InMemoryNetwork or a NetworkSimulator with a fake clock.
//
// Untrusted input is never asserted on: every datagram or message that fails a check is
// dropped and counted in RelayCounters (packets_rejected / updates_rejected by DropReason,
// requests_rejected by RejectReason), with a rate-limited log line.
//
// Thread-safety: a Relay is owned by one thread (all methods from that thread); it writes
// RelayCounters with relaxed atomics, which other threads (the metrics exporter) may read.
// Cost: Update() is O(datagrams received + entities sent); the per-packet paths reuse buffers.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "protocol/connection.h"
#include "protocol/datagram_socket.h"
#include "protocol/handshake.h"
#include "protocol/join_token.h"
#include "protocol/state_codec.h"
#include "relay/physics_pool.h"
#include "relay/rate_limit.h"
#include "relay/relay_config.h"
#include "relay/relay_counters.h"
#include "relay/room.h"

namespace edgephys {

class Session;

// How a Relay runs as one of several shards over one socket (relay/relay_shards.h). The
// defaults are a standalone relay, which behaves exactly as without them.
struct RelayShardOptions {
  // This relay is shard `index` of `count`: the connection ids it allocates are all
  // congruent to `index` modulo `count`, so a router can find a session's shard from the id.
  uint32_t index = 0;
  uint32_t count = 1;
  // The handshake cookie key, shared by all shards (one shard may answer a Hello and another
  // check the Connect that follows). Unset: a random key of this relay's own.
  std::optional<CookieJar::Key> cookie_key;
  // Several relays write one RelayCounters: the gauges this relay would store() (rooms,
  // clients, PhyS bodies) are published as fetch_add of the change in its own value instead,
  // so the shared gauges hold the sums. Its contribution is withdrawn when it is destroyed.
  bool shared_counters = false;
};

class Relay {
 public:
  // `socket` and `counters` are not owned and must outlive the relay.
  Relay(const RelayConfig& config, DatagramSocket* socket, RelayCounters* counters,
        const RelayShardOptions& shard = {});
  ~Relay();
  Relay(const Relay&) = delete;
  Relay& operator=(const Relay&) = delete;

  // Receives and handles every pending datagram (up to config.max_datagrams_per_update),
  // updates connections (resends, keep-alives, timeouts), ticks due rooms and closes idle
  // ones. `now` is seconds on a monotonic clock; `unix_now_s` is wall time for token expiry.
  void Update(double now, uint64_t unix_now_s);

  // Operator API: creates (or reconfigures an empty) room. kAlreadyExists if occupied.
  Status CreateRoom(const std::string& name, const RoomConfig& config, double now);

  // Disconnects every client with kServerShutdown.
  void Shutdown();

  // Introspection for tests and the admin surface.
  const Room* FindRoom(const std::string& name) const;
  size_t room_count() const { return rooms_.size(); }
  size_t session_count() const { return sessions_.size(); }
  const ConnectionStats* FindConnectionStats(uint32_t player_id) const;
  // How many entities the replication state of `player_id`'s session covers
  // (ClientReplicator::tracked_entities()); 0 if no such session. At most the entities its
  // room has had since the session joined that are still there: an entity despawned, by its
  // owner or with its owner's leaving, is forgotten by every member. O(sessions).
  size_t ReplicatedEntityCount(uint32_t player_id) const;
  // Connection id of the worker simulating `room`'s PhyS; 0 if embedded or none.
  uint32_t PhysicsWorkerOf(const std::string& room) const;

 private:
  friend class Session;
  void HandleDatagram(const Endpoint& from, std::span<const uint8_t> data, double now,
                      uint64_t unix_now_s);
  void HandleHello(const Endpoint& from, std::span<const uint8_t> data, double now);
  void HandleConnect(const Endpoint& from, std::span<const uint8_t> data, double now,
                     uint64_t unix_now_s);
  void SendReject(const Endpoint& to, uint16_t reason, size_t request_size);
  // Sends a reply to an address that has not completed the handshake, refusing (and
  // counting) any reply larger than the datagram that provoked it.
  void SendUnverified(const Endpoint& to, std::span<const uint8_t> reply, size_t request_size);
  void Send(const Endpoint& to, std::span<const uint8_t> data);

  // Session -> relay callbacks.
  void OnJoinRoom(Session& s, std::string_view room, double now);
  void OnLeaveRoom(Session& s, double now);
  void OnSpawn(Session& s, std::span<const uint8_t> message, const schema::Spawn* spawn);
  void OnDespawn(Session& s, uint32_t entity_id);
  void OnGrab(Session& s, uint32_t entity_id, uint32_t hand_id);
  void OnRelease(Session& s, uint32_t entity_id);
  void BroadcastPhysicsEvent(Room& room, schema::PhysicsEventKind kind, uint32_t a, uint32_t b);
  // Steps every room's PhyS (embedded worlds in parallel on the pool; remote links collect
  // what their worker sent), failing over unhealthy links first, then applies the results.
  void StepAllPhysics(double now);
  // Folds one room's PhyS output into its entities and broadcasts its events.
  void ApplyPhysics(Room& room, const RoomPhysics::StepOutput& output, double now);
  // A PhyS link on the least loaded worker (not `exclude_worker`), else embedded.
  std::unique_ptr<PhysicsLink> MakePhysicsLink(uint32_t exclude_worker, double now);
  // Rebuilds the room's PhyS on a new link from the containers, states and velocities held.
  void FailOver(Room& room, double now);
  void OnWorkerHello(Session& s);
  void OnWorkerResult(Session& s, const schema::WorkerResult& result);
  void OnWorkerStates(Session& s, std::span<const uint8_t> payload);
  void OnStates(Session& s, std::span<const uint8_t> payload);
  void SendError(Session& s, uint16_t reason, uint32_t entity_id, std::string_view detail);

  void RemoveSession(uint32_t connection_id, double now);
  // Runs the replication tick of every due room, clients in parallel on the pool.
  void TickDueRooms(double now);
  void BroadcastReliable(Room& room, std::span<const uint8_t> message, uint32_t except_player);
  void CloseIdleRooms(double now);
  Room* GetOrCreateRoom(const std::string& name, double now);
  // Sets a gauge to `value` (shared counters: adds the change since the last publication).
  void PublishGauge(RelayCounters::Gauge& gauge, int64_t* published, int64_t value);

  RelayConfig config_;
  RelayShardOptions shard_;
  PhysicsPool physics_pool_;
  AddressRateLimiter handshake_limiter_;
  DatagramSocket* socket_;
  RelayCounters* counters_;
  CookieJar cookies_;
  ReplayGuard replay_guard_;
  std::map<std::string, std::unique_ptr<Room>> rooms_;
  std::unordered_map<uint32_t, std::unique_ptr<Session>> sessions_;  // by connection id
  std::map<Endpoint, uint32_t> session_by_endpoint_;
  std::vector<uint8_t> receive_buffer_;
  StateBatch batch_;
  std::vector<RoomPhysics::StepOutput> step_outputs_;  // one per room with physics
  std::vector<Room*> physics_rooms_;
  struct TickJob {
    Room* room;
    Session* session;
  };
  std::vector<TickJob> tick_jobs_;
  uint32_t next_room_handle_ = 0;
  double now_ = 0;
  double last_rtt_sample_ = 0;
  std::vector<uint32_t> removal_scratch_;
  // Gauge values last published (shared_counters only).
  int64_t published_rooms_ = 0;
  int64_t published_clients_ = 0;
  int64_t published_bodies_ = 0;
  int64_t published_sleeping_ = 0;
};

}  // namespace edgephys
