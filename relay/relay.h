// Relay: the edgephys server's front. It owns the socket, admits clients through the
// handshake (protocol/handshake.h) with join tokens, keeps their Sessions and dispatches
// datagrams to them, and drives the rooms: each RoomHost (relay/room_host.h) holds one room's
// rules and state; the WorkerDirectory (relay/worker_directory.h) places rooms' PhyS.
//
// Data flow of one state update: socket -> Relay::HandleDatagram -> Session (connection) ->
// RoomHost::ApplyStates; on the room's tick, RoomHost::BeginTick picks the receivers and each
// Session's replicator writes its datagrams to the socket.
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
#include <limits>
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
#include "relay/bulk_tick_scheduler.h"
#include "relay/physics_pool.h"
#include "relay/rate_limit.h"
#include "relay/relay_config.h"
#include "relay/relay_counters.h"
#include "relay/room_host.h"
#include "relay/room_work_times.h"
#include "relay/session.h"
#include "relay/worker_directory.h"

namespace edgephys {

class ClusterHook;
struct ClusterOptions;

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

class Relay final : private SessionHost {
  friend class ClusterHook;  // reads rooms and sessions, creates restored rooms

 public:
  // `socket` and `counters` are not owned and must outlive the relay.
  Relay(const RelayConfig& config, DatagramSocket* socket, RelayCounters* counters,
        const RelayShardOptions& shard = {});
  ~Relay() override;
  Relay(const Relay&) = delete;
  Relay& operator=(const Relay&) = delete;

  // Receives and handles every pending datagram (up to config.max_datagrams_per_update),
  // steps PhyS, updates connections (resends, keep-alives, timeouts), ticks due rooms and
  // closes idle ones. `now` is seconds on a monotonic clock; `unix_now_s` is wall time for
  // token expiry.
  void Update(double now, uint64_t unix_now_s);


  // Operator API: creates (or reconfigures an empty) room. kInvalidArgument for a bad name or
  // config, kAlreadyExists if the room has members or entities.
  Status CreateRoom(const std::string& name, const RoomConfig& config, double now);

  // Disconnects every client with kServerShutdown.
  void Shutdown();

  // Joins a cluster of relays over Redis (relay/cluster_hook.h): rooms placed across relays,
  // Connects for rooms elsewhere redirected, rooms of dead relays restored here. Without it
  // (the default) the relay runs alone, exactly as before. kInvalidArgument on bad options.
  Status EnableCluster(const ClusterOptions& options);
  // Null unless EnableCluster succeeded.
  const ClusterHook* cluster() const { return cluster_.get(); }

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

  // --- Operator surface (the admin API, relay/relay_admin.h). Relay thread only. ---------
  const std::map<std::string, std::unique_ptr<RoomHost>>& rooms() const { return rooms_; }
  // The session of member `player_id` of `room`; null if it is not a member.
  const Session* FindMemberSession(const std::string& room, uint32_t player_id) const;
  // Ends member `player_id`'s connection with kKicked and `reason` (Session::BeginClose: the
  // SDK reports the reason) and removes it from the room at once. kNotFound if not a member.
  Status Kick(const std::string& room, uint32_t player_id, std::string_view reason, double now);
  // Kicks every member with `reason`, then removes the room with its entities and PhyS.
  // kNotFound if there is no such room.
  Status CloseRoom(const std::string& name, std::string_view reason, double now);
  // Ends every client connection (not PhyS workers) with kServerShutdown and `reason`.
  void CloseAllSessions(std::string_view reason, double now);
  // While not admitting (a drain): Connects are rejected (ServerFull), JoinRoom is refused
  // (Error{ServerFull}) and CreateRoom fails with kResourceExhausted. Default: admitting.
  void set_admitting(bool admitting) { admitting_ = admitting; }
  bool admitting() const { return admitting_; }
  // Client sessions (PhyS workers not counted), in a room or not. O(sessions).
  size_t client_count() const;

 private:
  // Cluster: another relay holds `name`'s lease now. Its members' connections end with
  // kServerShutdown and `reason` (the SDK resumes and is redirected to the owner) and the
  // local copy is dropped without a snapshot. No-op if the room is not here.
  void HandOverRoom(const std::string& name, std::string_view reason, double now);

  // Admission: the handshake and the socket.
  void HandleDatagram(const Endpoint& from, std::span<const uint8_t> data, double now,
                      uint64_t unix_now_s);
  // A data or disconnect packet of an established session: opened and handed to its
  // connection; its time charged to the session's room.
  void HandleSessionPacket(Session& s, std::span<const uint8_t> data, double now);
  // Publishes `s`'s reassembly bytes (RelayCounters::reassembly_held_bytes) after a packet;
  // when they grew the relay-wide sum past AbuseLimits::max_reassembly_bytes, ends the largest
  // client holders (kicked, counted in reassembly_evictions; never a PhyS worker, never one
  // holding less than an even share of the cap) until it is back under. O(sessions) per
  // eviction.
  void AccountReassembly(Session& s, double now);
  // Sets `s`'s share of the reassembly gauge to `held` bytes.
  void PublishHeld(Session& s, size_t held);
  // Whether `room` ticks in the bulk pass (more than kBulkRoomEntities entities at its last tick).
  static bool IsBulk(const RoomHost& room) { return room.room().frame().by_id.size() > kBulkRoomEntities; }
  // Handles the datagrams of bulk rooms' members that this update's receive loop set aside.
  void HandleDeferredDatagrams(double now);
  // A room is about to be destroyed: its per-room work series goes.
  void ForgetRoomWork(const RoomHost& room);
  void HandleHello(const Endpoint& from, std::span<const uint8_t> data, double now);
  void HandleConnect(const Endpoint& from, std::span<const uint8_t> data, double now,
                     uint64_t unix_now_s);
  // Makes the session of an admitted Connect and answers Accept (carrying the relay's proof,
  // chained to `connect_proof`). `client_key` empty: packets unsealed (packet_auth off).
  void Admit(const Endpoint& from, const JoinToken& token, std::span<const uint8_t> token_bytes,
             std::span<const uint8_t> client_key, uint64_t client_nonce,
             const HandshakeProof& connect_proof, double now);
  void SendReject(const Endpoint& to, uint16_t reason, size_t request_size);
  // Sends a reply to an address that has not completed the handshake, refusing (and
  // counting) any reply larger than the datagram that provoked it.
  void SendUnverified(const Endpoint& to, std::span<const uint8_t> reply, size_t request_size);

