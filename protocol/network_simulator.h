// NetworkSimulator: a DatagramSocket decorator that makes the network worse on purpose: loss,
// duplication, latency with jitter, and reordering, all deterministic for a given seed and
// driven by injected time. Part of edgephys::protocol so that the tests and the load
// generator's impaired bots (loadgen ccu --impaired) share one model; nothing in the relay or
// the SDK creates one. ImpairedSocket (below) impairs both directions of one socket.
//
// SendTo() decides the fate of each datagram at once (drawing from a std::mt19937_64 seeded
// with NetworkConditions::seed) and queues every copy that survives with a delay; Update(now)
// forwards to the inner socket, in order of due time (ties in send order), every copy whose
// time has come. A datagram sent at time t (the `now` of the latest Update(), 0 before the
// first) with delay d leaves at the first Update() with now >= t + d. Receiving is not
// simulated: ReceiveFrom() and LocalEndpoint() pass straight through, so wrap both ends to
// impair both directions.
//
// Ownership: `inner` is not owned and must outlive the simulator. Memory: at most
// `max_queued` datagrams are held (a send beyond that is dropped and counted); their buffers
// are reused, so steady-state operation does not allocate.
// Thread-safety: none. Cost: O(log queued) per datagram plus the copy.
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <random>
#include <vector>

#include "protocol/datagram_socket.h"
#include "protocol/datagram_delay_queue.h"

namespace edgephys {

struct NetworkConditions {
  double loss = 0;       // probability a datagram is dropped
  double duplicate = 0;  // probability a surviving datagram is delivered twice
  double reorder = 0;    // probability a datagram gets an extra delay so later ones overtake it
  double latency_s = 0;  // one-way delay
  double jitter_s = 0;   // delay varies uniformly within latency_s +- jitter_s (never below 0)
  uint64_t seed = 1;
  double reorder_delay_s = 0.02;  // the extra delay of a reordered datagram (up to this much)
};

struct NetworkSimulatorStats {
  uint64_t sent = 0;          // datagrams handed to SendTo()
  uint64_t dropped = 0;       // lost on purpose (NetworkConditions::loss)
  uint64_t duplicated = 0;    // extra copies made
  uint64_t delayed = 0;       // given a reordering delay
  uint64_t queue_full = 0;    // copies dropped because max_queued datagrams were waiting
  uint64_t forwarded = 0;     // copies handed to the inner socket
  uint64_t inner_errors = 0;  // inner SendTo() failures
};

class NetworkSimulator final : public DatagramSocket {
 public:
  static constexpr size_t kDefaultMaxQueued = 16384;

  explicit NetworkSimulator(DatagramSocket* inner, const NetworkConditions& conditions = {},
                            size_t max_queued = kDefaultMaxQueued);

  // Replaces the conditions and re-seeds the generator from conditions.seed. Datagrams already
  // queued keep their delays.
  void SetConditions(const NetworkConditions& conditions);
  const NetworkConditions& conditions() const { return conditions_; }

  // Forwards every queued datagram due at `now` (seconds, monotonic, injected).
  void Update(double now);

  // Always Ok: the datagram is queued or dropped by the simulation (see stats()).
  Status SendTo(const Endpoint& to, std::span<const uint8_t> data) override;
  size_t ReceiveFrom(Endpoint* from, std::span<uint8_t> buffer) override;
  Endpoint LocalEndpoint() const override;

  size_t queued() const { return queue_.size(); }
  const NetworkSimulatorStats& stats() const { return stats_; }

 private:
  double Uniform();  // [0, 1)
  void Enqueue(const Endpoint& to, std::span<const uint8_t> data);

  DatagramSocket* inner_;
  NetworkConditions conditions_;
  size_t max_queued_;
  std::mt19937_64 rng_;
  double now_ = 0;
  DatagramDelayQueue<Endpoint> queue_;  // copies waiting, by destination
  NetworkSimulatorStats stats_;
};

// ImpairedSocket: one socket whose two directions both cross a NetworkSimulator, as a client
// on a bad link sees it: what it sends goes through `up`, what arrives through `down` (held in
// an inbox until due). Update(now) releases both directions; ReceiveFrom() first takes every
// datagram waiting in `inner` into the down simulator, then returns the next one due.
// Arrival times are the read (ReceiveFromTimed reports 0: unknown).
//
// Ownership: `inner` is not owned and must outlive this socket. Memory: at most
// NetworkSimulator::kDefaultMaxQueued datagrams per direction, plus those due and not yet read.
// Thread-safety: none. Cost: a NetworkSimulator's per datagram and direction, plus one copy.
class ImpairedSocket final : public DatagramSocket {
 public:
  ImpairedSocket(DatagramSocket* inner, const NetworkConditions& up,
                 const NetworkConditions& down);

  void Update(double now);  // seconds, monotonic, injected

  Status SendTo(const Endpoint& to, std::span<const uint8_t> data) override;
  size_t ReceiveFrom(Endpoint* from, std::span<uint8_t> buffer) override;
  Endpoint LocalEndpoint() const override;

  const NetworkSimulatorStats& up_stats() const { return up_.stats(); }
  const NetworkSimulatorStats& down_stats() const { return down_.stats(); }

 private:
  // The down simulator's "network": due datagrams wait here for ReceiveFrom().
  class Inbox final : public DatagramSocket {
   public:
    Status SendTo(const Endpoint& from, std::span<const uint8_t> data) override;
    size_t ReceiveFrom(Endpoint* from, std::span<uint8_t> buffer) override;
    Endpoint LocalEndpoint() const override { return {}; }

   private:
    struct Datagram {
      Endpoint from;
      std::vector<uint8_t> data;
    };
    std::deque<Datagram> due_;
  };

  DatagramSocket* inner_;
  Inbox inbox_;
  NetworkSimulator up_;
  NetworkSimulator down_;
  double now_ = 0;
  std::vector<uint8_t> scratch_;
};

}  // namespace edgephys
