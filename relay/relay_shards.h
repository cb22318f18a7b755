// RelayShards: one relay spread over several cores. N Relay instances ("shards") each run on a
// thread of their own over ONE real UdpSocket; every room, and every session in it, lives on
// exactly one shard and is touched only by that shard's thread.
//
//   receive thread:  recvmmsg(2) batches -> route each datagram -> shard's SPSC ring -> wake
//   shard thread i:  pop its ring (as its Relay's DatagramSocket) -> Relay::Update ->
//                    sendmmsg(2) of everything that Update sent
//
// Routing (no shared mutable state; a pure function of the datagram and its source):
//   Data / Disconnect       connection id % N. Shard i allocates only ids = i (mod N)
//                           (RelayShardOptions), so a session's packets reach its shard.
//   Connect                 a player token: hash of the token's room name, so each room (and
//                           every token for it, hence per-room replay protection) lives on one
//                           shard. A worker token (kPermissionWorker): hash of the token's
//                           nonce (workers spread over shards; a replayed token still meets
//                           the same ReplayGuard). Each shard gives its physics rooms to the
//                           workers attached to it, else runs them embedded: attach at least N
//                           workers to offload every shard. Worker tokens should not be used to
//                           join rooms (such a session joins on the nonce's shard).
//   Hello                   hash of the source address (the shards share one cookie key, so
//                           any shard can check the Connect that follows).
//   anything else/malformed hash of the source address; that shard drops and counts it exactly
//                           as a single relay does (packets_rejected{reason}).
// Zero-length datagrams are discarded uncounted, as the single-threaded loop does.
//
// Limits: config.max_clients is split evenly (each shard admits ceil(max_clients / N)), so a
// shard whose rooms are popular can refuse (ServerFull) while others have room.
// config.physics_threads is split too (each shard max(1, physics_threads / N)). Per-address
// limits (handshakes_per_s, max_sessions_per_address) are enforced per shard: one address may
// reach up to N times them when its connections span rooms on different shards. A client that
// restarts with a token for a room on another shard leaves its old session to time out.
//
// Counters: all shards write the one RelayCounters (relaxed atomic adds; gauges as deltas), so
// the exporter's totals are the sums. A datagram whose shard ring is full is dropped and
// counted in io_queue_drops (not in packets_received). packets_sent / bytes_sent count a
// datagram when its shard queues it; one the kernel then refuses at sendmmsg is also counted
// in send_errors.
//
// Thread-safety: Start/Stop/destructor from one controlling thread; RunOnShard, CreateRoom,
// stats and the routing functions from any thread. The receive thread alone reads the socket;
// shard threads only call UdpSocket::SendBatch (safe concurrently, see udp_socket.h).
// Cost per datagram: one routing hash (a FlatBuffers verify for a Connect), one copy into the
// ring, and its share of one recvmmsg/sendmmsg system call per up to 64 datagrams.
#pragma once

#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "protocol/status.h"
#include "protocol/udp_socket.h"
#include "relay/relay.h"
#include "relay/relay_config.h"
#include "relay/relay_counters.h"

namespace edgephys {

struct RelayShardsOptions {
  size_t shards = 2;             // 1..kMaxShards
  size_t queue_capacity = 4096;  // datagrams per shard ring (rounded up to a power of two)
  double idle_wait_s = 0.001;    // longest a shard sleeps without datagrams (timer granularity)
};

class RelayShards {
 public:
  static constexpr size_t kMaxShards = 64;

  // Starts `options.shards` relays over `socket`, each on its own thread, and the receive
  // thread. `socket` and `counters` are not owned and must outlive this object. `now` passed
  // to the relays is seconds since Start(). kInvalidArgument for a shard count outside
  // 1..kMaxShards, a zero queue capacity or a null pointer.
  static Result<std::unique_ptr<RelayShards>> Start(const RelayConfig& config, UdpSocket* socket,
                                                    RelayCounters* counters,
                                                    const RelayShardsOptions& options);
  // Stop() if still running.
  ~RelayShards();
  RelayShards(const RelayShards&) = delete;
  RelayShards& operator=(const RelayShards&) = delete;

  // Stops receiving, lets each shard handle what it has queued, disconnects every client
  // (kServerShutdown, sent before it returns) and joins all threads. Idempotent.
  void Stop();

  size_t shard_count() const { return shards_.size(); }

  // Routing (pure functions of their arguments and the shard count).
  size_t ShardOfRoom(std::string_view room) const;
  size_t Route(const Endpoint& from, std::span<const uint8_t> datagram) const;

  // Runs fn(relay, now) on shard `shard`'s thread, between two Updates, and waits for it to
  // finish. For the operator API and introspection; not for the hot path (it takes a mutex
  // and wakes the shard). Returns false, without running fn, once the shard has stopped or
  // when `shard` is out of range.
  bool RunOnShard(size_t shard, const std::function<void(Relay&, double now)>& fn);

  // Operator API: Relay::CreateRoom on the room's shard. kNotConnected after Stop().
  Status CreateRoom(const std::string& name, const RoomConfig& config);

  struct ShardStats {
    uint64_t datagrams_queued = 0;  // routed to this shard
    uint64_t queue_drops = 0;       // dropped: this shard's ring was full
    uint64_t updates = 0;           // Relay::Update calls
    uint64_t send_batches = 0;      // sendmmsg batches flushed
    uint64_t send_refused = 0;      // datagrams the kernel refused at flush
    size_t rooms = 0;               // as of the shard's last Update
    size_t sessions = 0;
  };
  // A snapshot (relaxed reads; fields may be from slightly different moments).
  ShardStats stats(size_t shard) const;

 private:
  struct Shard;
  RelayShards(UdpSocket* socket, RelayCounters* counters, const RelayShardsOptions& options);
  void ReceiveLoop();
  void ShardLoop(Shard& shard);
  double Now() const;

  UdpSocket* socket_;
  RelayCounters* counters_;
  RelayShardsOptions options_;
  std::vector<std::unique_ptr<Shard>> shards_;
  std::thread receiver_;
  std::atomic<bool> stop_receiving_{false};
  bool stopped_ = false;
  std::chrono::steady_clock::time_point start_;
};

}  // namespace edgephys
