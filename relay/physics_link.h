// PhysicsLink: where a room's PhyS runs, as the relay sees it. Two implementations:
//  * EmbeddedPhysicsLink: a RoomPhysics in the relay process (the default).
//  * RemotePhysicsLink: a room handle on an attached edgephys-phys worker; commands go out as
//    Worker* control messages, results come back asynchronously (ReceiveResult/ReceiveStates)
//    and are handed out by the next Advance().
// The relay keeps every entity's container, latest state and velocities, so when a worker
// dies or stalls it rebuilds the room on another link without losing an entity (failover).
//
// Thread-safety: none; the relay's thread. Cost: embedded Advance() is the physics step;
// remote calls serialise a small message each.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <unordered_set>
#include <vector>

#include "edgephys/schema/control_generated.h"
#include "physics_backend/room_physics.h"
#include "physics_backend/worker_protocol.h"
#include "protocol/connection.h"

namespace edgephys {

// Where a RemotePhysicsLink is registered for routing (the relay's WorkerDirectory); told when
// the link goes.
class PhysicsLinkRegistry {
 public:
  virtual ~PhysicsLinkRegistry() = default;
  virtual void Unregister(uint32_t worker_id, uint32_t handle) = 0;
};

class PhysicsLink {
 public:
  using StepOutput = RoomPhysics::StepOutput;
  virtual ~PhysicsLink() = default;
  // Validates and adds an entity (same rules embedded or remote). kInvalidArgument with a
  // detail naming the problem when the components are refused.
  virtual Status Add(const schema::Container& c, PhysicsRole role) = 0;
  virtual void Remove(uint32_t id) = 0;
  virtual void Drive(uint32_t id, const EntityState& state) = 0;
  // The answer arrives in a later Advance() output. `force` skips the hover check (failover).
  virtual void RequestGrab(uint32_t entity, uint32_t hand, bool force = false) = 0;
  virtual void Release(uint32_t entity) = 0;
  virtual void Restore(uint32_t id, const EntityState& state, const Vec3f& linear,
                       const Vec3f& angular) = 0;
  // Steps (embedded) or collects what the worker sent (remote) up to `now`.
  virtual void Advance(double now, StepOutput* out) = 0;
  // False when the link cannot go on (its worker disconnected or stopped answering).
  virtual bool Healthy(double now) const = 0;
  // Connection id of the worker session, 0 for embedded.
  virtual uint32_t worker() const = 0;
  virtual physics::PhysicsCounters counters() const = 0;
  // The link is being replaced after a failure: send nothing more (not even a goodbye).
  virtual void Detach() {}
};

class EmbeddedPhysicsLink final : public PhysicsLink {
 public:
  EmbeddedPhysicsLink(const physics::PhysicsConfig& config, double now) : physics_(config, now) {}
  Status Add(const schema::Container& c, PhysicsRole role) override {
    std::string detail;
    Status st = physics_.Add(c, role, &detail);
    if (st.ok() || detail.empty()) return st;
    return Status(st.code(), st.message(), std::move(detail));
  }
  void Remove(uint32_t id) override { physics_.Remove(id); }
  void Drive(uint32_t id, const EntityState& s) override { physics_.Drive(id, s); }
  void RequestGrab(uint32_t entity, uint32_t hand, bool force) override {
    physics_.RequestGrab(entity, hand, !force);
  }
  void Release(uint32_t entity) override { (void)physics_.Release(entity); }
  void Restore(uint32_t id, const EntityState& s, const Vec3f& l, const Vec3f& a) override {
    physics_.Restore(id, s, l, a);
  }
  void Advance(double now, StepOutput* out) override { physics_.Advance(now, out); }
  bool Healthy(double) const override { return true; }
  uint32_t worker() const override { return 0; }
  physics::PhysicsCounters counters() const override { return physics_.counters(); }

 private:
  RoomPhysics physics_;
};

// Sends reliable control messages to a worker; implemented by the relay's worker session.
class WorkerChannel {
 public:
  virtual ~WorkerChannel() = default;
  virtual bool SendToWorker(std::span<const uint8_t> message) = 0;  // false: link broken
  virtual bool WorkerConnected() const = 0;
};

class RemotePhysicsLink final : public PhysicsLink {
 public:
  // `channel` (not owned) must outlive the link or be detached with Detach().
  RemotePhysicsLink(WorkerChannel* channel, uint32_t worker_id, uint32_t room_handle,
                    const physics::PhysicsConfig& config, double now);
  ~RemotePhysicsLink() override;

  Status Add(const schema::Container& c, PhysicsRole role) override;
  void Remove(uint32_t id) override;
  void Drive(uint32_t id, const EntityState& state) override;
  void RequestGrab(uint32_t entity, uint32_t hand, bool force) override;
  void Release(uint32_t entity) override;
  void Restore(uint32_t id, const EntityState& s, const Vec3f& l, const Vec3f& a) override;
  void Advance(double now, StepOutput* out) override;
  bool Healthy(double now) const override;
  uint32_t worker() const override { return worker_id_; }
  physics::PhysicsCounters counters() const override { return counters_; }

  // From the worker: a WorkerResult for this room, and a state payload (format 6 or 8).
  void ReceiveResult(const schema::WorkerResult& result, double now);
  void ReceiveStates(std::span<const uint8_t> payload, double now);
  // The worker is gone: stop sending.
  void Detach() override { channel_ = nullptr; }
  uint32_t handle() const { return handle_; }
  // The registry that routes this link's messages (told on destruction); may be null.
  void set_registry(PhysicsLinkRegistry* registry) { registry_ = registry; }

 private:
  void Send(flatbuffers::FlatBufferBuilder& fbb);
  WorkerChannel* channel_;
  PhysicsLinkRegistry* registry_ = nullptr;
  uint32_t worker_id_;
  uint32_t handle_;
  physics::PhysicsWorld validator_;  // empty: checks components, never simulates
  std::unordered_set<uint32_t> ids_;
  StepOutput pending_;
  std::vector<schema::Pose> drives_;  // batched per Advance
  double last_heard_;
  double stall_timeout_s_ = 0.75;  // a worker reports every 0.2 s; silence beyond: stalled
  physics::PhysicsCounters counters_{};
  bool broken_ = false;
};

}  // namespace edgephys
