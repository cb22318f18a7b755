// ExternalRoom: the clients of one scenario room on an EXTERNAL edgephys-relay (RelayTarget,
// loadgen/relay_target.h), over real loopback UDP sockets, for the scenarios whose in-process
// run uses a LoopbackRoom (multiobject, softbody).
//
// The room name and player ids are fresh per instance (a random salt), so a rerun against the
// same relay never lands in an earlier run's room or replaces its sessions. The clients do not
// require packet authentication (measurement bots: a `--packet-auth false` relay is accepted).
//
// PhysicsSteps() is the relay's PhyS clock for driving kinematic bodies (a stirrer, hands): its
// edgephys_physics_steps_total, scraped at most every 0.2 s and extrapolated between scrapes at
// the last rate, so a relay stepping slower than real time slows the driven bodies with it.
// That counter covers every room of the relay.
//
// Thread-safety: none; one thread drives it. Cost: Update() is one Client::Update per member;
// PhysicsSteps() one /metrics scrape (a few ms on loopback) per 0.2 s.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

#include "client/client.h"
#include "loadgen/loopback_room.h"
#include "loadgen/relay_target.h"

namespace edgephys::loadgen {

// The host's listener in a scenario that spawns its scene: remembers the relay's first refusal
// (a spawn over a budget arrives as OnError after Spawn() returned an id), so the scenario ends
// with the relay's reason instead of waiting for entities that will never come.
class RefusalWatch : public ClientListener {
 public:
  void OnError(uint16_t reason, uint32_t entity_id, std::string_view detail) override;
  bool refused() const { return refused_; }
  // "OverBudget (entity 1234): <the relay's detail>"; empty before a refusal.
  const std::string& what() const { return what_; }

 private:
  bool refused_ = false;
  std::string what_;
};

class ExternalRoom {
 public:
  // `listeners[i]` (may be nullptr, or shorter than `members`) listens to member i; member 0
  // is the host and gets `host_config`, the others `config` (require_packet_auth is turned off
  // in both). Connects every member at once. `relay` must outlive the room.
  ExternalRoom(RelayTarget* relay, const std::string& prefix, size_t members,
               ClientConfig host_config, ClientConfig config,
               const std::vector<ClientListener*>& listeners);
  ~ExternalRoom();
  ExternalRoom(const ExternalRoom&) = delete;
  ExternalRoom& operator=(const ExternalRoom&) = delete;

  // Updates until every member has joined; false (and a line on stderr naming the first member
  // that did not, with its state and reject reason) after `timeout_s`.
  bool JoinAll(double timeout_s);
  // One Client::Update per member; a connected member that has not asked to join does.
  void Update();
  // Disconnects every member and flushes the Disconnects. Idempotent.
  void DisconnectAll();
  bool AllConnected() const;

  size_t size() const;
  Client& client(size_t i);
  const Client& client(size_t i) const;
  // Bytes member i's connection received (opened packets); 0 before it connected.
  uint64_t ReceivedBytes(size_t i) const;
  const std::string& room() const { return room_; }
  // Seconds since construction.
  double Now() const;
  // The relay's PhyS steps now (see the header comment); 0 if /metrics cannot be read.
  double PhysicsSteps();

 private:
  struct Member;
  RelayTarget* relay_;
  std::string room_;
  std::vector<Member> members_;
  std::chrono::steady_clock::time_point t0_;
  bool disconnected_ = false;
  double steps_base_ = 0, steps_at_ = -1, steps_rate_ = 0;
};

// What a PhyS scene run (multiobject, softbody) on an external relay holds beside its room: the
// relay's /metrics, the host's RefusalWatch and `receiver_count` receivers, each Receiver(index),
// with the room's listener list (the host's first).
template <typename Receiver>
struct ExternalSceneClients {
  ExternalSceneClients(const ExternalRelayOptions& external, uint32_t receiver_count,
                       const std::unordered_map<uint32_t, size_t>* index)
      : relay(external, std::chrono::steady_clock::now()) {
    ReceiverSet<Receiver> set = MakeReceiverSet<Receiver>(receiver_count, &host_watch, index);
    receivers = std::move(set.receivers);
    listeners = std::move(set.listeners);
  }

  RelayTarget relay;
  RefusalWatch host_watch;
  std::vector<std::unique_ptr<Receiver>> receivers;
  std::vector<ClientListener*> listeners;
};

// A PhyS scene run's room on an external relay: the host and the receivers of
// ExternalSceneClients. The host publishes at 120 Hz, so the kinematic bodies it drives (a
// stirrer, hands) reach PhyS with little delay; every member gives up a handshake after 10 s.
template <typename Receiver>
class ExternalSceneRoom : public ExternalSceneClients<Receiver>, public ExternalRoom {
 public:
  ExternalSceneRoom(const ExternalRelayOptions& external, const std::string& prefix,
                    uint32_t receiver_count, const std::unordered_map<uint32_t, size_t>* index)
      : ExternalSceneClients<Receiver>(external, receiver_count, index),
        ExternalRoom(&this->relay, prefix, receiver_count + 1, Config(true), Config(false),
                     this->listeners) {}

 private:
  static ClientConfig Config(bool host) {
    ClientConfig c;
    c.handshake_timeout_s = 10;
    if (host) c.publish_rate_hz = 120;
    return c;
  }
};

}  // namespace edgephys::loadgen