  // SessionHost: what sessions ask of the relay.
  void OnJoinRoom(Session& s, std::string_view room, double now) override;
  void OnLeaveRoom(Session& s, double now) override;
  void OnWorkerHello(Session& s) override;
  void OnWorkerResult(Session& s, const schema::WorkerResult& result) override;
  void OnWorkerStates(Session& s, std::span<const uint8_t> payload) override;
  void Transmit(const Endpoint& to, std::span<const uint8_t> data) override;
  void OnServiceSoon(Session& s) override;

  // Services every connection (resends, keep-alives, timeouts), removes the closed ones, and
  // with `sample_rtt` records every connection's RTT.
  void UpdateSessions(double now, bool sample_rtt);
  void RemoveSession(uint32_t connection_id, double now);
  // Steps every room's PhyS (embedded worlds in parallel on the pool; remote links collect
  // what their worker sent), failing over unhealthy links first, then applies the results.
  void StepAllPhysics(double now);
  // Runs the replication tick of every due room, receivers in parallel on the pool.
  void TickDueRooms(double now);
  void CloseIdleRooms(double now);
  // Hands a batching socket's queued datagrams to the OS (DatagramSocket::Flush).
  void FlushSends();
  RoomHost& GetOrCreateRoom(const std::string& name, double now);
  RoomHostEnv room_env() { return RoomHostEnv{&config_.limits, counters_, &workers_}; }
  // Publishes the rooms, clients and (once a second) PhyS gauges.
  void PublishGauges(bool physics);
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
  // Declared before the rooms: remote links (held by rooms) unregister from it when destroyed.
  WorkerDirectory workers_;
  std::map<std::string, std::unique_ptr<RoomHost>> rooms_;
  std::unordered_map<uint32_t, std::unique_ptr<Session>> sessions_;  // by connection id
  std::map<Endpoint, uint32_t> session_by_endpoint_;
  std::vector<uint8_t> receive_buffer_;
  std::vector<PhysicsLink::StepOutput> step_outputs_;  // one per room with physics
  std::vector<RoomHost*> physics_rooms_;
  std::vector<PhysicsLink*> physics_links_;
  struct TickJob {
    const ReplicationFrame* frame;
    MemberLink* member;
    RoomHost* room;
    double seconds;  // the job's replication time, for the room's work metric
  };
  std::vector<TickJob> tick_jobs_;
  // Rooms with more entities than this tick in a second pass, after the others' datagrams are
  // sent (TickDueRooms).
  static constexpr size_t kBulkRoomEntities = 1024;
  std::vector<RoomHost*> bulk_rooms_;
  // Due bulk rooms wait for an imminent light room's tick (relay/bulk_tick_scheduler.h); one
  // that waits is held until bulk_hold_until_.
  BulkTickScheduler bulk_scheduler_;
  double bulk_hold_until_ = -std::numeric_limits<double>::infinity();
  // Datagrams of members of bulk rooms received in this update, handled after the light rooms'
  // tick and before the bulk rooms' (HandleDeferredDatagrams): a bulk room's acks (its
  // receivers acknowledging thousand-entity packets) never delay a light room's tick. At most
  // config.max_datagrams_per_update, so bounded by one update's receive loop.
  struct DeferredDatagram {
    Endpoint from;
    uint32_t connection_id;
    size_t offset;
    size_t size;
  };
  std::vector<DeferredDatagram> deferred_;
  std::vector<uint8_t> deferred_bytes_;
  bool deferring_ = false;  // inside Update's receive loop
  RoomWorkLedger room_work_;
  std::vector<MemberLink*> receivers_;
  double now_ = 0;
  bool admitting_ = true;
  double last_rtt_sample_ = 0;
  // The earliest Session::service_at() after the last UpdateSessions (-infinity: at once).
  // The earliest timer of any session at the last full pass over them: until then a pass
  // services only the sessions made due since (due_sessions_, connection ids).
  double sessions_deadline_ = -std::numeric_limits<double>::infinity();
  std::vector<uint32_t> due_sessions_, due_scratch_;
  void ServiceSession(uint32_t id, Session& s, double now, double* next);
  std::vector<uint32_t> removal_scratch_;
  // Gauge values last published (shared_counters only).
  int64_t published_rooms_ = 0;
  int64_t published_clients_ = 0;
  int64_t published_bodies_ = 0;
  int64_t published_sleeping_ = 0;
  // Last: destroyed first (its directory thread stops before the rooms go).
  std::unique_ptr<ClusterHook> cluster_;
};

}  // namespace edgephys
