// LoopbackRoom: the harness of the PhyS load scenarios (multiobject, softbody): an in-process
// relay on loopback UDP, a host client and receivers, plus the measurements they share (relay
// egress per receiver and PhyS step time over a window, trusted benchmark relay settings).
// Thread-safety: none; one thread drives the relay and the clients.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "client/client.h"
#include "protocol/container_builder.h"
#include "protocol/udp_socket.h"
#include "relay/relay.h"

namespace edgephys::loadgen {

// Runs `step()` (then sleeps 300 us) until every one of `clients` (Connect already called) is
// connected, then has each join `room` and runs until every one has joined; false as soon as a
// phase outlasts `timeout_s` seconds of `now()`. Shared by LoopbackRoom and relay-compare.
bool ConnectAndJoinAll(const std::vector<std::unique_ptr<Client>>& clients, const std::string& room,
                       double timeout_s, const std::function<double()>& now,
                       const std::function<void()>& step);

// An in-process relay on a loopback UDP socket with `clients` clients (client 0 the host),
// each with its own socket; player ids 1..clients. Shared by multiobject and softbody.
class LoopbackRoom {
 public:
  // `listeners[i]` (may be shorter, or hold nullptr) listens to client i.
  LoopbackRoom(const RelayConfig& config, std::string room, uint32_t clients,
               const ClientConfig& host_config, const std::vector<ClientListener*>& listeners);
  ~LoopbackRoom();
  // Connects every client and joins the room; false after `timeout_s` without success.
  bool ConnectAndJoin(double timeout_s);
  // One round: the relay, then every client.
  void Step() {
    UpdateRelay();
    UpdateClients();
  }
  void UpdateRelay();
  void UpdateClients();
  double Now() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }
  Relay& relay() { return *relay_; }
  RelayCounters& counters() { return counters_; }
  Client& client(size_t i) { return *clients_[i]; }
  size_t client_count() const { return clients_.size(); }
  const Room* room() const { return relay_->FindRoom(room_); }

 private:
  std::string room_;
  std::chrono::steady_clock::time_point start_;
  RelayCounters counters_;
  std::unique_ptr<UdpSocket> relay_socket_;
  std::unique_ptr<Relay> relay_;
  std::string secret_;
  std::vector<std::unique_ptr<UdpSocket>> sockets_;
  std::vector<std::unique_ptr<Client>> clients_;
};

// The receiving clients' listeners of a room (LoopbackRoom or ExternalRoom), owned here, and the
// listener list the room takes: the host's first, then each receiver's.
template <typename Receiver>
struct ReceiverSet {
  std::vector<std::unique_ptr<Receiver>> receivers;
  std::vector<ClientListener*> listeners;
};

// `count` receivers, each Receiver(arg); `host` (may be null) listens to the host.
template <typename Receiver, typename Arg>
ReceiverSet<Receiver> MakeReceiverSet(uint32_t count, ClientListener* host, Arg arg) {
  ReceiverSet<Receiver> set;
  set.listeners.push_back(host);
  for (uint32_t i = 0; i < count; ++i) {
    set.receivers.push_back(std::make_unique<Receiver>(arg));
    set.listeners.push_back(set.receivers.back().get());
  }
  return set;
}

// Counted observations of RelayCounters::physics_step_seconds (all buckets).
uint64_t HistogramCount(const AtomicHistogram<10>& h);

// A relay configuration for a trusted benchmark host: edgephys mode at the given quantisation,
// 60 Hz ticks, room for `receivers` + host, `max_entities` per player, abuse limits off (the
// host spawns a whole scene at once).
RelayConfig BenchmarkRelayConfig(uint32_t receivers, uint32_t max_entities, float position_step_m,
                                 float rotation_bound_deg);

// The spawn of a dissected entity, handed to PhyS (Offloaded).
SpawnDesc OffloadedSpawn(const EntitySpec& spec);

// Relay egress to the receivers (clients 1..n) and PhyS step counts over a measured window.
class WindowMeter {
 public:
  struct Totals {
    double elapsed_s = 0;
    double relay_bytes = 0;      // the relay's per-connection bytes sent, summed over receivers
    double socket_bytes = 0;     // the receivers' sockets' bytes received
    double socket_packets = 0;   // and datagrams (each carries kIpUdpHeaderBytes more)
    uint64_t physics_steps = 0;
    double step_ms_mean = 0;     // the relay's mean PhyS step over the window
    // Per receiver, per second, in Mb/s (10^6 bits).
    double RelayMbitPerReceiver(size_t receivers) const {
      return relay_bytes * 8 / 1e6 / (static_cast<double>(receivers) * elapsed_s);
    }
    double SocketMbitPerReceiver(size_t receivers) const {
      return socket_bytes * 8 / 1e6 / (static_cast<double>(receivers) * elapsed_s);
    }
    double IpUdpMbitPerReceiver(size_t receivers) const {
      return socket_packets * kIpUdpHeaderBytes * 8 / 1e6 /
             (static_cast<double>(receivers) * elapsed_s);
    }
  };
  void Start(LoopbackRoom& world, size_t receivers);
  Totals Finish(LoopbackRoom& world) const;

 private:
  size_t receivers_ = 0;
  std::vector<uint64_t> relay_bytes0_, socket_bytes0_, socket_packets0_;
  uint64_t steps0_ = 0, step_count0_ = 0;
  double step_sum0_ = 0, t0_ = 0;
};

// Runs `round` until the relay's PhyS ran `steps` more steps or `max_s` wall seconds passed.
template <typename Round>
void RunPhysicsSteps(LoopbackRoom& world, uint64_t steps, double max_s, Round&& round) {
  const uint64_t start = RelayCounters::Get(world.counters().physics_steps);
  const double t0 = world.Now();
  while (RelayCounters::Get(world.counters().physics_steps) - start < steps && world.Now() - t0 < max_s) {
    round();
  }
}

double Dist(const Vec3f& a, const Vec3f& b);
inline double Seconds(std::chrono::steady_clock::duration d) {
  return std::chrono::duration<double>(d).count();
}

}  // namespace edgephys::loadgen
