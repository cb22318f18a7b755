// PhysicsWorker: the body of edgephys-phys, a remote PhyS worker. It connects to a relay as a
// client (join token with the Worker permission), says WorkerHello, and then runs one
// RoomPhysics per room the relay assigns to it: entities, drives, grabs and restores come in
// as Worker* control messages; every step's moved bodies go back as format-6 payloads,
// soft-body particles as format-8 payloads, events and grab answers as WorkerResult.
// Every room is reported at least every 0.2 s (a heartbeat), and all its bodies once a second
// (a refresh that repairs lost state payloads), so the relay can tell a stalled worker.
//
// Thread-safety: none; one thread drives the Client and Update(). Cost: the rooms' physics
// steps plus encoding their moved bodies.
#pragma once

#include <map>
#include <memory>
#include <vector>

#include "client/protocol_peer.h"
#include "physics_backend/room_physics.h"
#include "protocol/connection.h"

namespace edgephys {

class PhysicsWorker final : public ClientListener, public ControlMessageListener {
 public:
  // `client` is not owned; this worker must be its listener (pass it to the Client). Attach
  // also routes the client's Worker* messages here (ProtocolPeer::SetControlMessageListener).
  explicit PhysicsWorker(const physics::PhysicsConfig& config) : config_(config) {}
  void Attach(Client* client) {
    client_ = client;
    ProtocolPeer::SetControlMessageListener(*client, this);
  }

  void OnConnected(uint32_t player_id) override;
  void OnOtherMessage(const schema::ControlMessage& message) override;

  // Steps every assigned room up to `now` and reports.
  void Update(double now);

  size_t room_count() const { return rooms_.size(); }
  uint64_t steps() const { return steps_; }

 private:
  struct WorkerRoom {
    std::unique_ptr<RoomPhysics> physics;
    double last_report = -1e9;
    double last_refresh = -1e9;
  };
  void SendStates(uint32_t handle, const std::vector<RoomPhysics::MovedBody>& bodies, double now);
  Client* client_ = nullptr;
  physics::PhysicsConfig config_;
  std::map<uint32_t, WorkerRoom> rooms_;  // by relay room handle
  RoomPhysics::StepOutput out_;
  std::vector<RoomPhysics::MovedBody> snapshot_;
  std::vector<uint8_t> payload_ = std::vector<uint8_t>(kMaxUnreliablePayload);
  std::vector<Vec3f> restore_nodes_;  // a WorkerRestore's soft-body particles, reused
  double now_ = 0;
  uint64_t steps_ = 0;
};

}  // namespace edgephys
